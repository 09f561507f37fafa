//! The second-order field of shells (the membrane's quadratic modes,
//! `fem::shell_geometric_stiffness`) against a closed form, an exact invariant and central
//! differences.

mod common;

use common::paper_material;
use fem::{
    Coupling, GeometricStiffness, Mesh, ModalBody, ModalOptions, ModeUpdate, Properties,
    ReferenceCondition, Support, design_bodies, modal_analysis, modal_body,
    shell_geometric_stiffness,
};
use laminate::{OrthotropicMaterial, Ply, PlyStack};
use nalgebra::{DMatrix, Matrix3, Vector3};
use sens::{Scalar, seed_chunk};

/// A strip `length × width`, `nx × ny` cells, x along the length: node `j (nx + 1) + i`.
fn strip(length: f64, width: f64, nx: usize, ny: usize) -> Mesh {
    Mesh::rectangle(length, width, nx, ny, 0).unwrap()
}

/// Three plies of `material` at the angle `b[0]` (radians), 7.5 mm in all.
fn props<S: Scalar>(material: OrthotropicMaterial, b: &[S]) -> Properties<S> {
    let t = S::from_f64(0.0025);
    let stack = PlyStack::new(
        (0..3)
            .map(|_| Ply {
                material,
                thickness: t,
                angle: b[0],
            })
            .collect(),
    )
    .unwrap();
    Properties {
        sections: vec![],
        laminates: vec![stack.stiffness()],
    }
}

/// `modes` modes of `mesh` (`nx` cells along x) with the edge x = 0 clamped.
fn cantilever_options(mesh: &Mesh, modes: usize) -> ModalOptions {
    let root = mesh.nodes_on_segment(Vector3::zeros(), Vector3::new(0.0, 1.0, 0.0), 1e-9);
    let mut options = ModalOptions::new(modes);
    options.reference = ReferenceCondition::Supports;
    options.supports = vec![Support {
        nodes: root,
        dofs: (0..6).collect(),
    }];
    options
}

fn body_of(mesh: &Mesh, props: &Properties<f64>, options: &ModalOptions) -> ModalBody<f64> {
    let analysis = modal_analysis(mesh, props, options).unwrap();
    modal_body(mesh, props, &analysis).unwrap()
}

/// An isotropic strip with ν = 0 bends without anticlastic curvature: its first mode is
/// `w(x)` alone, and a unit tension spread over the free end (resultant 1 N at every section
/// by equilibrium) has the geometric stiffness `∫ φ'² dx`, which for the first cantilever mode
/// is `4.6477 / L²` times `∫ φ² dx = 1 / m` (mass-normalised, `m` the mass per length).
#[test]
fn a_tension_at_the_free_end_stiffens_the_first_mode_by_the_closed_form() {
    let (length, width, nx, ny) = (1.0, 0.05, 40, 2);
    let mesh = strip(length, width, nx, ny);
    let material = OrthotropicMaterial::isotropic(70e9, 0.0, 2700.0).unwrap();
    let p = props(material, &[0.0]);
    let options = cantilever_options(&mesh, 3);
    let body = body_of(&mesh, &p, &options);
    // the first mode bends out of the plane (translations almost only along z)
    let w_share = (0..mesh.nodes.len())
        .map(|k| body.modes[(6 * k + 2, 0)].powi(2))
        .sum::<f64>()
        / (0..mesh.nodes.len())
            .map(|k| {
                (0..3)
                    .map(|i| body.modes[(6 * k + i, 0)].powi(2))
                    .sum::<f64>()
            })
            .sum::<f64>();
    assert!(w_share > 0.999, "{w_share}");
    let g = shell_geometric_stiffness(&mesh, &p, &options, &body, 0, usize::MAX).unwrap();
    let tip: Vec<usize> = (0..=ny).map(|j| j * (nx + 1) + nx).collect();
    let kg: f64 = tip.iter().map(|&k| g.nodal[3 * k][(0, 0)]).sum::<f64>() / tip.len() as f64;
    let m = 2700.0 * 0.0075 * width;
    let expected = 4.6477 / (length * length * m);
    eprintln!(
        "tip tension: {kg} against {expected} ({:.1e})",
        kg / expected - 1.0
    );
    // 40 elements along the length: the beam's lumped-mass discretisation is 4e-4 off
    assert!(
        (kg / expected - 1.0).abs() < 1.5e-3,
        "{kg} against {expected}"
    );
    // a tension at the clamp does nothing; one at the free end stiffens every bending mode
    assert!(g.nodal[..3].iter().all(|k| k.amax() == 0.0));
    assert!(kg > 0.0);
}

