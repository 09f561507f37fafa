//! Every simple default that `docs/decks.md` states is the code's: for each documented key, a
//! shipped deck with the key left out and the same deck with the key set (`--set`) to the value
//! read from the docs give identical results. A default changed in the code or in the docs
//! alone fails here.

mod common;

use common::{deck, json};
use std::path::Path;

/// The default column of the row of `key` in the table under the heading containing
/// `heading`, as a TOML value: the first alternative (`2 (tube), 1 (box, channel)` → `2`),
/// without backticks; for rows of several keys (`rtol`, `atol`) the key's own entry.
fn documented_default(heading: &str, key: &str) -> String {
    let docs =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/decks.md"))
            .unwrap();
    let mut in_section = false;
    for line in docs.lines() {
        if line.starts_with('#') {
            in_section = line.contains(heading);
            continue;
        }
        if !in_section || !line.starts_with("| `") {
            continue;
        }
        let cells: Vec<&str> = line.trim_matches('|').split(" | ").map(str::trim).collect();
        let keys: Vec<&str> = cells[0].split(", ").map(|k| k.trim_matches('`')).collect();
        let Some(pos) = keys.iter().position(|k| *k == key) else {
            continue;
        };
        let cell = if keys.len() > 1 {
            let parts: Vec<&str> = cells[2].split(", ").collect();
            assert_eq!(parts.len(), keys.len(), "{heading} {key}: {}", cells[2]);
            parts[pos]
        } else {
            cells[2]
        };
        let first = cell.split(" (").next().unwrap().trim().trim_matches('`');
        return match first {
            "5/6" => format!("{:?}", 5.0 / 6.0),
            other => other.to_string(),
        };
    }
    panic!("docs/decks.md: no row for `{key}` under a heading with `{heading}`");
}

/// `text` without the line that sets `key` in the table `[table]`.
fn without_key(text: &str, table: &str, key: &str) -> String {
    let mut out = Vec::new();
    let mut in_table = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            in_table = t.starts_with(&format!("[{table}]"));
        } else if in_table
            && t.strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with('='))
        {
            continue;
        }
        out.push(line);
    }
    out.join("\n") + "\n"
}

/// The command's JSON with the fields that name files removed.
fn result(args: &[String]) -> serde_json::Value {
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut v = json(&args);
    if let Some(o) = v.as_object_mut() {
        o.remove("deck");
        o.remove("output");
    }
    v
}

/// The command a case runs.
#[derive(Clone, Copy)]
enum Command {
    Laminate,
    Section,
    Modes,
    /// A short run.
    Run,
    /// A short run without the deck's finite-difference check (where it is not the subject).
    RunOnly,
    /// `flexsens static`.
    Static,
}

impl Command {
    fn args(self) -> &'static [&'static str] {
        match self {
            Command::Laminate => &["laminate", "--format", "json"],
            Command::Section => &["section", "--format", "json"],
            Command::Modes => &["modes", "--format", "json"],
            Command::Run => &["run", "--json", "--set", "analysis.t_end=0.001"],
            Command::Static => &["static", "--json"],
            Command::RunOnly => &[
                "run",
                "--json",
                "--set",
                "analysis.t_end=0.001",
                "--set",
                "finite_differences.enabled=false",
            ],
        }
    }
}

