//! `flexsens-fuzz`: a mutation fuzzer for flexsens's input readers, on stable Rust.
//!
//! Each target takes seed inputs (the shipped decks, the malformed-input corpus of
//! `tests/corpus`, mesh files, result files), mutates them (numbers replaced by extreme values,
//! lines deleted, repeated, swapped or spliced from another seed, bytes flipped, inserted or
//! deleted) and feeds them through the same library path as the command line:
//!
//! | target | input mutated | path exercised |
//! |---|---|---|
//! | `deck` | a deck | `flexsens check`: reader, validation, section and modal analyses, model build and assembly |
//! | `section-simple` | a simple-format section mesh | `flexsens section` on a deck reading it |
//! | `section-gmsh` | a Gmsh section mesh | `flexsens section` on a deck reading it |
//! | `shell-gmsh` | a Gmsh shell mesh | `flexsens modes` on a deck reading it |
//! | `hdf5` | a result file | `flexsens compare`'s reader and comparison |
//! | `merge` | a sweep shard's manifest and case list | `flexsens merge` of it with a valid second shard |
//!
//! An error is the expected answer to bad input; a panic is a crash. Crashing inputs are saved
//! in the output directory with their panic message, and the exit code is 1. The input being
//! run is kept in `OUT/TARGET.current` until it returns, so an abort (an allocation failure
//! under `ulimit -v`) or a hang (no answer within `--timeout`, exit code 3) leaves it behind.
//! Limits ([`flexsens::limits`]) are set small, as a user's `--max-*` flags would, so that the
//! size checks themselves are exercised and each input runs in milliseconds.
//!
//! The run is deterministic for a given `--seed` and iteration count. See `docs/fuzzing.md`.

use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::{Parser, ValueEnum};
use flexsens::commands::{self, Format};
use flexsens::limits::{self, Limits};
use flexsens::results::{Group, compare};

#[derive(Parser)]
#[command(
    name = "flexsens-fuzz",
    about = "Mutation fuzzing of flexsens's input readers"
)]
struct Args {
    /// Targets to fuzz, one after the other (default: all).
    #[arg(value_enum)]
    targets: Vec<Target>,
    /// Time per target, seconds.
    #[arg(long, default_value_t = 30.0)]
    seconds: f64,
    /// At most this many inputs per target (default: no limit but the time).
    #[arg(long)]
    iterations: Option<u64>,
    /// Seed of the random mutations.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A run that takes longer than this many seconds is reported as a hang.
    #[arg(long, default_value_t = 60.0)]
    timeout: f64,
    /// Where crashing inputs and the input being run are written.
    #[arg(long, default_value = "target/fuzz")]
    out: PathBuf,
    /// The project's root (seed inputs are read below it).
    #[arg(long, default_value = ".")]
    root: PathBuf,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum, Debug)]
enum Target {
    Deck,
    SectionSimple,
    SectionGmsh,
    ShellGmsh,
    Hdf5,
    Merge,
}

impl Target {
    const ALL: [Target; 6] = [
        Target::Deck,
        Target::SectionSimple,
        Target::SectionGmsh,
        Target::ShellGmsh,
        Target::Hdf5,
        Target::Merge,
    ];

    fn name(self) -> &'static str {
        match self {
            Target::Deck => "deck",
            Target::SectionSimple => "section-simple",
            Target::SectionGmsh => "section-gmsh",
            Target::ShellGmsh => "shell-gmsh",
            Target::Hdf5 => "hdf5",
            Target::Merge => "merge",
        }
    }

    /// The name the mutated input is written under in the work directory.
    fn file_name(self) -> &'static str {
        match self {
            Target::Deck => "deck.toml",
            Target::SectionSimple => "mesh.txt",
            Target::SectionGmsh => "mesh.msh",
            Target::ShellGmsh => "shell.msh",
            Target::Hdf5 => "results.h5",
            Target::Merge => "shard.merge",
        }
    }

    fn binary(self) -> bool {
        self == Target::Hdf5
    }

    /// Seed files, relative to the project root: (directory, file name ending).
    fn seed_globs(self) -> &'static [(&'static str, &'static str)] {
        match self {
            Target::Deck => &[("decks", ".toml"), ("tests/corpus/inputs", ".toml")],
            Target::SectionSimple => &[("fuzz/seeds", ".txt"), ("tests/corpus/inputs", ".txt")],
            Target::SectionGmsh => &[("crates/section/tests/data", ".msh")],
            Target::ShellGmsh => &[("fuzz/seeds", ".msh")],
            Target::Hdf5 => &[("crates/cli/tests/golden", ".h5")],
            Target::Merge => &[("fuzz/seeds", ".merge")],
        }
    }
}