/// The field held at one node differs from the field held at another by a rigid motion of
/// the shell, for every pair of modes: the clamp only fixes where the body frame puts the
/// field (an exact invariant, to the solver's round-off).
#[test]
fn the_clamp_moves_the_field_by_a_rigid_motion_only() {
    let mesh = strip(0.304, 0.04, 24, 4);
    let p = props(paper_material(), &[30f64.to_radians()]);
    let options = cantilever_options(&mesh, 4);
    let body = body_of(&mesh, &p, &options);
    let a = shell_geometric_stiffness(&mesh, &p, &options, &body, 0, usize::MAX).unwrap();
    let far = mesh.nodes.len() - 1;
    let b = shell_geometric_stiffness(&mesh, &p, &options, &body, far, usize::MAX).unwrap();
    let n = body.n_modes();
    for j in 0..n {
        for l in j..n {
            let d: Vec<Vector3<f64>> = (0..mesh.nodes.len())
                .map(|k| {
                    Vector3::from_fn(|i, _| a.nodal[3 * k + i][(j, l)] - b.nodal[3 * k + i][(j, l)])
                })
                .collect();
            let scale = d.iter().map(|v| v.norm()).fold(0.0, f64::max);
            let residual = rigid_fit_residual(&mesh.nodes, &d);
            assert!(scale > 0.0);
            assert!(
                residual < 1e-9 * scale,
                "modes {j}, {l}: {residual:e} of {scale:e} is not rigid"
            );
        }
    }
}

/// The largest departure of the nodal vectors `d` at `x` from their least-squares rigid motion
/// `t + θ × x`.
fn rigid_fit_residual(x: &[Vector3<f64>], d: &[Vector3<f64>]) -> f64 {
    let n = x.len();
    let mut a = DMatrix::zeros(3 * n, 6);
    let mut rhs = nalgebra::DVector::zeros(3 * n);
    for (k, (xk, dk)) in x.iter().zip(d).enumerate() {
        // t + θ × x = t − x̃ θ
        let skew = Matrix3::new(0.0, -xk[2], xk[1], xk[2], 0.0, -xk[0], -xk[1], xk[0], 0.0);
        for i in 0..3 {
            a[(3 * k + i, i)] = 1.0;
            for c in 0..3 {
                a[(3 * k + i, 3 + c)] = -skew[(i, c)];
            }
            rhs[3 * k + i] = dk[i];
        }
    }
    let fit = a.clone().svd(true, true).solve(&rhs, 1e-14).unwrap();
    (a * fit - rhs).amax()
}

/// The options of the paper's plate rod (`decks/slider_crank_plate.toml`) on `mesh` (`nx` ×
/// `ny` cells of 0.304 × 0.04 m): the crank-end edge pinned, the slider-end edge held across,
/// distributing couplings on both end edges, four eigenmodes and the couplings' static
/// correction modes.
fn interface_options(mesh: &Mesh, nx: usize, ny: usize) -> ModalOptions {
    let edge = |x: f64| -> Vec<usize> {
        (0..=ny)
            .map(|j| j * (nx + 1) + if x > 0.0 { nx } else { 0 })
            .collect()
    };
    let mut options = ModalOptions::new(4);
    options.reference = ReferenceCondition::Supports;
    options.supports = vec![
        Support {
            nodes: edge(0.0),
            dofs: vec![0, 1, 2],
        },
        Support {
            nodes: edge(1.0),
            dofs: vec![1, 2],
        },
    ];
    options.couplings = [edge(0.0), edge(1.0)]
        .into_iter()
        .map(|nodes| Coupling {
            nodes,
            point: None,
            rigid: false,
        })
        .collect();
    let n = mesh.nodes.len();
    options.correction = vec![n, n + 1];
    options
}

/// The field's derivative with respect to the ply angle (through the modes, Nelson's method,
/// and through the laminate's membrane stiffness) against Richardson-extrapolated central
/// differences of whole analyses, for eigenmodes alone and for the interface basis (static
/// correction modes at couplings, whose derivatives are those of a fixed combination).
#[test]
fn the_field_derivative_matches_central_differences() {
    let (nx, ny) = (16, 2);
    let mesh = strip(0.304, 0.04, nx, ny);
    for options in [
        cantilever_options(&mesh, 4),
        interface_options(&mesh, nx, ny),
    ] {
        field_derivative_check(&mesh, &options, 30.0);
    }
}

