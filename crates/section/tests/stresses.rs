//! Stress recovery of the warping analysis against closed forms: an isotropic rectangle's
//! bending and axial stresses and (ν = 0) its parabolic shear, a thick isotropic tube's
//! torsional shear `T r/J`, and a laminated thin-walled tube under axial force, torsion and
//! bending against classical laminate theory on its wall; the stresses' derivatives along a ply
//! angle, a material constant and a ply thickness against central differences of the analysis.

use laminate::{OrthotropicMaterial, PlateState, Ply, PlyStack};
use section::{PlySpec, SectionAnalysis, rectangle, tube};

#[test]
fn a_rectangle_carries_axial_force_and_bending_linearly_and_shear_as_a_parabola() {
    let e = 70e9;
    let m = OrthotropicMaterial::isotropic(e, 0.0, 2700.0).unwrap();
    let (b, h): (f64, f64) = (0.02, 0.04);
    let a = SectionAnalysis::new(&rectangle(b, h, 6, 12, m, 0.0).unwrap()).unwrap();
    let (i22, i33) = (b * h.powi(3) / 12.0, h * b.powi(3) / 12.0);
    let (n, m2, m3): (f64, f64, f64) = (1000.0, 50.0, -20.0);
    let scale = n / (b * h) + m2 * h / (2.0 * i22) + m3.abs() * b / (2.0 * i33);
    for p in a.stresses([n, 0.0, 0.0, 0.0, m2, m3]) {
        let [x2, x3] = p.position;
        let exact = n / (b * h) + m2 * x3 / i22 - m3 * x2 / i33;
        assert!((p.stress[0] - exact).abs() < 1e-8 * scale, "{p:?}: {exact}");
        assert!(p.stress[4].abs() < 1e-8 * scale && p.stress[5].abs() < 1e-8 * scale);
        // an isotropic region's material axes are the section's
        assert!((p.material_stress[0] - p.stress[0]).abs() < 1e-8 * scale);
    }
    // shear along x₃ (ν = 0: the elementary distribution is Saint-Venant's), converging as
    // the mesh is refined
    let f3 = 800.0;
    let peak = 1.5 * f3 / (b * h);
    let shear_error = |n3: usize| {
        let a = SectionAnalysis::new(&rectangle(b, h, n3 / 2, n3, m, 0.0).unwrap()).unwrap();
        (a.stresses([0.0, 0.0, f3, 0.0, 0.0, 0.0]).iter())
            .map(|p| {
                let x3 = p.position[1];
                (p.stress[4] - f3 / (2.0 * i22) * (h * h / 4.0 - x3 * x3)).abs()
            })
            .fold(0.0f64, f64::max)
            / peak
    };
    let (coarse, fine) = (shear_error(12), shear_error(24));
    assert!(
        coarse < 5e-3 && fine < coarse / 3.0,
        "{coarse:e} then {fine:e}"
    );
}

#[test]
fn a_thick_tube_in_torsion_carries_t_r_over_j() {
    let m = OrthotropicMaterial::isotropic(200e9, 0.3, 7800.0).unwrap();
    let (ri, t): (f64, f64) = (0.02, 0.005);
    let plies = [PlySpec::new("wall", m, 0.0, t, 4)];
    let a = SectionAnalysis::new(&tube(ri, &plies, 48).unwrap()).unwrap();
    let ro = ri + t;
    let j = std::f64::consts::PI / 2.0 * (ro.powi(4) - ri.powi(4));
    let torque = 300.0;
    for p in a.stresses([0.0, 0.0, 0.0, torque, 0.0, 0.0]) {
        let [x2, x3] = p.position;
        let r = x2.hypot(x3);
        // τ = T r / J along the hoop direction (−x₃, x₂)/r
        let (t12, t13) = (p.stress[5], p.stress[4]);
        let along = (-x3 * t12 + x2 * t13) / r;
        let exact = torque * r / j;
        assert!(
            (along - exact).abs() < 1e-3 * exact,
            "r = {r}: {along} vs {exact}"
        );
        assert!(
            (x2 * t12 + x3 * t13).abs() / r < 1e-3 * exact,
            "no radial shear"
        );
    }
}

