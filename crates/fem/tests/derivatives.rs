//! Design derivatives through dual numbers: K_b, eigenvalue and eigenvector derivatives
//! (Nelson), repeated eigenvalues (Dailey), the dual ModalBody.

mod common;

use common::{paper_material, rel};
use fem::{
    Assembly, Constraints, ElementOptions, MassKind, Mesh, ModalOptions, ModeUpdate, Properties,
    RayleighDamping, ReferenceCondition, analysis_derivatives, design_matrices, dof, lowest_modes,
    modal_analysis, modal_body, modal_body_dual,
};
use laminate::{OrthotropicMaterial, Ply, PlyStack};
use nalgebra::{DMatrix, Vector3};
use sens::{Dual, Scalar};

/// A stack with the given angles (radians), generic over the scalar.
fn plies<S: Scalar>(mat: OrthotropicMaterial, total: f64, angles: &[S]) -> PlyStack<S> {
    let t = S::from_f64(total / angles.len() as f64);
    PlyStack::new(
        angles
            .iter()
            .map(|&angle| Ply {
                material: mat,
                thickness: t,
                angle,
            })
            .collect(),
    )
    .unwrap()
}

fn strip_props<S: Scalar>(b: &[S]) -> Properties<S> {
    Properties {
        sections: vec![],
        laminates: vec![plies(paper_material(), 0.01, b).stiffness()],
    }
}

fn strip() -> Mesh {
    Mesh::rectangle(0.3, 0.04, 12, 2, 0).unwrap()
}

const B0: [f64; 3] = [0.5, -0.8, 1.1];

/// The entries of a sparse matrix, column by column.
fn dense(a: &faer::sparse::SparseColMat<usize, f64>) -> Vec<f64> {
    let (cp, ri) = (a.symbolic().col_ptr(), a.symbolic().row_idx());
    let mut d = vec![0.0; a.nrows() * a.ncols()];
    for j in 0..a.ncols() {
        for p in cp[j]..cp[j + 1] {
            d[j * a.nrows() + ri[p]] += a.val()[p];
        }
    }
    d
}

#[test]
fn stiffness_derivative_matches_closed_form_laminate_derivative() {
    let mesh = strip();
    let asm = Assembly::new(&mesh, &Constraints::new()).unwrap();
    let opts = ElementOptions::default();
    let dm = design_matrices::<2, _>(&mesh, &asm, &B0, strip_props, &opts, MassKind::Consistent)
        .unwrap();
    assert_eq!(dm.len(), 3);
    let stack = plies(paper_material(), 0.01, &B0);
    for k in 0..3 {
        // K is linear in (A, B, D, A_s): K evaluated on the Eq. (50) derivative laminate is K_b
        let d = stack.angle_derivative(&[k]);
        let props = Properties {
            sections: vec![],
            laminates: vec![d],
        };
        let (kv, mv) = asm
            .values(&mesh, &props, &opts, MassKind::Consistent)
            .unwrap();
        let scale = kv.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        // K_b keeps the entries the variable moves: compared entry by entry
        let (closed, kb) = (dense(&asm.matrix(kv.clone())), dense(&dm[k].k));
        let err = (closed.iter().zip(&kb))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale;
        assert!(
            err < 1e-12,
            "variable {k}: K_b differs from the closed form by {err:e}"
        );
        assert!(scale > 0.0);
        // mass does not depend on ply angles
        assert!(dm[k].m.val().iter().all(|&x| x == 0.0));
        assert!(mv.iter().all(|&x| x == 0.0));
    }
}

fn strip_analysis(b: &[f64], mass: MassKind) -> fem::ModalAnalysis {
    let mut o = ModalOptions::new(5);
    o.mass = mass;
    o.damping = Some(
        RayleighDamping {
            modes: [0, 3],
            ratios: [0.01, 0.03],
        }
        .into(),
    );
    modal_analysis(&strip(), &strip_props(b), &o).unwrap()
}

/// Align the sign of `x` with `reference`.
fn aligned(x: &DMatrix<f64>, reference: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = x.clone();
    for j in 0..x.ncols() {
        if x.column(j).dot(&reference.column(j)) < 0.0 {
            out.column_mut(j).neg_mut();
        }
    }
    out
}

