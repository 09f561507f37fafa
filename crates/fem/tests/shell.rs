//! Shell triangle: patch tests, thin-plate limit, laminated plates against Navier FSDT,
//! orthonormality of modes, dense vs Lanczos.

mod common;

use common::{navier_fsdt, paper_material, rel, stack};
use fem::{
    Assembly, Constraints, EigenMethod, EigenOptions, ElementOptions, MassKind, Mesh, Properties,
    dof, lowest_modes,
};
use laminate::{LaminateStiffness, OrthotropicMaterial};
use nalgebra::{DMatrix, DVector, Vector3};

fn iso_plate(h: f64) -> LaminateStiffness<f64> {
    let m = OrthotropicMaterial::isotropic(70e9, 0.3, 2700.0).unwrap();
    stack(m, h, &[0.0]).stiffness()
}

/// A distorted patch: 5 × 5 nodes on [0, 1] × [0, 0.8], interior nodes moved irregularly.
fn distorted_patch() -> (Mesh, Vec<usize>) {
    let mut mesh = Mesh::rectangle(1.0, 0.8, 4, 4, 0).unwrap();
    let mut boundary = Vec::new();
    for (k, p) in mesh.nodes.iter_mut().enumerate() {
        let (i, j) = (k % 5, k / 5);
        if i == 0 || i == 4 || j == 0 || j == 4 {
            boundary.push(k);
        } else {
            p.x += 0.07 * ((3 * k) as f64).sin();
            p.y += 0.06 * ((5 * k + 1) as f64).cos();
        }
    }
    (mesh, boundary)
}

/// Impose `exact` (6 values per node) on the boundary nodes, solve for the interior, and return
/// the largest interior error relative to the largest exact value.
fn patch_error(
    mesh: &Mesh,
    boundary: &[usize],
    lam: &LaminateStiffness<f64>,
    exact: impl Fn(&Vector3<f64>) -> [f64; 6],
) -> f64 {
    patch_error_with(mesh, boundary, lam, &ElementOptions::default(), exact)
}

fn patch_error_with(
    mesh: &Mesh,
    boundary: &[usize],
    lam: &LaminateStiffness<f64>,
    opts: &ElementOptions,
    exact: impl Fn(&Vector3<f64>) -> [f64; 6],
) -> f64 {
    let asm = Assembly::new(mesh, &Constraints::new()).unwrap();
    let props = Properties {
        sections: vec![],
        laminates: vec![lam.clone()],
    };
    let (kv, _) = asm
        .values(mesh, &props, opts, MassKind::Consistent)
        .unwrap();
    let k = asm.matrix(kv);
    let n = asm.n_free();
    let mut kd = DMatrix::<f64>::zeros(n, n);
    let cp = k.symbolic().col_ptr();
    let ri = k.symbolic().row_idx();
    for j in 0..n {
        for p in cp[j]..cp[j + 1] {
            kd[(ri[p], j)] = k.val()[p];
        }
    }
    let q_exact: Vec<f64> = mesh.nodes.iter().flat_map(exact).collect();
    let is_b: Vec<bool> = (0..n).map(|d| boundary.contains(&(d / 6))).collect();
    let free: Vec<usize> = (0..n).filter(|&d| !is_b[d]).collect();
    let fixed: Vec<usize> = (0..n).filter(|&d| is_b[d]).collect();
    let kff = DMatrix::from_fn(free.len(), free.len(), |i, j| kd[(free[i], free[j])]);
    let kfb = DMatrix::from_fn(free.len(), fixed.len(), |i, j| kd[(free[i], fixed[j])]);
    let qb = DVector::from_iterator(fixed.len(), fixed.iter().map(|&d| q_exact[d]));
    let qf = kff.lu().solve(&(-(kfb * qb))).unwrap();
    let scale = q_exact.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    free.iter()
        .enumerate()
        .map(|(i, &d)| (qf[i] - q_exact[d]).abs())
        .fold(0.0, f64::max)
        / scale
}

fn unsymmetric_laminate() -> LaminateStiffness<f64> {
    stack(paper_material(), 0.004, &[0.0, 30.0, -60.0]).stiffness()
}

