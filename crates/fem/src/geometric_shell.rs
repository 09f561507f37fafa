//! The second-order field of shell bodies: quadratic modes from the membrane
//! (docs/geometric-stiffening.md, "Shells").
//!
//! A shell that bends must move in its plane to keep its membrane strain to second order as
//! small as its stiffness allows: its ends come closer, as a beam's do. For the modes `φ_j` the
//! quadratic part of the Green–Lagrange membrane strain of `u = Σ w_j φ_j` is
//! `½ Σ w_j w_l e_jl`, `e_jl = [g_x^j·g_x^l, g_y^j·g_y^l, g_x^j·g_y^l + g_y^j·g_x^l]` with
//! `g_a^j` the gradient of `φ_j` along the element's in-plane axis `a` (its in-plane components
//! from the nodal translations, its normal component, the slope, from the nodal rotations as
//! the beams' slopes are). The second-order field `½ Σ w_j w_l Q_jl` adds the linear strain of
//! `Q_jl`; the field that leaves the least strain energy solves `K Q_jl = −f_jl`, `f_jl` the
//! internal force of the strain `e_jl` (`∫ B_mᵀ A e + B_κᵀ B e dA` of the laminate's `A` and
//! `B`), with the shell held only at one node (its body frame's) and by its rigid couplings:
//! any other support would add stresses the mechanism's joints do not cause.
//!
//! By reciprocity `−F·Q_jl(k) = (K⁻¹ F_k)ᵀ f_jl` is the geometric stiffness of the membrane
//! stresses a force `F` at node `k` causes (reacted at the clamp): the unit load cases of the
//! beams, computed from the other side with one solve per pair of modes instead of one per
//! nodal force. The result has the beams' form, [`GeometricStiffness`]
//! (`nodal[3k + i][(j, l)] = −Q_jl` at node `k`, component `i`), and the multibody layer uses
//! it the same way.
//!
//! Derivatives: the stiffness is factorised once in `f64`; the tangents of the modes and the
//! laminate enter the right-hand sides (`K Q_b = −f_b − K_b Q`, one triangular solve per
//! tangent; on the reverse-mode tape the solves are one operation,
//! `sens::Scalar::symmetric_solution`).

use std::rc::Rc;

use nalgebra::{DMatrix, Matrix3, SMatrix, Vector3};
use sens::{LinearSolver, Scalar};

use crate::assembly::{Assembly, Constraints, MassKind, Properties};
use crate::body::ModalOptions;
use crate::correction::{distribution, factor_held};
use crate::error::FemError;
use crate::geometric::GeometricStiffness;
use crate::mesh::{Element, Mesh};
use crate::modal::{ModalBody, NODE_DOFS};
use crate::shell::{MEMBRANE_POINTS, TriGeometry, membrane_operators};

/// The [`GeometricStiffness`] (second-order field) of the shell body `body` whose FE mesh is
/// `mesh`, with the element properties `props` (in the scalar of the design: a ply angle's
/// tangent reaches the field through the laminate as well as through the modes) and the
/// element options and couplings of `options`, measured from node `clamp`.
///
/// Errors: a mesh with beam elements, a body that does not match the mesh, a clamp that is not
/// a node, a shell that one node and its rigid couplings do not hold (a mesh in pieces).
///
/// The field involves the leading `field_modes` modes of the body (`GeometricStiffness` of
/// that order); pass `body.n_modes()` for all.
pub fn shell_geometric_stiffness<S: Scalar>(
    mesh: &Mesh,
    props: &Properties<S>,
    options: &ModalOptions,
    body: &ModalBody<S>,
    clamp: usize,
    field_modes: usize,
) -> Result<GeometricStiffness<S>, FemError> {
    let n_nodes = crate::geometric::check_body(mesh, body, clamp)?;
    if mesh
        .elements
        .iter()
        .any(|e| matches!(e, Element::Beam { .. }))
    {
        return Err(FemError::Stiffening(
            "second-order field: a body of beam and shell elements together is not supported \
             (use one kind of element per body)"
                .into(),
        ));
    }
    let mut constraints = Constraints::new();
    constraints.clamp(clamp);
    for coupling in options.couplings.iter().filter(|c| c.rigid) {
        let d = distribution(mesh, coupling)?;
        constraints.tie(&d.nodes, d.point);
    }
    let assembly = Assembly::new(mesh, &constraints)?;
    let (k, _) = assembly.values(mesh, props, &options.element, MassKind::Lumped)?;
    let k0 = assembly.matrix(k.iter().map(|x| x.value()).collect());
    let llt: Rc<dyn LinearSolver> = Rc::new(factor_held(&assembly, &k0, || {
        FemError::Stiffening(format!(
            "second-order field: the shell held at node {clamp} is not stiff against every \
             motion (is the mesh in one piece?)"
        ))
    })?);

    let nf = field_modes.min(body.n_modes());
    let pairs: Vec<(usize, usize)> = (0..nf).flat_map(|j| (j..nf).map(move |l| (j, l))).collect();
    let forces = membrane_forces(mesh, props, options, body, nf, &pairs)?;

    // K y = f for every pair, values first
    let n = assembly.n_free();
    let np = pairs.len();
    let mut f = vec![S::zero(); n * np];
    for (p, fp) in forces.iter().enumerate() {
        for (g, &fg) in fp.iter().enumerate() {
            // a force of zero value may still have tangents (a design that breaks a symmetry)
            if fg.value() != 0.0 || !fg.is_constant() {
                for &(i, c) in assembly.terms(g) {
                    f[p * n + i] += fg * c;
                }
            }
        }
    }
    let mut y: Vec<f64> = f.iter().map(|x| x.value()).collect();
    llt.solve_columns(&mut y, np);
    // tangents (or the tape's operation): K₀ x = f − (K − K₀) y
    if !S::PLAIN {
        let mut ky = vec![S::zero(); n * np];
        let (cp, ri) = (k0.symbolic().col_ptr(), k0.symbolic().row_idx());
        for j in 0..n {
            for p in cp[j]..cp[j + 1] {
                let dk = k[p] - k[p].value();
                if !dk.is_constant() {
                    for c in 0..np {
                        ky[c * n + ri[p]] += dk * y[c * n + j];
                    }
                }
            }
        }
        f.iter_mut().zip(ky).for_each(|(f, ky)| *f -= ky);
    }
    let x = S::symmetric_solution(&f, y, np, &llt);

    let mut out = GeometricStiffness {
        n_modes: body.n_modes(),
        field_modes: nf,
        eigenmodes: nf,
        clamp,
        nodal: vec![DMatrix::<S>::zeros(nf, nf); 3 * n_nodes],
        elements: None,
    };
    for (p, &(j, l)) in pairs.iter().enumerate() {
        for node in 0..n_nodes {
            for i in 0..3 {
                let mut v = S::zero();
                for &(dof, c) in assembly.terms(NODE_DOFS * node + i) {
                    v += x[p * n + dof] * c;
                }
                out.nodal[3 * node + i][(j, l)] = v;
                out.nodal[3 * node + i][(l, j)] = v;
            }
        }
    }
    Ok(out)
}

