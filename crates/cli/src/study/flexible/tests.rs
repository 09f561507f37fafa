//! Dailey's second-derivative terms through the deck's own properties: a splitting pair of
//! repeated frequencies, its eigenvector derivatives against central differences of the
//! tracked branches of perturbed decks.

use nalgebra::DMatrix;

use super::*;
use crate::deck::bodies::validate_one;
use crate::deck::design::validate as validate_design;
use crate::deck::laminates::validate as validate_laminates;

/// A free square plate of a [0/90] cross-ply: a 90° turn with a flip is a symmetry, so it
/// has repeated pairs; turning ply 0 alone breaks the symmetry and splits them.
const DECK: &str = r#"
[material.ud]
E1 = 128.0e9
E2 = 10.1e9
E3 = 10.1e9
G12 = 5.36e9
G13 = 5.36e9
G23 = 3.0e9
nu12 = 0.23
nu13 = 0.23
nu23 = 0.3
density = 1586.0
[laminate.plate]
plies = [
  { material = "ud", thickness = 1e-3, angle = 0.0 },
  { material = "ud", thickness = 1e-3, angle = 90.0 },
]
[body.p]
kind = "shell"
laminate = "plate"
length = 0.2
width = 0.2
elements = [8, 8]
modes = 8
reference = "free-free"
mass = "consistent"
[design.a]
laminate = "plate"
plies = [0]
"#;

fn source() -> (Source, crate::deck::RawDeck) {
    let src = Source::new("square.toml", DECK);
    let raw = src.parse().unwrap();
    (src, raw)
}

/// The body's modal analysis with ply 0 turned by `delta` degrees (from the laminates moved
/// by the design variable, as finite differences of a run do).
fn analysis_at(delta: f64, request: DesignRequest) -> (Built, fem::ModalAnalysis) {
    let (src, raw) = source();
    let mut lam = validate_laminates(&src, &raw).unwrap();
    let design = validate_design(&src, &raw, &lam).unwrap();
    let v = &design.variables[0];
    v.apply(&mut lam, v.value + delta).unwrap();
    let def = validate_one(&src, &raw, "p", &raw.body["p"], &lam).unwrap();
    let request = match request {
        DesignRequest::Variables(_) => DesignRequest::Variables(&design.variables),
        other => other,
    };
    let built = build(&src, "p", &def, request).unwrap();
    let a = fem::modal_analysis(&built.mesh, &built.props, &built.options).unwrap();
    (built, a)
}

#[test]
fn eigenvector_derivatives_of_a_splitting_pair_follow_the_branches() {
    let (src, _) = source();
    let (built, a) = analysis_at(0.0, DesignRequest::Variables(&[]));
    let lam = &a.pairs.values;
    // modes 4 and 5 (from 1) are a repeated pair
    assert!((lam[4] - lam[3]).abs() < 1e-9 * lam[3], "{lam:?}");
    let (_, d) = built
        .mode_derivatives::<1>(&src, "p", 0..1, &a, fem::ModeUpdate::Updated)
        .unwrap();
    let dl = &d.eigenvalues[0];
    assert!(
        (dl[4] - dl[3]).abs() > 0.5 * dl[3].abs().max(dl[4].abs()),
        "the pair splits: {dl:?}"
    );
    let z = &a.pairs.vectors * &d.rotations[0];
    let xb = &d.eigenvectors.as_ref().unwrap()[0];
    // the branches at ±h (degrees), matched to the rotated nominal basis by M-overlap
    let branch = |h: f64| -> DMatrix<f64> {
        let (_, p) = analysis_at(h, DesignRequest::None);
        let overlap = fem::eigen::project(&a.m, &z, &p.pairs.vectors);
        let mut out = DMatrix::zeros(z.nrows(), 2);
        for (c, j) in [3, 4].into_iter().enumerate() {
            let i = if overlap[(j, 3)].abs() > overlap[(j, 4)].abs() {
                3
            } else {
                4
            };
            let sign = overlap[(j, i)].signum();
            out.column_mut(c)
                .copy_from(&(p.pairs.vectors.column(i) * sign));
        }
        out
    };
    let h = 0.05;
    let (p1, m1, p2, m2) = (branch(h), branch(-h), branch(2.0 * h), branch(-2.0 * h));
    let fd = ((&p1 - &m1) / (2.0 * h) * 4.0 - (&p2 - &m2) / (4.0 * h)) / 3.0;
    for (c, j) in [3, 4].into_iter().enumerate() {
        let exact = xb.column(j);
        let err = (exact - fd.column(c)).norm() / exact.norm();
        eprintln!("mode {}: |x_b − FD| / |x_b| = {err:.1e}", j + 1);
        assert!(err < 1e-6, "mode {}: {err:e}", j + 1);
    }
}

