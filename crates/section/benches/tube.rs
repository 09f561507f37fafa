//! Analysis of an 8-ply composite tube of 20 000 8-node elements plus the derivatives with
//! respect to its 8 ply angles (by the adjoints of the two warping systems, through the stored
//! factorisation).

use criterion::{Criterion, criterion_group, criterion_main};
use laminate::OrthotropicMaterial;
use section::{DesignMap, PlySpec, SectionAnalysis, tube};
use std::hint::black_box;
use std::time::Duration;

fn tube_mesh() -> section::SectionMesh {
    let material = OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [5.36e9, 5.36e9, 5.36e9],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .expect("valid material");
    let angles = [0.0, 45.0, -45.0, 90.0, 90.0, -45.0, 45.0, 0.0];
    let plies: Vec<PlySpec> = angles
        .iter()
        .enumerate()
        .map(|(k, a)| {
            PlySpec::new(
                format!("ply{k}"),
                material,
                f64::to_radians(*a),
                0.000125,
                2,
            )
        })
        .collect();
    // 8 plies × 2 elements through × 1250 around = 20 000 elements.
    tube(0.02, &plies, 1250).expect("valid tube")
}

fn bench(c: &mut Criterion) {
    let mesh = tube_mesh();
    let design = DesignMap::each_region(&mesh);
    let mut group = c.benchmark_group("section");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500));
    group.bench_function("tube_20k_analysis", |b| {
        b.iter(|| black_box(SectionAnalysis::new(black_box(&mesh)).expect("analysis")))
    });
    group.bench_function("tube_20k_analysis_and_8_derivatives", |b| {
        b.iter(|| {
            let a = SectionAnalysis::new(black_box(&mesh)).expect("analysis");
            black_box(a.sensitivities::<8>(&design).expect("sensitivities"))
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
