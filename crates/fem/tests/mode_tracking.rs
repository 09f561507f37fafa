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

#[test]
fn tracking_rejects_a_different_layout() {
    let a = body(15.0);
    let mut b = a.clone();
    b.modes = b.modes.columns(0, 4).into_owned();
    b.eigenvalues.truncate(4);
    b.modal_damping.truncate(4);
    assert!(b.align_to(&a, 1e-6).is_err());
}