/// Away from the nominal design a beam's properties are its section analysed at that
/// design (values and derivatives), as a deck with the turned plies gives them.
#[test]
fn beam_properties_at_a_perturbed_design_are_those_of_the_perturbed_deck() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../decks/modes_beam_rod.toml"
    ))
    .unwrap()
        + "\n[design.theta]\nlaminate = \"tube_wall\"\n";
    let at = |delta: f64| {
        let src = Source::new("rod.toml", text.clone());
        let raw = src.parse().unwrap();
        let mut lam = validate_laminates(&src, &raw).unwrap();
        let design = validate_design(&src, &raw, &lam).unwrap();
        let nominal = lam.clone();
        let v = &design.variables[0];
        v.apply(&mut lam, v.value + delta).unwrap();
        let built = |lam| {
            let def = validate_one(&src, &raw, "rod", &raw.body["rod"], lam).unwrap();
            build(
                &src,
                "rod",
                &def,
                DesignRequest::Variables(&design.variables),
            )
            .unwrap()
        };
        (built(&nominal), built(&lam), v.value)
    };
    let delta = 3.0;
    let (nominal, moved, b0) = at(delta);
    let b = [Dual::<1>::new(b0 + delta, [1.0])];
    let p = nominal.design.properties(&b).unwrap();
    // `moved` was built from the turned laminates: its stored derivatives are at b0 + δ
    let q = moved
        .design
        .properties(&[Dual::<1>::new(b0, [1.0])])
        .unwrap();
    let (s, t) = (&p.sections[0], &q.sections[0]);
    let scale = t.stiffness.map(|x| x.v.abs()).max();
    let dscale = t.stiffness.map(|x| x.d[0].abs()).max();
    for (x, y) in s.stiffness.iter().zip(t.stiffness.iter()) {
        assert!((x.v - y.v).abs() < 1e-9 * scale, "{} vs {}", x.v, y.v);
        assert!(
            (x.d[0] - y.d[0]).abs() < 1e-8 * dscale,
            "{} vs {}",
            x.d[0],
            y.d[0]
        );
    }
    // and the move is not nothing: 3° changes the stiffness
    let p0 = nominal
        .design
        .properties(&[Dual::<1>::new(b0, [1.0])])
        .unwrap();
    let moved_by = p0.sections[0]
        .stiffness
        .iter()
        .zip(s.stiffness.iter())
        .fold(0.0f64, |m, (x, y)| m.max((x.v - y.v).abs()));
    assert!(moved_by > 1e-3 * scale, "{moved_by:e}");
}

/// Where a variable splits a repeated pair, the dual body carries the pair's block of its
/// modal stiffness, `λI + Xᵀ(K_b − λM_b)X`, not a diagonal: its eigenvalues are the pair's
/// one-sided derivatives, against perturbed decks (a step up: the lower branch takes the
/// smaller derivative); its trace is the sum of theirs.
#[test]
fn a_dual_body_whose_repeated_modes_split_carries_their_block() {
    let analysed = |delta: f64| {
        let (src, raw) = source();
        let mut lam = validate_laminates(&src, &raw).unwrap();
        let design = validate_design(&src, &raw, &lam).unwrap();
        let v = &design.variables[0];
        v.apply(&mut lam, v.value + delta).unwrap();
        let mut def = validate_one(&src, &raw, "p", &raw.body["p"], &lam).unwrap();
        def.lumped = true;
        let built = build(&src, "p", &def, DesignRequest::Variables(&design.variables)).unwrap();
        let a = fem::modal_analysis(&built.mesh, &built.props, &built.options).unwrap();
        (src, built, a)
    };
    let (src, built, a) = analysed(0.0);
    let lam = &a.pairs.values;
    assert!((lam[4] - lam[3]).abs() < 1e-9 * lam[3], "{lam:?}");
    let (dm, d) = built
        .mode_derivatives::<1>(&src, "p", 0..1, &a, fem::ModeUpdate::Updated)
        .unwrap();
    let body = fem::modal_body_dual::<1>(
        &built.mesh,
        &built.props,
        &a,
        &dm,
        &d,
        0,
        fem::ModeUpdate::Updated,
    )
    .unwrap();
    let k = body.stiffness_matrix.expect("a full modal stiffness");
    let block = DMatrix::from_fn(2, 2, |i, j| k[(3 + i, 3 + j)].d[0]);
    let mut slopes = block.symmetric_eigenvalues().as_slice().to_vec();
    slopes.sort_by(f64::total_cmp);
    assert!(
        (slopes[1] - slopes[0]).abs() > 1e-2 * slopes[1].abs(),
        "the pair splits: {slopes:?}"
    );
    let h = 1e-4;
    let (_, _, up) = analysed(h);
    let scale = slopes[0].abs().max(slopes[1].abs());
    for (i, slope) in slopes.iter().enumerate() {
        let fd = (up.pairs.values[3 + i] - lam[3 + i]) / h;
        assert!(
            (fd - slope).abs() < 1e-3 * scale,
            "mode {}: {slope:e} against {fd:e} per degree",
            4 + i
        );
    }
    // the pair's mode columns move with the pair's subspace: a step along their tangents stays
    // in the perturbed subspace to second order, without them it leaves it at first order
    let span = up.expand(&up.pairs.vectors.columns(3, 2).into_owned());
    let outside = |v: &DMatrix<f64>| {
        let fit = (span.transpose() * &span).try_inverse().unwrap() * (span.transpose() * v);
        (v - &span * fit).norm() / v.norm()
    };
    let columns = |tangent: bool| {
        DMatrix::from_fn(body.modes.nrows(), 2, |i, j| {
            let x = body.modes[(i, 3 + j)];
            x.v + if tangent { h * x.d[0] } else { 0.0 }
        })
    };
    let (moved, kept) = (outside(&columns(true)), outside(&columns(false)));
    eprintln!("moved {moved:e} kept {kept:e}");
    let trace = block[(0, 0)] + block[(1, 1)];
    let sum = d.eigenvalues[0][3] + d.eigenvalues[0][4];
    assert!(
        (trace - sum).abs() < 1e-9 * scale,
        "{trace:e} against {sum:e}"
    );
}
