//! `flexsens modes`: vibration modes of the deck's flexible bodies (the component modes of the
//! multibody model), their design derivatives, mode shapes for ParaView and the assembled
//! matrices for other tools.

use std::fmt::Write as _;
use std::path::Path;

use fem::{ModalAnalysis, ModeDerivatives};
use serde_json::json;

use super::Format;
use super::output::{self, Derivative, Quantity, Report};
use crate::deck;
use crate::deck::bodies::validate_one;
use crate::deck::design::validate as validate_design;
use crate::deck::laminates::validate as validate_laminates;
use crate::error::CliError;
use crate::files::write_atomic;
use crate::study::flexible::{Built, CHUNK, DesignRequest, build};
use crate::table::CsvTable;

/// What the command should write besides the report.
pub struct ModesRequest<'a> {
    pub only: Option<&'a str>,
    pub format: Format,
    pub derivatives: bool,
    pub vtk: Option<&'a Path>,
    pub export_matrices: Option<&'a Path>,
}
/// What the derivatives of repeated frequencies mean (the JSON says it beside them).
const REPEATED_DERIVATIVES: &str = "directional: within a group of repeated frequencies each \
     variable's derivatives are those of the eigenvalues along that variable (in the basis of \
     the group that its perturbation diagonalises), not of fixed modes; a variable that splits \
     the group gives different values to its modes, and only their sum is independent of the \
     basis";

fn frequency_derivative(lambda: f64, d_lambda: f64) -> f64 {
    // f = √λ / 2π ⇒ df = dλ / (4π √λ)
    d_lambda / (4.0 * std::f64::consts::PI * lambda.max(0.0).sqrt())
}

