//! Modes retained by number (`ModalOptions::select`): the body keeps exactly the chosen columns,
//! eigenvalues and damping of the full analysis (a damping fit refers to the computed modes'
//! numbers), and bad selections are refused.

mod common;

use common::{beam, slender};
use fem::{Damping, ModalOptions, RayleighDamping, ReferenceCondition, modal_analysis, modal_body};

#[test]
fn selected_modes_are_the_full_analysis_columns() {
    let mesh = beam(12);
    let props = slender().props();
    let damping: Damping = RayleighDamping {
        modes: [0, 4],
        ratios: [0.01, 0.03],
    }
    .into();
    let mut full = ModalOptions::new(5);
    full.reference = ReferenceCondition::FreeFree;
    full.damping = Some(damping);
    let mut chosen = ModalOptions::select(vec![0, 2, 4]);
    chosen.reference = ReferenceCondition::FreeFree;
    chosen.damping = Some(damping);
    let a = modal_analysis(&mesh, &props, &full).unwrap();
    let b = modal_analysis(&mesh, &props, &chosen).unwrap();
    let (ba, bb) = (
        modal_body(&mesh, &props, &a).unwrap(),
        modal_body(&mesh, &props, &b).unwrap(),
    );
    assert_eq!(bb.n_modes(), 3);
    for (j, &i) in [0, 2, 4].iter().enumerate() {
        assert_eq!(bb.eigenvalues[j], ba.eigenvalues[i]);
        assert_eq!(bb.modal_damping[j], ba.modal_damping[i]);
        assert_eq!(bb.modes.column(j), ba.modes.column(i));
    }
    assert_eq!(b.frequencies_hz().len(), 3);
    for bad in [vec![], vec![1, 1], vec![2, 1]] {
        let mut o = ModalOptions::select(bad.clone());
        o.n_modes = 5;
        assert!(modal_analysis(&mesh, &props, &o).is_err(), "{bad:?}");
    }
    let mut o = ModalOptions::select(vec![0, 5]);
    o.n_modes = 5;
    assert!(
        modal_analysis(&mesh, &props, &o).is_err(),
        "beyond the computed modes"
    );
}

/// Damping by coefficients: `2ζω = α + βλ` for every mode (stiffness-proportional damping gives
/// `ζ = βω/2`, growing with frequency), and bad coefficients are refused.
#[test]
fn damping_by_coefficients_is_alpha_plus_beta_lambda() {
    let mesh = beam(12);
    let props = slender().props();
    let (alpha, beta) = (3.0, 2e-5);
    let mut o = ModalOptions::new(4);
    o.damping = Some(Damping::Coefficients { alpha, beta });
    let a = modal_analysis(&mesh, &props, &o).unwrap();
    let body = modal_body(&mesh, &props, &a).unwrap();
    for (c, l) in body.modal_damping.iter().zip(&body.eigenvalues) {
        assert!(
            (c - (alpha + beta * l)).abs() <= 1e-14 * c.abs(),
            "{c} vs {l}"
        );
    }
    o.damping = Some(Damping::Coefficients {
        alpha: -1.0,
        beta: 0.0,
    });
    let a = modal_analysis(&mesh, &props, &o).unwrap();
    assert!(modal_body(&mesh, &props, &a).is_err());
}