#[test]
fn membrane_patch_test_on_distorted_mesh() {
    let (mesh, boundary) = distorted_patch();
    for (lam, membrane) in [
        (iso_plate(0.01), fem::Membrane::Allman),
        (unsymmetric_laminate(), fem::Membrane::Allman),
        (unsymmetric_laminate(), fem::Membrane::Cst),
    ] {
        // u = 1e-3 (1 + 2x + 3y), v = 1e-3 (−1 + 0.5x − 4y); drilling = in-plane rotation
        let opts = ElementOptions {
            membrane,
            ..Default::default()
        };
        let err = patch_error_with(&mesh, &boundary, &lam, &opts, |p| {
            let (u, v) = (
                1e-3 * (1.0 + 2.0 * p.x + 3.0 * p.y),
                1e-3 * (-1.0 + 0.5 * p.x - 4.0 * p.y),
            );
            let omega = 0.5 * 1e-3 * (0.5 - 3.0);
            [u, v, 0.0, 0.0, 0.0, omega]
        });
        assert!(err < 1e-10, "membrane patch error {err:e}");
    }
}

#[test]
fn constant_curvature_patch_test_on_distorted_mesh() {
    let (mesh, boundary) = distorted_patch();
    for lam in [iso_plate(0.01), iso_plate(0.0001), unsymmetric_laminate()] {
        // β = ∇φ, φ = ½kx x² + kxy xy + ½ky y², w = −φ: constant curvature, zero shear
        let (kx, ky, kxy) = (2e-3, -1e-3, 1.5e-3);
        let err = patch_error(&mesh, &boundary, &lam, |p| {
            let phi = 0.5 * kx * p.x * p.x + kxy * p.x * p.y + 0.5 * ky * p.y * p.y;
            let (bx, by) = (kx * p.x + kxy * p.y, kxy * p.x + ky * p.y);
            // β_x = θ_y, β_y = −θ_x
            [0.0, 0.0, -phi, -by, bx, 0.0]
        });
        assert!(err < 1e-9, "bending patch error {err:e}");
    }
}

#[test]
fn patch_test_fails_for_a_wrong_field() {
    // guard: a non-equilibrium field (quadratic membrane) is not reproduced
    let (mesh, boundary) = distorted_patch();
    let err = patch_error(&mesh, &boundary, &iso_plate(0.01), |p| {
        [1e-3 * p.x * p.x, 0.0, 0.0, 0.0, 0.0, 0.0]
    });
    assert!(err > 1e-6, "{err}");
}

/// Simply supported rectangular plate model: hard supports on all four edges.
/// `in_plane`: "ss1" fixes the tangential in-plane displacement on each edge, "ss2" the
/// normal one, "all" both.
fn ss_plate(
    a: f64,
    b: f64,
    n: usize,
    lam: LaminateStiffness<f64>,
    in_plane: &str,
) -> (Mesh, Assembly, Properties<f64>) {
    let mesh = Mesh::rectangle(a, b, n, n, 0).unwrap();
    let tol = 1e-9 * a;
    let y0 = mesh.nodes_on_segment(Vector3::zeros(), Vector3::new(a, 0.0, 0.0), tol);
    let y1 = mesh.nodes_on_segment(Vector3::new(0.0, b, 0.0), Vector3::new(a, b, 0.0), tol);
    let x0 = mesh.nodes_on_segment(Vector3::zeros(), Vector3::new(0.0, b, 0.0), tol);
    let x1 = mesh.nodes_on_segment(Vector3::new(a, 0.0, 0.0), Vector3::new(a, b, 0.0), tol);
    let mut c = Constraints::new();
    let (on_x_edges, on_y_edges): (&[usize], &[usize]) = match in_plane {
        "ss1" => (&[dof::UY], &[dof::UX]),
        "ss2" => (&[dof::UX], &[dof::UY]),
        _ => (&[dof::UX, dof::UY], &[dof::UX, dof::UY]),
    };
    for line in [&y0, &y1] {
        c.pinned_line(line, true, on_y_edges);
    }
    for line in [&x0, &x1] {
        c.pinned_line(line, false, on_x_edges);
    }
    let asm = Assembly::new(&mesh, &c).unwrap();
    (
        mesh,
        asm,
        Properties {
            sections: vec![],
            laminates: vec![lam],
        },
    )
}