fn report(
    name: &str,
    b: &Built,
    a: &ModalAnalysis,
    d: Option<&ModeDerivatives>,
    per: &[&'static str],
) -> Report {
    let lam = a.eigenvalues();
    let lam = lam.as_slice();
    let f = a.frequencies_hz();
    let mut values = vec![
        Quantity::vector("frequencies", "Hz", &f),
        Quantity::vector("eigenvalues", "rad^2/s^2", lam),
        Quantity::vector("modal_masses", "1", &a.modal_masses()),
    ];
    // groups of repeated frequencies among the retained modes (e.g. the two bending planes of
    // a round tube): 0 for a single mode, else the group's number from 1
    let groups: Vec<Vec<usize>> = fem::sensitivity::clusters(lam, fem::sensitivity::CLUSTER_RTOL)
        .into_iter()
        .filter(|g| g.len() > 1)
        .collect();
    let mut group_of = vec![0.0; lam.len()];
    for (k, g) in groups.iter().enumerate() {
        for &i in g {
            group_of[i] = (k + 1) as f64;
        }
    }
    values.push(Quantity::vector("repeated_group", "1", &group_of));
    if let Ok(Some(c)) = a.modal_damping() {
        let zeta: Vec<f64> = c
            .iter()
            .zip(lam)
            .map(|(c, l)| c / (2.0 * l.sqrt()))
            .collect();
        values.push(Quantity::vector("damping_ratios", "1", &zeta));
    }
    let mut preamble = vec![
        format!(
            "{} body: {} nodes, {} elements, {} free dof, reference {:?}, {} mass",
            b.kind,
            b.mesh.nodes.len(),
            b.mesh.elements.len(),
            a.assembly.n_free(),
            a.options.reference,
            if a.options.mass == fem::MassKind::Lumped {
                "lumped"
            } else {
                "consistent"
            }
        ),
        format!("{:>4} {:>14} {:>14}", "mode", "f/Hz", "omega/(rad/s)"),
    ];
    // retained modes by their number; static correction modes as c1, c2, …
    let numbers: Vec<String> = a
        .kept
        .iter()
        .map(|k| (k + 1).to_string())
        .chain((1..).map(|c| format!("c{c}")))
        .take(lam.len())
        .collect();
    for ((fi, l), label) in f.iter().zip(lam).zip(&numbers) {
        preamble.push(format!(
            "{:>4} {:>14.6} {:>14.6}",
            label,
            fi,
            l.max(0.0).sqrt()
        ));
    }
    let repeated: Vec<String> = groups
        .iter()
        .map(|g| {
            g.iter()
                .map(|&i| numbers[i].clone())
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    if !repeated.is_empty() {
        preamble.push(format!(
            "repeated frequencies (modes {}){}",
            repeated.join("; "),
            if d.is_some() {
                ": their derivatives are directional, per design variable"
            } else {
                ""
            }
        ));
    }
    let mut derivatives = Vec::new();
    if let Some(d) = d {
        for (var, name) in b.design.names().iter().enumerate() {
            let dl: Vec<f64> = a.kept.iter().map(|&i| d.eigenvalues[var][i]).collect();
            let df: Vec<f64> = dl
                .iter()
                .zip(lam)
                .map(|(&x, &l)| frequency_derivative(l, x))
                .collect();
            derivatives.push(Derivative {
                wrt: name.clone(),
                per: per[var],
                values: vec![
                    Quantity::vector("frequencies", "Hz", &df),
                    Quantity::vector("eigenvalues", "rad^2/s^2", &dl),
                ],
            });
        }
    }
    let mut info = serde_json::Map::new();
    info.insert("kind".into(), json!(b.kind));
    info.insert("nodes".into(), json!(b.mesh.nodes.len()));
    info.insert("elements".into(), json!(b.mesh.elements.len()));
    info.insert("free_dofs".into(), json!(a.assembly.n_free()));
    // retained modes by their number, static correction modes as "c1", …
    let listed: Vec<Vec<serde_json::Value>> = groups
        .iter()
        .map(|g| {
            g.iter()
                .map(|&i| match a.kept.get(i) {
                    Some(k) => json!(k + 1),
                    None => json!(numbers[i]),
                })
                .collect()
        })
        .collect();
    info.insert("repeated".into(), json!(listed));
    if d.is_some() && !groups.is_empty() {
        info.insert("repeated_derivatives".into(), json!(REPEATED_DERIVATIVES));
    }
    Report {
        kind: "body",
        name: name.into(),
        preamble,
        info,
        values,
        derivatives,
    }
}

/// Legacy ASCII VTK of the mesh with every mode's nodal translations and rotations.
fn vtk(name: &str, b: &Built, a: &ModalAnalysis) -> String {
    let x = a.mode_shapes();
    let f = a.frequencies_hz();
    let mut s = String::new();
    let _ = writeln!(s, "# vtk DataFile Version 3.0");
    let freqs: Vec<String> = f.iter().map(|v| format!("{v:.6e}")).collect();
    let _ = writeln!(
        s,
        "flexsens modes of body {name}; frequencies/Hz {}",
        freqs.join(" ")
    );
    let _ = writeln!(s, "ASCII\nDATASET UNSTRUCTURED_GRID");
    let _ = writeln!(s, "POINTS {} double", b.mesh.nodes.len());
    for p in &b.mesh.nodes {
        let _ = writeln!(s, "{:e} {:e} {:e}", p.x, p.y, p.z);
    }
    let size: usize = b.mesh.elements.iter().map(|e| e.nodes().len() + 1).sum();
    let _ = writeln!(s, "CELLS {} {size}", b.mesh.elements.len());
    for e in &b.mesh.elements {
        let n = e.nodes();
        let ids: Vec<String> = n.iter().map(|i| i.to_string()).collect();
        let _ = writeln!(s, "{} {}", n.len(), ids.join(" "));
    }
    let _ = writeln!(s, "CELL_TYPES {}", b.mesh.elements.len());
    for e in &b.mesh.elements {
        let _ = writeln!(s, "{}", if e.nodes().len() == 2 { 3 } else { 5 });
    }
    let _ = writeln!(s, "POINT_DATA {}", b.mesh.nodes.len());
    for m in 0..x.ncols() {
        for (what, off) in [("translation", 0), ("rotation", 3)] {
            let _ = writeln!(s, "VECTORS mode_{}_{what} double", m + 1);
            for n in 0..b.mesh.nodes.len() {
                let r = n * fem::NODE_DOFS + off;
                let _ = writeln!(s, "{:e} {:e} {:e}", x[(r, m)], x[(r + 1, m)], x[(r + 2, m)]);
            }
        }
    }
    s
}

/// A sparse matrix in Matrix Market coordinate format (1-based, all stored entries).
fn matrix_market(m: &faer::sparse::SparseColMat<usize, f64>, comment: &str) -> String {
    let cp = m.symbolic().col_ptr();
    let ri = m.symbolic().row_idx();
    let val = m.val();
    let mut s = String::from("%%MatrixMarket matrix coordinate real general\n");
    let _ = writeln!(s, "% {comment}");
    let _ = writeln!(s, "{} {} {}", m.nrows(), m.ncols(), val.len());
    for j in 0..m.ncols() {
        for p in cp[j]..cp[j + 1] {
            let _ = writeln!(s, "{} {} {:e}", ri[p] + 1, j + 1, val[p]);
        }
    }
    s
}

fn export(
    dir: &Path,
    name: &str,
    b: &Built,
    a: &ModalAnalysis,
    dm: Option<&[fem::DesignMatrices]>,
    per: &[&'static str],
) -> Result<(), CliError> {
    const DOF: [&str; 6] = ["ux", "uy", "uz", "rx", "ry", "rz"];
    let mut dofs = CsvTable::new();
    dofs.row(["row", "node", "dof"]);
    for (i, d) in a.assembly.dofs().iter().enumerate() {
        let (node, dof) = match *d {
            fem::ReducedDof::Node(g) => (g / fem::NODE_DOFS, DOF[g % fem::NODE_DOFS].to_string()),
            // the rigid motion of the tie-th rigid coupling, in the order of the deck
            fem::ReducedDof::Tie {
                tie,
                coordinate,
                node,
            } => (node, format!("rigid{}.q{}", tie + 1, coordinate + 1)),
        };
        dofs.row([(i + 1).to_string(), node.to_string(), dof]);
    }
    let dofs = dofs.finish();
    write_atomic(&dir.join(format!("{name}.dofs.csv")), dofs.as_bytes())?;
    let what = "rows and columns are the free dof listed in the .dofs.csv file";
    write_atomic(
        &dir.join(format!("{name}.K.mtx")),
        matrix_market(
            &a.k,
            &format!("flexsens: stiffness K of body {name} (N/m, N, N*m); {what}"),
        )
        .as_bytes(),
    )?;
    write_atomic(
        &dir.join(format!("{name}.M.mtx")),
        matrix_market(
            &a.m,
            &format!("flexsens: mass M of body {name} (kg, kg*m, kg*m^2); {what}"),
        )
        .as_bytes(),
    )?;
    if let Some(dm) = dm {
        for (var, (d, vname)) in dm.iter().zip(b.design.names()).enumerate() {
            let text = matrix_market(
                &d.k,
                &format!(
                    "flexsens: dK/d({vname}) of body {name}, per {}; {what}",
                    per[var]
                ),
            );
            write_atomic(&dir.join(format!("{name}.dK_{var}.mtx")), text.as_bytes())?;
        }
    }
    Ok(())
}

/// Run the command; the returned text goes to stdout.
pub fn run(path: &Path, overrides: &[String], req: &ModesRequest) -> Result<String, CliError> {
    let (src, raw) = deck::load(path, overrides)?;
    let model = validate_laminates(&src, &raw)?;
    let design = validate_design(&src, &raw, &model)?;
    let only = req.only;
    let selected = deck::select(&src, &raw.body, only, "body")?;
    if req.vtk.is_some() && selected.len() > 1 {
        let names: Vec<&str> = selected.iter().map(|(n, _)| n.as_str()).collect();
        return Err(src
            .error(
                None,
                None,
                format!(
                    "--vtk writes one body: choose one with --body ({})",
                    names.join(", ")
                ),
            )
            .into());
    }
    let mut reports = Vec::new();
    for (name, b) in selected {
        let def = validate_one(&src, &raw, name, b, &model)?;
        // per ply angle (radian), or per [design.*] variable (its unit)
        let request = match (req.derivatives, design.variables.is_empty()) {
            (false, _) => DesignRequest::None,
            (true, true) => DesignRequest::EachPly,
            (true, false) => DesignRequest::Variables(&design.variables),
        };
        let mut built = build(&src, name, &def, request)?;
        let per: Vec<&'static str> = match request {
            DesignRequest::Variables(vars) => vars.iter().map(|v| v.unit).collect(),
            _ => vec!["rad"; built.design.names().len()],
        };
        let (analysis, _) =
            crate::study::flexible::analyse(&src, name, b.span(), &def, &mut built, false)?;
        // the derivative matrices only where they are exported: the eigenvalue derivatives
        // alone need no more than their projections on the modes
        let (matrices, derivs) = match (req.derivatives, req.export_matrices.is_some()) {
            (false, _) => (None, None),
            (true, false) => (
                None,
                Some(built.eigenvalue_derivatives::<CHUNK>(&src, name, b.span(), &analysis)?),
            ),
            (true, true) => {
                let (dm, d) = built.mode_derivatives::<CHUNK>(
                    &src,
                    name,
                    b.span(),
                    &analysis,
                    fem::ModeUpdate::Fixed,
                )?;
                (Some(dm), Some(d))
            }
        };
        if let Some(path) = req.vtk {
            write_atomic(path, vtk(name, &built, &analysis).as_bytes())?;
        }
        if let Some(dir) = req.export_matrices {
            export(dir, name, &built, &analysis, matrices.as_deref(), &per)?;
        }
        reports.push(report(name, &built, &analysis, derivs.as_ref(), &per));
    }
    Ok(output::render(
        req.format,
        raw.title.as_deref(),
        "bodies",
        "body",
        &reports,
    ))
}