/// The orthotropic material of the fixed decks.
const CARBON: &str = r#"
[material.cf]
E1 = 140e9
E2 = 10e9
E3 = 10e9
G12 = 5e9
G13 = 5e9
G23 = 3.5e9
nu12 = 0.3
nu13 = 0.3
nu23 = 0.45
density = 1600
"#;

/// The fixed deck that reads a mutated simple-format section mesh (after [`CARBON`]).
const SECTION_DECK: &str = r#"
[material.al]
E = 70e9
nu = 0.33
density = 2700
[section.simple]
shape = "mesh"
file = "mesh.txt"
format = "simple"
"#;

/// The fixed deck that reads a mutated Gmsh section mesh (after [`CARBON`]).
const SECTION_GMSH_DECK: &str = r#"
[section.tube]
shape = "mesh"
file = "mesh.msh"
regions = { inner = { material = "cf", angle = 15.0, frame = "radial" }, outer = { material = "cf", angle = -15.0, frame = "xi" } }
"#;

/// The fixed deck that reads a mutated Gmsh shell mesh (after [`CARBON`]).
const SHELL_DECK: &str = r#"
[laminate.plate]
plies = [{ material = "cf", thickness = 1e-3, angle = 30.0 }, { material = "cf", thickness = 1e-3, angle = -30.0 }]
[body.plate]
kind = "shell"
laminate = "plate"
file = "shell.msh"
modes = 3
reference = "free-free"
"#;

/// xorshift64*: small, fast and deterministic.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers that break things: zero, signs, extremes, non-finite values, integer edges.
const INTERESTING_NUMBERS: [&str; 24] = [
    "0",
    "-0.0",
    "1",
    "-1",
    "2",
    "3",
    "1e-300",
    "-1e-300",
    "1e300",
    "-1e300",
    "1.7e308",
    "nan",
    "inf",
    "-inf",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "1000000000",
    "100000",
    "0.5",
    "1e-12",
    "360",
    "99999999999999999999999",
];

/// Whole lines worth splicing into a deck: tables and keys with extreme or odd values.
const INTERESTING_LINES: [&str; 12] = [
    "[analysis]\nt_end = 1e-3\n",
    "elements = 100000000\n",
    "modes = 1000000\n",
    "[design.x]\nkind = \"ply-angle\"\n",
    "angle = nan\n",
    "integrator = \"fixed\"\nstep = 1e-15\n",
    "reference = \"supports\"\n",
    "redundant = \"error\"\n",
    "$Nodes\n1 99999999999 1 99999999999\n",
    "element quad8 core 1 1 1 1 1 1 1 1\n",
    "node 1 nan nan\n",
    "[joint.j]\nkind = \"fixed\"\na = { body = \"ground\", point = [0, 0, 0] }\n",
];

/// Apply 1 to 4 random mutations to `input`; `other` is another seed for splicing.
fn mutate(rng: &mut Rng, input: &[u8], other: &[u8], binary: bool) -> Vec<u8> {
    let mut data = input.to_vec();
    let count = 1 + rng.below(4);
    for _ in 0..count {
        let choice = if binary {
            rng.below(6)
        } else {
            6 + rng.below(7)
        };
        mutate_once(rng, &mut data, other, choice);
    }
    data
}

