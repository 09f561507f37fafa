//! Static correction modes (`ModalOptions::correction`): the correction shapes keep the body's
//! modes mass-normalised with a diagonal modal stiffness, and a static load at a correction
//! node is then represented exactly by the reduced body (independent check: the full stiffness
//! solve), where the eigenmodes alone miss part of it.

mod common;

use common::{beam, slender};
use fem::{ModalOptions, ReferenceCondition, modal_analysis, modal_body};
use nalgebra::{DMatrix, DVector};

#[test]
fn correction_modes_represent_a_load_at_their_node_exactly() {
    let n = 12;
    let mesh = beam(n);
    let props = slender().props();
    let tip = n; // the beam's end node
    let run = |correction: Vec<usize>| {
        let mut o = ModalOptions::new(2);
        o.reference = ReferenceCondition::ClampedAtCentreOfMass;
        o.correction = correction;
        let a = modal_analysis(&mesh, &props, &o).unwrap();
        let body = modal_body(&mesh, &props, &a).unwrap();
        (a, body)
    };
    // a transverse load at the end (in both bending planes) and a moment about the axis
    let mut f = DVector::zeros(6 * (n + 1));
    f[6 * tip + 1] = 3.0;
    f[6 * tip + 2] = -1.0;
    f[6 * tip + 3] = 0.2;
    let (plain, _) = run(vec![]);
    let exact = {
        let nf = plain.assembly.n_free();
        let e = DMatrix::<f64>::identity(nf, nf);
        let k = fem::eigen::project(&plain.k, &e, &e);
        let ff = plain.assembly.restrict(f.as_slice());
        let u = k.lu().solve(&ff).unwrap();
        plain.expand(&DMatrix::from_column_slice(nf, 1, u.as_slice()))
    };
    let reduced = |a: &fem::ModalAnalysis| {
        let x = a.mode_shapes();
        let lam = a.eigenvalues();
        let q = x.transpose() * &f;
        let w = DVector::from_iterator(lam.len(), q.iter().zip(&lam).map(|(q, l)| q / l));
        &x * w
    };
    let err = |u: DVector<f64>| (u - exact.column(0)).amax() / exact.amax();
    let without = err(reduced(&plain));
    let (corrected, body) = run(vec![0, tip]);
    let with = err(reduced(&corrected));
    eprintln!("static tip load: 2 modes {without:.2e}, with correction at both ends {with:.2e}");
    assert!(without > 1e-2, "{without:e}");
    assert!(with < 1e-10, "{with:e}");
    // the correction adds the free dof of the two end nodes (6 each), after the 2 eigenmodes;
    // modes mass-normalised, modal stiffness diagonal, eigenmodes unchanged
    assert_eq!(body.n_modes(), 2 + 12);
    let x = corrected.mode_shapes();
    let mut mdiag = DVector::zeros(6 * (n + 1));
    for (k, (&mk, mu)) in body.node_masses.iter().zip(&body.node_inertias).enumerate() {
        for d in 0..3 {
            mdiag[6 * k + d] = mk;
            mdiag[6 * k + 3 + d] = mu[d];
        }
    }
    let mm = x.transpose() * DMatrix::from_diagonal(&mdiag) * &x;
    assert!((mm - DMatrix::identity(14, 14)).amax() < 1e-10);
    let free: Vec<usize> = corrected
        .assembly
        .dofs()
        .iter()
        .map(|d| match d {
            fem::ReducedDof::Node(g) => *g,
            _ => unreachable!("no ties"),
        })
        .collect();
    let xf = DMatrix::from_fn(free.len(), 14, |i, j| x[(free[i], j)]);
    let kr = fem::eigen::project(&corrected.k, &xf, &xf);
    let lam = corrected.eigenvalues();
    for i in 0..14 {
        for j in 0..14 {
            let expect = if i == j { lam[i] } else { 0.0 };
            assert!((kr[(i, j)] - expect).abs() < 1e-8 * lam[13], "K[{i},{j}]");
        }
    }
    assert_eq!(lam[..2], plain.eigenvalues()[..]);
    assert!(lam[2..].iter().all(|&l| l > lam[1]), "{lam:?}");
    // free-free bodies cannot take static shapes; an unknown node is named
    for (reference, nodes) in [
        (ReferenceCondition::FreeFree, vec![0]),
        (ReferenceCondition::ClampedAtCentreOfMass, vec![99]),
    ] {
        let mut o = ModalOptions::new(2);
        o.reference = reference;
        o.correction = nodes;
        assert!(modal_analysis(&mesh, &props, &o).is_err());
    }
}
