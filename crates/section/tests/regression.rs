//! Frozen references for the paper's beam rod (§5.1): a composite tube of area ≈ 3.16e-5 m²
//! (r_i = 4.5 mm, four 0.25 mm plies, all at 15°), one design variable driving all plies.
//! Values pinned 2026-11-21 from this implementation (4 plies × 1 element, 48 around); any
//! change must say why.

mod common;
use common::*;
use section::{DesignMap, PlySpec, analyse_with_derivatives, tube};

#[test]
fn paper_tube_at_15_degrees_frozen() {
    let theta = 15f64.to_radians();
    let plies: Vec<PlySpec> = (0..4)
        .map(|k| PlySpec::new(format!("ply{k}"), composite(), theta, 0.00025, 1))
        .collect();
    let mesh = tube(0.0045, &plies, 48).unwrap();
    let links: Vec<(usize, f64)> = (0..4).map(|k| (k, 1.0)).collect();
    let design = DesignMap::new().with_variable("theta", links);
    let s = analyse_with_derivatives::<1>(&mesh, &design).unwrap();
    let (k, dk) = (s.properties.stiffness, s.derivatives[0].stiffness);
    let got = [
        k[(0, 0)],
        k[(1, 1)],
        k[(3, 3)],
        k[(4, 4)],
        k[(0, 3)],
        dk[(0, 0)],
        dk[(0, 3)],
        dk[(3, 3)],
    ];
    assert!(rel(s.properties.area, 3.1416e-5) < 1e-3);
    for (g, f) in got.iter().zip(FROZEN) {
        assert!((g - f).abs() <= 1e-8 * f.abs(), "{g} vs frozen {f}");
    }
}

/// `[EA, GA₂, GJ, EI₂₂, K₁₄, dEA/dθ, dK₁₄/dθ, dGJ/dθ]`.
const FROZEN: [f64; 8] = [
    3_318_761.301_537_421,
    190_139.923_599_951_87,
    9.350_077_257_691_47,
    41.890_776_280_119_92,
    -3_905.796_993_646_104_5,
    -5_745_578.673_941_128,
    -7_968.355_675_743_554_5,
    30.579_012_854_609_65,
];
