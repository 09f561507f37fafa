//! Mode tracking (`ModalBody::align_to`) and the updated-mode dual body of a rod whose modes
//! come in clusters of four equal ones (a composite tube clamped at its middle node: two halves
//! × two bending planes): the tangents of `modal_body_dual` are the derivatives of the tracked
//! modes of perturbed designs.

use fem::{
    BeamSection, Mesh, ModalBody, ModalOptions, ModeUpdate, Properties, analysis_derivatives,
    modal_analysis, modal_body, modal_body_dual,
};
use laminate::OrthotropicMaterial;
use nalgebra::{DMatrix, Vector3};
use section::{DesignMap, PlySpec, SectionMesh, SectionSensitivities};
use sens::Dual;

const MODES: usize = 8;

fn tube(angle_deg: f64) -> SectionMesh {
    let g = 5.36e9;
    let m =
        OrthotropicMaterial::new([128e9, 10.1e9, 10.1e9], [g, g, g], [0.23; 3], 1586.0).unwrap();
    let plies: Vec<PlySpec> = (0..2)
        .map(|i| PlySpec::new(format!("p{i}"), m, angle_deg.to_radians(), 0.5e-3, 1))
        .collect();
    section::tube(4.5e-3, &plies, 24).unwrap()
}

fn beam() -> Mesh {
    Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(0.304, 0.0, 0.0),
        8,
        0,
        Vector3::y(),
    )
    .unwrap()
}

fn props(s: &SectionSensitivities) -> Properties<f64> {
    Properties {
        sections: vec![BeamSection::from_section(&s.properties)],
        laminates: vec![],
    }
}

fn body(angle_deg: f64) -> ModalBody<f64> {
    let s = SectionSensitivities {
        properties: section::analyse(&tube(angle_deg)).unwrap(),
        ..Default::default()
    };
    let p = props(&s);
    let a = modal_analysis(&beam(), &p, &ModalOptions::new(MODES)).unwrap();
    modal_body(&beam(), &p, &a).unwrap()
}

fn max_abs(m: &DMatrix<f64>) -> f64 {
    m.iter().fold(0.0f64, |a, x| a.max(x.abs()))
}

#[test]
fn tracked_modes_of_perturbed_designs_differentiate_to_the_updated_mode_tangents() {
    let angle = 15.0;
    let mesh = tube(angle);
    let map = DesignMap::new()
        .with_variable("angle", (0..mesh.regions.len()).map(|r| (r, 1.0)).collect());
    let sens = section::analyse_with_derivatives::<1>(&mesh, &map).unwrap();
    let p = props(&sens);
    let a = modal_analysis(&beam(), &p, &ModalOptions::new(MODES)).unwrap();
    let lam = a.eigenvalues().to_vec();
    // the clusters this test is about
    for c in [0, 4] {
        for i in 1..4 {
            assert!((lam[c + i] - lam[c]).abs() < 1e-9 * lam[c], "{lam:?}");
        }
    }
    assert!(lam[4] > 2.0 * lam[3]);
    let (_, d) = analysis_derivatives::<1, _>(
        &beam(),
        &a,
        &[angle.to_radians()],
        |b: &[Dual<1>]| Properties {
            sections: vec![BeamSection::from_sensitivities(&sens, b)],
            laminates: vec![],
        },
        ModeUpdate::Updated,
    )
    .unwrap();
    let dual = modal_body_dual::<1>(&beam(), &p, &a, &[], &d, 0, ModeUpdate::Updated).unwrap();
    let tangent = dual.modes.map(|x| x.d[0]);
    let nominal = body(angle);
    // central differences of the tracked modes, per radian
    let h_deg = 1e-3;
    let mut plus = body(angle + h_deg);
    let mut minus = body(angle - h_deg);
    // untracked, the perturbed bases within the clusters are each fixed by their own span
    // (`canonical_cluster_bases`), a choice that need not be continuous in the design (it
    // follows which rows of a cluster are largest, and a four-fold cluster has rows tied by
    // symmetry up to the lay-up's couplings): their differences are not the tangents
    let untracked = (&plus.modes - &minus.modes) / (2.0 * h_deg.to_radians());
    let untracked = max_abs(&(&untracked - &tangent)) / max_abs(&tangent);
    plus.align_to(&nominal, 1e-6).unwrap();
    minus.align_to(&nominal, 1e-6).unwrap();
    let tracked = max_abs(&(&plus.modes - &nominal.modes));
    let cd = (&plus.modes - &minus.modes) / (2.0 * h_deg.to_radians());
    let err = max_abs(&(&cd - &tangent)) / max_abs(&tangent);
    eprintln!(
        "tangent vs central differences untracked {untracked:.2e}, tracked {err:.2e} \
         (max |X_b| {:.2e}); max |ΔX| tracked {tracked:.2e}",
        max_abs(&tangent)
    );
    assert!(untracked > 1e-2, "{untracked:e}");
    assert!(tracked < 1e-3 * max_abs(&nominal.modes), "{tracked:e}");
    assert!(err < 1e-5, "{err:e}");
    // tracking keeps the modes mass-orthonormal and is the identity on the reference itself
    let mut same = nominal.clone();
    same.align_to(&nominal, 1e-6).unwrap();
    assert!(max_abs(&(&same.modes - &nominal.modes)) < 1e-12 * max_abs(&nominal.modes));
}