#[test]
fn a_laminated_thin_tube_loads_its_plies_as_laminate_theory_on_its_wall() {
    let g = 5.36e9;
    let m = OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [g, g, g],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .unwrap();
    let angles = [30f64, -30.0, -30.0, 30.0].map(f64::to_radians);
    let tp = 0.25e-3;
    // thin: t/R = 1 % (the hoop strain's variation across the wall, which laminate theory on
    // the wall leaves out, is of that order)
    let ri = 0.1;
    let plies: Vec<PlySpec> = (angles.iter().enumerate())
        .map(|(k, &a)| PlySpec::new(format!("p{k}"), m, a, tp, 1))
        .collect();
    let a = SectionAnalysis::new(&tube(ri, &plies, 160).unwrap()).unwrap();
    // the wall's laminate: x along the beam, y along the hoop (the wall frame's tangent)
    let wall = PlyStack::new(
        angles
            .iter()
            .map(|&angle| Ply {
                material: m,
                thickness: tp,
                angle,
            })
            .collect(),
    )
    .unwrap();
    let rm = ri + 2.0 * tp;
    let circumference = 2.0 * std::f64::consts::PI * rm;
    let inverse_a = wall.stiffness().a.try_inverse().unwrap();
    // the plies' membrane stresses (material axes) under wall resultants N = [Nx, Ns, Nxs]
    let clt = |nx: f64, nxs: f64, ply: usize| -> [f64; 6] {
        let e0 = inverse_a * nalgebra::Vector3::new(nx, 0.0, nxs);
        let state = PlateState {
            membrane: [e0[0], e0[1], e0[2]],
            curvature: [0.0; 3],
            shear_forces: [0.0; 2],
        };
        wall.ply_points(&state)[3 * ply + 1].stress
    };
    let region_ply = |region: usize| region % angles.len();
    // axial force and torsion: uniform around the wall
    for (forces, nx, nxs) in [
        (
            [2000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            2000.0 / circumference,
            0.0,
        ),
        // the tube's wall tangent t = (x₃, −x₂)/r turns against the torque's sense
        (
            [0.0, 0.0, 0.0, 40.0, 0.0, 0.0],
            0.0,
            -40.0 / (circumference * rm),
        ),
    ] {
        let mut worst = 0.0f64;
        let mut scale = 0.0f64;
        for p in a.stresses(forces) {
            let exact = clt(nx, nxs, region_ply(p.region));
            for c in [0, 1, 5] {
                worst = worst.max((p.material_stress[c] - exact[c]).abs());
                scale = scale.max(exact[c].abs());
            }
        }
        assert!(worst < 0.01 * scale, "{forces:?}: {worst} of {scale}");
    }
    // bending about x₂: Nx = M₂ x₃ / (π R³) around the wall
    let m2 = 30.0;
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for p in a.stresses([0.0, 0.0, 0.0, 0.0, m2, 0.0]) {
        let [x2, x3] = p.position;
        let r = x2.hypot(x3);
        let nx = m2 * (x3 / r * rm) / (std::f64::consts::PI * rm.powi(3));
        let exact = clt(nx, 0.0, region_ply(p.region));
        for c in [0, 1, 5] {
            worst = worst.max((p.material_stress[c] - exact[c]).abs());
            scale = scale.max(exact[c].abs());
        }
    }
    assert!(worst < 0.01 * scale, "bending: {worst} of {scale}");
}

#[test]
fn stress_derivatives_equal_central_differences_of_the_section_analysis() {
    // a three-ply tube; variables: the middle ply's angle, E2 of every region, the inner ply's
    // thickness (which moves the nodes, and the points with them)
    let m = OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [5.36e9, 5.36e9, 3.6e9],
        [0.23, 0.23, 0.4],
        1586.0,
    )
    .unwrap();
    let deg = std::f64::consts::PI / 180.0;
    let generated = |angle: f64, e2: f64, thickness: f64| {
        let mat = {
            let mut c = m.constants();
            c[1] = e2;
            m.with_constants(c).unwrap()
        };
        section::GeneratedSection::Tube {
            inner_radius: 0.01,
            plies: vec![
                PlySpec::new("p0", mat, 30.0 * deg, thickness, 1),
                PlySpec::new("p1", mat, angle, 0.0007, 1),
                PlySpec::new("p2", mat, 60.0 * deg, 0.0004, 1),
            ],
            circumferential: 24,
        }
    };
    let (angle, e2, t0) = (-45.0 * deg, 10.1e9, 0.0005);
    let nominal = generated(angle, e2, t0);
    let mesh = nominal.mesh().unwrap();
    let mut de2 = [0.0; 9];
    de2[1] = 1.0;
    let d_c = m.stiffness_derivative(&de2);
    let design = section::DesignMap::new()
        .with_named_variable(&mesh, "angle", &[("p1", 1.0)])
        .unwrap()
        .with_material_variable("e2", (0..mesh.regions.len()).map(|r| (r, d_c)).collect())
        .with_geometry_variable(
            "t0",
            &nominal
                .node_velocities(|p| f64::from(u8::from(p.name == "p0")))
                .unwrap(),
        );
    let forces = [1500.0, 60.0, -90.0, 25.0, 35.0, -45.0];
    let analysis = SectionAnalysis::new(&mesh).unwrap();
    let exact = analysis.stress_derivatives::<2>(forces, &design).unwrap();
    let at = |a: f64, e: f64, t: f64| {
        SectionAnalysis::new(&generated(a, e, t).mesh().unwrap())
            .unwrap()
            .stresses(forces)
    };
    let steps = [1e-6, 1e6, 1e-9];
    for (v, name) in ["angle", "e2", "t0"].iter().enumerate() {
        let h = steps[v];
        let mut p = [angle, e2, t0];
        let mut q = p;
        p[v] += h;
        q[v] -= h;
        let (plus, minus) = (at(p[0], p[1], p[2]), at(q[0], q[1], q[2]));
        let cd = |i: usize, c: usize, material: bool| {
            let (a, b) = match material {
                true => (plus[i].material_stress[c], minus[i].material_stress[c]),
                false => (plus[i].stress[c], minus[i].stress[c]),
            };
            (a - b) / (2.0 * h)
        };
        let mut scale = 0.0f64;
        for i in 0..plus.len() {
            for c in 0..6 {
                scale = scale.max(cd(i, c, true).abs());
            }
        }
        let mut worst = 0.0f64;
        for (i, d) in exact[v].iter().enumerate() {
            for c in 0..6 {
                worst = worst.max((d.material_stress[c] - cd(i, c, true)).abs() / scale);
                worst = worst.max((d.stress[c] - cd(i, c, false)).abs() / scale);
            }
        }
        eprintln!("{name}: largest difference {worst:.2e} of the largest derivative {scale:.3e}");
        assert!(scale > 0.0 && worst < 1e-6, "{name}: {worst:e}");
    }
    // the unit-force derivatives (chunked differently) combine linearly into the same ones
    let unit = analysis.unit_stress_derivatives::<1>(&design).unwrap();
    for (v, per_point) in unit.iter().enumerate() {
        let scale = (exact[v].iter())
            .flat_map(|d| d.material_stress)
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for (d, u) in exact[v].iter().zip(per_point) {
            for c in 0..6 {
                let combined: f64 = (0..6).map(|k| u[k][c] * forces[k]).sum();
                let gap = (combined - d.material_stress[c]).abs() / scale;
                assert!(gap < 1e-12, "variable {v}: {gap:e}");
            }
        }
    }
}