#[test]
fn eigenvalue_and_eigenvector_derivatives_match_central_differences() {
    for mass in [MassKind::Lumped, MassKind::Consistent] {
        let an = strip_analysis(&B0, mass);
        let (_, d) =
            analysis_derivatives::<2, _>(&strip(), &an, &B0, strip_props, ModeUpdate::Updated)
                .unwrap();
        let xb = d.eigenvectors.as_ref().unwrap();
        let p = an.n_modes;
        let x0 = an.pairs.vectors.columns(0, p).into_owned();
        let h = 1e-3;
        for k in 0..3 {
            let mut bp = B0;
            let mut bm = B0;
            bp[k] += h;
            bm[k] -= h;
            // central differences at h and 2h, Richardson-extrapolated (truncation O(h⁴))
            let (ap, am) = (strip_analysis(&bp, mass), strip_analysis(&bm, mass));
            bp[k] += h;
            bm[k] -= h;
            let (ap2, am2) = (strip_analysis(&bp, mass), strip_analysis(&bm, mass));
            let rich = |a: f64, b: f64, a2: f64, b2: f64| {
                (4.0 * (a - b) / (2.0 * h) - (a2 - b2) / (4.0 * h)) / 3.0
            };
            for i in 0..p {
                let fd = rich(
                    ap.pairs.values[i],
                    am.pairs.values[i],
                    ap2.pairs.values[i],
                    am2.pairs.values[i],
                );
                let got = d.eigenvalues[k][i];
                eprintln!(
                    "{mass:?} var {k} mode {i}: λ_b {got} vs FD {fd}: {:e}",
                    (got - fd).abs() / got.abs()
                );
                let scale = (0..3)
                    .map(|v| d.eigenvalues[v][i].abs())
                    .fold(0.0, f64::max);
                assert!(
                    (got - fd).abs() <= 1e-6 * scale,
                    "{mass:?} var {k} mode {i}: λ_b {got} vs FD {fd}"
                );
            }
            let xp = aligned(&ap.pairs.vectors.columns(0, p).into_owned(), &x0);
            let xm = aligned(&am.pairs.vectors.columns(0, p).into_owned(), &x0);
            let xp2 = aligned(&ap2.pairs.vectors.columns(0, p).into_owned(), &x0);
            let xm2 = aligned(&am2.pairs.vectors.columns(0, p).into_owned(), &x0);
            let fd = ((xp - xm) / (2.0 * h) * 4.0 - (xp2 - xm2) / (4.0 * h)) / 3.0;
            for i in 0..p {
                let got = xb[k].column(i);
                // relative to the largest derivative of this mode over the design variables
                let scale = (0..3).map(|v| xb[v].column(i).norm()).fold(0.0, f64::max);
                let err = (got - fd.column(i)).norm() / scale;
                eprintln!("  vector: {err:e}");
                assert!(
                    err < 1e-6,
                    "{mass:?} var {k} mode {i}: |x_b − FD|/max|x_b| = {err:e}"
                );
            }
        }
    }
}

#[test]
fn dual_modal_body_carries_the_derivatives_and_is_chunk_independent() {
    let mesh = strip();
    let an = strip_analysis(&B0, MassKind::Lumped);
    let props = strip_props(&B0);
    let body = modal_body(&mesh, &props, &an).unwrap();
    body.validate().unwrap();
    // lumped-mass orthonormality of the full-size modes: Xᵀ diag(m, μ) X = I
    let mut mdiag = vec![0.0; 6 * body.n_nodes()];
    for k in 0..body.n_nodes() {
        for d in 0..3 {
            mdiag[6 * k + d] = body.node_masses[k];
            mdiag[6 * k + 3 + d] = body.node_inertias[k][d];
        }
    }
    let x = &body.modes;
    let xmx = x.transpose() * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(mdiag)) * x;
    assert!((xmx - DMatrix::<f64>::identity(5, 5)).abs().max() < 1e-10);
    // total mass = ρ h A
    assert!(rel(body.total_mass(), 1586.0 * 0.01 * 0.3 * 0.04) < 1e-12);
    // the clamped node is the one at the centre of mass, at the body origin
    let origin_node = body
        .node_positions
        .iter()
        .position(|p| p.norm() < 1e-12)
        .unwrap();
    assert!(x.rows(6 * origin_node, 6).iter().all(|&v| v == 0.0));

    let (_, d) =
        analysis_derivatives::<3, _>(&mesh, &an, &B0, strip_props, ModeUpdate::Updated).unwrap();
    let d2 = analysis_derivatives::<1, _>(&mesh, &an, &B0, strip_props, ModeUpdate::Updated)
        .unwrap()
        .1;
    for k in 0..3 {
        for i in 0..5 {
            assert_eq!(
                d.eigenvalues[k][i], d2.eigenvalues[k][i],
                "chunk width changes λ_b"
            );
        }
    }
    let fixed = modal_body_dual::<3>(&mesh, &props, &an, &[], &d, 0, ModeUpdate::Fixed).unwrap();
    let updated =
        modal_body_dual::<3>(&mesh, &props, &an, &[], &d, 0, ModeUpdate::Updated).unwrap();
    for i in 0..5 {
        for k in 0..3 {
            assert_eq!(fixed.eigenvalues[i].d[k], d.eigenvalues[k][i]);
        }
        assert_eq!(fixed.eigenvalues[i].v, an.pairs.values[i]);
    }
    assert!(fixed.modes.iter().all(|m: &Dual<3>| m.d == [0.0; 3]));
    assert!(updated.modes.iter().any(|m: &Dual<3>| m.d != [0.0; 3]));
    // the damping matrix reproduces the modal damping: xᵢᵀ C xᵢ = 2 ζᵢ ωᵢ
    let cmat = an.damping_matrix().unwrap().unwrap();
    let x5 = an.pairs.vectors.columns(0, 5).into_owned();
    let xcx = fem::eigen::project(&cmat, &x5, &x5);
    for i in 0..5 {
        assert!(rel(xcx[(i, i)], updated.modal_damping[i].v) < 1e-9);
    }
    // modal damping: ζ = 1 % and 3 % at modes 1 and 4, and its derivative by central differences
    let w = |i: usize| an.pairs.values[i].sqrt();
    assert!(rel(updated.modal_damping[0].v, 2.0 * 0.01 * w(0)) < 1e-12);
    assert!(rel(updated.modal_damping[3].v, 2.0 * 0.03 * w(3)) < 1e-12);
    let c = |b: &[f64]| {
        let a = strip_analysis(b, MassKind::Lumped);
        modal_body(&mesh, &strip_props(b), &a)
            .unwrap()
            .modal_damping
    };
    for i in 0..5 {
        let grad: Vec<f64> = (0..3).map(|k| updated.modal_damping[i].d[k]).collect();
        let scale = grad.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        for k in 0..3 {
            let fd = richardson(&c, &B0, k, 1e-3)[i];
            assert!(
                (grad[k] - fd).abs() < 1e-6 * scale,
                "damping {i} var {k}: {} vs {fd}",
                grad[k]
            );
        }
    }
}