fn mutate_once(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8], choice: usize) {
    let n = data.len();
    match choice {
        // byte level (every target)
        0 if n > 0 => {
            let i = rng.below(n);
            data[i] ^= 1 << rng.below(8);
        }
        1 => {
            let i = rng.below(n + 1);
            data.insert(i, rng.next() as u8);
        }
        2 if n > 0 => {
            let i = rng.below(n);
            let len = (1 + rng.below(16)).min(n - i);
            data.drain(i..i + len);
        }
        3 if n > 0 => {
            // an integer field overwritten with an edge value (binary formats' counts/offsets)
            let edges: [u64; 6] = [0, 1, 0xff, 0xffff_ffff, 0x7fff_ffff_ffff_ffff, u64::MAX];
            let v = rng.pick(&edges).to_le_bytes();
            let width = *rng.pick(&[1usize, 2, 4, 8]);
            let i = rng.below(n);
            for (k, b) in v.iter().take(width).enumerate() {
                if let Some(d) = data.get_mut(i + k) {
                    *d = *b;
                }
            }
        }
        4 if n > 0 => {
            // a range repeated
            let i = rng.below(n);
            let len = (1 + rng.below(64)).min(n - i);
            let chunk = data[i..i + len].to_vec();
            let at = rng.below(n + 1);
            data.splice(at..at, chunk);
        }
        5 if !other.is_empty() && n > 0 => {
            // a range of another seed spliced in
            let i = rng.below(other.len());
            let len = (1 + rng.below(256)).min(other.len() - i);
            let at = rng.below(n + 1);
            data.splice(at..at, other[i..i + len].iter().copied());
        }
        // text level
        6 | 7 => replace_number(rng, data),
        8 => edit_lines(rng, data, other),
        9 => {
            let line = rng.pick(&INTERESTING_LINES).as_bytes();
            let at = line_start(rng, data);
            data.splice(at..at, line.iter().copied());
        }
        10 => {
            let byte_level = rng.below(6);
            mutate_once(rng, data, other, byte_level)
        }
        11 => {
            // a token (word) duplicated elsewhere: names, keys, element kinds
            let words: Vec<(usize, usize)> = word_spans(data);
            if let (Some(&(a, b)), Some(&(c, d))) = (
                words.get(rng.below(words.len())),
                words.get(rng.below(words.len())),
            ) {
                let w = data[a..b].to_vec();
                data.splice(c..d, w);
            }
        }
        _ => replace_number(rng, data),
    }
}

/// The start of a random line.
fn line_start(rng: &mut Rng, data: &[u8]) -> usize {
    let starts: Vec<usize> = std::iter::once(0)
        .chain(
            data.iter()
                .enumerate()
                .filter(|(_, b)| **b == b'\n')
                .map(|(i, _)| i + 1),
        )
        .collect();
    *rng.pick(&starts)
}

/// Spans of runs of letters, digits, `_`, `-`, `.`, `+` (numbers and words).
fn token_spans(data: &[u8], keep: impl Fn(&[u8]) -> bool) -> Vec<(usize, usize)> {
    let is_tok = |b: u8| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.' | b'+');
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if is_tok(data[i]) {
            let start = i;
            while i < data.len() && is_tok(data[i]) {
                i += 1;
            }
            if keep(&data[start..i]) {
                spans.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    spans
}

fn word_spans(data: &[u8]) -> Vec<(usize, usize)> {
    token_spans(data, |t| t[0].is_ascii_alphabetic())
}

fn replace_number(rng: &mut Rng, data: &mut Vec<u8>) {
    let numbers = token_spans(data, |t| {
        t[0].is_ascii_digit() || (t.len() > 1 && matches!(t[0], b'-' | b'+' | b'.'))
    });
    if numbers.is_empty() {
        return;
    }
    let (a, b) = *rng.pick(&numbers);
    let replacement = if rng.below(4) == 0 {
        // the same number scaled by a power of ten
        let text = String::from_utf8_lossy(&data[a..b]).into_owned();
        match text.parse::<f64>() {
            Ok(x) => format!("{:e}", x * 10f64.powi(rng.below(40) as i32 - 20)),
            Err(_) => "0".into(),
        }
    } else {
        rng.pick(&INTERESTING_NUMBERS).to_string()
    };
    data.splice(a..b, replacement.into_bytes());
}

fn edit_lines(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    let text = String::from_utf8_lossy(data).into_owned();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        return;
    }
    let i = rng.below(lines.len());
    match rng.below(4) {
        0 => {
            lines.remove(i);
        }
        1 => {
            let l = lines[i].clone();
            let at = rng.below(lines.len() + 1);
            lines.insert(at, l);
        }
        2 => {
            let j = rng.below(lines.len());
            lines.swap(i, j);
        }
        _ => {
            let other_text = String::from_utf8_lossy(other);
            let other_lines: Vec<&str> = other_text.lines().collect();
            if !other_lines.is_empty() {
                lines.insert(i, rng.pick(&other_lines).to_string());
            }
        }
    }
    *data = (lines.join("\n") + "\n").into_bytes();
}

/// Run one input through its target. `Ok` whatever the program answered; the caller catches
/// panics.
fn execute(target: Target, work: &Path, input: &[u8]) -> String {
    let file = work.join(target.file_name());
    std::fs::write(&file, input).expect("the work directory is writable");
    let outcome: Result<String, String> = match target {
        Target::Deck => commands::check::run(&file, &[]).map_err(|e| e.to_string()),
        Target::SectionSimple | Target::SectionGmsh => {
            let deck = work.join("section.toml");
            commands::section::run(&deck, &[], None, Format::Json, (true, &[]))
                .map_err(|e| e.to_string())
        }
        Target::ShellGmsh => {
            let deck = work.join("shell.toml");
            let req = commands::modes::ModesRequest {
                only: None,
                format: Format::Json,
                derivatives: false,
                vtk: None,
                export_matrices: None,
            };
            commands::modes::run(&deck, &[], &req).map_err(|e| e.to_string())
        }
        Target::Hdf5 => Group::from_hdf5_bytes(input.to_vec()).map(|g| {
            let c = compare(&g, &g, 0.0, 0.0);
            format!("{} datasets, same: {}", g.flatten().len(), c.matches())
        }),
        Target::Merge => merge_shards(work, input),
    };
    match outcome {
        Ok(_) => "ok".into(),
        Err(e) => e.lines().next().unwrap_or("").to_string(),
    }
}

/// The second shard of the sweep the `merge` seeds are the first shard of (as `sweep --shard
/// 2/2` writes it): its manifest and case list.
const SHARD_2: [&str; 2] = [
    r#"{"cases": 2, "command": "sweep", "deck": "rigid.toml",
"deck_fingerprint": "fde47ca3085bbf24", "flexsens_version": "@VERSION@",
"set": ["analysis.t_end=0.002"], "shard": [2, 2], "vary": ["rigid.slider.mass=0.04,0.05"]}"#,
    r#"{"case":2,"summary":{"design":[],"max_position_violation":4.8e-10,"objectives":[],"steps":35}}"#,
];