fn first_eigenvalue(
    mesh: &Mesh,
    asm: &Assembly,
    props: &Properties<f64>,
    count: usize,
) -> Vec<f64> {
    let (k, m) = consistent_matrices(mesh, asm, props);
    lowest_modes(&k, &m, count, &EigenOptions::default())
        .unwrap()
        .values
}

#[test]
fn thin_isotropic_plate_matches_kirchhoff_without_locking() {
    let (a, h) = (1.0f64, 1e-3f64); // a/h = 1000
    let lam = iso_plate(h);
    let d = 70e9 * h.powi(3) / (12.0 * (1.0 - 0.09));
    let kirchhoff = std::f64::consts::PI.powi(4) * 4.0 / a.powi(4) * d / (2700.0 * h);
    let (mesh, asm, props) = ss_plate(a, a, 24, lam, "all");
    let l = first_eigenvalue(&mesh, &asm, &props, 1);
    let err = rel(l[0].sqrt(), kirchhoff.sqrt());
    eprintln!("thin plate: ω₁ error {err:.3e}");
    assert!(
        err < 0.01,
        "ω₁² = {} vs Kirchhoff {kirchhoff}: {err:.2e}",
        l[0]
    );
}

fn laminated_case(angles: &[f64], a_over_h: f64, ss: &str, n: usize) -> (f64, f64) {
    let a = 1.0;
    let h = a / a_over_h;
    let st = stack(paper_material(), h, angles);
    let lam = st.stiffness();
    let navier = navier_fsdt(&lam, a, a, 3, ss == "ss2");
    let (mesh, asm, props) = ss_plate(a, a, n, lam, ss);
    let l = first_eigenvalue(&mesh, &asm, &props, 1);
    (l[0], navier)
}

#[test]
fn cross_ply_plates_match_navier_fsdt() {
    for a_over_h in [10.0, 100.0] {
        let (fe, navier) = laminated_case(&[0.0, 90.0, 90.0, 0.0], a_over_h, "ss1", 16);
        let err = rel(fe.sqrt(), navier.sqrt());
        eprintln!("[0/90/90/0] a/h = {a_over_h}: error {err:.3e}");
        assert!(
            err < 0.02,
            "a/h = {a_over_h}: ω₁² {fe} vs Navier {navier}: {err:.2e}"
        );
    }
}

#[test]
fn antisymmetric_angle_ply_plates_match_navier_fsdt() {
    for a_over_h in [10.0, 100.0] {
        let (fe, navier) = laminated_case(&[45.0, -45.0, 45.0, -45.0], a_over_h, "ss2", 16);
        let err = rel(fe.sqrt(), navier.sqrt());
        eprintln!("[45/-45/45/-45] a/h = {a_over_h}: error {err:.3e}");
        assert!(
            err < 0.02,
            "a/h = {a_over_h}: ω₁² {fe} vs Navier {navier}: {err:.2e}"
        );
    }
}

#[test]
fn navier_oracle_reduces_to_kirchhoff_for_thin_isotropic_plates() {
    let h = 1e-3;
    let l = navier_fsdt(&iso_plate(h), 1.0, 1.0, 2, false);
    let d = 70e9 * h.powi(3) / (12.0 * (1.0 - 0.09));
    let kirchhoff = std::f64::consts::PI.powi(4) * 4.0 * d / (2700.0 * h);
    assert!(rel(l, kirchhoff) < 1e-5, "{l} vs {kirchhoff}");
}