/// The internal forces `f_jl` (all dof of the mesh, global axes) of the quadratic membrane
/// strains `e_jl` of the mode pairs `pairs` (see the module doc).
fn membrane_forces<S: Scalar>(
    mesh: &Mesh,
    props: &Properties<S>,
    options: &ModalOptions,
    body: &ModalBody<S>,
    nm: usize,
    pairs: &[(usize, usize)],
) -> Result<Vec<Vec<S>>, FemError> {
    let mut out = vec![vec![S::zero(); NODE_DOFS * mesh.nodes.len()]; pairs.len()];
    for (e, el) in mesh.elements.iter().enumerate() {
        let Element::Shell {
            nodes,
            property,
            material_axis,
        } = *el
        else {
            continue;
        };
        let lam = props.laminate(e, property)?;
        let g = TriGeometry::new(nodes.map(|n| mesh.nodes[n]), &material_axis, e)?;
        let ops = membrane_operators(&g, options.element.membrane);
        let r: Matrix3<S> = g.frame.map(S::from_f64);
        // P_q = (A/3)(B_m,qᵀ A + B_κᵀ B): the nodal forces of a membrane strain at point q
        let weight = g.area / 3.0;
        let p: Vec<SMatrix<S, 18, 3>> = ops
            .bm
            .iter()
            .map(|bm| {
                let mut pq = SMatrix::<S, 18, 3>::zeros();
                for c in 0..18 {
                    for s in 0..3 {
                        let mut v = S::zero();
                        for t in 0..3 {
                            v += lam.a[(t, s)] * bm[(t, c)] + lam.b[(t, s)] * ops.bb[(t, c)];
                        }
                        pq[(c, s)] = v * weight;
                    }
                }
                pq
            })
            .collect();
        // the gradients (g_x, g_y) of each mode at each point, local axes
        let grads: Vec<[[Vector3<S>; 2]; 3]> = (0..nm)
            .map(|j| {
                let local = |node: usize, rot: bool| -> Vector3<S> {
                    let row = NODE_DOFS * node + if rot { 3 } else { 0 };
                    r * Vector3::new(
                        body.modes[(row, j)],
                        body.modes[(row + 1, j)],
                        body.modes[(row + 2, j)],
                    )
                };
                let u = nodes.map(|n| local(n, false));
                let th = nodes.map(|n| local(n, true));
                let mut inplane = [[S::zero(); 2]; 2]; // [component][axis]
                for (i, ui) in u.iter().enumerate() {
                    for (axis, &dn) in g.dn[i].iter().enumerate() {
                        inplane[0][axis] += ui[0] * dn;
                        inplane[1][axis] += ui[1] * dn;
                    }
                }
                MEMBRANE_POINTS.map(|l| {
                    // the slope of the normal displacement from the rotations: w,ₓ = −θ_y,
                    // w,ᵧ = θ_x (linear in the element)
                    let mut wx = S::zero();
                    let mut wy = S::zero();
                    for (i, t) in th.iter().enumerate() {
                        wx -= t[1] * l[i];
                        wy += t[0] * l[i];
                    }
                    [
                        Vector3::new(inplane[0][0], inplane[1][0], wx),
                        Vector3::new(inplane[0][1], inplane[1][1], wy),
                    ]
                })
            })
            .collect();
        let rt = r.transpose();
        for (fp, &(j, l)) in out.iter_mut().zip(pairs) {
            let mut local = SMatrix::<S, 18, 1>::zeros();
            for (q, pq) in p.iter().enumerate() {
                let [gxj, gyj] = &grads[j][q];
                let [gxl, gyl] = &grads[l][q];
                let strain = Vector3::new(gxj.dot(gxl), gyj.dot(gyl), gxj.dot(gyl) + gyj.dot(gxl));
                local += pq * strain;
            }
            for (a, &node) in nodes.iter().enumerate() {
                for half in 0..2 {
                    let o = 6 * a + 3 * half;
                    let v = rt * Vector3::new(local[o], local[o + 1], local[o + 2]);
                    for d in 0..3 {
                        fp[NODE_DOFS * node + 3 * half + d] += v[d];
                    }
                }
            }
        }
    }
    Ok(out)
}
