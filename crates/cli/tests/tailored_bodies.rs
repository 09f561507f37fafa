//! Tailored bodies: a beam made of `segments` with their own sections, a shell with `regions`
//! of their own laminates. Stepped cantilevers (a beam, a shell strip) against the closed-form
//! frequencies of Euler–Bernoulli stretches; the paper's tube split in two segments of two
//! laminates is the uniform tube, the paper's plate with a patch of a copy of its laminate the
//! uniform plate, and their parts' angle sensitivities add up to the common angle's and equal
//! replayed central differences of whole runs.

mod common;
use common::*;

/// A given section `name`: bending stiffness `ei` (N·m², both planes) and mass per length `m`
/// (kg/m); stiff in shear and tension, negligible rotary inertia (an Euler–Bernoulli beam).
fn slender(name: &str, ei: f64, m: f64) -> String {
    format!(
        "[section.{name}]\nshape = \"properties\"\nEA = 1.0e9\nGA2 = 1.0e10\nGA3 = 1.0e10\n\
         GJ = {ei:e}\nEI2 = {ei:e}\nEI3 = {ei:e}\nmass_per_length = {m:e}\n\
         inertia = [1.0e-9, 1.0e-9]\n\n"
    )
}

/// Clamped–free ω² (lowest `count`) of Euler–Bernoulli stretches `(EI, m, length)` in order
/// from the clamp: the product of each stretch's transfer matrix of `[w, w', M, Q]` in Krylov's
/// functions (closed form; moment and shear continuous at the steps), bisection on the
/// free-end determinant.
fn stepped_cantilever(stretches: &[(f64, f64, f64)], count: usize) -> Vec<f64> {
    let det = |omega: f64| -> f64 {
        let mut t = nalgebra::Matrix4::<f64>::identity();
        for &(ei, m, l) in stretches {
            let beta = (omega * omega * m / ei).powf(0.25);
            let z = beta * l;
            let s = 0.5 * (z.cosh() + z.cos());
            let tt = 0.5 * (z.sinh() + z.sin());
            let u = 0.5 * (z.cosh() - z.cos());
            let v = 0.5 * (z.sinh() - z.sin());
            let (b, b2, b3) = (beta, beta * beta, beta.powi(3));
            #[rustfmt::skip]
            let stretch = nalgebra::Matrix4::new(
                s, tt / b, u / (ei * b2), v / (ei * b3),
                b * v, s, tt / (ei * b), u / (ei * b2),
                ei * b2 * u, ei * b * v, s, tt / b,
                ei * b3 * tt, ei * b2 * u, b * v, s,
            );
            t = stretch * t;
        }
        // clamped start: w = w' = 0; free end: M = Q = 0
        let d = t[(2, 2)] * t[(3, 3)] - t[(2, 3)] * t[(3, 2)];
        d / (t[(2, 2)].abs() + t[(3, 3)].abs() + t[(2, 3)].abs() + t[(3, 2)].abs()).powi(2)
    };
    let mut out = Vec::new();
    let (mut lo, step) = (0.1, 0.05);
    let mut flo = det(lo);
    while out.len() < count {
        let hi = lo + step;
        let fhi = det(hi);
        if flo.signum() != fhi.signum() {
            let (mut a, mut b, mut fa) = (lo, hi, flo);
            for _ in 0..100 {
                let c = 0.5 * (a + b);
                let fc = det(c);
                if fc.signum() == fa.signum() {
                    (a, fa) = (c, fc);
                } else {
                    b = c;
                }
            }
            out.push(0.5 * (a + b));
        }
        (lo, flo) = (hi, fhi);
    }
    out.into_iter().map(|w| w * w).collect()
}