#[test]
fn modes_are_mass_orthonormal_dense_and_lanczos_agree() {
    let lam = stack(paper_material(), 0.002, &[30.0, -45.0]).stiffness();
    let (mesh, asm, props) = ss_plate(0.3, 0.2, 8, lam, "all");
    for mass in [MassKind::Consistent, MassKind::Lumped] {
        let (k, m) = asm
            .values(&mesh, &props, &ElementOptions::default(), mass)
            .unwrap();
        let (k, m) = (asm.matrix(k), asm.matrix(m));
        let mut results = Vec::new();
        for method in [EigenMethod::Dense, EigenMethod::Lanczos] {
            let pairs = lowest_modes(
                &k,
                &m,
                10,
                &EigenOptions {
                    method,
                    ..Default::default()
                },
            )
            .unwrap();
            let x = &pairs.vectors;
            let xmx = fem::eigen::project(&m, x, x);
            let xkx = fem::eigen::project(&k, x, x);
            let lmax = pairs.values[9];
            let ortho = (xmx - DMatrix::<f64>::identity(10, 10)).abs().max();
            let stiff = (xkx - DMatrix::from_diagonal(&DVector::from_vec(pairs.values.clone())))
                .abs()
                .max()
                / lmax;
            assert!(ortho < 1e-10, "{method:?} {mass:?}: |XᵀMX − I| = {ortho:e}");
            assert!(
                stiff < 1e-10,
                "{method:?} {mass:?}: |XᵀKX − Λ|/λmax = {stiff:e}"
            );
            // residual of the eigen-equation
            let mut r = 0.0f64;
            for i in 0..10 {
                let xi = x.column(i).into_owned();
                let mut kx = vec![0.0; xi.len()];
                let mut mx = vec![0.0; xi.len()];
                fem::eigen::spmv(&k, xi.as_slice(), &mut kx);
                fem::eigen::spmv(&m, xi.as_slice(), &mut mx);
                let res: f64 = kx
                    .iter()
                    .zip(&mx)
                    .map(|(a, b)| (a - pairs.values[i] * b).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let nk: f64 = kx.iter().map(|a| a * a).sum::<f64>().sqrt();
                r = r.max(res / nk);
            }
            assert!(r < 1e-7, "{method:?}: eigen residual {r:e}");
            results.push(pairs.values);
        }
        for i in 0..10 {
            assert!(
                rel(results[1][i], results[0][i]) < 1e-9,
                "{mass:?} mode {i}: {} vs {}",
                results[1][i],
                results[0][i]
            );
        }
    }
}

type Csc = faer::sparse::SparseColMat<usize, f64>;

/// Stiffness and consistent mass of a plate.
fn consistent_matrices(mesh: &Mesh, asm: &Assembly, props: &Properties<f64>) -> (Csc, Csc) {
    let (k, m) = asm
        .values(
            mesh,
            props,
            &ElementOptions::default(),
            MassKind::Consistent,
        )
        .unwrap();
    (asm.matrix(k), asm.matrix(m))
}

/// Stiffness and consistent mass of a simply supported aluminium plate, 0.4 m square, 4 mm,
/// 10 × 10 cells: its modes (1,2)/(2,1) and (1,3)/(3,1) are repeated pairs.
fn square_plate_matrices() -> (Csc, Csc) {
    let (mesh, asm, props) = ss_plate(0.4, 0.4, 10, iso_plate(0.004), "all");
    consistent_matrices(&mesh, &asm, &props)
}

/// The largest `|XᵀMX − I|`, `|XᵀKX − Λ|/λ_max` and relative eigen-equation residual of a set
/// of modes.
fn mode_errors(
    k: &faer::sparse::SparseColMat<usize, f64>,
    m: &faer::sparse::SparseColMat<usize, f64>,
    pairs: &fem::Eigenpairs,
) -> (f64, f64, f64) {
    let x = &pairs.vectors;
    let p = pairs.values.len();
    let lmax = pairs.values[p - 1].abs();
    let ortho = (fem::eigen::project(m, x, x) - DMatrix::<f64>::identity(p, p))
        .abs()
        .max();
    let stiff = (fem::eigen::project(k, x, x)
        - DMatrix::from_diagonal(&DVector::from_vec(pairs.values.clone())))
    .abs()
    .max()
        / lmax;
    let mut residual = 0.0f64;
    for i in 0..p {
        let xi = x.column(i).into_owned();
        let (mut kx, mut mx) = (vec![0.0; xi.len()], vec![0.0; xi.len()]);
        fem::eigen::spmv(k, xi.as_slice(), &mut kx);
        fem::eigen::spmv(m, xi.as_slice(), &mut mx);
        let r = kx
            .iter()
            .zip(&mx)
            .map(|(a, b)| (a - pairs.values[i] * b).powi(2))
            .sum::<f64>()
            .sqrt();
        let scale = mx.iter().map(|a| a * a).sum::<f64>().sqrt() * lmax;
        residual = residual.max(r / scale);
    }
    (ortho, stiff, residual)
}

/// Block Lanczos finds the modes of the dense solver whatever its block: a simply supported
/// square plate (repeated pairs (1,2)/(2,1), (1,3)/(3,1)), with enough modes asked to need a
/// restart, and a free-free plate (six zero eigenvalues).
#[test]
fn block_lanczos_agrees_with_dense_for_every_block_size() {
    let square = {
        let (k, m) = square_plate_matrices();
        (k, m, 30)
    };
    let free = {
        let mesh = Mesh::rectangle(0.6, 0.3, 10, 5, 0).unwrap();
        let asm = Assembly::new(&mesh, &Constraints::new()).unwrap();
        let props = Properties {
            sections: vec![],
            laminates: vec![iso_plate(0.004)],
        };
        let (k, m) = consistent_matrices(&mesh, &asm, &props);
        (k, m, 12)
    };
    for (name, (k, m, p)) in [("square", square), ("free-free", free)] {
        let opts = |method, block| EigenOptions {
            method,
            block,
            ..Default::default()
        };
        let dense = lowest_modes(&k, &m, p, &opts(EigenMethod::Dense, None)).unwrap();
        let scale = dense.values[p - 1];
        for block in [None, Some(1), Some(2), Some(3), Some(4), Some(7)] {
            let pairs = lowest_modes(&k, &m, p, &opts(EigenMethod::Lanczos, block)).unwrap();
            for i in 0..p {
                let err = (pairs.values[i] - dense.values[i]).abs() / scale;
                assert!(
                    err < 1e-10,
                    "{name}, block {block:?}, mode {i}: {} vs dense {}",
                    pairs.values[i],
                    dense.values[i]
                );
            }
            let (ortho, stiff, residual) = mode_errors(&k, &m, &pairs);
            assert!(
                ortho < 1e-10 && stiff < 1e-10 && residual < 1e-8,
                "{name}, block {block:?}: |XᵀMX − I| {ortho:e}, |XᵀKX − Λ| {stiff:e}, \
                 residual {residual:e}"
            );
        }
    }
}

/// Repeated modes get a basis fixed by their span: a square plate's pairs, computed by three
/// solvers that return different bases within each pair (and turned by an arbitrary rotation),
/// come out the same after `canonical_cluster_bases`, still M-orthonormal and K-diagonal.
#[test]
fn repeated_modes_get_a_basis_fixed_by_their_span() {
    let (k, m) = square_plate_matrices();
    let p = 10;
    let solve = |method, block| {
        let opts = EigenOptions {
            method,
            block,
            ..Default::default()
        };
        lowest_modes(&k, &m, p, &opts).unwrap()
    };
    let mut turned = solve(EigenMethod::Dense, None);
    let clusters = fem::sensitivity::clusters(&turned.values, fem::sensitivity::CLUSTER_RTOL);
    let pairs: Vec<&Vec<usize>> = clusters.iter().filter(|g| g.len() == 2).collect();
    assert!(
        pairs.len() >= 2,
        "the square plate's repeated pairs: {clusters:?}"
    );
    for (n, g) in pairs.iter().enumerate() {
        let (c, s) = ((0.3 + n as f64).cos(), (0.3 + n as f64).sin());
        let (a, b) = (
            turned.vectors.column(g[0]).into_owned(),
            turned.vectors.column(g[1]).into_owned(),
        );
        turned
            .vectors
            .column_mut(g[0])
            .copy_from(&(&a * c + &b * s));
        turned
            .vectors
            .column_mut(g[1])
            .copy_from(&(&b * c - &a * s));
    }
    let mut sets = vec![
        solve(EigenMethod::Dense, None),
        solve(EigenMethod::Lanczos, Some(1)),
        solve(EigenMethod::Lanczos, Some(4)),
        turned,
    ];
    // before: the bases of a pair differ between the solvers
    let gap = |x: &DMatrix<f64>, y: &DMatrix<f64>, j: usize| {
        (x.column(j) - y.column(j)).abs().max() / x.column(j).abs().max()
    };
    assert!(
        pairs
            .iter()
            .any(|g| gap(&sets[0].vectors, &sets[3].vectors, g[0]) > 0.1),
        "the rotation must change the basis"
    );
    for set in &mut sets {
        fem::eigen::canonical_cluster_bases(set, fem::sensitivity::CLUSTER_RTOL);
        let (ortho, stiff, residual) = mode_errors(&k, &m, set);
        assert!(ortho < 1e-10 && stiff < 1e-10 && residual < 1e-8);
    }
    for set in &sets[1..] {
        for j in 0..p {
            let d = gap(&sets[0].vectors, &set.vectors, j);
            assert!(d < 1e-6, "mode {j}: canonical bases differ by {d:e}");
        }
    }
}

/// An operator with thirteen distinct eigenvalues, the last 288 times: the Krylov space of a
/// block closes after a few steps, and the iteration must continue with fresh directions
/// (orthogonal to everything, no division by a vanished norm) to fill its basis, then find
/// the twelve lowest modes.
#[test]
fn block_lanczos_continues_past_an_invariant_subspace() {
    let n = 300;
    let diag = |f: &dyn Fn(usize) -> f64| {
        let t: Vec<faer::sparse::Triplet<usize, usize, f64>> = (0..n)
            .map(|i| faer::sparse::Triplet::new(i, i, f(i)))
            .collect();
        faer::sparse::SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &t).unwrap()
    };
    // K x = λ M x with diagonal K, M: λ_i = K_ii / M_ii, here i + 1 for the first twelve
    // unknowns (scattered by a permutation) and 100 for the others
    let place = |i: usize| (i * 37) % n;
    let lambda = |j: usize| {
        let i = (0..n).find(|&i| place(i) == j).unwrap();
        if i < 12 { (i + 1) as f64 } else { 100.0 }
    };
    let mass = |j: usize| 1.0 + 0.5 * ((j * 7) % 3) as f64;
    let k = diag(&|j| lambda(j) * mass(j));
    let m = diag(&mass);
    let exact: Vec<f64> = (1..=12).map(|i| i as f64).collect();
    for block in [Some(1), Some(4)] {
        let pairs = lowest_modes(
            &k,
            &m,
            12,
            &EigenOptions {
                method: EigenMethod::Lanczos,
                block,
                ..Default::default()
            },
        )
        .unwrap();
        for i in 0..12 {
            assert!(
                (pairs.values[i] - exact[i]).abs() < 1e-12,
                "block {block:?}, mode {i}: {} vs {}",
                pairs.values[i],
                exact[i]
            );
        }
        let (ortho, stiff, residual) = mode_errors(&k, &m, &pairs);
        assert!(ortho < 1e-12 && stiff < 1e-12 && residual < 1e-12);
    }
}