/// Central differences at `h` and `2h`, Richardson-extrapolated (truncation O(h⁴)).
fn richardson(f: &dyn Fn(&[f64]) -> Vec<f64>, b: &[f64], k: usize, h: f64) -> Vec<f64> {
    let at = |s: f64| {
        let mut x = b.to_vec();
        x[k] += s;
        f(&x)
    };
    let (p1, m1, p2, m2) = (at(h), at(-h), at(2.0 * h), at(-2.0 * h));
    (0..p1.len())
        .map(|i| (4.0 * (p1[i] - m1[i]) / (2.0 * h) - (p2[i] - m2[i]) / (4.0 * h)) / 3.0)
        .collect()
}

#[test]
fn beam_with_coupled_section_derivatives_match_central_differences() {
    // a section whose extension–twist and bending–twist couplings depend on a "ply angle"
    fn section<S: Scalar>(t: S) -> fem::BeamSection<S> {
        let (s, c) = t.sin_cos();
        let mut k = nalgebra::Matrix6::<S>::zeros();
        let base = [2e7, 6e5, 4e5, 3e2, 9e2, 4e3];
        for i in 0..6 {
            k[(i, i)] = S::from_f64(base[i]) * (S::one() + c * c * 0.3);
        }
        let ct = s * c * 0.25;
        k[(0, 3)] = ct * (base[0] * base[3]).sqrt();
        k[(3, 0)] = k[(0, 3)];
        k[(3, 4)] = ct * (base[3] * base[4]).sqrt() * 0.8;
        k[(4, 3)] = k[(3, 4)];
        k[(1, 5)] = s * s * 0.1 * (base[1] * base[5]).sqrt();
        k[(5, 1)] = k[(1, 5)];
        fem::BeamSection {
            stiffness: k,
            mass_per_length: S::from_f64(0.05),
            mass_centre: [S::from_f64(0.001), S::from_f64(-0.0005)],
            inertia: [S::from_f64(2e-6), S::from_f64(5e-6), S::from_f64(1e-7)],
        }
    }
    let props = |b: &[Dual<1>]| Properties {
        sections: vec![section(b[0])],
        laminates: vec![],
    };
    let mesh = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(0.304, 0.0, 0.0),
        16,
        0,
        Vector3::y(),
    )
    .unwrap();
    let modes_at = |t: f64| {
        let p = Properties {
            sections: vec![section(t)],
            laminates: vec![],
        };
        let mut o = ModalOptions::new(6);
        o.reference = ReferenceCondition::PinnedEnds { a: 0, b: 16 };
        modal_analysis(&mesh, &p, &o).unwrap()
    };
    let t0 = 0.4;
    let an = modes_at(t0);
    let (_, d) =
        analysis_derivatives::<1, _>(&mesh, &an, &[t0], props, ModeUpdate::Updated).unwrap();
    let h = 1e-5;
    let (ap, am) = (modes_at(t0 + h), modes_at(t0 - h));
    let x0 = an.pairs.vectors.columns(0, 6).into_owned();
    let xp = aligned(&ap.pairs.vectors.columns(0, 6).into_owned(), &x0);
    let xm = aligned(&am.pairs.vectors.columns(0, 6).into_owned(), &x0);
    for i in 0..6 {
        let fd = (ap.pairs.values[i] - am.pairs.values[i]) / (2.0 * h);
        let got = d.eigenvalues[0][i];
        assert!(
            (got - fd).abs() <= 1e-6 * got.abs(),
            "mode {i}: {got} vs {fd}"
        );
        let xb = d.eigenvectors.as_ref().unwrap()[0].column(i).into_owned();
        let fdx = (xp.column(i) - xm.column(i)) / (2.0 * h);
        assert!((&xb - fdx).norm() < 1e-6 * xb.norm(), "mode {i} vector");
    }
}

/// A tetragonal material (E1 = E2): a 0° ply is invariant under 90° rotations, so a square plate
/// has repeated eigenvalue pairs.
fn tetragonal() -> OrthotropicMaterial {
    OrthotropicMaterial::new(
        [50e9, 50e9, 10e9],
        [5e9, 4e9, 4e9],
        [0.25, 0.3, 0.3],
        1800.0,
    )
    .unwrap()
}

fn square_props<S: Scalar>(b: &[S]) -> Properties<S> {
    // laminate 0 with angle b[0] (one quadrant), laminate 1 with angle b[1] (the rest)
    let lam = |t: S| plies(tetragonal(), 0.004, &[t, -t * 0.5, t]).stiffness();
    Properties {
        sections: vec![],
        laminates: vec![lam(b[0]), lam(b[1])],
    }
}

