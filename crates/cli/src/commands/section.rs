//! `flexsens section`: cross-section stiffness, mass properties and centres of the deck's beam
//! sections, with their ply-angle derivatives.

use std::path::Path;

use section::{DesignMap, SectionProperties};
use serde_json::json;

use super::Format;
use super::output::{self, Derivative, Quantity, Report};
use super::ply_stress::{
    RegionExtremes, SECTION_LOAD_NAMES, parse_loads, section_quantities,
    section_quantity_derivatives,
};
use crate::deck;
use crate::deck::design::{DesignVariable, validate as validate_design};
use crate::deck::laminates::{LaminateModel, validate as validate_laminates};
use crate::deck::sections::{SectionDef, validate_one};
use crate::error::CliError;

use crate::study::flexible::{section_derivatives_of, section_design};

/// Unit of entry (r, c) of a stiffness relating `[ε, γ₂, γ₃ | κ₁, κ₂, κ₃]` to
/// `[F₁, F₂, F₃ | M₁, M₂, M₃]`: force rows and strain columns carry N, moments and curvatures
/// one metre more each.
fn stiffness_unit(split: usize) -> impl Fn(usize, usize) -> String {
    move |r, c| match (r >= split) as u8 + (c >= split) as u8 {
        0 => "N".into(),
        1 => "N*m".into(),
        _ => "N*m^2".into(),
    }
}

fn quantities(p: &SectionProperties) -> Vec<Quantity> {
    // a section given by its properties has no area
    let area = (!p.area.is_nan()).then(|| Quantity::scalar("area", "m^2", p.area));
    area.into_iter()
        .chain([
            Quantity::scalar("mass_per_length", "kg/m", p.mass_per_length),
            Quantity::vector("mass_centre", "m", &p.mass_centre),
            Quantity::vector("mass_inertia", "kg*m", &p.mass_inertia),
            Quantity::vector("tension_centre", "m", &p.tension_centre),
            Quantity::vector("shear_centre", "m", &p.shear_centre),
            Quantity::matrix("stiffness", "", 6, 6, |r, c| p.stiffness[(r, c)])
                .with_units(stiffness_unit(3)),
            Quantity::matrix("classical_stiffness", "", 4, 4, |r, c| {
                p.classical_stiffness[(r, c)]
            })
            .with_units(stiffness_unit(1)),
        ])
        .collect()
}

