//! Timoshenko beam element: closed-form and converged references, shear locking.

mod common;

use common::{
    Rect, Stretch, rel, timoshenko_cantilever, timoshenko_ss, timoshenko_stepped_cantilever,
};
use fem::{
    Assembly, BeamSegment, Constraints, ElementOptions, MassKind, Mesh, Properties, dof,
    lowest_modes,
};
use nalgebra::Vector3;

fn steel(hy: f64) -> Rect {
    Rect {
        e: 210e9,
        nu: 0.3,
        rho: 7850.0,
        hy,
        hz: 0.05,
        kappa: 5.0 / 6.0,
    }
}

/// Planar (x–y) bending eigenvalues of a beam along x with the given end supports.
fn planar_bending(
    rect: &Rect,
    l: f64,
    n_el: usize,
    clamp_left: bool,
    pin_ends: bool,
    count: usize,
    mass: MassKind,
) -> Vec<f64> {
    let mesh = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(l, 0.0, 0.0),
        n_el,
        0,
        Vector3::y(),
    )
    .unwrap();
    let supports = Supports {
        clamp_left,
        pin_ends,
    };
    planar_modes(&mesh, &rect.props(), supports, count, mass)
}

/// How a beam along x is held: clamped at its first node, and/or pinned at both ends.
#[derive(Clone, Copy)]
struct Supports {
    clamp_left: bool,
    pin_ends: bool,
}

/// Planar (x–y) bending eigenvalues of the beam `mesh` along x (nodes in order).
fn planar_modes(
    mesh: &Mesh,
    props: &Properties<f64>,
    Supports {
        clamp_left,
        pin_ends,
    }: Supports,
    count: usize,
    mass: MassKind,
) -> Vec<f64> {
    let n_el = mesh.elements.len();
    let mut c = Constraints::new();
    let all: Vec<usize> = (0..=n_el).collect();
    // bending in x–y only: keep u_y, θ_z
    c.fix_nodes(&all, &[dof::UX, dof::UZ, dof::RX, dof::RY]);
    if clamp_left {
        c.clamp(0);
    }
    if pin_ends {
        c.fix(0, dof::UY).fix(n_el, dof::UY);
    }
    let asm = Assembly::new(mesh, &c).unwrap();
    let (k, m) = asm
        .values(mesh, props, &ElementOptions::default(), mass)
        .unwrap();
    let pairs = lowest_modes(&asm.matrix(k), &asm.matrix(m), count, &Default::default()).unwrap();
    pairs.values
}

#[test]
fn simply_supported_timoshenko_first_five_within_half_percent() {
    let r = steel(0.1);
    let l = 1.0; // L/h = 10: shear and rotary inertia matter
    let got = planar_bending(&r, l, 40, false, true, 5, MassKind::Consistent);
    for n in 1..=5 {
        let exact = timoshenko_ss(
            r.e * r.i3(),
            r.kappa * r.g() * r.area(),
            r.rho * r.area(),
            r.rho * r.i3(),
            l,
            n,
        );
        let f_err = rel(got[n - 1].sqrt(), exact.sqrt());
        eprintln!("SS mode {n}: error {f_err:.3e}");
        assert!(
            f_err < 5e-3,
            "mode {n}: ω² {} vs {exact}, frequency error {f_err:.2e}",
            got[n - 1]
        );
    }
    // and the shear correction visibly matters at L/h = 10 (Euler–Bernoulli is > 2 % off at mode 5)
    let eb5 = (5.0 * std::f64::consts::PI / l).powi(4) * r.e * r.i3() / (r.rho * r.area());
    assert!(rel(got[4].sqrt(), eb5.sqrt()) > 0.02);
}

