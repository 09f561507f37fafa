//! Ply stresses of a shell body's modes (`fem::stress`): exact on every field the element
//! represents exactly (stretching, constant curvature, constant transverse shear) on a
//! distorted mesh turned in space with a turned material axis, against classical laminate
//! theory of the field's deformation; a clamped isotropic strip under a tip load against beam
//! theory (`6M/bh²` on the faces, `3V/2bh` at the middle) converging with the mesh; design
//! derivatives (ply angles, thicknesses and the modes) against central differences.

mod common;

use common::{body_of, paper_material, stack, static_displacements, stress_derivative_pairs};
use fem::{Constraints, Membrane, Mesh, Properties, ShellPlies, shell_modal_stresses};
use laminate::{OrthotropicMaterial, PlateState, Ply, PlyPosition, PlyStack};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};
use sens::Dual;

/// The plate field of constants `c = [a, b, c, d, g, h, k1, k2, k3, sx, sy]` in plate
/// coordinates `(x, y)` (along `e₁`, `e₂`): `u = a x + b y`, `v = c x + d y`,
/// `w = g x + h y − ½(k1 x² + k2 y² + k3 x y)`, rotations with the shear strains `(sx, sy)`;
/// its deformation is `ε⁰ = (a, d, b + c)`, `κ = (k1, k2, k3)`, `γ = (sx, sy)`.
fn plate_field(c: [f64; 11], x: f64, y: f64) -> [f64; 6] {
    let [a, b, cc, d, g, h, k1, k2, k3, sx, sy] = c;
    let w = g * x + h * y - 0.5 * (k1 * x * x + k2 * y * y + k3 * x * y);
    let beta_x = sx - g + k1 * x + 0.5 * k3 * y;
    let beta_y = sy - h + k2 * y + 0.5 * k3 * x;
    // β_x = θ_y, β_y = −θ_x; the drilling rotation is the in-plane rotation
    [
        a * x + b * y,
        cc * x + d * y,
        w,
        -beta_y,
        beta_x,
        0.5 * (cc - b),
    ]
}

#[test]
fn exact_fields_give_the_plies_their_laminate_theory_stresses() {
    // a distorted 4 × 3 patch, turned in space and moved; material axis 0.3 rad off the x edge
    let mut mesh = Mesh::rectangle(0.4, 0.3, 4, 3, 0).unwrap();
    for (k, p) in mesh.nodes.iter_mut().enumerate() {
        let (i, j) = (k % 5, k / 5);
        if i != 0 && i != 4 && j != 0 && j != 3 {
            p.x += 0.02 * ((3 * k) as f64).sin();
            p.y += 0.015 * ((5 * k + 1) as f64).cos();
        }
    }
    let turn = Rotation3::from_euler_angles(0.4, -0.7, 1.1);
    let origin = Vector3::new(0.3, -0.2, 0.5);
    let phi = 0.3_f64;
    let axis = turn * Vector3::new(phi.cos(), phi.sin(), 0.0);
    let (e1, e3) = (axis, turn * Vector3::z());
    let e2 = e3.cross(&e1);
    for p in &mut mesh.nodes {
        *p = turn * *p + origin;
    }
    for e in &mut mesh.elements {
        if let fem::Element::Shell { material_axis, .. } = e {
            *material_axis = axis;
        }
    }
    let frame = Matrix3::from_columns(&[e1, e2, e3]);
    let fields = [
        [
            1e-3, 2e-4, -4e-4, -6e-4, 0.01, -0.02, 0.3, -0.2, 0.45, 2e-4, -1e-4,
        ],
        [
            -2e-4, 5e-4, 1e-4, 3e-4, -0.03, 0.01, -0.1, 0.25, -0.15, -3e-4, 2e-4,
        ],
    ];
    let n = mesh.nodes.len();
    let modes = DMatrix::from_fn(6 * n, 2, |r, j| {
        let p = frame.transpose() * (mesh.nodes[r / 6] - origin);
        let local = plate_field(fields[j], p.x, p.y);
        let (t, rot) = (
            Vector3::new(local[0], local[1], local[2]),
            Vector3::new(local[3], local[4], local[5]),
        );
        let global = if r % 6 < 3 { frame * t } else { frame * rot };
        global[r % 3]
    });
    let lam = stack(paper_material(), 0.004, &[0.0, 45.0, -30.0, 90.0]);
    for membrane in [Membrane::Allman, Membrane::Cst] {
        let s = shell_modal_stresses(
            &mesh,
            &[ShellPlies::new(lam.clone())],
            membrane,
            &body_of(&mesh, modes.clone()),
        )
        .unwrap();
        assert_eq!(s.elements.len(), mesh.elements.len());
        let w = [0.7, -1.3];
        let c: [f64; 11] = std::array::from_fn(|i| w[0] * fields[0][i] + w[1] * fields[1][i]);
        let a_s = lam.stiffness().shear;
        let q = a_s * nalgebra::Vector2::new(c[9], c[10]);
        let expected = lam.ply_points(&PlateState {
            membrane: [c[0], c[3], c[1] + c[2]],
            curvature: [c[6], c[7], c[8]],
            shear_forces: [q[0], q[1]],
        });
        let scale = expected
            .iter()
            .flat_map(|p| p.stress)
            .fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale > 1e6);
        for i in 0..s.elements.len() {
            let d = s.deformation(i, &w);
            for (k, e) in expected.iter().enumerate() {
                let got = s.stress(i, k, &d);
                for r in 0..6 {
                    assert!(
                        (got[r] - e.stress[r]).abs() < 1e-9 * scale,
                        "{membrane:?} element {i} point {k} component {r}: {} vs {}",
                        got[r],
                        e.stress[r]
                    );
                }
            }
        }
    }
}

