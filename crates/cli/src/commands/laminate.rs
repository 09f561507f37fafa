//! `flexsens laminate`: plate stiffness of the deck's laminates and its ply-angle derivatives.

use std::path::Path;

use laminate::{LaminateStiffness, PlyStack};
use sens::{Dual, chunk_ranges};
use serde_json::json;

use super::Format;
use super::output::{self, Derivative, Quantity, Report};
use crate::deck::design::{DesignVariable, elastic, validate as validate_design};
use crate::deck::laminates::{LaminateDef, validate};
use crate::deck::{self, DeckError};

/// Width of the dual-number chunks (results do not depend on it).
const CHUNK: usize = 8;

fn quantities(k: &LaminateStiffness<f64>) -> Vec<Quantity> {
    let m3 = |name, unit, m: &nalgebra::Matrix3<f64>| {
        Quantity::matrix(name, unit, 3, 3, |r, c| m[(r, c)])
    };
    vec![
        Quantity::scalar("thickness", "m", k.thickness),
        Quantity::scalar("mass_per_area", "kg/m^2", k.mass_per_area),
        Quantity::scalar("first_moment", "kg/m", k.first_moment),
        Quantity::scalar("rotary_inertia", "kg", k.rotary_inertia),
        m3("A", "N/m", &k.a),
        m3("B", "N", &k.b),
        m3("D", "N*m", &k.d),
        Quantity::matrix("As", "N/m", 2, 2, |r, c| k.shear[(r, c)]),
    ]
}

/// Derivatives of the laminate's stiffness with respect to variables that turn its plies:
/// variable `j` turns ply `p` by `f` radians per unit for each `(p, f)` of `links[j]`.
pub fn angle_derivatives(
    stack: &PlyStack<f64>,
    links: &[Vec<(usize, f64)>],
) -> Vec<LaminateStiffness<f64>> {
    let (no_materials, no_thicknesses) =
        (vec![Vec::new(); links.len()], vec![Vec::new(); links.len()]);
    design_derivatives(stack, links, &no_materials, &no_thicknesses)
}

/// [`angle_derivatives`] for variables that also move the elastic constants of plies'
/// materials: variable `j` changes the constants of ply `p` (the nine elastic ones and the
/// density) by `dc` per unit for each `(p, dc)` of `materials[j]`.
pub fn design_derivatives(
    stack: &PlyStack<f64>,
    links: &[Vec<(usize, f64)>],
    materials: &[Vec<(usize, [f64; 10])>],
    thicknesses: &[Vec<(usize, f64)>],
) -> Vec<LaminateStiffness<f64>> {
    let mut out = Vec::with_capacity(links.len());
    for range in chunk_ranges(links.len(), CHUNK) {
        let mut angles: Vec<Dual<CHUNK>> = stack
            .plies()
            .iter()
            .map(|p| Dual::constant(p.angle))
            .collect();
        let mut c_bar: Vec<nalgebra::Matrix6<Dual<CHUNK>>> = stack
            .plies()
            .iter()
            .map(|p| p.material.stiffness().map(Dual::constant))
            .collect();
        let mut density: Vec<Dual<CHUNK>> = stack
            .plies()
            .iter()
            .map(|p| Dual::constant(p.material.density()))
            .collect();
        let mut thickness: Vec<Dual<CHUNK>> = stack
            .plies()
            .iter()
            .map(|p| Dual::constant(p.thickness))
            .collect();
        for (k, j) in range.clone().enumerate() {
            for &(p, f) in &links[j] {
                angles[p].d[k] += f;
            }
            for &(p, f) in &thicknesses[j] {
                thickness[p].d[k] += f;
            }
            for (p, dc) in &materials[j] {
                let d = stack.plies()[*p]
                    .material
                    .stiffness_derivative(&elastic(dc));
                for (x, y) in c_bar[*p].iter_mut().zip(d.iter()) {
                    x.d[k] += y;
                }
                density[*p].d[k] += dc[9];
            }
        }
        let dual = stack
            .with_plies(&angles, &thickness)
            .expect("the plies of a validated stack stay valid")
            .stiffness_with_materials(&c_bar, &density);
        for k in 0..range.len() {
            out.push(dual.tangent(k));
        }
    }
    out
}

