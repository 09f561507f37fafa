//! Ply stresses of a beam body's modes (`fem::beam_modal_stresses`): a skew cantilever under
//! tip loads has, at every element's ends and middle, the section forces of statics and the stresses
//! of the section analysis under them — on an isotropic rectangle, `N/A + M₂x₃/I₂ − M₃x₂/I₃`;
//! design derivatives (a ply angle of a laminated tube, through the section's stiffness and
//! its stress points, and a scale of the mode) against central differences.

mod common;

use common::{body_of, static_displacements, stress_derivative_pairs};
use fem::{
    BeamSection, BeamSegment, Constraints, Mesh, Properties, beam_modal_stresses, section_points,
};
use laminate::OrthotropicMaterial;
use nalgebra::{DMatrix, Vector3};
use section::{PlySpec, SectionAnalysis};
use sens::Dual;

const START: [f64; 3] = [0.1, -0.05, 0.02];
const END: [f64; 3] = [0.4, 0.15, 0.12];
const ORIENTATION: [f64; 3] = [0.2, -0.3, 1.0];

fn beam_mesh(elements: usize) -> Mesh {
    Mesh::segmented_beam(
        Vector3::from(START),
        Vector3::from(END),
        &[BeamSegment {
            length: 1.0,
            elements,
            property: 0,
        }],
        Vector3::from(ORIENTATION),
    )
    .unwrap()
}

/// The static displacements (6 per node, mesh axes) of the beam clamped at its first node under
/// the tip force `force` and moment `moment` (global).
fn cantilever(mesh: &Mesh, props: &Properties<f64>, force: [f64; 3], moment: [f64; 3]) -> Vec<f64> {
    let mut constraints = Constraints::new();
    constraints.clamp(0);
    let tip = mesh.nodes.len() - 1;
    let mut f = vec![0.0; 6 * mesh.nodes.len()];
    f[6 * tip..6 * tip + 3].copy_from_slice(&force);
    f[6 * tip + 3..6 * tip + 6].copy_from_slice(&moment);
    static_displacements(mesh, props, &constraints, &f)
}

#[test]
fn a_skew_cantilever_has_the_section_forces_of_statics_and_beam_theory_stresses() {
    let (e, nu) = (70e9, 0.3);
    let (w, h) = (0.02, 0.012);
    let material = OrthotropicMaterial::isotropic(e, nu, 2700.0).unwrap();
    let section_mesh = section::rectangle(w, h, 8, 6, material, 0.0).unwrap();
    let analysis = SectionAnalysis::new(&section_mesh).unwrap();
    let props = Properties {
        sections: vec![BeamSection::from_section(analysis.properties())],
        laminates: vec![],
    };
    let mesh = beam_mesh(5);
    let (force, moment) = ([30.0, -80.0, 120.0], [4.0, -6.0, 3.0]);
    let u = cantilever(&mesh, &props, force, moment);
    let points = section_points::<f64>(&analysis, &[], &[]);
    let body = body_of(&mesh, DMatrix::from_column_slice(u.len(), 1, &u));
    let s = beam_modal_stresses(&mesh, (&props, None), &[points], &body).unwrap();
    assert_eq!(s.elements.len(), 15);
    let (_, lam) = fem::beam::beam_frame(
        &Vector3::from(START),
        &Vector3::from(END),
        &Vector3::from(ORIENTATION),
    );
    let (f, m0, tip) = (
        Vector3::from(force),
        Vector3::from(moment),
        Vector3::from(END),
    );
    let (area, i2, i3) = (w * h, w * h.powi(3) / 12.0, h * w.powi(3) / 12.0);
    for i in 0..s.elements.len() {
        // statics: the section at x carries the tip's loads, M = M_tip + (tip − x) × F
        let x = s.elements[i].centroid;
        let (fl, ml) = (lam * f, lam * (m0 + (tip - x).cross(&f)));
        let exact = [fl.x, fl.y, fl.z, ml.x, ml.y, ml.z];
        let d = s.deformation(i, &[1.0]);
        let scale = exact.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for c in 0..6 {
            assert!(
                (d[c] - exact[c]).abs() < 1e-8 * scale,
                "element {i} force {c}: {} vs {}",
                d[c],
                exact[c]
            );
        }
        assert_eq!(d[6..], [0.0, 0.0]);
        // the section analysis under those forces, and the engineering bending formula
        let recovered = analysis.stresses(std::array::from_fn(|c| d[c]));
        let sigma_scale = recovered
            .iter()
            .fold(0.0f64, |a, p| a.max(p.material_stress[0].abs()));
        for (k, p) in recovered.iter().enumerate() {
            let sigma = s.stress(i, k, &d);
            for c in 0..6 {
                assert!((sigma[c] - p.material_stress[c]).abs() < 1e-9 * sigma_scale);
            }
            let [x2, x3] = p.position;
            let bending = d[0] / area + d[4] * x3 / i2 - d[5] * x2 / i3;
            assert!(
                (sigma[0] - bending).abs() < 1e-6 * sigma_scale,
                "element {i} point {k}: σ11 {} vs {bending}",
                sigma[0]
            );
        }
    }
}