/// At 0° the laminate is orthotropic in the strip's axes: membrane forces that vanish by its
/// symmetry still have derivatives (the angle makes it anisotropic), which the field keeps.
#[test]
fn the_field_derivative_where_the_design_breaks_a_symmetry() {
    let (nx, ny) = (16, 2);
    let mesh = strip(0.304, 0.04, nx, ny);
    field_derivative_check(&mesh, &cantilever_options(&mesh, 4), 0.0);
}

/// The field's angle derivative at `degrees` vs central differences of whole analyses.
fn field_derivative_check(mesh: &Mesh, options: &ModalOptions, degrees: f64) {
    let material = paper_material();
    let b0 = [degrees.to_radians()];
    let p0 = props(material, &b0);
    let analysis = modal_analysis(mesh, &p0, options).unwrap();
    let nominal = modal_body(mesh, &p0, &analysis).unwrap();
    let bodies = design_bodies::<1, _>(
        mesh,
        &p0,
        &analysis,
        &b0,
        |b| props(material, b),
        ModeUpdate::Updated,
    )
    .unwrap();
    let clamp = 0;
    let seeded = props(material, &seed_chunk::<1>(&b0, 0));
    let dual =
        shell_geometric_stiffness(mesh, &seeded, options, &bodies.chunks[0], clamp, usize::MAX)
            .unwrap();
    let at = |b: f64| -> (ModalBody<f64>, GeometricStiffness<f64>) {
        let p = props(material, &[b]);
        let mut body = body_of(mesh, &p, options);
        body.align_to(&nominal, 1e-6).unwrap();
        let g = shell_geometric_stiffness(mesh, &p, options, &body, clamp, usize::MAX).unwrap();
        (body, g)
    };
    let h = 1e-3;
    let (p1, m1, p2, m2) = (
        at(b0[0] + h),
        at(b0[0] - h),
        at(b0[0] + 2.0 * h),
        at(b0[0] - 2.0 * h),
    );
    // central differences at h and 2h, Richardson-extrapolated (truncation O(h⁴))
    let rich = |a: f64, b: f64, a2: f64, b2: f64| {
        (4.0 * (a - b) / (2.0 * h) - (a2 - b2) / (4.0 * h)) / 3.0
    };
    // The differences follow the analyses' bases (aligned to the nominal one); the derivatives
    // of correction modes are those of a fixed combination of their shapes: the two bases
    // differ by `X T(b)`, `T' = XᵀM (X'_FD − X'_dual)` (mass-normalised X), under which the
    // field's matrices change by `T'ᵀ G + G T'`.
    let x = &nominal.modes;
    let x_fd = DMatrix::from_fn(x.nrows(), x.ncols(), |r, c| {
        rich(
            p1.0.modes[(r, c)],
            m1.0.modes[(r, c)],
            p2.0.modes[(r, c)],
            m2.0.modes[(r, c)],
        )
    });
    let x_dual = bodies.chunks[0].modes.map(|v| v.d[0]);
    let mut mx = DMatrix::zeros(x.nrows(), x.ncols());
    for k in 0..nominal.n_nodes() {
        for i in 0..3 {
            for c in 0..x.ncols() {
                mx[(6 * k + i, c)] = nominal.node_masses[k] * x[(6 * k + i, c)];
                mx[(6 * k + 3 + i, c)] = nominal.node_inertias[k][i] * x[(6 * k + 3 + i, c)];
            }
        }
    }
    let t = mx.transpose() * (x_fd - x_dual);
    let n = nominal.n_modes();
    let g0 = shell_geometric_stiffness(mesh, &p0, options, &nominal, clamp, usize::MAX).unwrap();
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    let (mut value_error, mut value_scale) = (0.0f64, 0.0f64);
    for (c, d) in dual.nodal.iter().enumerate() {
        let basis = t.transpose() * &g0.nodal[c] + &g0.nodal[c] * &t;
        for j in 0..n {
            for l in 0..n {
                let fd = rich(
                    p1.1.nodal[c][(j, l)],
                    m1.1.nodal[c][(j, l)],
                    p2.1.nodal[c][(j, l)],
                    m2.1.nodal[c][(j, l)],
                );
                let got = d[(j, l)].d[0] + basis[(j, l)];
                worst = worst.max((got - fd).abs());
                scale = scale.max(got.abs());
                // the value part is the f64 field
                value_error = value_error.max((d[(j, l)].v - g0.nodal[c][(j, l)]).abs());
                value_scale = value_scale.max(g0.nodal[c][(j, l)].abs());
            }
        }
    }
    assert!(scale > 0.0);
    eprintln!("field derivative: {worst:.1e} of {scale:.1e}, value {value_error:.1e}");
    assert!(worst < 1e-6 * scale, "{worst:e} of {scale:e}");
    assert!(value_error < 1e-10 * value_scale, "{value_error:e}");
}