#[test]
fn free_free_plate_has_six_rigid_modes_and_no_spurious_ones() {
    let lam = iso_plate(0.01);
    let mesh = Mesh::rectangle(1.0, 0.5, 6, 3, 0).unwrap();
    let asm = Assembly::new(&mesh, &Constraints::new()).unwrap();
    let props = Properties {
        sections: vec![],
        laminates: vec![lam],
    };
    let (k, m) = asm
        .values(&mesh, &props, &ElementOptions::default(), MassKind::Lumped)
        .unwrap();
    let pairs = lowest_modes(
        &asm.matrix(k),
        &asm.matrix(m),
        8,
        &EigenOptions {
            method: EigenMethod::Lanczos,
            ..Default::default()
        },
    )
    .unwrap();
    let l7 = pairs.values[6];
    assert!(
        pairs.values[..6].iter().all(|l| l.abs() < 1e-8 * l7),
        "{:?}",
        pairs.values
    );
    assert!(
        pairs.values[6] > 1e-3 * pairs.values[7],
        "{:?}",
        pairs.values
    );
}

#[test]
fn gmsh_v4_text_is_parsed() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n$EndNodes\n$Elements\n2 3 1 3\n1 1 1 1\n1 1 2\n2 1 2 2\n2 1 2 3\n3 1 3 4\n$EndElements\n";
    let g = fem::parse_gmsh_v4(text).unwrap();
    assert_eq!(g.nodes.len(), 4);
    assert_eq!(g.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(g.entity, vec![1, 1]);
    let mesh = g.to_mesh(0, Vector3::x());
    assert_eq!(mesh.elements.len(), 2);
    let by = g.to_mesh_by_entity(|e| if e == 1 { 3 } else { 0 }, Vector3::x());
    assert!(matches!(
        by.elements[1],
        fem::Element::Shell { property: 3, .. }
    ));
    // errors carry the line number
    let bad = text.replace("1 1 0\n0 1 0", "1 x 0\n0 1 0");
    match fem::parse_gmsh_v4(&bad) {
        Err(fem::MeshError::Gmsh { line, .. }) => assert_eq!(line, 13),
        other => panic!("{other:?}"),
    }
}