fn square_model() -> (Mesh, Assembly) {
    // laminate 0 on the quadrant x, y < a/2, laminate 1 elsewhere. (A half-plate region would
    // not do: it is the 180° image of its complement, which acts as −I on the pair, so its
    // first-order perturbation of the pair is a multiple of the identity and cannot split it.)
    let n = 10;
    let mut mesh = Mesh::rectangle(0.5, 0.5, n, n, 0).unwrap();
    let nodes = mesh.nodes.clone();
    for el in mesh.elements.iter_mut() {
        if let fem::Element::Shell {
            nodes: en,
            property,
            ..
        } = el
        {
            let cx = en.iter().map(|&k| nodes[k].x).sum::<f64>() / 3.0;
            let cy = en.iter().map(|&k| nodes[k].y).sum::<f64>() / 3.0;
            *property = if cx < 0.25 && cy < 0.25 { 0 } else { 1 };
        }
    }
    let mut c = Constraints::new();
    let tol = 1e-9;
    let edges = [
        (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.5, 0.0, 0.0),
            true,
        ),
        (
            Vector3::new(0.0, 0.5, 0.0),
            Vector3::new(0.5, 0.5, 0.0),
            true,
        ),
        (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.0, 0.5, 0.0),
            false,
        ),
        (
            Vector3::new(0.5, 0.0, 0.0),
            Vector3::new(0.5, 0.5, 0.0),
            false,
        ),
    ];
    for (a, b, along_x) in edges {
        let line = mesh.nodes_on_segment(a, b, tol);
        c.pinned_line(&line, along_x, &[dof::UX, dof::UY]);
    }
    let asm = Assembly::new(&mesh, &c).unwrap();
    (mesh, asm)
}

fn square_values(mesh: &Mesh, asm: &Assembly, b: &[f64], count: usize) -> fem::Eigenpairs {
    let (k, m) = asm
        .values(
            mesh,
            &square_props(b),
            &ElementOptions::default(),
            MassKind::Consistent,
        )
        .unwrap();
    lowest_modes(&asm.matrix(k), &asm.matrix(m), count, &Default::default()).unwrap()
}

#[test]
fn repeated_pair_directional_derivatives_match_sorted_eigenvalue_differences() {
    let (mesh, asm) = square_model();
    // both halves at the same angle: a uniform tetragonal plate, symmetric under 90° rotations
    let b0 = [0.3, 0.3];
    let pairs = square_values(&mesh, &asm, &b0, 4);
    // modes 2 and 3 are a repeated pair (1,2)/(2,1)
    assert!(
        rel(pairs.values[2], pairs.values[1]) < 1e-9,
        "{:?}",
        pairs.values
    );
    assert!(rel(pairs.values[1], pairs.values[0]) > 0.5);
    let design = design_matrices::<2, _>(
        &mesh,
        &asm,
        &b0,
        square_props,
        &ElementOptions::default(),
        MassKind::Consistent,
    )
    .unwrap();
    for direction in [[1.0, 0.0], [0.3, -1.0], [1.0, 1.0]] {
        let dd = fem::directional_eigenvalue_derivatives(&pairs, &design, &direction);
        // one-sided differences of the sorted eigenvalues, Richardson-extrapolated
        let h = 1e-4;
        let at = |s: f64| {
            square_values(
                &mesh,
                &asm,
                &[b0[0] + s * direction[0], b0[1] + s * direction[1]],
                4,
            )
            .values
        };
        let (l1, l2) = (at(h), at(2.0 * h));
        let scale = dd.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        eprintln!("λ = {:?}, dd = {dd:?}", pairs.values);
        for i in 0..4 {
            let fd = 2.0 * (l1[i] - pairs.values[i]) / h - (l2[i] - pairs.values[i]) / (2.0 * h);
            eprintln!("  mode {i}: {} vs {fd}", dd[i]);
            assert!(
                (dd[i] - fd).abs() < 1e-6 * scale,
                "direction {direction:?} mode {i}: {} vs FD {fd}",
                dd[i]
            );
        }
        if direction == [1.0, 1.0] {
            // the same change everywhere keeps the 90° symmetry: the pair stays together
            assert!((dd[2] - dd[1]).abs() < 1e-9 * scale, "{dd:?}");
        } else {
            // the pair genuinely splits (the test would be vacuous otherwise)
            assert!(
                (dd[2] - dd[1]).abs() > 0.1 * scale,
                "direction {direction:?}: pair does not split: {dd:?}"
            );
        }
    }
}

#[test]
fn sparse_ldlt_nelson_path_matches_dense_path() {
    // a strip large enough for the sparse path, with a repeated-free spectrum
    let mesh = Mesh::rectangle(0.6, 0.08, 24, 4, 0).unwrap();
    let mut c = Constraints::new();
    let left = mesh.nodes_on_segment(Vector3::zeros(), Vector3::new(0.0, 0.08, 0.0), 1e-9);
    c.fix_nodes(&left, &dof::ALL);
    let asm = Assembly::new(&mesh, &c).unwrap();
    let opts = ElementOptions::default();
    let (k, m) = asm
        .values(&mesh, &strip_props(&B0), &opts, MassKind::Consistent)
        .unwrap();
    let (k, m) = (asm.matrix(k), asm.matrix(m));
    let pairs = lowest_modes(
        &k,
        &m,
        6,
        &fem::EigenOptions {
            method: fem::EigenMethod::Lanczos,
            ..Default::default()
        },
    )
    .unwrap();
    let dm = design_matrices::<3, _>(&mesh, &asm, &B0, strip_props, &opts, MassKind::Consistent)
        .unwrap();
    let sparse = fem::mode_derivatives_with(&k, &m, &pairs, &dm, true, None, false).unwrap();
    let dense = fem::mode_derivatives_with(&k, &m, &pairs, &dm, true, None, true).unwrap();
    for v in 0..3 {
        let (xs, xd) = (
            &sparse.eigenvectors.as_ref().unwrap()[v],
            &dense.eigenvectors.as_ref().unwrap()[v],
        );
        for i in 0..6 {
            let err = (xs.column(i) - xd.column(i)).norm() / xd.column(i).norm().max(1e-300);
            assert!(
                err < 1e-8,
                "var {v} mode {i}: sparse vs dense Nelson {err:e}"
            );
            assert_eq!(sparse.eigenvalues[v][i], dense.eigenvalues[v][i]);
        }
    }
}