/// The clamped strip `[0, l] × [0, b]` of one isotropic ply (ν = 0), `nx × ny` cells, under a
/// tip force `p` (z) spread over its end nodes: the worst error of the elements' top-face
/// bending stress against `6M/bh²` and of their mid-plane shear against `3V/2bh`, away from
/// the root and the tip (relative to the root's value).
fn strip_errors(nx: usize, ny: usize) -> (f64, f64) {
    let (l, b, h, p) = (0.5, 0.05, 0.004, 20.0);
    let m = OrthotropicMaterial::isotropic(70e9, 0.0, 2700.0).unwrap();
    let lam = PlyStack::new(vec![Ply {
        material: m,
        thickness: h,
        angle: 0.0,
    }])
    .unwrap();
    let mesh = Mesh::rectangle(l, b, nx, ny, 0).unwrap();
    let mut constraints = Constraints::new();
    let root: Vec<usize> = (0..=ny).map(|j| j * (nx + 1)).collect();
    for &k in &root {
        constraints.clamp(k);
    }
    let props = Properties {
        sections: vec![],
        laminates: vec![lam.stiffness()],
    };
    let mut f = vec![0.0; 6 * mesh.nodes.len()];
    for j in 0..=ny {
        let share = if j == 0 || j == ny { 0.5 } else { 1.0 } / ny as f64;
        f[6 * (j * (nx + 1) + nx) + 2] = p * share;
    }
    let full = static_displacements(&mesh, &props, &constraints, &f);
    let s = shell_modal_stresses(
        &mesh,
        &[ShellPlies::new(lam)],
        Membrane::Allman,
        &body_of(&mesh, DMatrix::from_column_slice(full.len(), 1, &full)),
    )
    .unwrap();
    let top = 2; // the ply's top point
    let middle = 1;
    assert_eq!(
        s.laminates[0].points[top].place,
        fem::PointPlace::Ply(PlyPosition::Top)
    );
    let root_stress = 6.0 * p * l / (b * h * h);
    let shear = 1.5 * p / (b * h);
    let (mut bending, mut transverse) = (0.0f64, 0.0f64);
    for i in 0..s.elements.len() {
        let x = s.elements[i].centroid.x;
        if x < 0.2 * l || x > 0.8 * l {
            continue;
        }
        let d = s.deformation(i, &[1.0]);
        // fibre along x: σ11 = σ_xx; a load along +z bends the top face into compression
        let sigma = s.stress(i, top, &d)[0];
        let exact = -6.0 * p * (l - x) / (b * h * h);
        bending = bending.max((sigma - exact).abs() / root_stress);
        let tau = s.stress(i, middle, &d)[4];
        transverse = transverse.max((tau - shear).abs() / shear);
    }
    (bending, transverse)
}

