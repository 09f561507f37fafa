//! The evaluations a shard records and `flexsens merge` gathers into one optimisation.

use super::*;

/// What a shard of an optimisation writes beside its iterations for `flexsens merge`.
pub(super) const EVALUATIONS_FILE: &str = "evaluations.jsonl";

pub(super) fn row_json(r: &Row) -> serde_json::Value {
    let mut v = serde_json::json!({
        "start": r.start,
        "evaluation": r.evaluation,
        "x": r.x,
        "violation": r.violation,
        "stationarity": r.stationarity,
        "multipliers": r.multipliers,
    });
    match &r.eval {
        Ok(e) => {
            v["units"] = serde_json::json!(e.units);
            v["f"] = serde_json::json!(e.f);
            v["df"] = serde_json::json!(e.df);
            v["q"] = serde_json::json!(e.q);
            v["dq"] = serde_json::json!(e.dq);
        }
        Err(m) => v["error"] = serde_json::json!(m),
    }
    v
}

pub(super) fn row_from_json(v: &serde_json::Value) -> Option<Row> {
    let floats = |v: &serde_json::Value| -> Option<Vec<f64>> {
        v.as_array()?
            .iter()
            .map(|x| x.as_f64().or(x.is_null().then_some(f64::NAN)))
            .collect()
    };
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let eval = match v["error"].as_str() {
        Some(m) => Err(m.to_string()),
        None => Ok(Eval {
            units: v["units"]
                .as_array()?
                .iter()
                .map(|u| u.as_str().map(String::from))
                .collect::<Option<_>>()?,
            f: v["f"].as_f64()?,
            df: floats(&v["df"])?,
            q: floats(&v["q"])?,
            dq: v["dq"]
                .as_array()?
                .iter()
                .map(floats)
                .collect::<Option<_>>()?,
        }),
    };
    Some(Row {
        start: v["start"].as_u64()? as usize,
        evaluation: v["evaluation"].as_u64()? as usize,
        x: floats(&v["x"])?,
        eval,
        violation: num(&v["violation"]),
        stationarity: num(&v["stationarity"]),
        multipliers: floats(&v["multipliers"])?,
    })
}

/// Gather the shards of one optimisation (`optimize --shard I/N`; their manifests already
/// checked to be the N shards of one problem) into `out`, as the optimisation on one machine
/// would have written it.
pub(crate) fn merge(
    dirs: &[std::path::PathBuf],
    manifests: &[serde_json::Value],
    out: &Path,
) -> Result<(String, u8), CliError> {
    let first = &manifests[0];
    let deck = std::path::PathBuf::from(first["deck"].as_str().unwrap_or_default());
    let set = crate::commands::shard::manifest_strings(first, "set");
    let (problem, mechanism) = setup(&deck, &set)?;
    let n_starts = problem.def.starts.len();
    let mut rows = Vec::new();
    let mut statuses = Vec::new();
    for (dir, m) in dirs.iter().zip(manifests) {
        let bad =
            |e: String| CliError::Usage(format!("{}: {EVALUATIONS_FILE}: {e}", dir.display()));
        let i = m["shard"][0].as_u64().unwrap_or(0) as usize;
        let n = m["shard"][1].as_u64().unwrap_or(0) as usize;
        if m["starts"].as_u64() != Some(n_starts as u64) {
            return Err(CliError::Usage(format!(
                "{}: the shard has {} starts, the deck {n_starts}",
                dir.display(),
                m["starts"]
            )));
        }
        let text = crate::limits::read_text(&dir.join(EVALUATIONS_FILE)).map_err(bad)?;
        let mut own = Vec::new();
        for (k, line) in text.lines().enumerate() {
            let v: serde_json::Value =
                serde_json::from_str(line).map_err(|e| bad(format!("line {}: {e}", k + 1)))?;
            if let Some(status) = v["status"].as_str() {
                own.push(v["start"].as_u64().unwrap_or(0) as usize);
                statuses.push((
                    v["start"].as_u64().unwrap_or(0) as usize,
                    status.to_string(),
                ));
            } else {
                rows.push(
                    row_from_json(&v)
                        .ok_or_else(|| bad(format!("line {}: not an evaluation", k + 1)))?,
                );
            }
        }
        let expected: Vec<usize> = crate::commands::shard::shard_cases(n_starts, Some((i, n)))
            .into_iter()
            .map(|s| s + 1)
            .collect();
        if own != expected {
            return Err(CliError::Usage(format!(
                "{}: shard {i}/{n} ran starts {own:?}, not its starts {expected:?}",
                dir.display()
            )));
        }
    }
    rows.sort_by_key(|r| (r.start, r.evaluation));
    statuses.sort();
    finish(&problem, mechanism, &rows, &statuses, out, false)
}