/// Counts read from a Gmsh file reserve no memory before their lines are read: a crafted
/// header is an error with its line, not an allocation abort.
#[test]
fn a_gmsh_header_with_an_absurd_node_count_is_an_error_not_an_abort() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 100000000000000 1 \
                100000000000000\n2 1 0 100000000000000000\n1\n$EndNodes\n";
    assert!(matches!(
        fem::parse_gmsh_v4(text),
        Err(fem::MeshError::Gmsh { .. })
    ));
}

#[test]
fn frequencies_do_not_depend_on_the_orientation_in_space() {
    // a free-free laminated plate and a free-free beam, rotated arbitrarily in space (consistent
    // mass): same spectrum as in the reference position
    let r = nalgebra::Rotation3::from_euler_angles(0.4, -0.7, 1.1);
    let lam = stack(paper_material(), 0.003, &[30.0, -45.0, 10.0]).stiffness();
    let plate = Mesh::rectangle(0.3, 0.1, 6, 3, 0).unwrap();
    let mut rotated = plate.clone();
    for p in rotated.nodes.iter_mut() {
        *p = r * *p + Vector3::new(0.3, -0.2, 0.5);
    }
    for el in rotated.elements.iter_mut() {
        if let fem::Element::Shell { material_axis, .. } = el {
            *material_axis = r * *material_axis;
        }
    }
    let props = Properties {
        sections: vec![],
        laminates: vec![lam],
    };
    let spectrum = |mesh: &Mesh, props: &Properties<f64>| {
        let asm = Assembly::new(mesh, &Constraints::new()).unwrap();
        let (k, m) = consistent_matrices(mesh, &asm, props);
        lowest_modes(&k, &m, 12, &EigenOptions::default())
            .unwrap()
            .values
    };
    let (a, b) = (spectrum(&plate, &props), spectrum(&rotated, &props));
    for i in 6..12 {
        assert!(
            rel(b[i], a[i]) < 1e-9,
            "plate mode {i}: {} vs {}",
            b[i],
            a[i]
        );
    }
    let rect = common::Rect {
        e: 70e9,
        nu: 0.3,
        rho: 2700.0,
        hy: 0.02,
        hz: 0.01,
        kappa: 5.0 / 6.0,
    };
    let beam = Mesh::straight_beam(
        Vector3::zeros(),
        Vector3::new(1.0, 0.0, 0.0),
        10,
        0,
        Vector3::y(),
    )
    .unwrap();
    let mut rb = beam.clone();
    for p in rb.nodes.iter_mut() {
        *p = r * *p;
    }
    for el in rb.elements.iter_mut() {
        if let fem::Element::Beam { orientation, .. } = el {
            *orientation = r * *orientation;
        }
    }
    let (a, b) = (spectrum(&beam, &rect.props()), spectrum(&rb, &rect.props()));
    for i in 6..12 {
        assert!(
            rel(b[i], a[i]) < 1e-9,
            "beam mode {i}: {} vs {}",
            b[i],
            a[i]
        );
    }
}