/// (heading, key, deck, table, command); the deck fits the default's first alternative.
const CASES: &[(&str, &str, &str, &str, Command)] = &[
    (
        "[laminate.NAME]",
        "symmetric",
        "laminate_paper_composite.toml",
        "laminate.layup_15",
        Command::Laminate,
    ),
    (
        "[laminate.NAME]",
        "reference",
        "laminate_paper_composite.toml",
        "laminate.layup_15",
        Command::Laminate,
    ),
    (
        "[laminate.NAME]",
        "shear_correction",
        "laminate_paper_composite.toml",
        "laminate.layup_15",
        Command::Laminate,
    ),
    (
        "[section.NAME]",
        "angle",
        "section_isotropic_rectangle.toml",
        "section.bar",
        Command::Section,
    ),
    (
        "[section.NAME]",
        "elements_around",
        "section_composite_tube.toml",
        "section.rod",
        Command::Section,
    ),
    (
        "[section.NAME]",
        "elements_per_ply",
        "section_composite_tube.toml",
        "section.rod",
        Command::Section,
    ),
    (
        "[body.NAME]",
        "orientation",
        "modes_beam_rod.toml",
        "body.rod",
        Command::Modes,
    ),
    (
        "[body.NAME]",
        "elements",
        "modes_beam_rod.toml",
        "body.rod",
        Command::Modes,
    ),
    (
        "[body.NAME]",
        "reference",
        "modes_beam_rod.toml",
        "body.rod",
        Command::Modes,
    ),
    (
        "[body.NAME]",
        "correction_damping",
        "slider_crank_beam.toml",
        "body.rod",
        Command::Modes,
    ),
    (
        "[body.NAME]",
        "mass",
        "modes_beam_rod.toml",
        "body.rod",
        Command::Modes,
    ),
    (
        "[body.NAME]",
        "material_axis",
        "modes_plate_rod.toml",
        "body.rod",
        Command::Modes,
    ),
    (
        "[body.NAME]",
        "stiffening",
        "slider_crank_beam.toml",
        "body.rod",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "t_start",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "integrator",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "rtol",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "error_weights",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "order",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "stability_limit",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[analysis]",
        "redundant",
        "slider_crank_beam.toml",
        "analysis",
        Command::RunOnly,
    ),
    (
        "[sensitivity]",
        "enabled",
        "slider_crank_beam.toml",
        "sensitivity",
        Command::RunOnly,
    ),
    (
        "[sensitivity]",
        "method",
        "slider_crank_beam.toml",
        "sensitivity",
        Command::RunOnly,
    ),
    (
        "[sensitivity]",
        "modes",
        "slider_crank_beam.toml",
        "sensitivity",
        Command::RunOnly,
    ),
    (
        "[sensitivity]",
        "error_control",
        "slider_crank_beam.toml",
        "sensitivity",
        Command::RunOnly,
    ),
    (
        "[finite_differences]",
        "enabled",
        "slider_crank_beam.toml",
        "finite_differences",
        Command::Run,
    ),
    (
        "[finite_differences]",
        "scheme",
        "slider_crank_beam.toml",
        "finite_differences",
        Command::Run,
    ),
    (
        "[finite_differences]",
        "perturbation",
        "slider_crank_beam.toml",
        "finite_differences",
        Command::Run,
    ),
    (
        "[finite_differences]",
        "sizes",
        "slider_crank_beam.toml",
        "finite_differences",
        Command::Run,
    ),
    (
        "[finite_differences]",
        "steps",
        "slider_crank_beam.toml",
        "finite_differences",
        Command::Run,
    ),
    (
        "[design.NAME]",
        "kind",
        "slider_crank_beam.toml",
        "design.theta",
        Command::RunOnly,
    ),
    (
        "[operating]",
        "modes",
        "rotor_blade_composite.toml",
        "operating",
        Command::Static,
    ),
    (
        "[operating]",
        "orders",
        "rotor_blade_composite.toml",
        "operating",
        Command::Static,
    ),
    (
        "[operating]",
        "speeds",
        "rotor_blade_composite.toml",
        "operating",
        Command::Static,
    ),
];

#[test]
fn documented_defaults_are_the_codes() {
    let dir = tempfile::tempdir().unwrap();
    for (i, &(heading, key, deck_name, table, command)) in CASES.iter().enumerate() {
        let command = command.args();
        let value = documented_default(heading, key);
        let text = std::fs::read_to_string(deck(deck_name)).unwrap();
        let path = dir.path().join(format!("{i}_{deck_name}"));
        std::fs::write(&path, without_key(&text, table, key)).unwrap();
        let args = |set: Option<String>, out: &str| -> Vec<String> {
            let mut a: Vec<String> = vec![command[0].into(), path.display().to_string()];
            a.extend(command[1..].iter().map(|s| s.to_string()));
            if command[0] == "run" || command[0] == "static" {
                a.extend(["-o".into(), dir.path().join(out).display().to_string()]);
            }
            if let Some(s) = set {
                a.extend(["--set".into(), s]);
            }
            a
        };
        let omitted = result(&args(None, &format!("{i}a")));
        let explicit = result(&args(
            Some(format!("{table}.{key}={value}")),
            &format!("{i}b"),
        ));
        assert!(
            omitted == explicit,
            "{heading} `{key}`: the documented default {value} is not the code's (the deck \
             without the key and with `--set {table}.{key}={value}` differ)"
        );
    }
}