/// The square plate at `b = [0.3, 0.3]` with its repeated pair: its matrices, lowest four
/// eigenpairs, design matrices and second-derivative terms along both variables.
struct SquarePair {
    mesh: Mesh,
    asm: Assembly,
    k: faer::sparse::SparseColMat<usize, f64>,
    m: faer::sparse::SparseColMat<usize, f64>,
    pairs: fem::Eigenpairs,
    dm: Vec<fem::DesignMatrices>,
    second: Vec<Vec<fem::sensitivity::SecondDerivatives>>,
}

fn square_pair() -> SquarePair {
    let (mesh, asm) = square_model();
    let b0 = [0.3, 0.3];
    let opts = ElementOptions::default();
    let pairs = square_values(&mesh, &asm, &b0, 4);
    let (k, m) = asm
        .values(&mesh, &square_props(&b0), &opts, MassKind::Consistent)
        .unwrap();
    let (k, m) = (asm.matrix(k), asm.matrix(m));
    let dm = design_matrices::<2, _>(&mesh, &asm, &b0, square_props, &opts, MassKind::Consistent)
        .unwrap();
    let second = fem::second_derivative_terms::<2, _>(
        &mesh,
        &asm,
        (&b0, &[true, true]),
        square_props,
        &opts,
        MassKind::Consistent,
        &pairs,
    )
    .unwrap();
    SquarePair {
        mesh,
        asm,
        k,
        m,
        pairs,
        dm,
        second,
    }
}

#[test]
fn repeated_pair_eigenvector_derivatives_follow_the_split_branches() {
    // Dailey: along variable 0 the pair splits; the derivative of the rotated basis ZΓ matches
    // central differences of the analytic eigenvector branches through the crossing
    let b0 = [0.3, 0.3];
    let SquarePair {
        mesh,
        asm,
        k,
        m,
        pairs,
        dm,
        second,
    } = square_pair();
    let with = fem::mode_derivatives(&k, &m, &pairs, &dm, true, Some(&second)).unwrap();
    let without = fem::mode_derivatives(&k, &m, &pairs, &dm, true, None).unwrap();
    let v = 0;
    let gamma = &with.rotations[v];
    let z = &pairs.vectors * gamma; // the rotated nominal basis
    let xb = &with.eigenvectors.as_ref().unwrap()[v];
    // branches at ±h, matched to the rotated nominal basis by M-overlap (the order of the pair
    // reverses for −h), signs aligned
    let branch = |s: f64| -> DMatrix<f64> {
        let mut b = b0;
        b[v] += s;
        let p = square_values(&mesh, &asm, &b, 4);
        let overlap = fem::eigen::project(&m, &z, &p.vectors);
        let mut out = DMatrix::zeros(z.nrows(), 4);
        for j in 0..4 {
            let (mut best, mut bi) = (0.0, 0);
            for i in 0..4 {
                if overlap[(j, i)].abs() > best {
                    best = overlap[(j, i)].abs();
                    bi = i;
                }
            }
            let sign = overlap[(j, bi)].signum();
            out.column_mut(j).copy_from(&(p.vectors.column(bi) * sign));
        }
        out
    };
    // the split of the pair at ±h is only h·Δλ_b: smaller steps drown the within-pair rotation
    // in the eigen solver's round-off (1e-5 gives 6 % error, 1e-4 gives 1e-3)
    let h = 1e-3;
    let (p1, m1, p2, m2) = (branch(h), branch(-h), branch(2.0 * h), branch(-2.0 * h));
    let fd = ((&p1 - &m1) / (2.0 * h) * 4.0 - (&p2 - &m2) / (4.0 * h)) / 3.0;
    let xw = &without.eigenvectors.as_ref().unwrap()[v];
    for j in 0..4 {
        let err = (xb.column(j) - fd.column(j)).norm() / xb.column(j).norm();
        eprintln!("mode {j}: |x_b − FD|/|x_b| = {err:e}");
        assert!(err < 1e-5, "mode {j}: {err:e}");
    }
    // without the second-derivative terms the pair's derivatives are wrong (the terms matter)
    let err_without = (xw.column(1) - fd.column(1)).norm() / fd.column(1).norm();
    assert!(err_without > 1e-3, "{err_without}");
}

