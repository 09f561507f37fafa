//! `flexsens laminate --load`: the plies' stresses, strains and failure indices of a laminate
//! under given plate resultants (docs/failure-criteria.md).

use laminate::{Criterion, PlateState, PlyPosition, PlyStrength};

use super::output::Quantity;
use crate::deck::laminates::{LaminateDef, LaminateModel};
use crate::error::CliError;

/// The resultants `--load` names, in the order of [`PlateLoad::values`], with their units.
pub const LOAD_NAMES: [(&str, &str); 8] = [
    ("Nx", "N/m"),
    ("Ny", "N/m"),
    ("Nxy", "N/m"),
    ("Mx", "N"),
    ("My", "N"),
    ("Mxy", "N"),
    ("Qx", "N/m"),
    ("Qy", "N/m"),
];

/// Plate resultants at a point: `[Nx, Ny, Nxy, Mx, My, Mxy, Qx, Qy]` (forces and moments per
/// unit width, laminate axes; zero where not given).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlateLoad {
    pub values: [f64; 8],
}

impl PlateLoad {
    /// The load of `--load NAME=VALUE` arguments (each may list several, comma-separated).
    pub fn parse(args: &[String]) -> Result<Option<Self>, CliError> {
        if args.is_empty() {
            return Ok(None);
        }
        let names: Vec<&str> = LOAD_NAMES.iter().map(|(n, _)| *n).collect();
        let mut values = [0.0; 8];
        let mut seen = [false; 8];
        for item in args.iter().flat_map(|a| a.split(',')) {
            let Some((name, value)) = item.split_once('=') else {
                return Err(CliError::Usage(format!(
                    "--load {item}: expected NAME=VALUE with NAME one of {}",
                    names.join(", ")
                )));
            };
            let name = name.trim();
            let Some(i) = names.iter().position(|n| n.eq_ignore_ascii_case(name)) else {
                return Err(CliError::Usage(format!(
                    "--load {item}: `{name}` is not a resultant; one of {}",
                    names.join(", ")
                )));
            };
            let v: f64 = value
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    CliError::Usage(format!(
                        "--load {item}: `{}` is not a finite number ({})",
                        value.trim(),
                        LOAD_NAMES[i].1
                    ))
                })?;
            if seen[i] {
                return Err(CliError::Usage(format!(
                    "--load: {} is given twice",
                    LOAD_NAMES[i].0
                )));
            }
            seen[i] = true;
            values[i] = v;
        }
        Ok(Some(Self { values }))
    }
}

/// The ply points' labels, bottom first: `ply/position`.
fn point_label(ply: usize, position: PlyPosition) -> String {
    let p = match position {
        PlyPosition::Bottom => "bottom",
        PlyPosition::Middle => "middle",
        PlyPosition::Top => "top",
    };
    format!("{ply}/{p}")
}

/// What the load does to laminate `def`: the reference-surface strains and curvatures, each
/// ply's stresses and strains at its bottom, middle and top (material axes), and with the
/// plies' strengths their failure indices and the laminate's least reserve factor per
/// criterion. Returns the quantities and the lines of the table's preamble.
pub fn ply_quantities(
    def: &LaminateDef,
    model: &LaminateModel,
    load: &PlateLoad,
) -> Result<(Vec<Quantity>, Vec<String>), String> {
    let stack = &def.stack;
    let abd = stack.stiffness().abd();
    let resultants = nalgebra::Vector6::from_column_slice(&load.values[..6]);
    let strains = abd
        .lu()
        .solve(&resultants)
        .ok_or("the laminate's [A B; B D] is singular")?;
    let state = PlateState {
        membrane: [strains[0], strains[1], strains[2]],
        curvature: [strains[3], strains[4], strains[5]],
        shear_forces: [load.values[6], load.values[7]],
    };
    let points = stack.ply_points(&state);
    let strengths: Vec<Option<&PlyStrength>> = (def.ply_materials.iter())
        .map(|m| model.strengths.get(m))
        .collect();
    let n = points.len();
    let mut q = vec![
        Quantity::vector(
            "midplane_strain",
            "1",
            &[strains[0], strains[1], strains[2]],
        ),
        Quantity::vector("curvature", "1/m", &[strains[3], strains[4], strains[5]]),
        Quantity::matrix("ply_stress", "Pa", n, 6, |r, c| points[r].stress[c]),
        Quantity::matrix("ply_strain", "1", n, 6, |r, c| points[r].strain[c]),
    ];
    let mut lines = vec![
        "ply stresses (MPa, material axes; the plies' points bottom first):".to_string(),
        format!(
            "{:>10} {:>11} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
            "ply/point", "z/mm", "s11", "s22", "s33", "t23", "t13", "t12"
        ),
    ];
    for p in &points {
        let s: Vec<String> = p
            .stress
            .iter()
            .map(|x| format!("{:>10.3}", x / 1e6))
            .collect();
        lines.push(format!(
            "{:>10} {:>11.4} {}",
            point_label(p.ply, p.position),
            p.z * 1e3,
            s.join(" ")
        ));
    }
    if strengths.iter().any(Option::is_some) {
        let criteria = Criterion::ALL;
        let index = |r: usize, c: usize| -> f64 {
            let p = &points[r];
            match strengths[p.ply] {
                Some(s) => criteria[c].index(&stack.plies()[p.ply].material, s, &p.stress),
                None => f64::NAN,
            }
        };
        q.push(Quantity::matrix(
            "failure_index",
            "1",
            n,
            criteria.len(),
            index,
        ));
        let mut reserve = Vec::with_capacity(criteria.len());
        lines.push(format!(
            "least reserve factors (plies with strengths: {}):",
            (0..stack.plies().len())
                .filter(|&k| strengths[k].is_some())
                .map(|k| k.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
        for (c, criterion) in criteria.iter().enumerate() {
            let (r, fi) = (0..n)
                .map(|r| (r, index(r, c)))
                .filter(|(_, fi)| !fi.is_nan())
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .expect("a ply with strengths");
            reserve.push(1.0 / fi);
            lines.push(format!(
                "  {:<14} R = {:<12.5} at ply {}",
                criterion.name(),
                1.0 / fi,
                point_label(points[r].ply, points[r].position)
            ));
        }
        q.push(Quantity::vector("reserve_factor", "1", &reserve));
    }
    Ok((q, lines))
}
