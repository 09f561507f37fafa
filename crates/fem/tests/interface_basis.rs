//! Interface bases: distributing couplings over node sets (checked against statics: a rigid
//! motion is reproduced, a load keeps its resultant and moment), static correction modes at
//! couplings (a coupling load is represented exactly, checked against the full stiffness
//! solve), and the design derivatives of a body with correction modes (against central
//! differences of basis-independent quantities: the reduced body's static and dynamic
//! flexibility at its couplings).

mod common;

use common::paper_material;
use fem::{
    Coupling, Mesh, ModalBody, ModalOptions, ModeUpdate, Properties, ReferenceCondition,
    analysis_derivatives, distribution, modal_analysis, modal_body, modal_body_dual,
};
use laminate::{Ply, PlyStack};
use nalgebra::{DMatrix, DVector, Vector3};
use sens::{Dual, Scalar};

fn props<S: Scalar>(b: &[S]) -> Properties<S> {
    let t = S::from_f64(0.0075 / b.len() as f64);
    let stack = PlyStack::new(
        b.iter()
            .map(|&angle| Ply {
                material: paper_material(),
                thickness: t,
                angle,
            })
            .collect(),
    )
    .unwrap();
    Properties {
        sections: vec![],
        laminates: vec![stack.stiffness()],
    }
}

/// The plate strip of the paper's §5.2 (0.304 × 0.04 m), 12 × 2 cells: node `j·13 + i`.
fn strip() -> Mesh {
    Mesh::rectangle(0.304, 0.04, 12, 2, 0).unwrap()
}

/// Couplings over the two end edges (`x = 0` and `x = L`), distributing or rigid.
fn end_edges(rigid: bool) -> Vec<Coupling> {
    vec![
        Coupling {
            nodes: vec![0, 13, 26],
            point: None,
            rigid,
        },
        Coupling {
            nodes: vec![12, 25, 38],
            point: None,
            rigid,
        },
    ]
}

fn options(modes: usize, correction: bool, rigid: bool) -> ModalOptions {
    let mut o = ModalOptions::new(modes);
    o.reference = ReferenceCondition::ClampedSectionAtCentre;
    o.couplings = end_edges(rigid);
    if correction {
        o.correction = vec![39, 40];
    }
    o
}

fn skew(r: &Vector3<f64>) -> nalgebra::Matrix3<f64> {
    nalgebra::Matrix3::new(0.0, -r.z, r.y, r.z, 0.0, -r.x, -r.y, r.x, 0.0)
}