/// Dailey's second-derivative terms are computed only for the variables that split a cluster
/// (`fem::splits_clusters`), and the others' derivatives do not read them: on the square plate
/// with its repeated pair, the quadrant's angle and the rest's split the pair, a common turn of
/// both (the plate stays tetragonal) keeps it together. The mode derivatives with the terms of
/// the splitting variables alone equal those with every variable's, bit for bit, and the
/// properties are evaluated at the perturbed designs of the splitting variables only.
#[test]
fn second_derivative_terms_only_for_the_variables_that_split_a_cluster() {
    let (mesh, asm) = square_model();
    // variables 0 and 1 as in `square_props`; variable 2 turns both laminates together
    let props = |b: &[Dual<4>]| square_props(&[b[0] + b[2], b[1] + b[2]]);
    let b0 = [0.3, 0.3, 0.0];
    let opts = ElementOptions::default();
    let pairs = square_values(&mesh, &asm, &[0.3, 0.3], 4);
    let (k, m) = asm
        .values(
            &mesh,
            &square_props(&[0.3, 0.3]),
            &opts,
            MassKind::Consistent,
        )
        .unwrap();
    let (k, m) = (asm.matrix(k), asm.matrix(m));
    let dm = design_matrices::<4, _>(&mesh, &asm, &b0, props, &opts, MassKind::Consistent).unwrap();
    let split = fem::splits_clusters(&pairs, &dm);
    assert_eq!(split, [true, true, false]);
    // the common turn moves the pair's eigenvalue together (a real change, not a null variable)
    let d = fem::mode_derivatives(&k, &m, &pairs, &dm, false, None).unwrap();
    assert_eq!(d.eigenvalues[2][1], d.eigenvalues[2][2]);
    assert!(
        d.eigenvalues[2][1].abs() > 1e-3 * pairs.values[1],
        "{:?}",
        d.eigenvalues[2]
    );
    let mut calls = 0;
    let mut counted = |b: &[Dual<4>]| {
        calls += 1;
        props(b)
    };
    let mode = MassKind::Consistent;
    let terms = |needed: &[bool], p: &mut dyn FnMut(&[Dual<4>]) -> Properties<Dual<4>>| {
        fem::second_derivative_terms::<4, _>(&mesh, &asm, (&b0, needed), p, &opts, mode, &pairs)
            .unwrap()
    };
    let only = terms(&split, &mut counted);
    assert_eq!(
        calls, 4,
        "two perturbed designs for each of the two splitting variables"
    );
    assert!(only[2].is_empty() && !only[0].is_empty() && !only[1].is_empty());
    let all = terms(&[true; 3], &mut |b: &[Dual<4>]| props(b));
    let with_only = fem::mode_derivatives(&k, &m, &pairs, &dm, true, Some(&only)).unwrap();
    let with_all = fem::mode_derivatives(&k, &m, &pairs, &dm, true, Some(&all)).unwrap();
    let without = fem::mode_derivatives(&k, &m, &pairs, &dm, true, None).unwrap();
    let vectors = |d: &fem::ModeDerivatives, v: usize| d.eigenvectors.as_ref().unwrap()[v].clone();
    for v in 0..3 {
        assert_eq!(
            vectors(&with_only, v),
            vectors(&with_all, v),
            "variable {v}"
        );
        assert_eq!(with_only.eigenvalues[v], with_all.eigenvalues[v]);
    }
    // the terms matter where they are computed, and not where they are skipped
    assert_ne!(vectors(&without, 0), vectors(&with_all, 0));
    assert_eq!(vectors(&without, 2), vectors(&with_all, 2));
}

/// The eigenvalue derivatives from element-by-element projections on the modes
/// (`analysis_eigenvalue_derivatives`, `Assembly::projected_tangents`, no derivative matrix
/// assembled) equal those of the assembled `K_b`, `M_b`: on the strip with lumped and
/// consistent mass, and on the square plate's repeated pair that the variables split (the
/// sorted derivatives and the rotation of the pair's basis).
#[test]
fn eigenvalue_derivatives_from_element_projections_equal_the_assembled_ones() {
    let same = |a: &fem::ModeDerivatives, b: &fem::ModeDerivatives, what: &str| {
        let scale = a
            .eigenvalues
            .iter()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a
            .eigenvalues
            .iter()
            .flatten()
            .zip(b.eigenvalues.iter().flatten())
        {
            assert!((x - y).abs() <= 1e-10 * scale, "{what}: {x} vs {y}");
        }
        for (x, y) in a.rotations.iter().zip(&b.rotations) {
            assert!((x - y).abs().max() <= 1e-8, "{what}: rotations {x} vs {y}");
        }
        assert!(b.eigenvectors.is_none());
    };
    for mass in [MassKind::Lumped, MassKind::Consistent] {
        let an = strip_analysis(&B0, mass);
        let (_, full) =
            analysis_derivatives::<2, _>(&strip(), &an, &B0, strip_props, ModeUpdate::Fixed)
                .unwrap();
        let fast =
            fem::analysis_eigenvalue_derivatives::<2, _>(&strip(), &an, &B0, strip_props).unwrap();
        same(&full, &fast, &format!("strip, {mass:?} mass"));
    }
    let (mesh, asm) = square_model();
    let b0 = [0.3, 0.3];
    let pairs = square_values(&mesh, &asm, &b0, 4);
    let opts = ElementOptions::default();
    let design =
        design_matrices::<2, _>(&mesh, &asm, &b0, square_props, &opts, MassKind::Consistent)
            .unwrap();
    let (k, m) = asm
        .values(&mesh, &square_props(&b0), &opts, MassKind::Consistent)
        .unwrap();
    let full = fem::mode_derivatives(&asm.matrix(k), &asm.matrix(m), &pairs, &design, false, None)
        .unwrap();
    let seeded = sens::seed_chunk::<2>(&b0, 0);
    let projected = asm
        .projected_tangents(
            &mesh,
            &square_props(&seeded),
            &opts,
            MassKind::Consistent,
            &pairs.vectors,
            &fem::sensitivity::clusters(&pairs.values, fem::sensitivity::CLUSTER_RTOL),
        )
        .unwrap();
    let fast = fem::eigenvalue_derivatives(&pairs, &projected);
    assert_eq!(fast.clusters, vec![vec![0], vec![1, 2], vec![3]]);
    // each variable alone splits the pair
    assert!(
        (fast.eigenvalues[0][2] - fast.eigenvalues[0][1]).abs()
            > 1e-3 * fast.eigenvalues[0][1].abs()
    );
    same(&full, &fast, "square plate, repeated pair");
}