/// A three-ply tube whose middle ply is at `angle` (rad).
fn tube(angle: f64) -> section::SectionMesh {
    let m = OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [5.36e9, 5.36e9, 3.6e9],
        [0.23, 0.23, 0.4],
        1586.0,
    )
    .unwrap();
    let deg = std::f64::consts::PI / 180.0;
    section::tube(
        0.01,
        &[
            PlySpec::new("p0", m, 30.0 * deg, 0.0005, 1),
            PlySpec::new("p1", m, angle, 0.0007, 1),
            PlySpec::new("p2", m, -30.0 * deg, 0.0004, 1),
        ],
        16,
    )
    .unwrap()
}

#[test]
fn beam_ply_stress_derivatives_equal_central_differences() {
    // variables: the middle ply's angle (the section's stiffness, so the forces of the fixed
    // mode, and its stress points) and a scale of the mode
    let angle = 0.6;
    let mesh = beam_mesh(4);
    let nominal = SectionAnalysis::new(&tube(angle)).unwrap();
    let props0 = Properties {
        sections: vec![BeamSection::from_section(nominal.properties())],
        laminates: vec![],
    };
    let u = cantilever(&mesh, &props0, [20.0, -30.0, 50.0], [1.0, -2.0, 1.5]);
    let design = section::DesignMap::new()
        .with_named_variable(&tube(angle), "angle", &[("p1", 1.0)])
        .unwrap();
    let build = |b: [Dual<2>; 2]| {
        let analysis = SectionAnalysis::new(&tube(b[0].v)).unwrap();
        let sens = analysis.sensitivities::<1>(&design).unwrap();
        let derivatives = analysis.unit_stress_derivatives::<1>(&design).unwrap();
        let props = Properties {
            sections: vec![BeamSection::from_sensitivities(&sens, &b[..1])],
            laminates: vec![],
        };
        let points = section_points(&analysis, &derivatives, &b[..1]);
        let modes = DMatrix::from_fn(u.len(), 1, |r, _| {
            Dual::constant(u[r]) * (Dual::constant(1.0) + b[1])
        });
        beam_modal_stresses(&mesh, (&props, None), &[points], &body_of(&mesh, modes)).unwrap()
    };
    let base = [angle, 0.0];
    let dual = build(std::array::from_fn(|i| Dual::variable(base[i], i)));
    let value = |b: [f64; 2]| build(b.map(Dual::constant));
    let w = [Dual::constant(0.7)];
    let steps = [1e-6, 1e-6];
    for j in 0..2 {
        let (mut p, mut m) = (base, base);
        p[j] += steps[j];
        m[j] -= steps[j];
        let pairs = stress_derivative_pairs(&dual, (&value(p), &value(m)), &w, (j, steps[j]));
        let largest = pairs.iter().fold(0.0f64, |m, p| m.max(p.2.abs()));
        let moved = pairs.iter().filter(|p| p.2.abs() > 1e-3 * largest).count();
        let worst = (pairs.iter())
            .map(|(_, exact, fd)| (exact - fd).abs() / largest)
            .fold(0.0f64, f64::max);
        eprintln!("variable {j}: worst {worst:.2e} of {largest:.3e}, {moved} moved");
        assert!(worst < 1e-6, "variable {j}: {worst:e}");
        assert!(moved > 100, "variable {j} moves the stresses ({moved})");
    }
}