/// The rod with its outer half's plies turned by `delta` degrees from its inner half's 15°:
/// its clusters of four (two halves × two bending planes) split into the halves' pairs.
fn split_body(delta: f64) -> ModalBody<f64> {
    let section = |angle: f64| {
        let s = SectionSensitivities {
            properties: section::analyse(&tube(angle)).unwrap(),
            ..Default::default()
        };
        BeamSection::from_section(&s.properties)
    };
    let half = |property| fem::BeamSegment {
        length: 0.152,
        elements: 4,
        property,
    };
    let mesh = Mesh::segmented_beam(
        Vector3::zeros(),
        Vector3::new(0.304, 0.0, 0.0),
        &[half(0), half(1)],
        Vector3::y(),
    )
    .unwrap();
    let p = Properties {
        sections: vec![section(15.0), section(15.0 + delta)],
        laminates: vec![],
    };
    let a = modal_analysis(&mesh, &p, &ModalOptions::new(MODES)).unwrap();
    modal_body(&mesh, &p, &a).unwrap()
}

/// Tracking a design whose halves differ to the uniform rod turns each split cluster's modes
/// into a basis that is no longer an eigenbasis: the tracked body carries the full modal
/// stiffness and damping in it, so that it is the same reduced model (the same modal
/// flexibility `X K⁻¹ Xᵀ`, the same frequencies), which a diagonal would not be.
#[test]
fn tracking_a_split_cluster_keeps_the_reduced_model() {
    let mut nominal = split_body(0.0);
    assert!(nominal.stiffness_matrix.is_none());
    // any basis of the uniform rod's cluster of four is its eigenbasis: mix the halves'
    for (i, j) in [(0, 2), (1, 3)] {
        let (a, b) = (nominal.modes.column(i), nominal.modes.column(j));
        let (sum, difference) = ((a + b) / 2f64.sqrt(), (a - b) / 2f64.sqrt());
        nominal.modes.set_column(i, &sum);
        nominal.modes.set_column(j, &difference);
    }
    let mut same = nominal.clone();
    same.align_to(&nominal, 1e-6).unwrap();
    assert!(
        same.stiffness_matrix.is_none(),
        "nothing split, nothing full"
    );
    let split = split_body(0.5);
    let lam = &split.eigenvalues;
    // the cluster of four (two halves × two planes) splits into the halves' pairs
    assert!((lam[2] - lam[0]).abs() > 1e-2 * lam[0], "{lam:?}");
    let mut tracked = split.clone();
    tracked.modal_damping = lam.iter().map(|l| 2e-5 * l).collect();
    let damped = tracked.clone();
    tracked.align_to(&nominal, 1e-6).unwrap();
    let k = tracked
        .stiffness_matrix
        .as_deref()
        .expect("a full stiffness")
        .clone();
    let off = k.iter().enumerate().filter(|(i, _)| i % (MODES + 1) != 0);
    let largest_off = off.fold(0.0f64, |a, (_, x)| a.max(x.abs()));
    assert!(largest_off > 1e-3 * lam[0], "{largest_off:e}");
    let flexibility = |modes: &DMatrix<f64>, k: &DMatrix<f64>| {
        modes * k.clone().try_inverse().unwrap() * modes.transpose()
    };
    let diagonal = DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(lam));
    let reference = flexibility(&split.modes, &diagonal);
    let err = max_abs(&(flexibility(&tracked.modes, &k) - &reference)) / max_abs(&reference);
    assert!(err < 1e-10, "{err:e}");
    let mut values = k.symmetric_eigenvalues().as_slice().to_vec();
    values.sort_by(f64::total_cmp);
    for (a, b) in values.iter().zip(lam) {
        assert!((a - b).abs() < 1e-10 * b, "{a} against {b}");
    }
    // the damping turns with it: still 2e-5 K
    let c = tracked.damping_matrix.as_deref().expect("a full damping");
    assert!(max_abs(&(c - &k * 2e-5)) < 1e-12 * max_abs(c));
    assert!(damped.damping_matrix.is_none());
}

#[test]
fn tracking_rejects_a_different_layout() {
    let a = body(15.0);
    let mut b = a.clone();
    b.modes = b.modes.columns(0, 4).into_owned();
    b.eigenvalues.truncate(4);
    b.modal_damping.truncate(4);
    assert!(b.align_to(&a, 1e-6).is_err());
}
