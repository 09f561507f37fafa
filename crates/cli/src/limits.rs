//! Size limits: every count read from a deck, a mesh file or the command line that sizes an
//! allocation or a loop is checked against these before anything is allocated or run, so that
//! no input can exhaust memory or run for ever. Each limit has a default and a command-line
//! override (`--max-elements`, `--max-steps`, `--max-cases`, `--max-input-bytes`,
//! `--max-memory`); an input
//! over a limit is refused as bad input (exit code 2) with the key, the value, the limit and
//! the flag that raises it.
//!
//! The limits are process-wide: the binary sets them once from its flags before running a
//! command; tests and the fuzz driver may set smaller ones.

use std::io::Read;
use std::path::Path;
use std::sync::RwLock;

/// The limits in force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Elements (cells) of one generated or read mesh, and of one direction of a generated
    /// mesh (`--max-elements`).
    pub elements: usize,
    /// Time steps of a fixed-step run, and step attempts of an adaptive one (`--max-steps`).
    pub steps: usize,
    /// Cases of one sweep (`--max-cases`).
    pub cases: usize,
    /// Bytes of one input file: a deck, a mesh, a result file (`--max-input-bytes`).
    pub input_bytes: u64,
    /// Bytes one analysis may need by its estimate (`--max-memory`), checked before it
    /// allocates: a cross-section's warping analysis at [`SECTION_BYTES_PER_ELEMENT`], a
    /// flexible body's modal analysis at [`BEAM_BYTES_PER_ELEMENT`] or
    /// [`SHELL_BYTES_PER_ELEMENT`].
    pub memory: u64,
}

/// The memory a cross-section's warping analysis needs per element of its mesh, about: the
/// assembled system and its sparse Cholesky factor (the fill of a 2-D mesh's nested
/// dissection). Measured (peak resident size): 19 KB per element for tubes of 2 000–33 000
/// elements, 25–26 KB for rectangles of 10 000–40 000; it grows slowly with the size.
pub const SECTION_BYTES_PER_ELEMENT: u64 = 32 * 1024;

/// The memory a beam body's modal analysis needs per element, about (its matrices, their
/// sparse factor, the eigensolver's vectors and the modal body). Measured (peak resident size
/// of `flexsens modes`, four modes): 12.8 KiB per element at 100 000 elements, 14 KiB at
/// 400 000.
pub const BEAM_BYTES_PER_ELEMENT: u64 = 16 * 1024;

/// The memory a shell body's modal analysis needs per triangle, about. Measured (peak resident
/// size of `flexsens modes` on a square plate): 16–17 KiB per triangle from 8 000 to 65 000
/// triangles with four modes, 17.5 KiB with twenty.
pub const SHELL_BYTES_PER_ELEMENT: u64 = 24 * 1024;

impl Limits {
    /// The defaults: generous for real work, small enough to fail at once on a typo.
    pub const DEFAULT: Limits = Limits {
        elements: 1_000_000,
        steps: 1_000_000,
        cases: 100_000,
        input_bytes: 1 << 28,
        memory: 16 << 30,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

static LIMITS: RwLock<Limits> = RwLock::new(Limits::DEFAULT);

/// The limits in force.
pub fn get() -> Limits {
    *LIMITS.read().unwrap_or_else(|e| e.into_inner())
}

/// Put `limits` in force for the rest of the process. A count above `i64::MAX` (more than any
/// deck can write) means no limit and is held there, so that comparing it with a deck's
/// signed integers cannot wrap.
pub fn set(limits: Limits) {
    let held = |n: usize| n.min(i64::MAX as usize);
    let limits = Limits {
        elements: held(limits.elements),
        steps: held(limits.steps),
        cases: held(limits.cases),
        input_bytes: limits.input_bytes,
        memory: limits.memory,
    };
    *LIMITS.write().unwrap_or_else(|e| e.into_inner()) = limits;
}

/// A `--max-*` count on the command line: a whole number of at least 1.
pub fn parse_count(arg: &str) -> Result<usize, String> {
    let digits = arg.trim();
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("`{arg}` is not a whole number"));
    }
    if digits.bytes().all(|b| b == b'0') {
        return Err("a limit of 0 would refuse every input: give at least 1".into());
    }
    // a count beyond the machine's is no limit
    Ok(digits.parse::<usize>().unwrap_or(usize::MAX))
}

/// `--max-input-bytes`: a whole number of at least 1.
pub fn parse_bytes(arg: &str) -> Result<u64, String> {
    parse_count(arg).map(|n| n as u64)
}

/// Read a whole input file as bytes, refusing one larger than the input-size limit before
/// reading it, and stopping at the limit for files whose size is not known in advance (pipes,
/// devices such as `/dev/zero`). The error is a sentence for the caller to prefix with what
/// the file is.
pub fn read_input(path: &Path) -> Result<Vec<u8>, String> {
    read_bounded(path, get().input_bytes)
}

/// [`read_input`] with the limit `max`.
fn read_bounded(path: &Path, max: u64) -> Result<Vec<u8>, String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let meta = file.metadata().map_err(|e| e.to_string())?;
    if meta.is_dir() {
        return Err("it is a directory".into());
    }
    let too_large = |size: &str| {
        format!(
            "{size} is more than the limit of {max} bytes for an input file (--max-input-bytes \
             raises it)"
        )
    };
    if meta.is_file() && meta.len() > max {
        return Err(too_large(&format!("its size of {} bytes", meta.len())));
    }
    let mut bytes = Vec::new();
    file.take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > max {
        return Err(too_large("its content"));
    }
    Ok(bytes)
}

/// Read a whole text input file (UTF-8) under the input-size limit, see [`read_input`].
pub fn read_text(path: &Path) -> Result<String, String> {
    utf8(read_input(path)?)
}

fn utf8(bytes: Vec<u8>) -> Result<String, String> {
    String::from_utf8(bytes).map_err(|e| {
        format!(
            "it is not UTF-8 text (byte {})",
            e.utf8_error().valid_up_to()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A count on the command line is a whole number of at least 1; one beyond the machine's
    /// counts is no limit.
    #[test]
    fn command_line_counts_are_whole_and_positive() {
        assert_eq!(parse_count("25"), Ok(25));
        assert_eq!(parse_count("18446744073709551616000"), Ok(usize::MAX));
        for bad in ["0", "000", "-5", "1e6", "", "ten"] {
            assert!(parse_count(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_bytes("4096"), Ok(4096));
    }

    #[test]
    fn reading_stops_at_the_limit_for_unsized_files() {
        if Path::new("/dev/zero").exists() {
            let e = read_bounded(Path::new("/dev/zero"), 1000).unwrap_err();
            assert!(
                e.contains("its content is more than the limit of 1000"),
                "{e}"
            );
        }
        let dir = tempfile::tempdir().unwrap();
        let small = dir.path().join("small");
        std::fs::write(&small, vec![b'a'; 1000]).unwrap();
        let large = dir.path().join("large");
        std::fs::write(&large, vec![b'a'; 1001]).unwrap();
        assert_eq!(read_bounded(&small, 1000).unwrap().len(), 1000);
        let e = read_bounded(&large, 1000).unwrap_err();
        assert!(e.contains("its size of 1001 bytes"), "{e}");
        assert_eq!(
            read_bounded(dir.path(), 1000).unwrap_err(),
            "it is a directory"
        );
        std::fs::write(&small, [b'a', 0xff]).unwrap();
        let e = utf8(read_bounded(&small, 1000).unwrap()).unwrap_err();
        assert_eq!(e, "it is not UTF-8 text (byte 1)");
    }
}