/// `flexsens merge` of a first shard made from `input` (its `shard.json`, a line
/// `# cases.jsonl`, then its `cases.jsonl`; `@VERSION@` stands for this build's version) and
/// the valid [`SHARD_2`], each with the case directory its case list names; made afresh for
/// every input, since a merge moves the case directories.
fn merge_shards(work: &Path, input: &[u8]) -> Result<String, String> {
    let dir = work.join("merge");
    let _ = std::fs::remove_dir_all(&dir);
    let version = env!("CARGO_PKG_VERSION");
    let text = String::from_utf8_lossy(input).replace("@VERSION@", version);
    let (manifest, cases) = text
        .split_once("\n# cases.jsonl\n")
        .unwrap_or((text.as_str(), ""));
    let second = SHARD_2.map(|s| s.replace("@VERSION@", version));
    let shards = [dir.join("shard_1"), dir.join("shard_2")];
    for (d, [manifest, cases], case) in [
        (&shards[0], [manifest, cases], "case_001"),
        (
            &shards[1],
            [second[0].as_str(), second[1].as_str()],
            "case_002",
        ),
    ] {
        std::fs::create_dir_all(d.join(case)).expect("the work directory is writable");
        std::fs::write(d.join("shard.json"), manifest).expect("writable");
        std::fs::write(d.join("cases.jsonl"), cases).expect("writable");
        std::fs::write(d.join(case).join("results.h5"), b"(merge reads no result)")
            .expect("writable");
    }
    commands::merge::merge(&shards, &dir.join("out"))
        .map(|(t, _)| t)
        .map_err(|e| e.to_string())
}

