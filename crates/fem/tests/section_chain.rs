//! The chain section analysis → beam section → beam modes, with ply-angle derivatives pushed
//! through it, against central differences of the whole chain.

use fem::{
    BeamSection, Mesh, ModalOptions, ModeUpdate, Properties, analysis_derivatives, modal_analysis,
};
use laminate::OrthotropicMaterial;
use nalgebra::Vector3;
use section::{DesignMap, PlySpec, SectionMesh};
use sens::Dual;

fn tube(angle_deg: f64) -> SectionMesh {
    let g = 5.36e9;
    let m =
        OrthotropicMaterial::new([128e9, 10.1e9, 10.1e9], [g, g, g], [0.23; 3], 1586.0).unwrap();
    let plies: Vec<PlySpec> = (0..2)
        .map(|i| PlySpec::new(format!("p{i}"), m, angle_deg.to_radians(), 0.5e-3, 1))
        .collect();
    section::tube(4.5e-3, &plies, 24).unwrap()
}

/// One design variable: the common angle of both plies.
fn design(mesh: &SectionMesh) -> DesignMap {
    DesignMap::new().with_variable("angle", (0..mesh.regions.len()).map(|r| (r, 1.0)).collect())
}

fn frequencies(angle_deg: f64) -> Vec<f64> {
    let beam = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(0.304, 0.0, 0.0),
        8,
        0,
        Vector3::y(),
    )
    .unwrap();
    let props = Properties {
        sections: vec![BeamSection::from_section(
            &section::analyse(&tube(angle_deg)).unwrap(),
        )],
        laminates: vec![],
    };
    let mut o = ModalOptions::new(4);
    o.reference = fem::ReferenceCondition::FreeFree;
    modal_analysis(&beam, &props, &o)
        .unwrap()
        .eigenvalues()
        .to_vec()
}

#[test]
fn eigenvalue_derivatives_through_the_section_chain_match_central_differences() {
    let angle = 25.0;
    let mesh = tube(angle);
    let sens = section::analyse_with_derivatives::<1>(&mesh, &design(&mesh)).unwrap();
    let beam = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(0.304, 0.0, 0.0),
        8,
        0,
        Vector3::y(),
    )
    .unwrap();
    let props = Properties {
        sections: vec![BeamSection::from_section(&sens.properties)],
        laminates: vec![],
    };
    let mut o = ModalOptions::new(4);
    o.reference = fem::ReferenceCondition::FreeFree;
    let a = modal_analysis(&beam, &props, &o).unwrap();
    let (_, d) = analysis_derivatives::<1, _>(
        &beam,
        &a,
        &[angle.to_radians()],
        |b: &[Dual<1>]| Properties {
            sections: vec![BeamSection::from_sensitivities(&sens, b)],
            laminates: vec![],
        },
        ModeUpdate::Updated,
    )
    .unwrap();
    let h = 0.01; // degrees
    let (lp, lm) = (frequencies(angle + h), frequencies(angle - h));
    for i in 0..4 {
        let fd = (lp[i] - lm[i]) / (2.0 * h.to_radians());
        let exact = d.eigenvalues[0][i];
        assert!(
            (exact - fd).abs() <= 1e-6 * exact.abs(),
            "mode {}: {exact} vs {fd}",
            i + 1
        );
    }
    // the f64 conversion keeps every property
    let bs = BeamSection::from_section(&sens.properties);
    assert_eq!(bs.stiffness, sens.properties.stiffness);
    assert_eq!(bs.mass_per_length, sens.properties.mass_per_length);
}