#[test]
fn cantilever_timoshenko_first_five_within_half_percent() {
    let r = steel(0.1);
    let l = 1.0;
    let got = planar_bending(&r, l, 40, true, false, 5, MassKind::Consistent);
    let exact = timoshenko_cantilever(
        r.e * r.i3(),
        r.kappa * r.g() * r.area(),
        r.rho * r.area(),
        r.rho * r.i3(),
        l,
        5,
    );
    for n in 0..5 {
        let f_err = rel(got[n].sqrt(), exact[n].sqrt());
        eprintln!("cantilever mode {}: error {f_err:.3e}", n + 1);
        assert!(
            f_err < 5e-3,
            "mode {}: ω² {} vs {}, error {f_err:.2e}",
            n + 1,
            got[n],
            exact[n]
        );
    }
    // the exact transfer-matrix oracle reduces to Euler–Bernoulli's 1.875104² for slender beams
    let s = steel(0.001);
    let ex = timoshenko_cantilever(
        s.e * s.i3(),
        1e6 * s.g() * s.area(),
        s.rho * s.area(),
        0.0,
        1.0,
        1,
    );
    let eb = 1.875_104_068_711_961f64.powi(4) * s.e * s.i3() / (s.rho * s.area());
    assert!(rel(ex[0], eb) < 1e-6, "{} vs {eb}", ex[0]);
}

/// A cantilever of two sections (a deep steel root over 40 % of its length, a section of half
/// the depth beyond): the segmented mesh's first five frequencies against the exact transfer
/// matrices of the two uniform stretches, within 0.5 %; and the mesh puts its nodes where the
/// segments say.
#[test]
fn stepped_cantilever_matches_the_transfer_matrix_of_its_stretches() {
    let (root, tip) = (steel(0.1), steel(0.05));
    let l = 1.0;
    let segments = [
        BeamSegment {
            length: 0.4 * l,
            elements: 16,
            property: 0,
        },
        BeamSegment {
            length: 0.6 * l,
            elements: 24,
            property: 1,
        },
    ];
    let mesh = Mesh::segmented_beam(
        Vector3::zeros(),
        Vector3::new(l, 0.0, 0.0),
        &segments,
        Vector3::y(),
    )
    .unwrap();
    assert_eq!((mesh.nodes.len(), mesh.elements.len()), (41, 40));
    assert!((mesh.nodes[16].x - 0.4).abs() < 1e-15 && (mesh.nodes[40].x - l).abs() < 1e-15);
    assert!((mesh.nodes[28].x - 0.7).abs() < 1e-15);
    let props = Properties {
        sections: vec![root.section(), tip.section()],
        laminates: vec![],
    };
    let supports = Supports {
        clamp_left: true,
        pin_ends: false,
    };
    let got = planar_modes(&mesh, &props, supports, 5, MassKind::Consistent);
    let stretch = |r: &Rect, l: f64| Stretch {
        ei: r.e * r.i3(),
        kga: r.kappa * r.g() * r.area(),
        rho_a: r.rho * r.area(),
        rho_i: r.rho * r.i3(),
        l,
    };
    let exact = timoshenko_stepped_cantilever(&[stretch(&root, 0.4), stretch(&tip, 0.6)], 5);
    for n in 0..5 {
        let f_err = rel(got[n].sqrt(), exact[n].sqrt());
        eprintln!("stepped cantilever mode {}: error {f_err:.3e}", n + 1);
        assert!(
            f_err < 5e-3,
            "mode {}: ω² {} vs {}, error {f_err:.2e}",
            n + 1,
            got[n],
            exact[n]
        );
    }
    // the step matters: each uniform beam alone is off by more than 2 % in the first mode
    for r in [&root, &tip] {
        let uniform = timoshenko_stepped_cantilever(&[stretch(r, l)], 1);
        let off = rel(uniform[0].sqrt(), exact[0].sqrt());
        assert!(off > 0.02, "a uniform beam is within {off:.1e}");
    }
}

#[test]
fn slender_beam_has_no_shear_locking() {
    // L/h = 1000 with only 6 elements: Euler–Bernoulli within 0.5 %
    let r = steel(0.001);
    let l = 1.0;
    for mass in [MassKind::Consistent, MassKind::Lumped] {
        let got = planar_bending(&r, l, 6, false, true, 2, mass);
        let eb1 = (std::f64::consts::PI / l).powi(4) * r.e * r.i3() / (r.rho * r.area());
        let err = rel(got[0].sqrt(), eb1.sqrt());
        eprintln!("{mass:?} slender: error {err:.3e}");
        assert!(
            err < 5e-3,
            "{mass:?}: ω₁² {} vs EB {eb1}: {err:.2e}",
            got[0]
        );
    }
}

