//! `flexsens compare A.h5 B.h5`: dataset-by-dataset comparison of two result files, for
//! golden-file checks in CI. Exit code 1 on mismatch, 2 when a file cannot be read.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::CliError;
use crate::results::{Group, compare};

/// How many differences are listed.
const SHOWN: usize = 20;

/// Compare: the report, and whether the files match.
pub fn run(a: &Path, b: &Path, rtol: f64, atol: f64) -> Result<(String, bool), CliError> {
    for (name, v) in [("--rtol", rtol), ("--atol", atol)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(CliError::Usage(format!(
                "{name} {v} must be a finite number ≥ 0"
            )));
        }
    }
    // a file that cannot be read is bad input (exit 2), not a difference (exit 1): a CI script
    // can tell them apart
    let read = |p: &Path| {
        Group::read_hdf5(p).map_err(|e| match e {
            CliError::Runtime(m) => CliError::Usage(m),
            other => other,
        })
    };
    let ga = read(a)?;
    let gb = read(b)?;
    let c = compare(&ga, &gb, rtol, atol);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "compared {} datasets, {} values: {} vs {} (rtol {rtol:e}, atol {atol:e})",
        c.datasets,
        c.values,
        a.display(),
        b.display()
    );
    if c.matches() {
        let _ = writeln!(s, "match");
        return Ok((s, true));
    }
    for p in &c.problems {
        let _ = writeln!(s, "  {p}");
    }
    if !c.differences.is_empty() {
        let _ = writeln!(
            s,
            "  {} datasets differ beyond the tolerance; largest first:",
            c.differences.len()
        );
        for d in c.differences.iter().take(SHOWN) {
            let at = match d.time {
                Some(t) => format!("t = {t:e} s (entry {})", d.index),
                None => format!("entry {}", d.index),
            };
            let _ = writeln!(
                s,
                "  {}: {at}: {:e} vs {:e}, |difference| {:e} = {:.3e} × tolerance",
                d.dataset,
                d.a,
                d.b,
                (d.a - d.b).abs(),
                d.excess
            );
        }
    }
    let _ = writeln!(s, "mismatch");
    Ok((s, false))
}