#[test]
fn a_coupling_follows_rigid_motions_and_spreads_loads_statically() {
    let mesh = Mesh::rectangle(0.3, 0.1, 6, 4, 0).unwrap();
    // a straight edge (its rotation about the line comes from the nodal rotations), a patch
    // of the plate, and a single node, each about a point off the centroid
    for (nodes, point) in [
        (
            vec![0, 7, 14, 21, 28],
            Some(Vector3::new(-0.02, 0.05, 0.01)),
        ),
        (vec![9, 10, 11, 16, 17, 18], None),
        (vec![24], Some(Vector3::new(0.1, 0.2, 0.0))),
    ] {
        let d = distribution(
            &mesh,
            &Coupling {
                nodes: nodes.clone(),
                point,
                rigid: false,
            },
        )
        .unwrap();
        let u = Vector3::new(0.3, -0.2, 0.7);
        let th = Vector3::new(-0.4, 0.9, 0.25);
        let mut x = DMatrix::zeros(6 * mesh.nodes.len(), 1);
        for &k in &nodes {
            let r = mesh.nodes[k] - d.point;
            let uk = u + th.cross(&r);
            for i in 0..3 {
                x[(6 * k + i, 0)] = uk[i];
                x[(6 * k + 3 + i, 0)] = th[i];
            }
        }
        let got = d.rows(&x);
        for i in 0..3 {
            // (to round-off through the fit's 1e-6 rotation weight: a condition number of 1e6)
            assert!((got[(i, 0)] - u[i]).abs() < 1e-9, "{nodes:?}: u {got}");
            assert!((got[(3 + i, 0)] - th[i]).abs() < 1e-9, "{nodes:?}: θ {got}");
        }
        // a unit force or moment at the point: same resultant and moment about the point
        for c in 0..6 {
            let f = d.load(c, mesh.nodes.len());
            let (mut force, mut moment) = (Vector3::zeros(), Vector3::zeros());
            for &k in &nodes {
                let fk = Vector3::new(f[6 * k], f[6 * k + 1], f[6 * k + 2]);
                let mk = Vector3::new(f[6 * k + 3], f[6 * k + 4], f[6 * k + 5]);
                force += fk;
                moment += skew(&(mesh.nodes[k] - d.point)) * fk + mk;
            }
            let mut e = [0.0; 6];
            e[c] = 1.0;
            for i in 0..3 {
                assert!(
                    (force[i] - e[i]).abs() < 1e-9,
                    "{nodes:?} load {c}: {force} {moment}"
                );
                assert!((moment[i] - e[3 + i]).abs() < 1e-9, "{nodes:?} load {c}");
            }
        }
    }
    // an edge's force goes to its nodes, not to their rotations (to 1e-6 of the force)
    let d = distribution(
        &mesh,
        &Coupling {
            nodes: vec![0, 7, 14, 21, 28],
            point: None,
            rigid: false,
        },
    )
    .unwrap();
    let f = d.load(2, mesh.nodes.len());
    for k in [0, 7, 14, 21, 28] {
        assert!((f[6 * k + 2] - 0.2).abs() < 1e-6, "{}", f[6 * k + 2]);
        assert!(f[6 * k + 3].abs() < 1e-6 && f[6 * k + 4].abs() < 1e-6);
    }
    // bad sets are named
    for nodes in [vec![], vec![3, 3], vec![999]] {
        let e = distribution(
            &mesh,
            &Coupling {
                nodes,
                point: None,
                rigid: false,
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("coupling"), "{e}");
    }
}

#[test]
fn correction_at_couplings_represents_their_loads_exactly() {
    correction_at_couplings_represents_their_loads_exactly_for(false);
}

#[test]
fn correction_at_rigid_couplings_represents_their_loads_exactly() {
    correction_at_couplings_represents_their_loads_exactly_for(true);
}

fn correction_at_couplings_represents_their_loads_exactly_for(rigid: bool) {
    let mesh = strip();
    let b = [0.4, 0.4, 0.4];
    let p = props(&b);
    let plain = modal_analysis(&mesh, &p, &options(2, false, rigid)).unwrap();
    let corrected = modal_analysis(&mesh, &p, &options(2, true, rigid)).unwrap();
    // the body has a node for each coupling after the mesh's, at the edge's middle
    let body = modal_body(&mesh, &p, &corrected).unwrap();
    assert_eq!(body.n_nodes(), 39 + 2);
    assert_eq!(body.node_masses[39], 0.0);
    let origin = corrected.origin;
    assert!((body.node_positions[40] + origin - Vector3::new(0.304, 0.02, 0.0)).norm() < 1e-12);
    // correction: the six loads of each coupling (none fixed by the clamp at mid-length)
    assert_eq!(body.n_modes(), 2 + 12);
    // a force and moment at the right coupling, against the full stiffness solve
    let d = &corrected.couplings[1];
    let n = mesh.nodes.len();
    let f = d.load(2, n) * 5.0 + d.load(3, n) * 0.3 - d.load(1, n) * 2.0;
    let nf = corrected.assembly.n_free();
    let e = DMatrix::<f64>::identity(nf, nf);
    let k = fem::eigen::project(&corrected.k, &e, &e);
    let ff = corrected.assembly.restrict(f.as_slice());
    let exact = corrected.expand(&DMatrix::from_column_slice(
        nf,
        1,
        k.lu().solve(&ff).unwrap().as_slice(),
    ));
    let reduced = |a: &fem::ModalAnalysis| {
        let x = a.mode_shapes();
        let q = x.transpose() * &f;
        let lam = a.eigenvalues();
        &x * DVector::from_iterator(lam.len(), q.iter().zip(&lam).map(|(q, l)| q / l))
    };
    let err = |u: DVector<f64>| (u - exact.column(0)).amax() / exact.amax();
    let (without, with) = (err(reduced(&plain)), err(reduced(&corrected)));
    eprintln!("coupling load: 2 modes {without:.2e}, with correction {with:.2e}");
    assert!(without > 1e-2, "{without:e}");
    assert!(with < 1e-9, "{with:e}");
    // the coupling node's rows give the fitted motion of the edge
    let x = corrected.mode_shapes();
    let rows = d.rows(&x);
    for r in 0..6 {
        for j in 0..body.n_modes() {
            assert!((body.modes[(6 * 40 + r, j)] - rows[(r, j)]).abs() < 1e-15);
        }
    }
}

/// `R (K_r − ω² M_r)⁻¹ Rᵀ` at body node `node` (`R` its six mode rows, `M_r` from the lumped
/// masses, `K_r` the full modal stiffness or `diag(λ)`): the same for any basis of the same
/// span. Values and, for each tangent `t < T`, derivatives.
fn flexibility<const T: usize>(
    body: &ModalBody<Dual<T>>,
    node: usize,
    omega2: f64,
) -> (DMatrix<f64>, Vec<DMatrix<f64>>) {
    let r = body.n_modes();
    let part = |a: &DMatrix<Dual<T>>, t: Option<usize>| {
        a.map(|x| match t {
            None => x.v,
            Some(t) => x.d[t],
        })
    };
    let mut mr = DMatrix::from_element(r, r, Dual::<T>::constant(0.0));
    for k in 0..body.n_nodes() {
        let w = [
            body.node_masses[k],
            body.node_masses[k],
            body.node_masses[k],
            body.node_inertias[k].x,
            body.node_inertias[k].y,
            body.node_inertias[k].z,
        ];
        for d in 0..6 {
            for i in 0..r {
                for j in 0..r {
                    mr[(i, j)] += body.modes[(6 * k + d, i)] * body.modes[(6 * k + d, j)] * w[d];
                }
            }
        }
    }
    let kr = body
        .stiffness_matrix
        .as_deref()
        .cloned()
        .unwrap_or_else(|| {
            DMatrix::from_fn(r, r, |i, j| {
                if i == j {
                    body.eigenvalues[i]
                } else {
                    Dual::constant(0.0)
                }
            })
        });
    let a = &kr - &mr * Dual::from_f64(omega2);
    let rows = body.modes.rows(6 * node, 6).into_owned();
    let (av, rv) = (part(&a, None), part(&rows, None));
    let inv = av.clone().try_inverse().unwrap();
    let value = &rv * &inv * rv.transpose();
    let tangents = (0..T)
        .map(|t| {
            let (at, rt) = (part(&a, Some(t)), part(&rows, Some(t)));
            &rt * &inv * rv.transpose() + &rv * &inv * rt.transpose()
                - &rv * &inv * at * &inv * rv.transpose()
        })
        .collect();
    (value, tangents)
}

/// An f64 body as a dual one without tangents.
fn constant(b: &ModalBody<f64>) -> ModalBody<Dual<3>> {
    let c = |x: &f64| Dual::constant(*x);
    ModalBody {
        node_positions: b.node_positions.clone(),
        node_masses: b.node_masses.iter().map(c).collect(),
        node_inertias: b
            .node_inertias
            .iter()
            .map(|m| m.map(Dual::constant))
            .collect(),
        modes: b.modes.map(Dual::constant),
        eigenvalues: b.eigenvalues.iter().map(c).collect(),
        modal_damping: b.modal_damping.iter().map(c).collect(),
        stiffness_matrix: None,
        damping_matrix: None,
    }
}

#[test]
fn derivatives_through_correction_modes_match_central_differences() {
    derivatives_through_correction_modes_match_central_differences_for(false);
}

#[test]
fn derivatives_through_rigid_couplings_match_central_differences() {
    derivatives_through_correction_modes_match_central_differences_for(true);
}

fn derivatives_through_correction_modes_match_central_differences_for(rigid: bool) {
    let mesh = strip();
    let b0 = [0.3, -0.5, 0.9];
    let opts = options(4, true, rigid);
    let an = modal_analysis(&mesh, &props(&b0), &opts).unwrap();
    let (dm, d) =
        analysis_derivatives::<3, _>(&mesh, &an, &b0, props, ModeUpdate::Updated).unwrap();
    let dual =
        modal_body_dual::<3>(&mesh, &props(&b0), &an, &dm, &d, 0, ModeUpdate::Updated).unwrap();
    assert!(dual.stiffness_matrix.is_some());
    // the dual body's values are the f64 body's
    let plain = modal_body(&mesh, &props(&b0), &an).unwrap();
    assert!(dual.modes.iter().zip(&plain.modes).all(|(a, b)| a.v == *b));
    assert!(
        dual.eigenvalues
            .iter()
            .zip(&plain.eigenvalues)
            .all(|(a, b)| a.v == *b)
    );
    // static flexibility at the couplings (which the correction makes exact) and the dynamic
    // one at half the lowest frequency (which the eigenmodes and the masses enter)
    let omega2 = 0.25 * an.pairs.values[0];
    let h = 1e-5;
    for (node, w2) in [(39, 0.0), (40, 0.0), (39, omega2), (40, omega2)] {
        let (value, tangents) = flexibility(&dual, node, w2);
        let scale = value.amax();
        for v in 0..3 {
            let at = |s: f64| {
                let mut b = b0;
                b[v] += s * h;
                let a = modal_analysis(&mesh, &props(&b), &opts).unwrap();
                let body = modal_body(&mesh, &props(&b), &a).unwrap();
                flexibility(&constant(&body), node, w2).0
            };
            let fd = (at(1.0) - at(-1.0)) / (2.0 * h);
            let err = (&tangents[v] - &fd).amax();
            let size = tangents[v].amax();
            eprintln!(
                "node {node}, ω² {w2:.3e}, variable {v}: |dS| {size:.3e} (|S| {scale:.3e}), \
                 error against central differences {err:.2e}"
            );
            assert!(size > 1e-3 * scale, "the variable moves the flexibility");
            assert!(err < 1e-6 * size, "{err:e} against {size:e}");
        }
    }
    // fixed modes: the shapes keep their values, the stiffness takes K_b
    let fixed =
        modal_body_dual::<3>(&mesh, &props(&b0), &an, &dm, &d, 0, ModeUpdate::Fixed).unwrap();
    assert!(fixed.modes.iter().all(|x| x.d == [0.0; 3]));
    let k = fixed.stiffness_matrix.as_ref().unwrap();
    assert!(k[(5, 7)].d.iter().any(|x| x.abs() > 0.0));
}

/// A force at a coupling stiffens a beam body as the nodal forces the coupling spreads it into
/// (`Distribution::load`, whose statics the first test checks) do when applied at the nodes.
#[test]
fn a_force_at_a_coupling_stiffens_as_its_spread_nodal_forces() {
    let n = 10;
    let mesh = common::beam(n);
    let props = common::slender().props();
    let mut o = ModalOptions::new(4);
    o.reference = ReferenceCondition::ClampedNode(0);
    o.couplings = vec![Coupling {
        nodes: vec![7, 8, 9, 10],
        point: Some(mesh.nodes[10] + Vector3::new(0.01, 0.02, 0.0)),
        rigid: false,
    }];
    let an = modal_analysis(&mesh, &props, &o).unwrap();
    let body = modal_body(&mesh, &props, &an).unwrap();
    let g = fem::geometric_stiffness(&mesh, &body, 0)
        .unwrap()
        .with_couplings(&an.couplings);
    let f = Vector3::new(3.0, -1.0, 2.0);
    let at_coupling = g.at(&[(n + 1, f)]);
    let d = &an.couplings[0];
    let spread: Vec<(usize, Vector3<f64>)> = d
        .nodes
        .iter()
        .map(|&k| {
            let fk = (0..3).fold(Vector3::zeros(), |acc, axis| {
                let l = d.load(axis, n + 1);
                acc + Vector3::new(l[6 * k], l[6 * k + 1], l[6 * k + 2]) * f[axis]
            });
            (k, fk)
        })
        .collect();
    let at_nodes = g.at(&spread);
    let scale = at_nodes.amax();
    assert!(scale > 0.0);
    assert!((at_coupling - at_nodes).amax() < 1e-12 * scale);
}

/// A rigid coupling (RBE2) over the last three elements of a cantilever, loaded at a point
/// beyond the end: the flexible part carries the force and its moment about the tie's first
/// node, and the point moves with the rigid tip, against the closed-form Timoshenko cantilever
/// (the beam elements are exact at the nodes for end loads).
#[test]
fn a_rigid_coupling_makes_a_rigid_tip_of_a_cantilever() {
    let n = 10;
    let mesh = common::beam(n);
    let rect = common::slender();
    let props = rect.props();
    let point = Vector3::new(1.3, 0.0, 0.0);
    let mut o = ModalOptions::new(2);
    o.reference = ReferenceCondition::ClampedNode(0);
    o.couplings = vec![Coupling {
        nodes: vec![7, 8, 9, 10],
        point: Some(point),
        rigid: true,
    }];
    let an = modal_analysis(&mesh, &props, &o).unwrap();
    // the clamped node, four tied nodes (six rigid coordinates), six free nodes
    assert_eq!(an.assembly.n_free(), 6 * 6 + 6);
    let nn = mesh.nodes.len();
    let d = &an.couplings[0];
    let force = 40.0;
    let f = d.load(2, nn) * force;
    let nf = an.assembly.n_free();
    let e = DMatrix::<f64>::identity(nf, nf);
    let k = fem::eigen::project(&an.k, &e, &e);
    let q = k.lu().solve(&an.assembly.restrict(f.as_slice())).unwrap();
    let u = DMatrix::from_column_slice(6 * nn, 1, &an.assembly.expand(q.as_slice()));
    // closed form: the flexible part (length l = 0.7) under the force and the moment of its arm
    // (a = 0.4 from node 7 to the point), bending in x–z about y (EI₂, shear κGA)
    let (l, a) = (0.7, 0.4);
    let ei = rect.e * rect.i2();
    let kga = rect.kappa * rect.g() * rect.area();
    let m = force * a;
    let w7 = force * l.powi(3) / (3.0 * ei) + m * l * l / (2.0 * ei) + force * l / kga;
    let slope = force * l * l / (2.0 * ei) + m * l / ei;
    let rel = |x: f64, y: f64| (x - y).abs() / y.abs();
    assert!(
        rel(u[(6 * 7 + 2, 0)], w7) < 1e-9,
        "{} {w7}",
        u[(6 * 7 + 2, 0)]
    );
    // the coupling point, and every tied node, move with the rigid tip
    let at_point = d.rows(&u);
    assert!(rel(at_point[(2, 0)], w7 + a * slope) < 1e-9);
    for k in 7..=10 {
        let x = mesh.nodes[k].x - mesh.nodes[7].x;
        assert!(rel(u[(6 * k + 2, 0)], w7 + x * slope) < 1e-9, "node {k}");
        assert!(rel(-u[(6 * k + 4, 0)], slope) < 1e-9, "node {k}");
    }
}

/// The modes of a plate strip with a rigid end edge whose nodes also carry a support, against
/// an independent solve: the full mesh's matrices with every tie and support written as a
/// constraint `G u = 0` on all dof and eliminated by the null space of `G` (dense SVD), where
/// the assembly carries each tie's free rigid motions node by node.
#[test]
fn a_rigid_coupling_on_supported_nodes_keeps_the_motions_they_allow() {
    let mesh = strip();
    let p = props(&[0.3, -0.5, 0.9]);
    let edge = vec![12, 25, 38];
    let mut o = ModalOptions::new(5);
    o.reference = ReferenceCondition::Supports;
    o.supports = vec![
        fem::Support {
            nodes: vec![0, 13, 26],
            dofs: vec![0, 1, 2, 3, 4, 5],
        },
        fem::Support {
            nodes: edge.clone(),
            dofs: vec![2],
        },
    ];
    o.couplings = vec![Coupling {
        nodes: edge.clone(),
        point: None,
        rigid: true,
    }];
    let an = modal_analysis(&mesh, &p, &o).unwrap();
    // u_z = 0 at three nodes on a line along y leaves the edge's u_x, u_y and its rotations
    // about y and z: four coordinates
    let nn = mesh.nodes.len();
    assert_eq!(an.assembly.n_free(), 6 * (nn - 6) + 4);
    // the independent solve
    let full = fem::Assembly::new(&mesh, &fem::Constraints::new()).unwrap();
    let (kv, mv) = full
        .values(&mesh, &p, &o.element, fem::MassKind::Lumped)
        .unwrap();
    let e = DMatrix::<f64>::identity(6 * nn, 6 * nn);
    let kf = fem::eigen::project(&full.matrix(kv), &e, &e);
    let mf = fem::eigen::project(&full.matrix(mv), &e, &e);
    let mut g: Vec<DVector<f64>> = Vec::new();
    let unit = |dof: usize| {
        let mut r = DVector::zeros(6 * nn);
        r[dof] = 1.0;
        r
    };
    for k in [0, 13, 26] {
        for d in 0..6 {
            g.push(unit(6 * k + d));
        }
    }
    for &k in &edge {
        g.push(unit(6 * k + 2));
    }
    let centre = mesh.nodes[25];
    for &k in &edge {
        if k == 25 {
            continue;
        }
        // u_k = u_25 + θ_25 × r and θ_k = θ_25
        let r = mesh.nodes[k] - centre;
        let cross = skew(&r);
        for d in 0..3 {
            let mut row = unit(6 * k + d);
            row[6 * 25 + d] -= 1.0;
            for c in 0..3 {
                row[6 * 25 + 3 + c] += cross[(d, c)];
            }
            g.push(row);
            let mut row = unit(6 * k + 3 + d);
            row[6 * 25 + 3 + d] -= 1.0;
            g.push(row);
        }
    }
    let gm = DMatrix::from_columns(&g).transpose();
    // the null space: the range of the projector I − G⁺G (singular values 1 against 0)
    let proj =
        DMatrix::<f64>::identity(6 * nn, 6 * nn) - gm.clone().pseudo_inverse(1e-12).unwrap() * &gm;
    let svd = proj.svd(true, false);
    let u = svd.u.unwrap();
    let null: Vec<DVector<f64>> = (0..6 * nn)
        .filter(|&i| svd.singular_values[i] > 0.5)
        .map(|i| u.column(i).into_owned())
        .collect();
    assert_eq!(null.len(), an.assembly.n_free());
    let nmat = DMatrix::from_columns(&null);
    assert!((&gm * &nmat).amax() < 1e-10);
    let kr = nmat.transpose() * &kf * &nmat;
    let mr = nmat.transpose() * &mf * &nmat;
    let l = mr.cholesky().unwrap().l();
    let li = l.clone().try_inverse().unwrap();
    let a = &li * kr * li.transpose();
    let mut reference: Vec<f64> = a.symmetric_eigen().eigenvalues.iter().copied().collect();
    reference.sort_by(f64::total_cmp);
    for (i, (got, want)) in an.computed_eigenvalues().iter().zip(&reference).enumerate() {
        eprintln!("mode {}: {got:.6e} against {want:.6e}", i + 1);
        assert!((got - want).abs() < 1e-8 * want, "mode {}", i + 1);
    }
    // the expanded modes keep the edge straight and rigid, with u_z = 0 there
    let x = an.mode_shapes();
    for j in 0..5 {
        let u = |k: usize, d: usize| x[(6 * k + d, j)];
        for &k in &edge {
            assert!(u(k, 2).abs() < 1e-12);
            for d in 3..6 {
                assert!((u(k, d) - u(25, d)).abs() < 1e-12);
            }
        }
    }
}

/// A body of `shape`'s layout whose every datum is a deterministic number of either sign: the
/// adjoints a dual body's tangents are contracted with.
fn some_adjoints(shape: &ModalBody<Dual<3>>) -> ModalBody<f64> {
    let next = std::cell::Cell::new(0usize);
    let f = |_: &Dual<3>| {
        let k = next.get();
        next.set(k + 1);
        ((k * 37 % 101) as f64 * 0.173).sin()
    };
    ModalBody {
        node_positions: shape.node_positions.clone(),
        node_masses: shape.node_masses.iter().map(f).collect(),
        node_inertias: shape
            .node_inertias
            .iter()
            .map(|v| v.map(|x| f(&x)))
            .collect(),
        modes: shape.modes.map(|x| f(&x)),
        eigenvalues: shape.eigenvalues.iter().map(f).collect(),
        modal_damping: shape.modal_damping.iter().map(f).collect(),
        stiffness_matrix: (shape.stiffness_matrix.as_ref()).map(|k| Box::new(k.map(|x| f(&x)))),
        damping_matrix: (shape.damping_matrix.as_ref()).map(|c| Box::new(c.map(|x| f(&x)))),
    }
}

/// `Σ bar · tangent t` over the data of `body`, for each of its three tangents.
fn contracted(body: &ModalBody<Dual<3>>, bar: &ModalBody<f64>) -> [f64; 3] {
    let mut out = [0.0; 3];
    let mut add = |x: &Dual<3>, b: f64| {
        for (o, d) in out.iter_mut().zip(&x.d) {
            *o += b * d;
        }
    };
    let pairs = |a: &[Dual<3>], b: &[f64], add: &mut dyn FnMut(&Dual<3>, f64)| {
        a.iter().zip(b).for_each(|(x, &b)| add(x, b))
    };
    pairs(&body.node_masses, &bar.node_masses, &mut add);
    for (a, b) in body.node_inertias.iter().zip(&bar.node_inertias) {
        pairs(a.as_slice(), b.as_slice(), &mut add);
    }
    pairs(body.modes.as_slice(), bar.modes.as_slice(), &mut add);
    pairs(&body.eigenvalues, &bar.eigenvalues, &mut add);
    pairs(&body.modal_damping, &bar.modal_damping, &mut add);
    for (a, b) in [
        (&body.stiffness_matrix, &bar.stiffness_matrix),
        (&body.damping_matrix, &bar.damping_matrix),
    ] {
        if let (Some(a), Some(b)) = (a, b) {
            pairs(a.as_slice(), b.as_slice(), &mut add);
        }
    }
    out
}

#[test]
fn eigenvector_derivatives_contracted_by_the_adjoint_equal_the_dual_bodys() {
    // with and without correction modes, undamped, proportionally damped and with the
    // correction modes' damping floored: the body without the eigenvectors' part plus their
    // adjoint contraction is the full body's contraction, for adjoints of every datum
    let mesh = strip();
    let b0 = [0.3, -0.5, 0.9];
    let rayleigh = fem::RayleighDamping {
        modes: [0, 2],
        ratios: [0.01, 0.03],
    };
    for correction in [false, true] {
        for damping in 0..3 {
            let mut opts = options(4, correction, false);
            if damping > 0 {
                opts.damping = Some(rayleigh.into());
            }
            if damping == 2 {
                opts.correction_damping = fem::CorrectionDamping::AtLeast(0.1);
            }
            let an = modal_analysis(&mesh, &props(&b0), &opts).unwrap();
            let (dm, d) =
                analysis_derivatives::<3, _>(&mesh, &an, &b0, props, ModeUpdate::Updated).unwrap();
            let update = ModeUpdate::Updated;
            let full = modal_body_dual::<3>(&mesh, &props(&b0), &an, &dm, &d, 0, update).unwrap();
            let mut without = d.clone();
            without.eigenvectors = None;
            without.eigenvectors_by_adjoint = true;
            let rest =
                modal_body_dual::<3>(&mesh, &props(&b0), &an, &dm, &without, 0, update).unwrap();
            let bar = some_adjoints(&full);
            let y_bar = fem::eigenvector_adjoints(&an, &without, &bar).unwrap();
            let by_adjoint =
                fem::eigenvector_adjoint(&an.k, &an.m, &an.pairs, &dm, &y_bar, None).unwrap();
            let (want, rest) = (contracted(&full, &bar), contracted(&rest, &bar));
            for v in 0..3 {
                // against the eigenvectors' part (the eigenvalues' adjoints, times λ_b, are
                // larger and the same in both)
                let part = want[v] - rest[v];
                let err = (rest[v] + by_adjoint[v] - want[v]).abs();
                eprintln!(
                    "correction {correction}, damping {damping}, variable {v}: the eigenvectors' \
                     part {part:e}, by the adjoint {:e}; error {err:.1e}",
                    by_adjoint[v]
                );
                assert!(part.abs() > 1e-6 * want[v].abs(), "the eigenvectors matter");
                assert!(err < 1e-8 * part.abs());
            }
        }
    }
}
