//! Composite tubes: extension–twist coupling of single-angle and balanced lay-ups.

mod common;
use common::*;
use section::{PlySpec, SectionProperties, analyse, tube};

fn tube_at(angles: &[f64]) -> SectionProperties {
    let plies: Vec<PlySpec> = angles
        .iter()
        .enumerate()
        .map(|(k, &a)| PlySpec::new(format!("ply{k}"), composite(), a, 0.0005, 1))
        .collect();
    analyse(&tube(0.01, &plies, 48).unwrap()).unwrap()
}

/// Extension–twist coupling `K₁₄` scaled by `sqrt(K₁₁ K₄₄)`.
fn coupling(p: &SectionProperties) -> f64 {
    let k = p.stiffness;
    k[(0, 3)] / (k[(0, 0)] * k[(3, 3)]).sqrt()
}

#[test]
fn single_angle_extension_twist_coupling() {
    let deg = std::f64::consts::PI / 180.0;
    for a in [0.0, 90.0] {
        let c = coupling(&tube_at(&[a * deg; 4]));
        assert!(c.abs() < 1e-10, "θ = {a}°: coupling {c}");
    }
    for a in [15.0, 30.0, 45.0, 75.0] {
        let plus = coupling(&tube_at(&[a * deg; 4]));
        let minus = coupling(&tube_at(&[-a * deg; 4]));
        assert!(
            plus.abs() > 0.01,
            "θ = {a}°: coupling {plus} should be clearly nonzero"
        );
        assert!(
            (plus + minus).abs() < 1e-9 * plus.abs(),
            "θ = ±{a}°: {plus} vs {minus}"
        );
    }
}

/// A `[θ/−θ]` tube: in the thin-wall (laminate) limit the coupling is `∝ A₁₆ = 0`; with the plies
/// at different radii a remainder of relative size `~ t/R` survives (it is physical, not
/// numerical). Checks: the remainder is small, halves when the wall thickness halves, and
/// `[θ/−θ]` and `[−θ/θ]` are exact mirror images (opposite couplings, to round-off).
#[test]
fn balanced_tube_coupling_vanishes_with_wall_thickness() {
    let deg = std::f64::consts::PI / 180.0;
    let run = |angles: &[f64], t: f64| {
        let plies: Vec<PlySpec> = angles
            .iter()
            .enumerate()
            .map(|(k, &a)| PlySpec::new(format!("ply{k}"), composite(), a * deg, t, 2))
            .collect();
        coupling(&analyse(&tube(0.01 - t, &plies, 48).unwrap()).unwrap())
    };
    for a in [20.0, 45.0] {
        let single = run(&[a, a], 0.0005);
        let thick = run(&[a, -a], 0.0005);
        let thin = run(&[a, -a], 0.00025);
        let mirror = run(&[-a, a], 0.0005);
        assert!(
            thick.abs() < 0.1 * single.abs(),
            "θ = {a}°: {thick} vs single {single}"
        );
        assert!(
            (thin / thick - 0.5).abs() < 0.05,
            "θ = {a}°: {thin} vs {thick}"
        );
        assert!(
            (thick + mirror).abs() < 1e-9 * thick.abs(),
            "θ = {a}°: {thick} vs {mirror}"
        );
    }
}

/// A thin single-ply tube against thin-walled laminate theory: with `κ₁ = 0` and free hoop
/// stress, `EA = 2πR(A₁₁ − A₁₂²/A₂₂)`, `GJ = 2πR³(A₆₆ − A₂₆²/A₂₂)` and, with the wall frame's
/// tangent `t = n × x₁` (`γ_xt = −R κ₁`), `K₁₄ = −2πR²(A₁₆ − A₁₂A₂₆/A₂₂)`. Checks the material
/// rotation, the wall frames and the sign conventions together.
#[test]
fn thin_tube_matches_laminate_theory() {
    use laminate::{plane_stress, rotate_stiffness, rotation_about_normal};
    let (rm, t) = (0.05, 0.0005);
    for deg in [0.0_f64, 30.0, -30.0, 60.0] {
        let a = deg.to_radians();
        let plies = [PlySpec::new("p", composite(), a, t, 2)];
        let p = analyse(&tube(rm - 0.5 * t, &plies, 96).unwrap()).unwrap();
        let q = plane_stress(&rotate_stiffness(
            &composite().stiffness(),
            &rotation_about_normal(a),
        )) * t;
        let (a11, a12, a22, a16, a26, a66) = (
            q[(0, 0)],
            q[(0, 1)],
            q[(1, 1)],
            q[(0, 2)],
            q[(1, 2)],
            q[(2, 2)],
        );
        let two_pi = 2.0 * std::f64::consts::PI;
        let ea = two_pi * rm * (a11 - a12 * a12 / a22);
        let gj = two_pi * rm.powi(3) * (a66 - a26 * a26 / a22);
        let k14 = -two_pi * rm * rm * (a16 - a12 * a26 / a22);
        let k = p.stiffness;
        assert!(
            rel(k[(0, 0)], ea) < 1e-2,
            "{deg}°: EA {} vs {ea}",
            k[(0, 0)]
        );
        assert!(
            rel(k[(3, 3)], gj) < 1e-2,
            "{deg}°: GJ {} vs {gj}",
            k[(3, 3)]
        );
        let scale = (ea * gj).sqrt();
        assert!(
            (k[(0, 3)] - k14).abs() < 1e-2 * scale,
            "{deg}°: K14 {} vs {k14}",
            k[(0, 3)]
        );
    }
}

/// Frames taken from the elements: the tube generator's `η` runs counter-clockwise, opposite to
/// the radial frame's tangent, so `AlongElement(Eta)` at `θ` is the radial frame at `−θ`
/// (the frame turned by 180° about `x₁`). The element tangent of the quadratic arc differs from
/// the exact circle's by `O(h²)`, hence the loose tolerance.
#[test]
fn element_aligned_frames_follow_the_wall() {
    use section::{ElementDirection, WallFrame};
    let deg = std::f64::consts::PI / 180.0;
    let plies: Vec<PlySpec> = [35.0, -60.0]
        .iter()
        .enumerate()
        .map(|(k, &a)| PlySpec::new(format!("ply{k}"), composite(), a * deg, 0.0005, 1))
        .collect();
    let radial = tube(0.01, &plies, 48).unwrap();
    let mut along = radial.clone();
    for r in &mut along.regions {
        r.frame = WallFrame::AlongElement(ElementDirection::Eta);
        r.ply_angle = -r.ply_angle;
    }
    let (p, q) = (analyse(&radial).unwrap(), analyse(&along).unwrap());
    let d = scaled_diff(&p.stiffness, &q.stiffness, &p.stiffness);
    assert!(d < 1e-4, "element-aligned frames differ by {d:e}");
    assert!(coupling(&p).abs() > 0.05);
    // The ξ direction is radial here: a different (wrong) frame gives clearly different results.
    for r in &mut along.regions {
        r.frame = WallFrame::AlongElement(ElementDirection::Xi);
    }
    let w = analyse(&along).unwrap();
    assert!(scaled_diff(&p.stiffness, &w.stiffness, &p.stiffness) > 1e-2);
}
