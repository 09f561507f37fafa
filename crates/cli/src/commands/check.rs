//! `flexsens check DECK.toml`: validate a deck without running it.
//!
//! Everything `run`, `modes`, `section` and `laminate` would reject is reported with its place
//! in the file: syntax and types, unknown keys, missing values, undefined names, physically
//! invalid values; for a mechanism, the modal analyses of its flexible bodies and their design
//! derivatives (as a run builds them before it integrates), the basis check, the assembly of
//! the initial configuration (a mechanism that cannot be assembled is an error) and redundant
//! joint equations (reported; `analysis.redundant = "error"` makes them an error). It lists
//! the design variables with what they move, and the `[optimize]` problem. Nothing is integrated and nothing is written.

use std::fmt::Write as _;
use std::path::Path;

use crate::deck::laminates::validate as validate_laminates;
use crate::deck::{self, bodies, sections};
use crate::error::CliError;

/// Check the deck; the report goes to stdout.
pub fn run(path: &Path, overrides: &[String]) -> Result<String, CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let empty = raw.material.is_empty()
        && raw.laminate.is_empty()
        && raw.section.is_empty()
        && raw.body.is_empty()
        && raw.rigid.is_empty()
        && raw.joint.is_empty()
        && raw.analysis.is_none();
    if empty {
        return Err(src
            .error(
                None,
                None,
                "the deck defines nothing to check (no material, laminate, section, body, \
                 joint or analysis): is it the right file?",
            )
            .into());
    }
    let model = validate_laminates(&src, &raw)?;
    for (name, s) in &raw.section {
        sections::validate_one(&src, name, s, &model)?;
    }
    let mut stiffened = Vec::new();
    for (name, b) in &raw.body {
        let def = bodies::validate_one(&src, &raw, name, b, &model)?;
        stiffened.push(format!(
            "{name} {}",
            if def.stiffening { "on" } else { "off" }
        ));
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} materials, {} laminates, {} sections, {} flexible bodies, {} rigid bodies, {} joints, {} forces, {} responses",
        src.file.display(),
        raw.material.len(),
        raw.laminate.len(),
        raw.section.len(),
        raw.body.len(),
        raw.rigid.len(),
        raw.joint.len(),
        raw.force.len(),
        raw.response.len()
    );
    if !stiffened.is_empty() {
        let _ = writeln!(s, "geometric stiffening: {}", stiffened.join(", "));
    }
    // what each design variable moves, at which value, in which unit
    let design = crate::deck::design::validate(&src, &raw, &model)?;
    for v in &design.variables {
        let _ = writeln!(
            s,
            "design variable {} = {} {}: {}",
            v.name,
            v.value,
            v.unit,
            v.describe()
        );
    }
    if raw.optimize.is_some() {
        let o = crate::deck::optimize::validate(&src, &raw, &design, &model)?;
        let _ = writeln!(
            s,
            "optimize: {} {} over {} variables, {} constraints, {} starts",
            if o.maximize { "maximise" } else { "minimise" },
            o.objective.label(),
            o.bounds.len(),
            o.constraints.len(),
            o.starts.len()
        );
    }
    let operating = match &raw.operating {
        Some(_) => Some(crate::deck::operating::validate(&src, &raw)?),
        None => None,
    };
    if let Some(o) = &operating {
        let _ = writeln!(s, "{}", describe_operating(o));
    }
    let mechanism = raw.analysis.is_some() || !raw.joint.is_empty() || !raw.rigid.is_empty();
    if mechanism {
        let mech = crate::study::Mechanism::validate(&src, &raw, true)?;
        // the design derivatives of the bodies, as a run builds them before it integrates:
        // what they refuse (a variable that splits repeated frequencies, …) is refused here too
        if mech.design.enabled {
            super::sensitivity::prepare(&src, &mech)?;
        }
        if let Some(o) = &operating {
            check_operating(&src, o, &mech)?;
        }
        let (system, state) = super::compute::assembled(&src, &mech)?;
        super::compute::warn_redundant_with_stiffening(&src, &mech, &system, &state);
        for name in &mech.body_order {
            if let Some(b) = &mech.bodies[name].basis {
                let _ = writeln!(s, "basis of body {name}: {}", b.describe());
            }
        }
        if system.elastic_rates() && system.elastic_start().is_none() {
            let _ = writeln!(
                s,
                "start: the flexible bodies take elastic rates to meet the drivers' speeds (the \
                 mechanism is locked when its bodies are rigid)"
            );
        }
        if let Some(p) = system.elastic_start() {
            let _ = writeln!(
                s,
                "start: assembled with the flexible bodies deformed ({})",
                super::compute::describe_prestress(p)
            );
        }
        let removed = system.removed_equations();
        if removed.is_empty() {
            let _ = writeln!(s, "mechanism: assembled; no redundant joint equations");
        } else {
            let list: Vec<String> = removed
                .iter()
                .map(|(j, k)| format!("{} (equation {})", mech.model.joint(*j).name, k + 1))
                .collect();
            let _ = writeln!(
                s,
                "mechanism: assembled; {} redundant joint equations removed: {}",
                removed.len(),
                list.join(", ")
            );
        }
        let moved = state
            .q
            .iter()
            .zip(&mech.state.q)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        if moved > 1e-6 {
            let _ = writeln!(
                s,
                "note: assembling moved the initial positions by up to {moved:.3e} (check the joint points)"
            );
        }
    }
    let _ = writeln!(s, "deck OK");
    Ok(s)
}

/// What `flexsens static` will compute for `[operating]`, in one line.
/// `[operating]` against the mechanism: the spin driver's axis, the times within the run.
fn check_operating(
    src: &crate::deck::Source,
    o: &crate::deck::operating::OperatingDef,
    mech: &crate::study::Mechanism,
) -> Result<(), crate::deck::DeckError> {
    crate::deck::operating::check_times(src, o, &mech.times)?;
    if let Some((name, span)) = &o.driver {
        let id = mech.model.joint_id(name).expect("validated driver");
        mbs::Spin::of_driver(&mech.model, id, 1.0).map_err(|e| {
            src.error(
                span.clone(),
                Some("operating.driver".into()),
                format!("`{name}`: {e}"),
            )
        })?;
    }
    Ok(())
}

fn describe_operating(o: &crate::deck::operating::OperatingDef) -> String {
    use super::operating::rpm;
    if let (Some((first, _)), Some((last, _))) = (o.at.first(), o.at.last()) {
        return format!(
            "operating: the run's states at {} times from {first} to {last} s, {} modes reported",
            o.at.len(),
            o.modes
        );
    }
    match &o.driver {
        Some((name, _)) => format!(
            "operating: steady spins of `{name}` at {} speeds from {} to {} rpm, {} modes \
             reported",
            o.speeds.len(),
            rpm(o.speeds[0]),
            rpm(o.speeds[o.speeds.len() - 1]),
            o.modes
        ),
        None => format!("operating: static equilibrium, {} modes reported", o.modes),
    }
}
