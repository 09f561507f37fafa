//! Assembly and lowest-mode (+ derivative) benchmarks on laminated plates of ~10 000 and
//! ~100 000 dof (simply supported, consistent mass, two ply-angle design variables).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use faer::sparse::SparseColMat;
use fem::{
    Assembly, Constraints, EigenOptions, ElementOptions, MassKind, Mesh, Properties,
    design_matrices, dof, lowest_modes, mode_derivatives,
};
use laminate::{OrthotropicMaterial, Ply, PlyStack};
use nalgebra::Vector3;
use sens::Scalar;

fn material() -> OrthotropicMaterial {
    OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [5.36e9, 5.36e9, 5.36e9],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .unwrap()
}

fn props<S: Scalar>(b: &[S]) -> Properties<S> {
    let angles = [b[0], b[1], b[1], b[0]];
    let t = S::from_f64(0.0025);
    let stack = PlyStack::new(
        angles
            .iter()
            .map(|&angle| Ply {
                material: material(),
                thickness: t,
                angle,
            })
            .collect(),
    )
    .unwrap();
    Properties {
        sections: vec![],
        laminates: vec![stack.stiffness()],
    }
}

/// A 1 m × 1 m plate with `n × n` cells, hard simply supported edges.
fn model(n: usize) -> (Mesh, Assembly) {
    let mesh = Mesh::rectangle(1.0, 1.0, n, n, 0).unwrap();
    let mut c = Constraints::new();
    let tol = 1e-9;
    for (a, b, along_x) in [
        (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            true,
        ),
        (
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(1.0, 1.0, 0.0),
            true,
        ),
        (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            false,
        ),
        (
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(1.0, 1.0, 0.0),
            false,
        ),
    ] {
        let line = mesh.nodes_on_segment(a, b, tol);
        c.pinned_line(&line, along_x, &[dof::UX, dof::UY]);
    }
    let asm = Assembly::new(&mesh, &c).unwrap();
    (mesh, asm)
}

const B0: [f64; 2] = [0.5, -0.3];

/// The stiffness and mass at `B0` and their 10 lowest modes.
fn modes(
    mesh: &Mesh,
    asm: &Assembly,
) -> (
    SparseColMat<usize, f64>,
    SparseColMat<usize, f64>,
    fem::Eigenpairs,
) {
    let (k, m) = asm
        .values(
            mesh,
            &props(&B0),
            &ElementOptions::default(),
            MassKind::Consistent,
        )
        .unwrap();
    let (k, m) = (asm.matrix(k), asm.matrix(m));
    let pairs = lowest_modes(&k, &m, 10, &EigenOptions::default()).unwrap();
    (k, m, pairs)
}

fn modes_and_derivatives(mesh: &Mesh, asm: &Assembly) -> (Vec<f64>, Vec<Vec<f64>>) {
    let opts = ElementOptions::default();
    let (k, m, pairs) = modes(mesh, asm);
    let dm = design_matrices::<2, _>(mesh, asm, &B0, props, &opts, MassKind::Consistent).unwrap();
    let d = mode_derivatives(&k, &m, &pairs, &dm, true, None).unwrap();
    (pairs.values, d.eigenvalues)
}

/// What `flexsens modes --derivatives` does: the eigenvalue derivatives alone, from the element
/// matrices' tangents projected on the modes (no `K_b` assembled, no Nelson solves).
fn modes_and_eigenvalue_derivatives(mesh: &Mesh, asm: &Assembly) -> (Vec<f64>, Vec<Vec<f64>>) {
    let opts = ElementOptions::default();
    let (_, _, pairs) = modes(mesh, asm);
    let seeded = sens::seed_chunk::<2>(&B0, 0);
    let projected = asm
        .projected_tangents(
            mesh,
            &props(&seeded),
            &opts,
            MassKind::Consistent,
            &pairs.vectors,
            &fem::sensitivity::clusters(&pairs.values, fem::sensitivity::CLUSTER_RTOL),
        )
        .unwrap();
    let d = fem::eigenvalue_derivatives(&pairs, &projected);
    (pairs.values, d.eigenvalues)
}

fn bench(c: &mut Criterion) {
    for (label, n) in [("10k", 40usize), ("100k", 128)] {
        let (mesh, asm) = model(n);
        let opts = ElementOptions::default();
        // one timed run of each phase, printed for the record
        let t = Instant::now();
        let (k, m) = asm
            .values(&mesh, &props(&B0), &opts, MassKind::Consistent)
            .unwrap();
        let t_asm = t.elapsed();
        let (k, m) = (asm.matrix(k), asm.matrix(m));
        let t = Instant::now();
        let pairs = lowest_modes(&k, &m, 10, &EigenOptions::default()).unwrap();
        let t_eig = t.elapsed();
        let t = Instant::now();
        let dm =
            design_matrices::<2, _>(&mesh, &asm, &B0, props, &opts, MassKind::Consistent).unwrap();
        let t_kb = t.elapsed();
        let t = Instant::now();
        let _ = mode_derivatives(&k, &m, &pairs, &dm, true, None).unwrap();
        let t_nel = t.elapsed();
        eprintln!(
            "{label}: {} free dof, nnz {}: assembly {t_asm:?}, 10 modes {t_eig:?}, K_b (2 vars) {t_kb:?}, \
             Nelson (10 modes × 2 vars) {t_nel:?}; f1 = {:.3} Hz",
            asm.n_free(),
            asm.nnz(),
            pairs.values[0].sqrt() / (2.0 * std::f64::consts::PI)
        );

        let mut g = c.benchmark_group(format!("plate_{label}"));
        g.sample_size(10).warm_up_time(Duration::from_millis(500));
        if n > 100 {
            g.measurement_time(Duration::from_secs(30));
        }
        g.bench_function("assembly_f64", |bch| {
            bch.iter(|| {
                black_box(
                    asm.values(&mesh, &props(&B0), &opts, MassKind::Consistent)
                        .unwrap(),
                )
            })
        });
        g.bench_function("assembly_dual2_Kb", |bch| {
            bch.iter(|| {
                black_box(
                    design_matrices::<2, _>(&mesh, &asm, &B0, props, &opts, MassKind::Consistent)
                        .unwrap(),
                )
            })
        });
        g.bench_function("modes10_plus_derivatives", |bch| {
            bch.iter(|| black_box(modes_and_derivatives(&mesh, &asm)))
        });
        g.bench_function("modes10_plus_eigenvalue_derivatives", |bch| {
            bch.iter(|| black_box(modes_and_eigenvalue_derivatives(&mesh, &asm)))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