/// The derivative blocks of a laminate: per ply angle (per radian), or with `[design.*]`
/// variables per variable that moves this laminate (per degree).
fn derivative_blocks(name: &str, def: &LaminateDef, vars: &[DesignVariable]) -> Vec<Derivative> {
    let stack = &def.stack;
    if vars.is_empty() {
        let each: Vec<_> = (0..stack.plies().len()).map(|i| vec![(i, 1.0)]).collect();
        return angle_derivatives(stack, &each)
            .iter()
            .enumerate()
            .map(|(i, d)| Derivative {
                wrt: format!("plies.{i}.angle"),
                per: "rad",
                values: quantities(d),
            })
            .collect();
    }
    let materials_of = |v: &DesignVariable| -> Vec<(usize, [f64; 10])> {
        def.ply_materials
            .iter()
            .enumerate()
            .filter_map(|(p, m)| Some((p, *v.material_links(m)?)))
            .collect()
    };
    let mine: Vec<&DesignVariable> = vars
        .iter()
        .filter(|v| {
            !v.ply_links(name).is_empty()
                || !v.thickness_links(name).is_empty()
                || !materials_of(v).is_empty()
        })
        .collect();
    let links: Vec<_> = mine.iter().map(|v| v.ply_links(name).to_vec()).collect();
    let materials: Vec<_> = mine.iter().map(|v| materials_of(v)).collect();
    let thicknesses: Vec<_> = mine
        .iter()
        .map(|v| v.thickness_links(name).to_vec())
        .collect();
    mine.iter()
        .zip(design_derivatives(stack, &links, &materials, &thicknesses))
        .map(|(v, d)| Derivative {
            wrt: v.name.clone(),
            per: v.unit,
            values: quantities(&d),
        })
        .collect()
}

fn report(name: &str, def: &LaminateDef, derivatives: bool, vars: &[DesignVariable]) -> Report {
    let stack = &def.stack;
    let mut preamble = vec![
        format!(
            "{} plies, reference surface {:?}, shear correction {:.4}",
            stack.plies().len(),
            stack.reference(),
            stack.shear_correction()
        ),
        format!(
            "{:>3}  {:<16} {:>12} {:>10}",
            "ply", "material", "thickness/m", "angle/deg"
        ),
    ];
    for (i, p) in stack.plies().iter().enumerate() {
        preamble.push(format!(
            "{i:>3}  {:<16} {:>12.4e} {:>10.3}",
            def.ply_materials[i],
            p.thickness,
            p.angle.to_degrees()
        ));
    }
    let plies: Vec<_> = stack
        .plies()
        .iter()
        .zip(&def.ply_materials)
        .map(|(p, m)| json!({"material": m, "thickness": p.thickness, "angle_deg": p.angle.to_degrees()}))
        .collect();
    let mut info = serde_json::Map::new();
    info.insert("plies".into(), json!(plies));
    let derivatives = if derivatives {
        derivative_blocks(name, def, vars)
    } else {
        Vec::new()
    };
    Report {
        kind: "laminate",
        name: name.to_string(),
        preamble,
        info,
        values: quantities(&stack.stiffness()),
        derivatives,
    }
}

/// Run the command; the returned text goes to stdout.
pub fn run(
    path: &Path,
    overrides: &[String],
    only: Option<&str>,
    format: Format,
    derivatives: bool,
) -> Result<String, DeckError> {
    let (src, raw) = deck::load(path, overrides)?;
    let model = validate(&src, &raw)?;
    let design = validate_design(&src, &raw, &model)?;
    let selected = deck::select(&src, &model.laminates, only, "laminate")?;
    let reports: Vec<Report> = selected
        .iter()
        .map(|(name, def)| report(name, def, derivatives, &design.variables))
        .collect();
    Ok(output::render(
        format,
        raw.title.as_deref(),
        "laminates",
        "laminate",
        &reports,
    ))
}
