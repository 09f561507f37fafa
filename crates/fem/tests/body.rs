//! Reference conditions of floating-frame bodies and the f64 ModalBody.

mod common;

use common::{Rect, beam, rel, slender};
use fem::{ModalOptions, ReferenceCondition, modal_analysis, modal_body};
use nalgebra::Vector3;

fn eb(r: &Rect, beta_l: f64, l: f64) -> f64 {
    // weak-axis Euler–Bernoulli eigenvalue (βL)⁴ EI/(ρA L⁴)
    beta_l.powi(4) * r.e * r.i2() / (r.rho * r.area() * l.powi(4))
}

#[test]
fn free_free_beam_drops_six_rigid_modes() {
    let r = slender();
    let mesh = beam(40);
    let mut o = ModalOptions::new(3);
    o.reference = ReferenceCondition::FreeFree;
    let an = modal_analysis(&mesh, &r.props(), &o).unwrap();
    assert_eq!(an.n_rigid, 6);
    let exact = eb(&r, 4.730_040_744_862_704, 1.0);
    assert!(
        rel(an.eigenvalues()[0].sqrt(), exact.sqrt()) < 5e-3,
        "{} vs {exact}",
        an.eigenvalues()[0]
    );
    let body = modal_body(&mesh, &r.props(), &an).unwrap();
    body.validate().unwrap();
    // frame at the centre of mass
    let first_moment = body
        .node_positions
        .iter()
        .zip(&body.node_masses)
        .fold(Vector3::zeros(), |a, (p, m)| a + p * *m);
    assert!(first_moment.norm() < 1e-12 * body.total_mass());
    assert!(rel(body.total_mass(), r.rho * r.area()) < 1e-12);
}

#[test]
fn clamped_at_centre_of_mass_gives_two_half_cantilevers() {
    let r = slender();
    let mesh = beam(40);
    let an = modal_analysis(&mesh, &r.props(), &ModalOptions::new(2)).unwrap();
    // node 20 (x = 0.7) is clamped: both halves are cantilevers of length 0.5, a repeated pair
    assert!(an.constraints.is_fixed(6 * 20) && an.constraints.is_fixed(6 * 20 + 5));
    let exact = eb(&r, 1.875_104_068_711_961, 0.5);
    for i in 0..2 {
        assert!(
            rel(an.eigenvalues()[i].sqrt(), exact.sqrt()) < 5e-3,
            "{} vs {exact}",
            an.eigenvalues()[i]
        );
    }
    let body = modal_body(&mesh, &r.props(), &an).unwrap();
    assert!(body.node_positions[20].norm() < 1e-15);
    assert!((body.node_positions[0] - Vector3::new(-0.5, 0.0, 0.0)).norm() < 1e-12);
    // the clamped node does not move in any mode
    assert!(body.modes.rows(6 * 20, 6).iter().all(|&v| v == 0.0));
}

#[test]
fn pinned_ends_give_the_simply_supported_beam() {
    let r = slender();
    let mesh = beam(40);
    let mut o = ModalOptions::new(2);
    o.reference = ReferenceCondition::PinnedEnds { a: 0, b: 40 };
    let an = modal_analysis(&mesh, &r.props(), &o).unwrap();
    let exact = eb(&r, std::f64::consts::PI, 1.0);
    assert!(
        rel(an.eigenvalues()[0].sqrt(), exact.sqrt()) < 5e-3,
        "{} vs {exact}",
        an.eigenvalues()[0]
    );
    // strong-axis bending is the second mode, four times stiffer (hy = 2 hz)
    assert!(rel(an.eigenvalues()[1], 4.0 * an.eigenvalues()[0]) < 1e-2);
    let body = modal_body(&mesh, &r.props(), &an).unwrap();
    assert!(body.node_positions[0].norm() < 1e-15);
    // frequencies in Hz and unit modal masses for reporting
    let f = an.frequencies_hz();
    assert!(rel(f[0], exact.sqrt() / (2.0 * std::f64::consts::PI)) < 5e-3);
    assert!(an.modal_masses().iter().all(|m| (m - 1.0).abs() < 1e-10));
    // invalid reference conditions are reported
    o.reference = ReferenceCondition::PinnedEnds { a: 0, b: 0 };
    assert!(modal_analysis(&mesh, &r.props(), &o).is_err());
}