/// The frequencies (Hz) of the body `arm` of `deck`.
fn frequencies(dir: &tempfile::TempDir, deck: &str) -> Vec<f64> {
    let path = dir.path().join("arm.toml");
    std::fs::write(&path, deck).unwrap();
    let j = json(&["modes", path.to_str().unwrap(), "--format", "json"]);
    j["bodies"]["arm"]["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_f64().unwrap())
        .collect()
}

/// A 1 m cantilever whose stiff, heavy root (EI 400 N·m², 2 kg/m) covers 0.4 m, a lighter
/// stretch (100 N·m², 1 kg/m) the rest: its first four in-plane frequencies within 0.2 % of the
/// closed form (either uniform beam is 17 % or more off in the first); segments given by
/// their element counts' default share of ten elements and by explicit counts agree with it.
#[test]
fn a_stepped_cantilever_has_the_closed_form_frequencies() {
    let dir = tempfile::tempdir().unwrap();
    let body = |segments: &str| {
        format!(
            "{}{}[body.arm]\nkind = \"beam\"\nstart = [0.0, 0.0, 0.0]\nend = [1.0, 0.0, 0.0]\n\
             segments = {segments}\nreference = \"clamped-node\"\nplanar = [0.0, 0.0, 1.0]\n\
             modes = 4\nmass = \"consistent\"\n",
            slender("root", 400.0, 2.0),
            slender("tip", 100.0, 1.0),
        )
    };
    let fine = frequencies(
        &dir,
        &body(
            "[{ section = \"root\", length = 0.4, elements = 24 }, \
             { section = \"tip\", elements = 36 }]",
        ),
    );
    let exact = stepped_cantilever(&[(400.0, 2.0, 0.4), (100.0, 1.0, 0.6)], 4);
    let hz = |w2: f64| w2.sqrt() / (2.0 * std::f64::consts::PI);
    for (n, (f, w2)) in fine.iter().zip(&exact).enumerate() {
        let err = f / hz(*w2) - 1.0;
        assert!(
            err.abs() < 2e-3,
            "mode {}: {f} Hz against {} Hz ({err:.1e})",
            n + 1,
            hz(*w2)
        );
    }
    for (ei, m) in [(400.0, 2.0), (100.0, 1.0)] {
        let uniform = stepped_cantilever(&[(ei, m, 1.0)], 1);
        let off = hz(uniform[0]) / fine[0] - 1.0;
        assert!(off.abs() > 0.15, "a uniform beam is within {off:.2}");
    }
    // ten elements shared 4 + 6 by default: the first frequency within 0.2 % still
    let coarse = frequencies(
        &dir,
        &body("[{ section = \"root\", length = 0.4 }, { section = \"tip\" }]"),
    );
    assert!((coarse[0] / hz(exact[0]) - 1.0).abs() < 2e-3, "{coarse:?}");
}

/// The paper's beam deck with its rod split at mid-length into two segments: `segments` and
/// `laminates` are the rod's (the tube's section at lay-up 15°, its laminate copied as
/// `tip_wall` for the outer half).
fn split_rod(segments: &str, design: &str) -> String {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    let tip = "[laminate.tip_wall]\nplies = [\n  { material = \"paper_composite\", thickness = \
               0.25e-3, angle = 15.0 },\n  { material = \"paper_composite\", thickness = \
               0.25e-3, angle = 15.0 },\n  { material = \"paper_composite\", thickness = \
               0.25e-3, angle = 15.0 },\n  { material = \"paper_composite\", thickness = \
               0.25e-3, angle = 15.0 },\n]\n\n[section.tip_tube]\nshape = \"tube\"\n\
               inner_radius = 4.529e-3\nlaminate = \"tip_wall\"\nelements_per_ply = 1\n\
               elements_around = 32\n\n[body.rod]";
    let text = text
        .replace("[body.rod]", tip)
        .replace(
            "section = \"tube\"\nstart",
            &format!("segments = {segments}\nstart"),
        )
        .replace(
            "elements = 8                # node 4 at mid-length carries the body frame (centre of mass)\n",
            "",
        )
        .replace(
            "[design.theta]\n# the common angle of all plies of the tube (the paper's design variable), degrees\nlaminate = \"tube_wall\"",
            design,
        );
    assert!(text.contains("segments =") && !text.contains("elements = 8 "));
    text
}

/// The rod's halves: the tube's section and its copy of the tip laminate.
const HALVES: &str = "[{ section = \"tube\", length = 0.152, elements = 4 }, \
                      { section = \"tip_tube\", elements = 4 }]";

/// An angle for each half.
const DESIGN: &str = "[design.theta_root]\nlaminate = \"tube_wall\"\n\n\
                      [design.theta_tip]\nlaminate = \"tip_wall\"";

/// The paper deck's damping, fitted to its first and fourth modes.
const FITTED: &str = "damping = { modes = [1, 4], ratios = [0.01, 0.03] }";

/// A stiffness-proportional damping given by its coefficient (1.4 % at the first mode).
const GIVEN: &str = "damping = { beta = 1.0e-5 }";

/// Per-segment angles of the split rod: the deck with its two halves at the tube's own lay-up
/// is the uniform deck (the same mid-span history to round-off); each half's angle has a
/// sensitivity of its own (the root's and the tip's differ), both equal replayed central
/// differences of whole runs, and together they are the common angle's derivative. The rod is
/// clamped at its middle node, so its halves' modes are repeated pairs at the nominal design,
/// which each half's angle splits: the run carries the pairs' block of the modal stiffness.
#[test]
fn per_segment_angles_add_up_to_the_common_angle_and_equal_differences() {
    let uniform = std::fs::read_to_string(deck("slider_crank_beam.toml"))
        .unwrap()
        .replace(FITTED, GIVEN);
    let split = split_rod(HALVES, DESIGN).replace(FITTED, GIVEN);
    parts_add_up_to_the_whole(&uniform, &split, "0.01");
}

/// A thin outer ply (0.08 mm in both halves) and the tip half's thickness of it as the variable:
/// it splits the halves' repeated pairs, whose Dailey terms analyse the section at a step
/// relative to the variable (a step of 1e-4 in its units, 0.1 mm, inverted the thin ply's
/// section and failed the run); its sensitivity equals replayed central differences of whole
/// runs.
#[test]
fn a_thin_ply_of_one_half_splits_the_pairs_and_equals_differences() {
    let outer = "thickness = 0.25e-3, angle = 15.0 },\n]";
    let design = "[design.t_tip]\nkind = \"ply-thickness\"\nlaminate = \"tip_wall\"\nplies = [3]";
    let text = split_rod(HALVES, design).replace(FITTED, GIVEN);
    assert_eq!(text.matches(outer).count(), 2, "the outer ply of each half");
    let text = text.replace(outer, "thickness = 0.08e-3, angle = 15.0 },\n]");
    let dir = tempfile::tempdir().unwrap();
    let sets = ["analysis.t_end=0.003", "sensitivity.method=\"direct\""];
    let (_, g) = run_text(dir.path(), "thin", &text, &sets);
    let errors = replayed_differences(&g, "mid_deflection", "0.0001", 1);
    eprintln!("replayed differences: {errors:?}");
    assert!(errors[0] < 1e-5, "{errors:?}");
}

/// Runs of the deck `whole` (one design variable: an angle over the whole body) and of `parts`
/// (the same body in two parts, each of its own copy of the laminate, an angle each), over
/// `t_end` s with direct sensitivities: the same mid-span history to round-off; each part's
/// sensitivity equal to replayed central differences, the two different from each other and
/// adding up to the whole's.
fn parts_add_up_to_the_whole(whole: &str, parts: &str, t_end: &str) {
    let dir = tempfile::tempdir().unwrap();
    let t_end = format!("analysis.t_end={t_end}");
    let sets = [t_end.as_str(), "sensitivity.method=\"direct\""];
    let run = |name: &str, text: &str| run_text(dir.path(), name, text, &sets).1;
    let (whole, parts) = (run("whole", whole), run("parts", parts));
    let (w, p) = (
        f64s(&whole, "responses/mid_deflection"),
        f64s(&parts, "responses/mid_deflection"),
    );
    let err = worst_difference(&w, &p);
    assert!(err < 1e-9, "the parts against the whole: {err:e}");
    let common = f64s(&whole, "sensitivities/mid_deflection");
    let both = f64s(&parts, "sensitivities/mid_deflection");
    let fd = f64s(
        &parts,
        "finite_differences/central_relative_0.0001_replay/mid_deflection",
    );
    let column =
        |x: &[f64], v: usize| -> Vec<f64> { x.iter().skip(v).step_by(2).copied().collect() };
    let (first, second) = (column(&both, 0), column(&both, 1));
    for v in 0..2 {
        let err = worst_difference(&column(&both, v), &column(&fd, v));
        assert!(err < 1e-4, "part {v}: direct against differences {err:e}");
    }
    // the parts are not alike: their derivatives differ
    assert!(worst_difference(&first, &second) > 0.05);
    let sum: Vec<f64> = first.iter().zip(&second).map(|(a, b)| a + b).collect();
    let err = worst_difference(&common, &sum);
    assert!(
        err < 1e-6,
        "the parts' sum against the whole's angle: {err:e}"
    );
}

/// A damping fitted to a mode whose repeated frequency a variable splits has no derivative
/// there: `run` and `check` say so and what to do instead.
#[test]
fn a_fit_to_a_split_pair_is_refused() {
    for command in ["check", "run"] {
        let (_dir, err) = bad_deck(&split_rod(HALVES, DESIGN), |p| {
            let mut args = with_deck(command, p, &[]);
            if command == "run" {
                let out = p.with_extension("out");
                args.extend(["-o".into(), out.display().to_string()]);
            }
            args
        });
        assert!(
            err.contains("key `body.rod`")
                && err.contains("splits the repeated frequencies of modes 1, 2")
                && err.contains("the damping is fitted to mode 1")
                && err.contains("`alpha` and `beta`"),
            "{command}: {err}"
        );
    }
}

/// An isotropic steel without Poisson's effect (a strip then bends as a beam, `EI = E w t³/12`).
const STEEL: &str = "[material.steel]\nE1 = 2.0e11\nE2 = 2.0e11\nE3 = 2.0e11\nG12 = 1.0e11\n\
    G13 = 1.0e11\nG23 = 1.0e11\nnu12 = 0.0\nnu13 = 0.0\nnu23 = 0.0\ndensity = 7850.0\n\n\
    [laminate.thin]\nplies = [{ material = \"steel\", thickness = 1.0e-3, angle = 0.0 }]\n\n\
    [laminate.thick]\nplies = [\n  { material = \"steel\", thickness = 1.0e-3, angle = 0.0 },\n  \
    { material = \"steel\", thickness = 1.0e-3, angle = 0.0 },\n]\n\n";

/// A 0.5 m × 20 mm steel strip clamped at x = 0, 1 mm thick but for a region 2 mm thick over
/// its first 0.2 m: its first three bending frequencies within 0.5 % of the closed form of the
/// stepped Euler–Bernoulli cantilever (measured 7e-5, 8e-4, 3e-3; either uniform strip is 3 %
/// or more off in the first), the region given by a box or by its element list alike.
#[test]
fn a_shell_strip_with_a_thick_root_region_has_the_closed_form_frequencies() {
    let dir = tempfile::tempdir().unwrap();
    let strip = |regions: &str| {
        format!(
            "{STEEL}[body.arm]\nkind = \"shell\"\nlaminate = \"thin\"\nlength = 0.5\n\
             width = 0.02\nelements = [50, 2]\nregions = {regions}\nreference = \"supports\"\n\
             supports = [{{ plane = {{ x = 0.0 }}, fix = \"clamped\" }}]\nmodes = 3\n\
             mass = \"consistent\"\n"
        )
    };
    let by_box = frequencies(
        &dir,
        &strip("[{ laminate = \"thick\", box = [[0.0, 0.0, -1.0], [0.2, 0.02, 1.0]] }]"),
    );
    let (w, e, rho) = (0.02, 2.0e11, 7850.0);
    let stretch = |t: f64, l: f64| (e * w * t.powi(3) / 12.0, rho * w * t, l);
    let exact = stepped_cantilever(&[stretch(2e-3, 0.2), stretch(1e-3, 0.3)], 3);
    let hz = |w2: f64| w2.sqrt() / (2.0 * std::f64::consts::PI);
    for (n, (f, w2)) in by_box.iter().zip(&exact).enumerate() {
        let err = f / hz(*w2) - 1.0;
        assert!(
            err.abs() < 5e-3,
            "mode {}: {f} Hz against {} Hz ({err:.1e})",
            n + 1,
            hz(*w2)
        );
    }
    for t in [1e-3, 2e-3] {
        let uniform = stepped_cantilever(&[stretch(t, 0.5)], 1);
        let off = hz(uniform[0]) / by_box[0] - 1.0;
        assert!(off.abs() > 0.03, "a uniform strip is within {off:.2}");
    }
    // the same cells listed: two triangles a cell, cells numbered along x, 50 a row
    let listed: Vec<String> = (0..2)
        .flat_map(|row| (0..20).flat_map(move |i| [2 * (50 * row + i), 2 * (50 * row + i) + 1]))
        .map(|e| e.to_string())
        .collect();
    let by_list = frequencies(
        &dir,
        &strip(&format!(
            "[{{ laminate = \"thick\", elements = [{}] }}]",
            listed.join(", ")
        )),
    );
    for (a, b) in by_box.iter().zip(&by_list) {
        assert!((a / b - 1.0).abs() < 1e-12, "{a} against {b}");
    }
}

/// The paper's plate deck with a region over its middle third laminated with `patch`, a copy
/// of its laminate, and an angle for it.
fn patched_plate() -> String {
    let text = std::fs::read_to_string(deck("slider_crank_plate.toml")).unwrap();
    let start = text.find("[laminate.plate]").unwrap();
    let end = start + text[start..].find("\n\n").unwrap();
    let patch = text[start..end].replace("[laminate.plate]", "[laminate.patch]");
    let text = text
        .replacen("[body.rod]", &format!("{patch}\n\n[body.rod]"), 1)
        .replacen(
            "\nreference = \"supports\"\n",
            "\nregions = [{ laminate = \"patch\", box = [[0.1, 0.0, -1.0], [0.2, 0.04, 1.0]] }]\n\
             reference = \"supports\"\n",
            1,
        )
        .replacen(
            "[objective.peak_deflection]",
            "[design.theta_patch]\nlaminate = \"patch\"\n\n[objective.peak_deflection]",
            1,
        );
    assert!(text.contains("[laminate.patch]") && text.contains("regions = ["));
    text
}

/// Per-region angles of the patched plate: at the plate's own lay-up it is the uniform plate
/// (the same mid-span history to round-off); the plate's and the patch's angles have
/// sensitivities of their own, both equal replayed central differences of whole runs, and
/// together they are the common angle's derivative.
#[test]
fn per_region_angles_add_up_to_the_common_angle_and_equal_differences() {
    let uniform = std::fs::read_to_string(deck("slider_crank_plate.toml")).unwrap();
    parts_add_up_to_the_whole(&uniform, &patched_plate(), "0.005");
}