/// `body` with the modes `modes` in another scalar (the rest constant).
fn with_modes<S: Scalar>(body: &ModalBody<f64>, modes: DMatrix<S>) -> ModalBody<S> {
    ModalBody {
        node_positions: body.node_positions.clone(),
        node_masses: body.node_masses.iter().map(|&m| S::from_f64(m)).collect(),
        node_inertias: (body.node_inertias.iter())
            .map(|v| v.map(S::from_f64))
            .collect(),
        modes,
        eigenvalues: body.eigenvalues.iter().map(|&x| S::from_f64(x)).collect(),
        modal_damping: body.modal_damping.iter().map(|&x| S::from_f64(x)).collect(),
        stiffness_matrix: (body.stiffness_matrix.as_ref()).map(|k| Box::new(k.map(S::from_f64))),
        damping_matrix: (body.damping_matrix.as_ref()).map(|c| Box::new(c.map(S::from_f64))),
    }
}

/// A weighted sum of every entry of the field's matrices.
fn field_sum<S: Scalar>(g: &GeometricStiffness<S>) -> S {
    let mut sum = S::zero();
    for (c, m) in g.nodal.iter().enumerate() {
        for (i, &x) in m.iter().enumerate() {
            sum += x * (1.0 + ((7 * c + 3 * i) % 11) as f64);
        }
    }
    sum
}

/// Recorded on the reverse-mode tape with the modes as inputs (the laminate held), the field's
/// static solves are one operation each way: the gradient of a weighted sum of the field with
/// respect to the modes, contracted with a direction, equals the forward tangent along it and
/// the central difference of the `f64` field (exact: the field is quadratic in the modes).
#[test]
fn the_field_reversed_on_the_tape_gives_the_forward_and_central_differences() {
    let (nx, ny) = (8, 2);
    let mesh = strip(0.304, 0.04, nx, ny);
    let options = interface_options(&mesh, nx, ny);
    let p0 = props(paper_material(), &[30f64.to_radians()]);
    let body = body_of(&mesh, &p0, &options);
    let x = &body.modes;
    let scale = x.amax();
    let direction = DMatrix::from_fn(x.nrows(), x.ncols(), |r, c| {
        scale * (((5 * r + 3 * c) % 13) as f64 / 13.0 - 0.5)
    });
    fn field<S: Scalar>(
        (mesh, options): (&Mesh, &ModalOptions),
        props: &Properties<S>,
        body: &ModalBody<S>,
    ) -> GeometricStiffness<S> {
        shell_geometric_stiffness(mesh, props, options, body, 0, usize::MAX).unwrap()
    }
    let on = (&mesh, &options);
    // forward: the tangent along the direction
    let dual_modes = x.zip_map(&direction, |v, d| sens::Dual::<1>::new(v, [d]));
    let lift = |v: f64| sens::Dual::<1>::constant(v);
    let forward = field_sum(&field(on, &p0.map(&lift), &with_modes(&body, dual_modes))).d[0];
    // central difference of the f64 field
    let h = 1e-3;
    let at = |s: f64| field_sum(&field(on, &p0, &with_modes(&body, x + &direction * s)));
    let central = (at(h) - at(-h)) / (2.0 * h);
    // reverse: one sweep
    let mark = sens::Tape::len();
    let inputs = x.map(sens::Rev::input);
    let constant = |v: f64| sens::Rev::constant(v);
    let y = field_sum(&field(
        on,
        &p0.map(&constant),
        &with_modes(&body, inputs.clone()),
    ));
    let mut adjoints = Vec::new();
    y.seed(&mut adjoints, 1.0);
    sens::Tape::backpropagate(&mut adjoints, mark);
    let reverse: f64 = (inputs.iter().zip(direction.iter()))
        .map(|(i, d)| i.adjoint(&adjoints) * d)
        .sum();
    sens::Tape::rewind(mark);
    assert!(forward != 0.0);
    // the three agree to a few 1e-11: the same stiff solves (the shell's stiffness with its
    // drilling terms) taken in another order; a missing term or transpose would be O(1)
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    assert!(
        rel(reverse, forward) < 1e-9,
        "reverse {reverse} vs forward {forward}"
    );
    assert!(
        rel(central, forward) < 1e-8,
        "central {central} vs forward {forward}"
    );
}