#[test]
fn a_clamped_strip_under_a_tip_load_has_the_beam_stresses_converging_with_the_mesh() {
    let coarse = strip_errors(10, 2);
    let fine = strip_errors(20, 4);
    eprintln!("strip: coarse {coarse:?}, fine {fine:?}");
    assert!(fine.0 < 0.012 && fine.1 < 1e-3, "{fine:?}");
    assert!(
        fine.0 < 0.6 * coarse.0,
        "bending converges: {coarse:?} {fine:?}"
    );
}

#[test]
fn ply_stress_derivatives_equal_central_differences() {
    // variables: the second ply's angle, the first ply's thickness, a scale of the first mode
    let mesh = Mesh::rectangle(0.3, 0.1, 3, 2, 0).unwrap();
    let n = mesh.nodes.len();
    let field = |j: usize| {
        DVector::from_fn(6 * n, |r, _| {
            let p = mesh.nodes[r / 6];
            let base = [0.4e-3, -0.2e-3, 2e-3, 0.01, -0.02, 1e-3][r % 6];
            base * (1.0 + (j + 1) as f64 * p.x) * (1.0 + 3.0 * p.y * p.x) + 1e-4 * (r % 7) as f64
        })
    };
    let base = [0.0, 45.0f64.to_radians(), 0.0];
    let build = |b: [Dual<3>; 3]| {
        let plies = (0..3)
            .map(|i| Ply {
                material: paper_material(),
                thickness: if i == 0 {
                    Dual::constant(0.004 / 3.0) + b[2]
                } else {
                    Dual::constant(0.004 / 3.0)
                },
                angle: match i {
                    1 => b[1],
                    2 => Dual::constant(-1.0),
                    _ => Dual::constant(0.2),
                },
            })
            .collect();
        let stack = PlyStack::new(plies).unwrap();
        let modes = DMatrix::from_fn(6 * n, 2, |r, j| {
            let x = Dual::constant(field(j)[r]);
            if j == 0 {
                x * (Dual::constant(1.0) + b[0])
            } else {
                x
            }
        });
        shell_modal_stresses(
            &mesh,
            &[ShellPlies::new(stack)],
            Membrane::Allman,
            &body_of(&mesh, modes),
        )
        .unwrap()
    };
    let seeded: [Dual<3>; 3] = std::array::from_fn(|i| Dual::variable(base[i], i));
    let dual = build(seeded);
    let value = |b: [f64; 3]| build(b.map(Dual::constant));
    let w = [Dual::constant(0.8), Dual::constant(-0.5)];
    let steps = [1e-6, 1e-6, 1e-9];
    for j in 0..3 {
        let (mut p, mut m) = (base, base);
        p[j] += steps[j];
        m[j] -= steps[j];
        let pairs = stress_derivative_pairs(&dual, (&value(p), &value(m)), &w, (j, steps[j]));
        let largest = pairs.iter().fold(0.0f64, |m, p| m.max(p.2.abs()));
        let moved = pairs.iter().filter(|p| p.2.abs() > 1e-3 * largest).count();
        for (at, exact, fd) in pairs {
            assert!(
                (exact - fd).abs() < 1e-6 * largest + 1e-5 * fd.abs(),
                "variable {j} at {at:?}: {exact} vs {fd}"
            );
        }
        assert!(moved > 50, "variable {j} moves the stresses ({moved})");
    }
}