#[test]
fn in_plane_bending_of_a_strip_converges_with_the_allman_membrane() {
    // cantilever strip bending in its own plane (membrane only): the first frequency against the
    // Timoshenko beam of the same depth (κ = 5/6, a close but not exact plane-stress reference)
    let (l, d, t) = (0.304f64, 0.04f64, 0.0075f64);
    let (e, nu, rho) = (70e9, 0.3, 2700.0);
    let lam = stack(
        OrthotropicMaterial::isotropic(e, nu, rho).unwrap(),
        t,
        &[0.0],
    )
    .stiffness();
    let g = e / (2.0 * (1.0 + nu));
    let exact = common::timoshenko_cantilever(
        e * t * d.powi(3) / 12.0,
        5.0 / 6.0 * g * t * d,
        rho * t * d,
        rho * t * d.powi(3) / 12.0,
        l,
        1,
    )[0];
    let ratio = |nx: usize, ny: usize, membrane: fem::Membrane| {
        let mesh = Mesh::rectangle(l, d, nx, ny, 0).unwrap();
        let mut c = Constraints::new();
        let all: Vec<usize> = (0..mesh.nodes.len()).collect();
        c.fix_nodes(&all, &[dof::UZ, dof::RX, dof::RY]);
        let left = mesh.nodes_on_segment(Vector3::zeros(), Vector3::new(0.0, d, 0.0), 1e-9);
        c.fix_nodes(&left, &dof::ALL);
        let asm = Assembly::new(&mesh, &c).unwrap();
        let props = Properties {
            sections: vec![],
            laminates: vec![lam.clone()],
        };
        let opts = ElementOptions {
            membrane,
            ..Default::default()
        };
        let (k, m) = asm
            .values(&mesh, &props, &opts, MassKind::Consistent)
            .unwrap();
        let p = lowest_modes(&asm.matrix(k), &asm.matrix(m), 1, &EigenOptions::default()).unwrap();
        (p.values[0] / exact).sqrt()
    };
    let (coarse, fine) = (
        ratio(16, 2, fem::Membrane::Allman),
        ratio(32, 4, fem::Membrane::Allman),
    );
    eprintln!("Allman 16×2: {coarse:.4}, 32×4: {fine:.4}");
    assert!(
        (coarse - 1.0).abs() < 0.06 && (fine - 1.0).abs() < 0.02,
        "{coarse} {fine}"
    );
    assert!(fine < coarse);
    // the constant-strain membrane locks in in-plane bending (kept as an option)
    let cst = ratio(16, 2, fem::Membrane::Cst);
    assert!(cst > 1.2, "{cst}");
}