fn report(
    name: &str,
    def: &SectionDef,
    (derivatives, vars): (bool, &[DesignVariable]),
    load: Option<(&[f64; 6], &LaminateModel)>,
) -> Result<Report, String> {
    let mesh = &def.mesh;
    if def.given.is_some() && load.is_some() {
        return Err(
            "a section given by its properties has no points to recover stresses at (--load)"
                .into(),
        );
    }
    if let Some(given) = &def.given {
        return Ok(given_report(
            name,
            &given.properties().map_err(|e| e.to_string())?,
        ));
    }
    // one analysis for the properties, their derivatives and the stresses, and the stresses'
    // extremes found once for their values and derivatives
    let analysis = if derivatives {
        section::SectionAnalysis::for_derivatives(mesh)
    } else {
        section::SectionAnalysis::new(mesh)
    }
    .map_err(|e| e.to_string())?;
    let extremes = load.map(|(forces, model)| {
        (
            *forces,
            RegionExtremes::of(&analysis, &def.materials, model, *forces),
        )
    });
    let (values, derivs) = if derivatives {
        // per region's ply angle, or per [design.*] variable that moves the section
        let design = if vars.is_empty() {
            DesignMap::each_region(mesh)
        } else {
            let (mut map, _) = section_design(name, def, vars)?;
            map.variables.retain(|v| !v.is_empty());
            map
        };
        // a region's angle per radian, a design variable per its unit
        let per = |name: &str| {
            vars.iter()
                .find(|v| v.name == name)
                .map_or("rad", |v| v.unit)
        };
        let s = section_derivatives_of(&analysis, &design).map_err(|e| e.to_string())?;
        // with a load, the stresses' derivatives at the fixed forces too
        let loaded = match &extremes {
            Some((forces, extremes)) => {
                let points = analysis
                    .stress_derivatives::<4>(*forces, &design)
                    .map_err(|e| e.to_string())?;
                (points.iter())
                    .map(|d| section_quantity_derivatives(&analysis, extremes, d))
                    .collect()
            }
            None => vec![Vec::new(); s.variables.len()],
        };
        let d = (s.variables.iter().zip(&s.derivatives).zip(loaded))
            .map(|((v, d), more)| Derivative {
                wrt: if vars.is_empty() {
                    format!("{v}.angle")
                } else {
                    v.clone()
                },
                per: per(v),
                values: quantities(d).into_iter().chain(more).collect(),
            })
            .collect();
        (s.properties, d)
    } else {
        (analysis.properties().clone(), Vec::new())
    };
    let mut preamble = vec![
        format!("shape {}, {} nodes, {} elements", def.shape, mesh.nodes.len(), mesh.elements.len()),
        "strains [eps, gamma2, gamma3, kappa1, kappa2, kappa3], forces [F1, F2, F3, M1, M2, M3], about the origin"
            .to_string(),
        format!("{:<28} {:>10}", "region", "angle/deg"),
    ];
    let mut regions = Vec::new();
    for r in &mesh.regions {
        preamble.push(format!("{:<28} {:>10.3}", r.name, r.ply_angle.to_degrees()));
        regions.push(json!({"name": r.name, "angle_deg": r.ply_angle.to_degrees()}));
    }
    let mut values = quantities(&values);
    if let Some((_, extremes)) = &extremes {
        let (q, lines) = section_quantities(&analysis, extremes);
        values.extend(q);
        preamble.extend(lines);
    }
    let mut info = serde_json::Map::new();
    info.insert("shape".into(), json!(def.shape));
    info.insert("nodes".into(), json!(mesh.nodes.len()));
    info.insert("elements".into(), json!(mesh.elements.len()));
    info.insert("regions".into(), json!(regions));
    Ok(Report {
        kind: "section",
        name: name.into(),
        preamble,
        info,
        values,
        derivatives: derivs,
    })
}

/// The report of a section given by its properties: what the deck gave and what follows from
/// it (compliance-derived centres and classical stiffness); no design variable moves it.
fn given_report(name: &str, p: &SectionProperties) -> Report {
    let mut info = serde_json::Map::new();
    info.insert("shape".into(), json!("properties"));
    Report {
        kind: "section",
        name: name.into(),
        preamble: vec![
            "shape properties (given, not analysed)".to_string(),
            "strains [eps, gamma2, gamma3, kappa1, kappa2, kappa3], forces [F1, F2, F3, M1, M2, M3], about the origin"
                .to_string(),
        ],
        info,
        values: quantities(p),
        derivatives: Vec::new(),
    }
}

/// Run the command; the returned text goes to stdout.
pub fn run(
    path: &Path,
    overrides: &[String],
    only: Option<&str>,
    format: Format,
    (derivatives, load): (bool, &[String]),
) -> Result<String, CliError> {
    let load: Option<[f64; 6]> =
        parse_loads(load, &SECTION_LOAD_NAMES)?.map(|v| std::array::from_fn(|i| v[i]));
    let (src, raw) = deck::load(path, overrides)?;
    let model = validate_laminates(&src, &raw)?;
    let design = validate_design(&src, &raw, &model)?;
    let selected = deck::select(&src, &raw.section, only, "section")?;
    let mut reports = Vec::new();
    for (name, s) in selected {
        let def = validate_one(&src, name, s, &model)?;
        let r = report(
            name,
            &def,
            (derivatives, &design.variables),
            load.as_ref().map(|f| (f, &model)),
        )
        .map_err(|e| src.error(Some(s.span()), Some(format!("section.{name}")), e))?;
        reports.push(r);
    }
    Ok(output::render(
        format,
        raw.title.as_deref(),
        "sections",
        "section",
        &reports,
    ))
}