/// The strip held only in its deflection along both end lines, its in-plane motion free
/// ([`ReferenceCondition::PartlyFree`]).
fn partly_free_analysis(b: &[f64]) -> fem::ModalAnalysis {
    let mut o = ModalOptions::new(5);
    o.reference = ReferenceCondition::PartlyFree;
    // node (i, j) of the 12 × 2 mesh is 13 j + i: the lines x = 0 and x = 0.3
    o.supports = [0, 12]
        .map(|i| fem::Support {
            nodes: (0..3).map(|j| 13 * j + i).collect(),
            dofs: vec![dof::UZ],
        })
        .to_vec();
    modal_analysis(&strip(), &strip_props(b), &o).unwrap()
}

/// A partly free body discards the three in-plane rigid modes its supports leave (its elastic
/// modes carry no in-plane momentum), and its eigenvalue and eigenvector derivatives match
/// Richardson-extrapolated central differences as a held body's do.
#[test]
fn partly_free_modes_and_derivatives_match_central_differences() {
    let an = partly_free_analysis(&B0);
    assert_eq!(an.n_rigid, 3);
    assert!(an.pairs.values[0] > 1e-3 * an.pairs.values[4]);
    let p = an.n_modes;
    let x0 = an.pairs.vectors.columns(0, p).into_owned();
    let n = strip().nodes.len();
    for d in [dof::UX, dof::UY] {
        let mut r = vec![0.0; 6 * n];
        (0..n).for_each(|k| r[6 * k + d] = 1.0);
        let r = DMatrix::from_column_slice(
            an.assembly.n_free(),
            1,
            an.assembly.restrict(&r).as_slice(),
        );
        let mr = fem::eigen::project(&an.m, &x0, &r);
        let total = fem::eigen::project(&an.m, &r, &r)[(0, 0)];
        for i in 0..p {
            assert!(
                mr[(i, 0)].abs() < 1e-9 * total.sqrt(),
                "mode {i} carries momentum along dof {d}: {}",
                mr[(i, 0)]
            );
        }
    }
    let (_, d) =
        analysis_derivatives::<3, _>(&strip(), &an, &B0, strip_props, ModeUpdate::Updated).unwrap();
    let xb = d.eigenvectors.as_ref().unwrap();
    let h = 1e-3;
    for k in 0..3 {
        let at = |s: f64| {
            let mut b = B0;
            b[k] += s;
            partly_free_analysis(&b)
        };
        let (ap, am, ap2, am2) = (at(h), at(-h), at(2.0 * h), at(-2.0 * h));
        for i in 0..p {
            let fd = (4.0 * (ap.pairs.values[i] - am.pairs.values[i]) / (2.0 * h)
                - (ap2.pairs.values[i] - am2.pairs.values[i]) / (4.0 * h))
                / 3.0;
            let got = d.eigenvalues[k][i];
            let scale = (0..3)
                .map(|v| d.eigenvalues[v][i].abs())
                .fold(0.0, f64::max);
            assert!(
                (got - fd).abs() <= 1e-6 * scale,
                "var {k} mode {i}: λ_b {got} vs FD {fd}"
            );
        }
        let cols =
            |a: &fem::ModalAnalysis| aligned(&a.pairs.vectors.columns(0, p).into_owned(), &x0);
        let fd = ((cols(&ap) - cols(&am)) / (2.0 * h) * 4.0
            - (cols(&ap2) - cols(&am2)) / (4.0 * h))
            / 3.0;
        for i in 0..p {
            let scale = (0..3).map(|v| xb[v].column(i).norm()).fold(0.0, f64::max);
            let err = (xb[k].column(i) - fd.column(i)).norm() / scale;
            assert!(
                err < 1e-6,
                "var {k} mode {i}: |x_b − FD|/max|x_b| = {err:e}"
            );
        }
    }
}

/// `K_b`, `M_b` of a variable that moves only a region's elements (the square's quadrant or
/// its complement), assembled from the moved elements alone ([`Assembly::tangent_values`]),
/// equal central differences of the whole assembly, zeros included where the region has no
/// entry; and an element moves exactly when its property carries a tangent.
#[test]
fn design_matrices_of_a_region_equal_central_differences_of_the_assembly() {
    let (mesh, asm) = square_model();
    let opts = ElementOptions::default();
    let b0 = [0.3, -0.4];
    for mass in [MassKind::Consistent, MassKind::Lumped] {
        let dm = design_matrices::<1, _>(&mesh, &asm, &b0, square_props, &opts, mass).unwrap();
        for (j, d) in dm.iter().enumerate() {
            let seeded = sens::seed_chunk::<1>(&b0, j);
            let props = square_props(&seeded);
            let moved = (mesh.elements.iter())
                .filter(|el| props.moves(el))
                .map(|el| match el {
                    fem::Element::Shell { property, .. } => *property,
                    fem::Element::Beam { .. } => unreachable!("a shell mesh"),
                });
            assert!(moved.clone().count() > 0 && moved.clone().all(|p| p == j));
            let h = 1e-6;
            let at = |s: f64| {
                let mut b = b0;
                b[j] += s;
                let (k, m) = asm.values(&mesh, &square_props(&b), &opts, mass).unwrap();
                (dense(&asm.matrix(k)), dense(&asm.matrix(m)))
            };
            let ((kp, mp), (km, mm)) = (at(h), at(-h));
            for (exact, plus, minus, stiffness) in [(&d.k, &kp, &km, true), (&d.m, &mp, &mm, false)]
            {
                let exact = dense(exact);
                let scale = plus.iter().fold(0.0f64, |a, b| a.max(b.abs()));
                let mut nonzero = 0;
                for i in 0..exact.len() {
                    let fd = (plus[i] - minus[i]) / (2.0 * h);
                    assert!(
                        (exact[i] - fd).abs() <= 1e-8 * scale,
                        "variable {j}, entry {i}: {} vs {fd}",
                        exact[i]
                    );
                    nonzero += (exact[i] != 0.0) as usize;
                }
                // the angle moves its region's stiffness (not its mass: the plies' masses do
                // not turn)
                assert_eq!(nonzero > 0, stiffness, "variable {j}: {nonzero} entries");
            }
        }
    }
}