#[test]
fn reference_surface_offset_is_an_exact_reparametrisation() {
    // the same free laminate described about its mid-plane or its bottom face (B and I₁ ≠ 0):
    // the FSDT kinematics are related by u_bottom = u_mid − (h/2) β, so the spectra agree (up to
    // the small drilling penalty, which sees the in-plane rotation of the reference surface)
    let plies = |reference| {
        let t = 0.002;
        let ps: Vec<laminate::Ply<f64>> = [0.0f64, 90.0, 30.0]
            .iter()
            .map(|a| laminate::Ply {
                material: paper_material(),
                thickness: t,
                angle: a.to_radians(),
            })
            .collect();
        laminate::PlyStack::with_options(ps, reference, 5.0 / 6.0)
            .unwrap()
            .stiffness()
    };
    let mesh = Mesh::rectangle(0.2, 0.1, 8, 4, 0).unwrap();
    let asm = Assembly::new(&mesh, &Constraints::new()).unwrap();
    let spectrum = |lam: LaminateStiffness<f64>| {
        let props = Properties {
            sections: vec![],
            laminates: vec![lam],
        };
        let (k, m) = asm
            .values(
                &mesh,
                &props,
                &ElementOptions::default(),
                MassKind::Consistent,
            )
            .unwrap();
        lowest_modes(&asm.matrix(k), &asm.matrix(m), 14, &EigenOptions::default())
            .unwrap()
            .values
    };
    let mid = spectrum(plies(laminate::ReferenceSurface::MidPlane));
    let bottom = spectrum(plies(laminate::ReferenceSurface::Bottom));
    assert!(
        plies(laminate::ReferenceSurface::Bottom).b.norm()
            > 1e-3 * plies(laminate::ReferenceSurface::MidPlane).d.norm()
    );
    for i in 6..14 {
        eprintln!("mode {i}: {:e}", rel(bottom[i], mid[i]));
        assert!(
            rel(bottom[i], mid[i]) < 1e-4,
            "mode {i}: {} vs {}",
            bottom[i],
            mid[i]
        );
    }
}
