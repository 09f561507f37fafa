//! `flexsens laminate --load` and `flexsens section --load`: the plies' stresses, strains and
//! failure indices of a laminate under given plate resultants, and of a beam section's regions
//! under given section forces (docs/failure-criteria.md).

use laminate::{Criterion, PlateState, PlyPoint, PlyPosition, PlyStrength};
use sens::Scalar;

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
        Ok(parse_loads(args, &LOAD_NAMES)?.map(|v| Self {
            values: std::array::from_fn(|i| v[i]),
        }))
    }
}

/// The section forces `--load` names for a section, with their units.
pub const SECTION_LOAD_NAMES: [(&str, &str); 6] = [
    ("F1", "N"),
    ("F2", "N"),
    ("F3", "N"),
    ("M1", "N*m"),
    ("M2", "N*m"),
    ("M3", "N*m"),
];

/// The values of `--load NAME=VALUE` arguments (each may list several, comma-separated) for
/// the quantities `known` (name, unit), zero where not given; `None` without arguments.
pub fn parse_loads(args: &[String], known: &[(&str, &str)]) -> Result<Option<Vec<f64>>, CliError> {
    if args.is_empty() {
        return Ok(None);
    }
    let names: Vec<&str> = known.iter().map(|(n, _)| *n).collect();
    let mut values = vec![0.0; known.len()];
    let mut seen = vec![false; known.len()];
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
                    known[i].1
                ))
            })?;
        if seen[i] {
            return Err(CliError::Usage(format!(
                "--load: {} is given twice",
                known[i].0
            )));
        }
        seen[i] = true;
        values[i] = v;
    }
    Ok(Some(values))
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
) -> (Vec<Quantity>, Vec<String>) {
    let stack = &def.stack;
    let strengths = ply_strengths(def, model);
    let response = LoadResponse::of(&fem::ShellPlies::new(stack.clone()), load, &strengths);
    let points = &response.points;
    let n = points.len();
    let mut q = response.quantities(|x| x);
    let mut lines = vec![
        "ply stresses (MPa, material axes; the plies' points bottom first):".to_string(),
        format!(
            "{:>10} {:>11} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
            "ply/point", "z/mm", "s11", "s22", "s33", "t23", "t13", "t12"
        ),
    ];
    for p in points {
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
    if let Some(fi) = &response.indices {
        let index = |r: usize, c: usize| fi[r][c];
        lines.push(format!(
            "least reserve factors (plies with strengths: {}):",
            (0..stack.plies().len())
                .filter(|&k| strengths[k].is_some())
                .map(|k| k.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
        let at = |r: usize| format!("at ply {}", point_label(points[r].ply, points[r].position));
        q.push(least_reserve(n, index, at, &mut lines));
    }
    (q, lines)
}

/// Each ply's strengths (`None`: its material states none).
fn ply_strengths<'a>(def: &LaminateDef, model: &'a LaminateModel) -> Vec<Option<&'a PlyStrength>> {
    (def.ply_materials.iter())
        .map(|m| model.strengths.get(m))
        .collect()
}

/// What a plate load does to a laminate, in the scalar of its plies: the deformation, each
/// ply point's stress and strain, and (with strengths) each point's index under every
/// criterion (NaN for a ply without strengths).
struct LoadResponse<S: Scalar> {
    state: PlateState<S>,
    points: Vec<PlyPoint<S>>,
    indices: Option<Vec<Vec<S>>>,
}

impl<S: Scalar> LoadResponse<S> {
    fn of(
        plies: &fem::ShellPlies<S>,
        load: &PlateLoad,
        strengths: &[Option<&PlyStrength>],
    ) -> Self {
        let (stack, c_bar) = (&plies.stack, &plies.c_bar);
        let v = load.values.map(S::from_f64);
        let state = stack.state_under_with_materials(
            [v[0], v[1], v[2], v[3], v[4], v[5]],
            [v[6], v[7]],
            c_bar,
        );
        let points = stack.ply_points_with_materials(&state, c_bar);
        let indices = strengths.iter().any(Option::is_some).then(|| {
            (points.iter())
                .map(|p| {
                    (Criterion::ALL.iter())
                        .map(|c| match strengths[p.ply] {
                            Some(s) => c.index(&stack.plies()[p.ply].material, s, &p.stress),
                            None => S::from_f64(f64::NAN),
                        })
                        .collect()
                })
                .collect()
        });
        LoadResponse {
            state,
            points,
            indices,
        }
    }

    /// The quantities of the response, each number read by `part` (its value, or a tangent).
    fn quantities(&self, part: impl Fn(S) -> f64) -> Vec<Quantity> {
        let (state, points) = (&self.state, &self.points);
        let n = points.len();
        let mut q = vec![
            Quantity::vector("midplane_strain", "1", &state.membrane.map(&part)),
            Quantity::vector("curvature", "1/m", &state.curvature.map(&part)),
            Quantity::matrix("ply_stress", "Pa", n, 6, |r, c| part(points[r].stress[c])),
            Quantity::matrix("ply_strain", "1", n, 6, |r, c| part(points[r].strain[c])),
        ];
        if let Some(fi) = &self.indices {
            // a ply without strengths: NaN, its tangents too
            let at = |r: usize, c: usize| match fi[r][c].value().is_nan() {
                true => f64::NAN,
                false => part(fi[r][c]),
            };
            q.push(Quantity::matrix(
                "failure_index",
                "1",
                n,
                Criterion::ALL.len(),
                at,
            ));
        }
        q
    }
}

/// The derivatives of [`ply_quantities`]'s quantities (the least reserve factors aside) with
/// respect to each variable of `design` (one laminate's: `Design::shell_plies`), per variable.
pub fn ply_quantity_derivatives(
    def: &LaminateDef,
    model: &LaminateModel,
    load: &PlateLoad,
    design: &crate::study::flexible::Design,
) -> Vec<Vec<Quantity>> {
    const CHUNK: usize = 8;
    let strengths = ply_strengths(def, model);
    let values = design.values();
    let mut out = Vec::with_capacity(values.len());
    for range in sens::chunk_ranges(values.len(), CHUNK) {
        let seeded = sens::seed_chunk::<CHUNK>(values, range.start);
        let plies = design
            .shell_plies(&seeded)
            .expect("the plies of a validated stack stay valid");
        let response = LoadResponse::of(&plies[0], load, &strengths);
        for k in 0..range.len() {
            out.push(response.quantities(|x: sens::Dual<CHUNK>| x.d[k]));
        }
    }
    out
}

/// What the section forces `forces` do to the regions of a section: per region the extremes of
/// its material-axis stresses over its integration points and, for regions whose material
/// states strengths (`materials`: each region's `[material.*]` name), each criterion's largest
/// failure index and the section's least reserve factor per criterion.
pub fn section_quantities(
    analysis: &section::SectionAnalysis,
    extremes: &RegionExtremes,
) -> (Vec<Quantity>, Vec<String>) {
    let mesh = analysis.mesh();
    let nr = mesh.regions.len();
    let mut q = vec![Quantity::matrix(
        "region_stress_extremes",
        "Pa",
        nr,
        7,
        |r, c| extremes.stress[r][c].0,
    )];
    let mut lines = vec![
        "region stresses (MPa, material axes): s11 min, max; s22 min, max; |t23|, |t13|, |t12| max"
            .to_string(),
    ];
    for (r, e) in extremes.stress.iter().enumerate() {
        let v: Vec<String> = e.iter().map(|x| format!("{:>9.3}", x.0 / 1e6)).collect();
        lines.push(format!("  {:<24} {}", mesh.regions[r].name, v.join(" ")));
    }
    let index = |r: usize, c: usize| extremes.index[r][c].0;
    if (0..nr).any(|r| !index(r, 0).is_nan()) {
        q.push(Quantity::matrix(
            "region_failure_index",
            "1",
            nr,
            Criterion::ALL.len(),
            index,
        ));
        lines.push("least reserve factors (regions with strengths):".to_string());
        let place = |r: usize| format!("in region {}", mesh.regions[r].name);
        q.push(least_reserve(nr, index, place, &mut lines));
    }
    (q, lines)
}

/// The derivatives of [`section_quantities`]'s region extremes and failure indices (the least
/// reserve factors aside) along one design variable, from the points' stress derivatives
/// `derivatives` (`SectionAnalysis::stress_derivatives`): each extreme's is its active
/// point's.
pub fn section_quantity_derivatives(
    analysis: &section::SectionAnalysis,
    extremes: &RegionExtremes,
    derivatives: &[section::StressDerivative],
) -> Vec<Quantity> {
    let mesh = analysis.mesh();
    let nr = mesh.regions.len();
    // component and sign of each extreme's stress
    const COMPONENT: [usize; 7] = [0, 0, 1, 1, 3, 4, 5];
    let stress = |r: usize, c: usize| {
        let (_, k) = extremes.stress[r][c];
        let d = derivatives[k].material_stress[COMPONENT[c]];
        match c >= 4 {
            true => d * extremes.points[k].material_stress[COMPONENT[c]].signum(),
            false => d,
        }
    };
    let mut q = vec![Quantity::matrix(
        "region_stress_extremes",
        "Pa",
        nr,
        7,
        stress,
    )];
    if (0..nr).any(|r| !extremes.index[r][0].0.is_nan()) {
        let index = |r: usize, c: usize| {
            let (fi, k) = extremes.index[r][c];
            if fi.is_nan() {
                return f64::NAN;
            }
            let p = &extremes.points[k];
            let strength = extremes.strengths[r].expect("a region with an index");
            let seeded: [sens::Dual<1>; 6] = std::array::from_fn(|i| {
                sens::Dual::new(p.material_stress[i], [derivatives[k].material_stress[i]])
            });
            Criterion::ALL[c]
                .index(&mesh.regions[r].material, strength, &seeded)
                .d[0]
        };
        q.push(Quantity::matrix(
            "region_failure_index",
            "1",
            nr,
            Criterion::ALL.len(),
            index,
        ));
    }
    q
}

/// What the section forces do to each region of a section, found once for the values and the
/// derivatives: each stress extreme (s11 min, max; s22 min, max; |t23|, |t13|, |t12| max) and
/// each criterion's largest index (NaN without strengths), with the integration point where
/// it is.
pub struct RegionExtremes<'a> {
    points: Vec<section::SectionPoint>,
    stress: Vec<[(f64, usize); 7]>,
    index: Vec<Vec<(f64, usize)>>,
    strengths: Vec<Option<&'a PlyStrength>>,
}

impl<'a> RegionExtremes<'a> {
    /// The extremes under `forces` (`materials`: each region's `[material.*]` name, whose
    /// strengths `model` holds).
    pub fn of(
        analysis: &section::SectionAnalysis,
        materials: &[Option<String>],
        model: &'a LaminateModel,
        forces: [f64; 6],
    ) -> Self {
        let mesh = analysis.mesh();
        let points = analysis.stresses(forces);
        let nr = mesh.regions.len();
        let strengths: Vec<Option<&PlyStrength>> = (0..nr)
            .map(|r| materials[r].as_ref().and_then(|m| model.strengths.get(m)))
            .collect();
        let start = [
            (f64::INFINITY, 0),
            (f64::NEG_INFINITY, 0),
            (f64::INFINITY, 0),
            (f64::NEG_INFINITY, 0),
            (0.0, 0),
            (0.0, 0),
            (0.0, 0),
        ];
        let mut stress = vec![start; nr];
        let mut index = vec![vec![(f64::NAN, 0); Criterion::ALL.len()]; nr];
        for (k, p) in points.iter().enumerate() {
            let s = p.material_stress;
            let e = &mut stress[p.region];
            let candidates = [s[0], s[0], s[1], s[1], s[3].abs(), s[4].abs(), s[5].abs()];
            for (c, &x) in candidates.iter().enumerate() {
                let better = match c {
                    0 | 2 => x < e[c].0,
                    _ => x > e[c].0,
                };
                if better {
                    e[c] = (x, k);
                }
            }
            if let Some(strength) = strengths[p.region] {
                let material = &mesh.regions[p.region].material;
                for (c, criterion) in Criterion::ALL.iter().enumerate() {
                    let fi = criterion.index(material, strength, &s);
                    let cell = &mut index[p.region][c];
                    if cell.0.is_nan() || fi > cell.0 {
                        *cell = (fi, k);
                    }
                }
            }
        }
        RegionExtremes {
            points,
            stress,
            index,
            strengths,
        }
    }
}

/// The least reserve factor `1/FI` of each criterion over `rows` rows of failure indices
/// `index(row, criterion)` (NaN: no strengths there), with a line per criterion naming where
/// it is (`place`).
fn least_reserve(
    rows: usize,
    index: impl Fn(usize, usize) -> f64,
    place: impl Fn(usize) -> String,
    lines: &mut Vec<String>,
) -> Quantity {
    let mut reserve = Vec::with_capacity(Criterion::ALL.len());
    for (c, criterion) in Criterion::ALL.iter().enumerate() {
        let (r, fi) = (0..rows)
            .map(|r| (r, index(r, c)))
            .filter(|(_, fi)| !fi.is_nan())
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("a row with strengths");
        reserve.push(1.0 / fi);
        lines.push(format!(
            "  {:<14} R = {:<12.5} {}",
            criterion.name(),
            1.0 / fi,
            place(r)
        ));
    }
    Quantity::vector("reserve_factor", "1", &reserve)
}