/// `Σ_i ȳ_iᵀ x_{i,b}` of the eigenvector derivatives of `d` in the basis of the values
/// (`X_b Γᵀ`), per variable: what [`fem::eigenvector_adjoint`] computes without them.
fn contracted(d: &fem::ModeDerivatives, ybar: &DMatrix<f64>) -> Vec<f64> {
    let xb = d.eigenvectors.as_ref().expect("eigenvector derivatives");
    (xb.iter().zip(&d.rotations))
        .map(|(x, g)| (x * g.transpose()).dot(ybar))
        .collect()
}

/// Deterministic adjoints of all sizes and signs, zero for the modes in `skip`.
fn some_adjoints(n: usize, p: usize, skip: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(n, p, |i, j| {
        if skip.contains(&j) {
            0.0
        } else {
            ((i * 7 + j * 13) as f64 * 0.731).sin() * (1.0 + j as f64)
        }
    })
}

fn assert_contractions_agree(adjoint: &[f64], direct: &[f64]) {
    let scale = direct.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(scale > 0.0, "the contractions vanish");
    for (v, (a, d)) in adjoint.iter().zip(direct).enumerate() {
        assert!(
            (a - d).abs() < 1e-10 * scale,
            "variable {v}: adjoint {a:e}, Nelson's derivatives {d:e}"
        );
    }
}

/// The strip's laminate with two ply angles `b[0]`, `b[1]` and the total thickness `b[2]`
/// (which moves the mass too).
fn strip_props_thickness<S: Scalar>(b: &[S]) -> Properties<S> {
    let ply = |angle: S| Ply {
        material: paper_material(),
        thickness: b[2] * 0.5,
        angle,
    };
    Properties {
        sections: vec![],
        laminates: vec![
            PlyStack::new(vec![ply(b[0]), ply(b[1])])
                .unwrap()
                .stiffness(),
        ],
    }
}

#[test]
fn eigenvector_adjoint_equals_the_contracted_nelson_derivatives() {
    // distinct eigenvalues: the dense path (a small strip) and the sparse LDLᵀ one (a larger
    // strip), one mode's adjoint zero; two ply angles and the thickness
    let b0 = [0.5, -0.8, 0.01];
    for (nx, ny) in [(12, 2), (24, 4)] {
        let mesh = Mesh::rectangle(0.6, 0.08, nx, ny, 0).unwrap();
        let mut c = Constraints::new();
        let left = mesh.nodes_on_segment(Vector3::zeros(), Vector3::new(0.0, 0.08, 0.0), 1e-9);
        c.fix_nodes(&left, &dof::ALL);
        let asm = Assembly::new(&mesh, &c).unwrap();
        let opts = ElementOptions::default();
        let (k, m) = asm
            .values(
                &mesh,
                &strip_props_thickness(&b0),
                &opts,
                MassKind::Consistent,
            )
            .unwrap();
        let (k, m) = (asm.matrix(k), asm.matrix(m));
        let pairs = lowest_modes(&k, &m, 5, &Default::default()).unwrap();
        let (props, mass) = (strip_props_thickness, MassKind::Consistent);
        let dm = design_matrices::<3, _>(&mesh, &asm, &b0, props, &opts, mass).unwrap();
        assert!(
            dm[2].m.val().iter().any(|&x| x != 0.0),
            "the thickness moves the mass"
        );
        let d = fem::mode_derivatives(&k, &m, &pairs, &dm, true, None).unwrap();
        let ybar = some_adjoints(k.nrows(), 5, &[2]);
        let adjoint = fem::eigenvector_adjoint(&k, &m, &pairs, &dm, &ybar, None).unwrap();
        assert_contractions_agree(&adjoint, &contracted(&d, &ybar));
    }
}

#[test]
fn eigenvector_adjoint_of_a_split_pair_equals_the_contracted_dailey_derivatives() {
    // the square plate's repeated pair, split by variable 0 (Dailey's terms) and kept together
    // by variable 1
    let SquarePair {
        k,
        m,
        pairs,
        dm,
        second,
        ..
    } = square_pair();
    assert!(
        fem::sensitivity::has_repeated(&pairs),
        "the square has a repeated pair"
    );
    let d = fem::mode_derivatives(&k, &m, &pairs, &dm, true, Some(&second)).unwrap();
    let ybar = some_adjoints(k.nrows(), 4, &[]);
    let adjoint = fem::eigenvector_adjoint(&k, &m, &pairs, &dm, &ybar, Some(&second)).unwrap();
    assert_contractions_agree(&adjoint, &contracted(&d, &ybar));
}
