//! `flexsens laminate`: plate stiffness of the deck's laminates and its ply-angle derivatives;
//! with `--load`, the plies' stresses and failure indices under given resultants.

use std::path::Path;

use laminate::{LaminateStiffness, PlyStack};
use sens::{chunk_ranges, seed_chunk};
use serde_json::json;

use super::Format;
use super::output::{self, Derivative, Quantity, Report};
use super::ply_stress::{PlateLoad, ply_quantities, ply_quantity_derivatives};
use crate::deck;
use crate::deck::bodies::ShellLaminate;
use crate::deck::design::{DesignVariable, validate as validate_design};
use crate::deck::laminates::{LaminateDef, LaminateModel, validate};
use crate::error::CliError;
use crate::study::flexible::{Design, DesignRequest, LaminateDesign, shell_design};

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
    let n = links.len();
    derivatives(&Design::Shell {
        laminates: vec![LaminateDesign {
            stack: stack.clone(),
            links: links.to_vec(),
            materials: vec![Vec::new(); n],
            thicknesses: vec![Vec::new(); n],
        }],
        names: vec![String::new(); n],
        values: vec![0.0; n],
    })
}

/// The laminate stiffness's derivatives with respect to each variable of a shell design,
/// through the shell bodies' own `Design::properties`.
pub(crate) fn derivatives(design: &Design) -> Vec<LaminateStiffness<f64>> {
    let values = design.values();
    let mut out = Vec::with_capacity(values.len());
    for range in chunk_ranges(values.len(), CHUNK) {
        let seeded = seed_chunk::<CHUNK>(values, range.start);
        let props = design
            .properties(&seeded)
            .expect("the plies of a validated stack stay valid");
        for k in 0..range.len() {
            out.push(props.laminates[0].tangent(k));
        }
    }
    out
}

/// The derivative blocks of a laminate: per ply angle (per radian), or with `[design.*]`
/// variables per variable that moves this laminate (per its unit); with a load, its ply
/// stresses', strains' and failure indices' derivatives too.
fn derivative_blocks(name: &str, def: &LaminateDef, req: &Request) -> Vec<Derivative> {
    let laminate = [ShellLaminate::of(name, def)];
    let vars = req.vars;
    let request = match vars.is_empty() {
        true => DesignRequest::EachPly,
        false => DesignRequest::Variables(vars),
    };
    let design = shell_design(&laminate, request);
    let mut blocks: Vec<Vec<Quantity>> = derivatives(&design).iter().map(quantities).collect();
    if let Some((load, model)) = req.load {
        let loaded = ply_quantity_derivatives(def, model, load, &design);
        for (block, more) in blocks.iter_mut().zip(loaded) {
            block.extend(more);
        }
    }
    if vars.is_empty() {
        return (blocks.into_iter().enumerate())
            .map(|(i, values)| Derivative {
                wrt: format!("plies.{i}.angle"),
                per: "rad",
                values,
            })
            .collect();
    }
    (vars.iter().zip(blocks).enumerate())
        .filter(|(j, _)| design.depends_on(*j))
        .map(|(_, (v, values))| Derivative {
            wrt: v.name.clone(),
            per: v.unit,
            values,
        })
        .collect()
}

/// What is asked of each laminate.
struct Request<'a> {
    derivatives: bool,
    vars: &'a [DesignVariable],
    load: Option<(&'a PlateLoad, &'a LaminateModel)>,
}

fn report(name: &str, def: &LaminateDef, req: &Request) -> Report {
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
    let derivatives = if req.derivatives {
        derivative_blocks(name, def, req)
    } else {
        Vec::new()
    };
    let mut values = quantities(&stack.stiffness());
    if let Some((load, model)) = req.load {
        let (q, lines) = ply_quantities(def, model, load);
        values.extend(q);
        preamble.extend(lines);
    }
    Report {
        kind: "laminate",
        name: name.to_string(),
        preamble,
        info,
        values,
        derivatives,
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
    let load = PlateLoad::parse(load)?;
    let (src, raw) = deck::load(path, overrides)?;
    let model = validate(&src, &raw)?;
    let design = validate_design(&src, &raw, &model)?;
    let selected = deck::select(&src, &model.laminates, only, "laminate")?;
    let req = Request {
        derivatives,
        vars: &design.variables,
        load: load.as_ref().map(|l| (l, &model)),
    };
    let reports: Vec<Report> = selected
        .iter()
        .map(|(name, def)| report(name, def, &req))
        .collect();
    Ok(output::render(
        format,
        raw.title.as_deref(),
        "laminates",
        "laminate",
        &reports,
    ))
}