#[test]
fn static_tip_deflection_is_exact_with_one_element() {
    // cantilever, tip load P in y: δ = PL³/(3EI) + PL/(κGA), exact for the flexibility element
    let r = steel(0.1);
    let l = 2.0;
    let mesh = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(l, 0.0, 0.0),
        1,
        0,
        Vector3::y(),
    )
    .unwrap();
    let (k, _) = fem::element_matrices(
        &mesh,
        0,
        &r.props(),
        &ElementOptions::default(),
        MassKind::Consistent,
    )
    .unwrap();
    // node 2 block, node 1 clamped
    let k22 = k.view((6, 6), (6, 6)).into_owned();
    let mut f = nalgebra::DVector::zeros(6);
    f[1] = 1000.0;
    let d = k22.lu().solve(&f).unwrap();
    let exact =
        1000.0 * l.powi(3) / (3.0 * r.e * r.i3()) + 1000.0 * l / (r.kappa * r.g() * r.area());
    assert!(rel(d[1], exact) < 1e-10, "{} vs {exact}", d[1]);
    // tip rotation θ_z = PL²/(2EI)
    assert!(rel(d[5], 1000.0 * l * l / (2.0 * r.e * r.i3())) < 1e-10);
}

#[test]
fn coupled_section_element_is_symmetric_with_rigid_body_null_space() {
    // a fully populated (positive-definite) 6×6 section, beam along a skew axis
    let mut c = nalgebra::Matrix6::<f64>::zeros();
    let diag = [1e7, 3e6, 2e6, 5e3, 8e3, 6e3];
    for i in 0..6 {
        c[(i, i)] = diag[i];
    }
    for i in 0..6 {
        for j in 0..6 {
            if i != j {
                c[(i, j)] =
                    0.2 * (diag[i] * diag[j]).sqrt() * (((i + 2 * j) % 5) as f64 - 2.0) / 4.0;
            }
        }
    }
    let c = (c + c.transpose()) * 0.5;
    assert!(c.cholesky().is_some());
    let sec = fem::BeamSection {
        stiffness: c,
        mass_per_length: 2.0,
        mass_centre: [0.01, -0.02],
        inertia: [1e-3, 2e-3, 1e-4],
    };
    let props = fem::Properties {
        sections: vec![sec],
        laminates: vec![],
    };
    let mesh = Mesh {
        nodes: vec![Vector3::new(0.1, 0.2, 0.3), Vector3::new(0.5, -0.1, 0.9)],
        elements: vec![fem::Element::Beam {
            nodes: [0, 1],
            property: 0,
            orientation: Vector3::new(0.0, 0.0, 1.0),
        }],
    };
    let (k, m) = fem::element_matrices(
        &mesh,
        0,
        &props,
        &ElementOptions::default(),
        MassKind::Consistent,
    )
    .unwrap();
    let kn = k.norm();
    assert!((&k - k.transpose()).norm() < 1e-12 * kn);
    assert!((&m - m.transpose()).norm() < 1e-12 * m.norm());
    // six rigid motions: translations and small rotations about the origin
    for r in 0..6 {
        let mut q = nalgebra::DVector::zeros(12);
        for (a, p) in mesh.nodes.iter().enumerate() {
            if r < 3 {
                q[6 * a + r] = 1.0;
            } else {
                let mut w = Vector3::zeros();
                w[r - 3] = 1.0;
                let u = w.cross(p);
                for d in 0..3 {
                    q[6 * a + d] = u[d];
                    q[6 * a + 3 + d] = w[d];
                }
            }
        }
        assert!(
            (&k * &q).norm() < 1e-9 * kn * q.norm(),
            "rigid mode {r} strains the element"
        );
        // mass: total mass recovered for translations
        if r < 3 {
            let mt = q.dot(&(&m * &q));
            assert!(
                rel(mt, 2.0 * (mesh.nodes[1] - mesh.nodes[0]).norm()) < 1e-12,
                "translational mass {mt}"
            );
        }
    }
    // positive semi-definite with exactly six zero eigenvalues
    let ev = k.symmetric_eigenvalues();
    let zeros = ev.iter().filter(|&&e| e.abs() < 1e-9 * kn).count();
    assert_eq!(zeros, 6, "{ev}");
    assert!(ev.iter().all(|&e| e > -1e-9 * kn));
}