/// The first words of an answer with numbers and paths blurred: a rough count of the
/// distinct error kinds reached.
fn kind_of(answer: &str) -> String {
    let after_key = answer.rsplit("`: ").next().unwrap_or(answer);
    after_key
        .split_whitespace()
        .take(4)
        .map(|w| {
            if w.chars().any(|c| c.is_ascii_digit() || c == '/') {
                "#"
            } else {
                w
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn read_seeds(root: &Path, target: Target) -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    for (dir, ending) in target.seed_globs() {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        let mut paths: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.to_string_lossy().ends_with(ending))
            .collect();
        paths.sort();
        for p in paths {
            if let Ok(bytes) = std::fs::read(&p) {
                seeds.push(bytes);
            }
        }
    }
    seeds
}

/// The panic message of the last panic on this thread.
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    let targets = if args.targets.is_empty() {
        Target::ALL.to_vec()
    } else {
        args.targets.clone()
    };
    limits::set(Limits {
        elements: 2_000,
        steps: 10_000,
        cases: 10,
        input_bytes: 1 << 22,
        memory: 1 << 30,
    });
    panic::set_hook(Box::new(|info| {
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        *LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!("{msg}{at}"));
    }));
    std::fs::create_dir_all(&args.out).expect("the output directory can be created");
    let work = args.out.join("work");
    std::fs::create_dir_all(&work).expect("the work directory can be created");
    std::fs::write(work.join("shell.toml"), format!("{CARBON}{SHELL_DECK}")).expect("writable");
    // watchdog: the start of the current input, ms since `epoch` (0: none running)
    let epoch = Instant::now();
    let started = Arc::new(AtomicU64::new(0));
    let current: Arc<Mutex<PathBuf>> = Arc::new(Mutex::new(PathBuf::new()));
    {
        let started = started.clone();
        let current = current.clone();
        let timeout = Duration::from_secs_f64(args.timeout);
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_millis(200));
                let s = started.load(Ordering::SeqCst);
                if s > 0 && epoch.elapsed() > Duration::from_millis(s) + timeout {
                    let c = current.lock().unwrap_or_else(|e| e.into_inner()).clone();
                    println!(
                        "HANG: an input ran for more than {:.0} s; it is kept as {}",
                        timeout.as_secs_f64(),
                        c.display()
                    );
                    std::process::exit(3);
                }
            }
        });
    }
    let mut crashes = 0usize;
    for target in targets {
        let deck = if target == Target::SectionGmsh {
            SECTION_GMSH_DECK
        } else {
            SECTION_DECK
        };
        std::fs::write(work.join("section.toml"), format!("{CARBON}{deck}")).expect("writable");
        let seeds = read_seeds(&args.root, target);
        if seeds.is_empty() {
            println!(
                "{}: no seed inputs found below {} (run from the project root or pass --root)",
                target.name(),
                args.root.display()
            );
            return std::process::ExitCode::from(2);
        }
        let current_file = args.out.join(format!("{}.current", target.name()));
        *current.lock().unwrap_or_else(|e| e.into_inner()) = current_file.clone();
        let mut rng = Rng(args.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
        let t0 = Instant::now();
        let mut runs = 0u64;
        let mut kinds = std::collections::BTreeMap::<String, u64>::new();
        while t0.elapsed().as_secs_f64() < args.seconds && args.iterations.is_none_or(|n| runs < n)
        {
            let seed = rng.pick(&seeds).clone();
            let other = rng.pick(&seeds).clone();
            // one run in eight takes a seed as it is
            let input = if runs.is_multiple_of(8) && (runs / 8) < seeds.len() as u64 {
                seeds[(runs / 8) as usize].clone()
            } else {
                mutate(&mut rng, &seed, &other, target.binary())
            };
            std::fs::write(&current_file, &input).expect("writable");
            started.store(epoch.elapsed().as_millis() as u64 + 1, Ordering::SeqCst);
            let answer = panic::catch_unwind(AssertUnwindSafe(|| execute(target, &work, &input)));
            started.store(0, Ordering::SeqCst);
            runs += 1;
            match answer {
                Ok(a) => *kinds.entry(kind_of(&a)).or_default() += 1,
                Err(_) => {
                    crashes += 1;
                    let msg = LAST_PANIC
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .take()
                        .unwrap_or_default();
                    let saved = args.out.join(format!(
                        "crash-{}-{runs}.{}",
                        target.name(),
                        target.file_name().rsplit('.').next().unwrap_or("bin")
                    ));
                    let _ = std::fs::write(&saved, &input);
                    println!(
                        "CRASH {}: {msg}\n  input kept as {}",
                        target.name(),
                        saved.display()
                    );
                }
            }
        }
        let _ = std::fs::remove_file(&current_file);
        let secs = t0.elapsed().as_secs_f64();
        println!(
            "{}: {runs} inputs in {secs:.0} s ({:.0}/s) from {} seeds, {} distinct answers ({} ok)",
            target.name(),
            runs as f64 / secs.max(1e-9),
            seeds.len(),
            kinds.len(),
            kinds.get("ok").copied().unwrap_or(0)
        );
    }
    println!("{crashes} crashes");
    if crashes > 0 {
        std::process::ExitCode::from(1)
    } else {
        std::process::ExitCode::SUCCESS
    }
}