#[test]
fn symmetric_change_of_a_centre_clamped_beam_keeps_pairs_and_basis() {
    // clamped at its centre, a uniform beam has exactly repeated pairs (two equal half
    // cantilevers); a uniform stiffness change keeps them repeated: the derivatives must not
    // rotate the basis and must satisfy the first-order eigen-equation
    use sens::{Dual, Scalar};
    fn props<S: Scalar>(t: S) -> fem::Properties<S> {
        let base = slender().section();
        let f = S::one() + t.sin() * 0.5;
        fem::BeamSection {
            stiffness: base.stiffness.map(|x| f * x),
            mass_per_length: S::from_f64(base.mass_per_length),
            mass_centre: [S::zero(); 2],
            inertia: base.inertia.map(S::from_f64),
        }
        .into_props()
    }
    trait IntoProps<S: Scalar> {
        fn into_props(self) -> fem::Properties<S>;
    }
    impl<S: Scalar> IntoProps<S> for fem::BeamSection<S> {
        fn into_props(self) -> fem::Properties<S> {
            fem::Properties {
                sections: vec![self],
                laminates: vec![],
            }
        }
    }
    let mesh = beam(20);
    let t0 = 0.2;
    let an = modal_analysis(&mesh, &props(t0), &ModalOptions::new(4)).unwrap();
    assert!(rel(an.eigenvalues()[1], an.eigenvalues()[0]) < 1e-9);
    let (dm, d) = fem::analysis_derivatives::<1, _>(
        &mesh,
        &an,
        &[t0],
        |b: &[Dual<1>]| props(b[0]),
        fem::ModeUpdate::Updated,
    )
    .unwrap();
    assert!(d.clusters.iter().any(|c| c.len() == 2));
    assert!(
        (&d.rotations[0]
            - nalgebra::DMatrix::<f64>::identity(d.rotations[0].nrows(), d.rotations[0].ncols()))
        .abs()
        .max()
            == 0.0
    );
    // λ_b = (∂f/∂t / f) λ for a uniform stiffness scaling
    let ratio = 0.5 * t0.cos() / (1.0 + 0.5 * t0.sin());
    for i in 0..4 {
        assert!(rel(d.eigenvalues[0][i], ratio * an.pairs.values[i]) < 1e-8);
    }
    // (K − λM) x_b = −(K_b − λ_b M) x and xᵀ M x_b = 0 (M_b = 0)
    let xb = &d.eigenvectors.as_ref().unwrap()[0];
    let n = an.k.nrows();
    for i in 0..4 {
        let x = an.pairs.vectors.column(i).into_owned();
        let xbi = xb.column(i).into_owned();
        let (mut a, mut b, mut c, mut e) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        fem::eigen::spmv(&an.k, xbi.as_slice(), &mut a);
        fem::eigen::spmv(&an.m, xbi.as_slice(), &mut b);
        fem::eigen::spmv(&dm[0].k, x.as_slice(), &mut c);
        fem::eigen::spmv(&an.m, x.as_slice(), &mut e);
        let (l, lb) = (an.pairs.values[i], d.eigenvalues[0][i]);
        let res: f64 = (0..n)
            .map(|q| (a[q] - l * b[q] + c[q] - lb * e[q]).powi(2))
            .sum::<f64>()
            .sqrt();
        let scale: f64 = c.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            res < 1e-8 * scale,
            "mode {i}: residual {res:e} vs {scale:e}"
        );
        // a uniform scaling of K leaves the modes unchanged
        assert!(
            xbi.norm() < 1e-6 * x.norm(),
            "mode {i}: |x_b| = {:e}",
            xbi.norm()
        );
        let norm: f64 = x.iter().zip(&b).map(|(p, q)| p * q).sum();
        assert!(
            norm.abs() < 1e-10 * xbi.norm().max(1.0),
            "mode {i}: xᵀMx_b = {norm:e}"
        );
    }
}
