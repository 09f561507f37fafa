//! Supports stated in the deck (`supports = [...]`, `reference = "supports"`): node sets by
//! plane, box or list, and the dof fixed there. Checked against the closed-form frequencies of a
//! simply supported square plate (with mesh convergence), against the built-in pinned-ends
//! reference of a beam, and for their deck errors.

mod common;

use common::{ALUMINIUM_BEAM, bad_deck, deck, json, with_deck};

/// A square isotropic plate, 1 m × 1 m × 10 mm (simply supported with [`SS_EDGES`]).
const SS_PLATE: &str = r#"
[material.al]
E = 70.0e9
nu = 0.3
density = 2700.0

[laminate.sheet]
plies = [{ material = "al", thickness = 0.01, angle = 0.0 }]

[body.plate]
kind = "shell"
laminate = "sheet"
length = 1.0
width = 1.0
elements = [16, 16]
modes = 4
mass = "consistent"
"#;

/// The simple supports of the 1 m × 1 m plates (hard: `w` and the rotation about the edge
/// normal fixed; the in-plane displacement along the edge fixed too).
const SS_EDGES: &str = r#"reference = "supports"
supports = [
  { plane = { x = 0.0 }, fix = ["uy", "uz", "rx"] },
  { plane = { x = 1.0 }, fix = ["uy", "uz", "rx"] },
  { plane = { y = 0.0 }, fix = ["ux", "uz", "ry"] },
  { plane = { y = 1.0 }, fix = ["ux", "uz", "ry"] },
]
"#;

fn frequencies(text: &str, sets: &[&str], body: &str) -> Vec<f64> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("deck.toml");
    std::fs::write(&p, text).unwrap();
    let mut args = vec!["modes", p.to_str().unwrap(), "--format", "json"];
    for s in sets {
        args.extend(["--set", s]);
    }
    let doc = json(&args);
    doc["bodies"][body]["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn simply_supported_square_plate_matches_the_closed_form_and_converges() {
    // thin plate: f_mn = (π/2) (m² + n²) √(D / ρh) / a², D = E h³ / 12(1 − ν²)
    let d = 70e9 * 0.01f64.powi(3) / (12.0 * (1.0 - 0.09));
    let f = |m: f64, n: f64| std::f64::consts::PI / 2.0 * (m * m + n * n) * (d / 27.0).sqrt();
    let exact = [f(1.0, 1.0), f(1.0, 2.0), f(2.0, 1.0), f(2.0, 2.0)];
    let errors: Vec<Vec<f64>> = [16, 32, 48]
        .iter()
        .map(|n| {
            let set = format!("body.plate.elements=[{n}, {n}]");
            let got = frequencies(&format!("{SS_PLATE}{SS_EDGES}"), &[&set], "plate");
            got.iter().zip(&exact).map(|(g, e)| g / e - 1.0).collect()
        })
        .collect();
    eprintln!("relative errors at 16, 32, 48 elements a side: {errors:?}");
    // measured: mode 1 1.2e-2, 2.5e-3, 8.5e-4 — second order in the element size
    for m in 0..4 {
        assert!(errors[0][m] > 0.0 && errors[1][m] > 0.0, "{errors:?}");
        assert!(errors[1][m] < errors[0][m] / 3.5, "{errors:?}");
        assert!(errors[2][m] < errors[1][m] / 1.9, "{errors:?}");
        assert!(errors[2][m] < 5e-3, "{errors:?}");
    }
    assert!(errors[1][0] < 5e-3, "{errors:?}");
}

/// The aluminium beam of the modes tests with four modes (the tests add its supports).
fn beam() -> String {
    format!("{ALUMINIUM_BEAM}modes = 4\n")
}

#[test]
fn supports_can_state_a_built_in_reference_condition() {
    let b = beam();
    let pinned = frequencies(&format!("{b}reference = \"pinned-ends\"\n"), &[], "beam");
    let stated = frequencies(
        &format!(
            "{b}reference = \"supports\"\nsupports = [\n  {{ nodes = [0], fix = [\"ux\", \
             \"uy\", \"uz\", \"rx\"] }},\n  {{ box = [[0.99, -1, -1], [1.01, 1, 1]], fix = \
             [\"uy\", \"uz\"] }},\n]\n"
        ),
        &[],
        "beam",
    );
    for (x, y) in pinned.iter().zip(&stated) {
        assert!((x / y - 1.0).abs() < 1e-10, "{pinned:?} against {stated:?}");
    }
    // supports add to a reference condition: a beam clamped at its centre vibrates as two equal
    // cantilevers (its modes in pairs); pinning the far end stiffens that half only, and the
    // pairs split
    let centre = frequencies(&format!("{b}\n"), &[], "beam");
    let held = frequencies(
        &format!("{b}supports = [{{ plane = {{ x = 1.0 }}, fix = \"pinned\" }}]\n"),
        &[],
        "beam",
    );
    assert!((centre[1] / centre[0] - 1.0).abs() < 1e-9, "{centre:?}");
    assert!((held[0] / centre[0] - 1.0).abs() < 1e-9, "{held:?}");
    assert!(held[1] > 1.5 * held[0], "{held:?} against {centre:?}");
}

#[test]
fn bad_supports_are_reported_with_their_key() {
    let b = beam();
    let cases: [(&str, &str, &str); 8] = [
        (
            "reference = \"supports\"\n",
            "body.beam.reference",
            "needs supports",
        ),
        (
            "reference = \"supports\"\nsupports = [{ plane = { x = 2.0 }, fix = \"pinned\" }]\n",
            "body.beam.supports[0]",
            "no node of the body lies there",
        ),
        (
            "supports = [{ plane = { x = 0.0 }, fix = [\"uz\", \"tx\"] }]\n",
            "body.beam.supports[0].fix",
            "list of dof names",
        ),
        (
            "supports = [{ nodes = [0], plane = { x = 0.0 }, fix = \"pinned\" }]\n",
            "body.beam.supports[0]",
            "in one way",
        ),
        (
            "reference = \"free-free\"\nsupports = [{ nodes = [0], fix = \"pinned\" }]\n",
            "body.beam.reference",
            "use reference = \"supports\"",
        ),
        (
            "reference = \"supports\"\nsupports = [{ nodes = [0], fix = \"pinned\" }]\n",
            "body.beam",
            "rigid-body motion(s) free: rotation about z through (0, 0, 0) m; rotation about y",
        ),
        (
            "reference = \"partly-free\"\n",
            "body.beam.reference",
            "needs supports",
        ),
        (
            "reference = \"partly-free\"\nsupports = [{ nodes = [0], fix = \"pinned\" }]\n\
             basis = \"interface\"\n",
            "body.beam.basis",
            "a free-free or partly-free body takes basis = \"modes\"",
        ),
    ];
    for (extra, key, words) in cases {
        let (_d, err) = bad_deck(&format!("{b}{extra}"), |p| with_deck("modes", p, &[]));
        assert!(err.contains(key) && err.contains(words), "{extra}: {err}");
    }
}

/// A thick cross-ply plate, [0/90/90/0], a/h = 10, E₁/E₂ = 40 (simply supported with
/// [`SS_EDGES`]).
const CROSS_PLY: &str = r#"
[material.ud]
E1 = 400.0e9
E2 = 10.0e9
E3 = 10.0e9
G12 = 6.0e9
G13 = 6.0e9
G23 = 5.0e9
nu12 = 0.25
nu13 = 0.25
nu23 = 0.25
density = 1500.0

[laminate.xply]
plies = [
  { material = "ud", thickness = 0.025, angle = 0.0 },
  { material = "ud", thickness = 0.025, angle = 90.0 },
  { material = "ud", thickness = 0.025, angle = 90.0 },
  { material = "ud", thickness = 0.025, angle = 0.0 },
]

[body.plate]
kind = "shell"
laminate = "xply"
length = 1.0
width = 1.0
elements = [32, 32]
modes = 8
mass = "consistent"
"#;

/// The Navier solution of first-order shear deformation theory for a simply supported
/// symmetric cross-ply plate (SS-1; Reddy, *Mechanics of Laminated Composite Plates and Shells*,
/// §6.3): `w = W sin αx sin βy`, `φx = X cos αx sin βy`, `φy = Y sin αx cos βy` turn the
/// equations of motion into `(S − ω² M) [W, X, Y] = 0` with the plate stiffnesses `D`, the
/// transverse shear stiffnesses `A₅₅` (xz), `A₄₄` (yz) and the inertias `I₀`, `I₂`. Returns the
/// lowest (bending) frequency of the half-wave numbers `(m, n)` in Hz.
fn navier_fsdt(d: &[Vec<f64>], a55: f64, a44: f64, i0: f64, i2: f64, m: f64, n: f64) -> f64 {
    let (al, be) = (m * std::f64::consts::PI, n * std::f64::consts::PI);
    let s = nalgebra::Matrix3::new(
        a55 * al * al + a44 * be * be,
        a55 * al,
        a44 * be,
        a55 * al,
        d[0][0] * al * al + d[2][2] * be * be + a55,
        (d[0][1] + d[2][2]) * al * be,
        a44 * be,
        (d[0][1] + d[2][2]) * al * be,
        d[2][2] * al * al + d[1][1] * be * be + a44,
    );
    // M^(-1/2) S M^(-1/2), M = diag(I₀, I₂, I₂)
    let r = nalgebra::Vector3::new(i0, i2, i2).map(|x| 1.0 / x.sqrt());
    let scaled = nalgebra::Matrix3::from_fn(|i, j| s[(i, j)] * r[i] * r[j]);
    let w2 = nalgebra::SymmetricEigen::new(scaled).eigenvalues.min();
    w2.sqrt() / (2.0 * std::f64::consts::PI)
}

#[test]
fn simply_supported_cross_ply_plate_matches_the_navier_solution() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("deck.toml");
    std::fs::write(&p, CROSS_PLY).unwrap();
    // the plate's stiffness and inertia as flexsens computes them
    let lam = json(&["laminate", p.to_str().unwrap(), "--format", "json"]);
    let v = &lam["laminates"]["xply"]["values"];
    let (d, shear) = (common::matrix(&v["D"]), common::matrix(&v["As"]));
    let (i0, i2) = (
        v["mass_per_area"].as_f64().unwrap(),
        v["rotary_inertia"].as_f64().unwrap(),
    );
    let exact: Vec<f64> = [(1.0, 1.0), (1.0, 2.0), (2.0, 1.0)]
        .iter()
        .map(|&(m, n)| navier_fsdt(&d, shear[0][0], shear[1][1], i0, i2, m, n))
        .collect();
    // the plate also has in-plane shear modes (its edges hold only the tangential in-plane
    // displacement): each bending frequency is compared with the nearest one found
    let nearest = |got: &[f64], f: f64| {
        got.iter()
            .map(|g| g / f - 1.0)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap()
    };
    let plate = format!("{CROSS_PLY}{SS_EDGES}");
    let coarse = frequencies(&plate, &["body.plate.elements=[16, 16]"], "plate");
    let fine = frequencies(&plate, &["body.plate.elements=[48, 48]"], "plate");
    for &f in &exact {
        let (e16, e48) = (nearest(&coarse, f), nearest(&fine, f));
        eprintln!("Navier {f:.2} Hz: 16 cells {e16:.2e}, 48 cells {e48:.2e}");
        // measured: (1, 1) 8.8e-3 and 9.7e-4, (1, 2) 2.0e-2 and 2.2e-3 (32 cells: 2.2e-3, 5.0e-3)
        assert!(
            e48.abs() < 5e-3 && e48.abs() < e16.abs() / 4.0,
            "{f}: {e16:e} {e48:e}"
        );
    }
    assert!(
        (fine[0] / exact[0] - 1.0).abs() < 5e-3,
        "{fine:?} against {exact:?}"
    );
}

/// An aluminium strip 0.5 m × 40 mm × 4 mm pinned along both end lines.
const STRIP: &str = r#"
[material.al]
E = 70.0e9
nu = 0.3
density = 2700.0

[laminate.sheet]
plies = [{ material = "al", thickness = 0.004, angle = 0.0 }]

[body.strip]
kind = "shell"
laminate = "sheet"
length = 0.5
width = 0.04
elements = [160, 16]
modes = 6
mass = "consistent"
reference = "supports"
supports = [
  { plane = { x = 0.0 }, fix = "pinned" },
  { plane = { x = 0.5 }, fix = "pinned" },
]
"#;

#[test]
fn strip_pinned_along_its_end_lines_bends_and_twists_as_a_beam() {
    let (e, nu, rho, l, b, h): (f64, f64, f64, f64, f64, f64) =
        (70e9, 0.3, 2700.0, 0.5, 0.04, 0.004);
    let pi = std::f64::consts::PI;
    // bending: f₁ = (π / 2L²) √(EI / ρA), a narrow strip bends with E
    let bending = pi / (2.0 * l * l) * (e * h * h / (12.0 * rho)).sqrt();
    // torsion: f = (1 / 2L) √(GJ / ρI_p), St Venant's J = b h³/3 (1 − 0.63 h/b)
    let gj = e / (2.0 * (1.0 + nu)) * b * h.powi(3) / 3.0 * (1.0 - 0.63 * h / b);
    let rho_ip = rho * (b.powi(3) * h + b * h.powi(3)) / 12.0;
    let torsion = (gj / rho_ip).sqrt() / (2.0 * l);
    let nearest = |got: &[f64], f: f64| {
        got.iter()
            .map(|g| g / f - 1.0)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap()
    };
    let mut previous = f64::INFINITY;
    for n in [40, 80, 160] {
        let set = format!("body.strip.elements=[{n}, 16]");
        let mut got = frequencies(STRIP, &[&set], "strip");
        let eb = got[0] / bending - 1.0;
        // the bending harmonics k² f₁ first (the fourth lies near the torsion mode), then the
        // torsion mode is the one nearest its closed form
        for k in 1..=4 {
            let target = (k * k) as f64 * bending;
            let i = (0..got.len())
                .min_by(|&i, &j| (got[i] - target).abs().total_cmp(&(got[j] - target).abs()))
                .unwrap();
            got.remove(i);
        }
        let et = nearest(&got, torsion);
        eprintln!("{n} elements along: bending {eb:.1e}, torsion {et:.1e}");
        // measured: bending 1.1e-3, 4.1e-4, 2.4e-4; torsion 2.0e-2, 1.1e-2, 5.7e-3 — first
        // order in the element length (the MITC3 triangles converge slowly in twist), towards
        // the closed form (Richardson: 0.0 %)
        assert!(eb.abs() < 2e-3, "bending {eb:e}");
        assert!(
            et > 0.0 && et < previous,
            "torsion {et:e} after {previous:e}"
        );
        previous = et;
    }
    assert!(previous < 1e-2, "torsion {previous:e}");
}

/// A strip held only in its deflection along both end lines, its in-plane rigid motions held
/// at its two corners on one edge (the recipe of the error for unheld rigid motions), is a
/// simply supported beam in bending — f_k = k² (π / 2L²) √(EI / ρA) — and in its plane a beam
/// simply supported at those corners, f = (π / 2L²) √(E b² / 12ρ). `fix = "pinned"` on the end
/// lines holds the in-plane motion along the whole lines instead: that in-plane mode is gone.
/// Left out, the corners' supports are asked for by the error.
#[test]
fn strip_held_only_in_deflection_is_simply_supported() {
    let (e, rho, l, b, h): (f64, f64, f64, f64, f64) = (70e9, 2700.0, 0.5, 0.04, 0.004);
    let pi = std::f64::consts::PI;
    let bending = pi / (2.0 * l * l) * (e * h * h / (12.0 * rho)).sqrt();
    let in_plane = pi / (2.0 * l * l) * (e * b * b / (12.0 * rho)).sqrt();
    let pinned = "supports = [\n  { plane = { x = 0.0 }, fix = \"pinned\" },\n  \
                  { plane = { x = 0.5 }, fix = \"pinned\" },\n";
    let deflection_only = "supports = [\n  { plane = { x = 0.0 }, fix = [\"uz\"] },\n  \
                           { plane = { x = 0.5 }, fix = [\"uz\"] },\n";
    assert!(STRIP.contains(pinned));
    let base = STRIP.replace(pinned, deflection_only);
    // node 0 is the corner (0, 0), node 80 the corner (L, 0) of an 80 × 4 mesh
    let held = base.replace(
        deflection_only,
        &format!(
            "{deflection_only}  {{ nodes = [0], fix = [\"ux\", \"uy\"] }},\n  \
             {{ nodes = [80], fix = [\"uy\"] }},\n"
        ),
    );
    let sets = ["body.strip.elements=[80, 4]", "body.strip.modes=12"];
    let nearest = |got: &[f64], f: f64| {
        got.iter()
            .map(|g| g / f - 1.0)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap()
    };
    let got = frequencies(&held, &sets, "strip");
    for k in 1..=3 {
        let e = nearest(&got, (k * k) as f64 * bending);
        // measured 4e-5, 4e-4, 3.0e-3 (80 elements along)
        assert!(e.abs() < 5e-3, "bending mode {k}: {e:e}");
    }
    // measured −1.7 %: the shear of a strip 0.08 of its length wide
    let e = nearest(&got, in_plane);
    assert!(e.abs() < 3e-2, "in-plane mode: {e:e}");
    let got = frequencies(STRIP, &sets, "strip");
    assert!(
        nearest(&got, in_plane).abs() > 5e-2,
        "pinned lines hold the in-plane motion: {got:?}"
    );
    let (_d, err) = bad_deck(&base, |p| with_deck("modes", p, &[]));
    assert!(
        err.contains("rigid-body motion(s) free")
            && err.contains("fix = [\"ux\", \"uy\"]")
            && !err.contains("free-free"),
        "{err}"
    );
}

/// The natural frequency (Hz) of a free-free Timoshenko beam (bending stiffness `ei`, shear
/// stiffness `kga`, mass and rotary inertia per length `rho_a`, `rho_i`, length `l`) between
/// `lo` and `hi`: the root of the 4 × 4 determinant of the end conditions (no moment, no
/// shear force at both ends) on the exact solutions cosh, sinh, cos, sin.
fn free_free_timoshenko(
    ei: f64,
    kga: f64,
    rho_a: f64,
    rho_i: f64,
    l: f64,
    lo: f64,
    hi: f64,
) -> f64 {
    let det = |f: f64| {
        let w2 = (2.0 * std::f64::consts::PI * f).powi(2);
        // EI κGA s⁴ + ω² (κGA ρI + ρA EI) s² + ρA ω² (ρI ω² − κGA) = 0 in s²
        let (a4, a2, a0) = (
            ei * kga,
            w2 * (kga * rho_i + rho_a * ei),
            rho_a * w2 * (rho_i * w2 - kga),
        );
        let disc = (a2 * a2 - 4.0 * a4 * a0).sqrt();
        let (a, b) = (
            ((disc - a2) / (2.0 * a4)).sqrt(),
            ((disc + a2) / (2.0 * a4)).sqrt(),
        );
        // the rotation ψ of each solution: w = cosh ax → ψ = ca sinh ax, w = cos bx → ψ = cb sin bx
        let ca = a + rho_a * w2 / (kga * a);
        let cb = -b + rho_a * w2 / (kga * b);
        // rows ψ' (moment) and w' − ψ (shear) at x
        let rows = |x: f64| {
            let (ch, sh, c, s) = ((a * x).cosh(), (a * x).sinh(), (b * x).cos(), (b * x).sin());
            [
                [ca * a * ch, ca * a * sh, cb * b * c, cb * b * s],
                [(a - ca) * sh, (a - ca) * ch, -(b + cb) * s, (b + cb) * c],
            ]
        };
        let [r0, r1] = rows(0.0);
        let [r2, r3] = rows(l);
        nalgebra::Matrix4::from_rows(
            &[r0.into(), r1.into(), r2.into(), r3.into()].map(|r: nalgebra::RowVector4<f64>| r),
        )
        .determinant()
    };
    let (mut lo, mut hi) = (lo, hi);
    assert!(det(lo) * det(hi) < 0.0, "no root between {lo} and {hi} Hz");
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if det(lo) * det(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// A strip held only in its deflection along both end lines and otherwise free
/// (`reference = "partly-free"`: the in-plane translations and the rotation about the normal
/// are free, as free-free leaves all six) is a simply supported beam in bending —
/// f_k = k² (π / 2L²) √(EI / ρA) — and a free-free beam in its plane: Euler–Bernoulli
/// f_k = (β_k L)² / (2π L²) √(E b² / 12ρ), β₁L = 4.7300, β₂L = 7.8532, lowered 2.2 % and 5.9 %
/// by shear and rotary inertia (Timoshenko, Cowper's κ), which the mesh converges to: the
/// shipped `decks/modes_strip_partly_free.toml` and two coarser meshes. The supports alone are
/// refused, naming the motions they leave free and offering `partly-free`.
#[test]
fn strip_held_only_in_deflection_and_free_in_its_plane_is_free_free_in_plane() {
    let (e, nu, rho, l, b, h): (f64, f64, f64, f64, f64, f64) =
        (70e9, 0.3, 2700.0, 0.5, 0.04, 0.004);
    let pi = std::f64::consts::PI;
    let bending = pi / (2.0 * l * l) * (e * h * h / (12.0 * rho)).sqrt();
    let kga = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu) * e / (2.0 * (1.0 + nu)) * b * h;
    let in_plane = [4.730_040_745, 7.853_204_624].map(|beta_l: f64| {
        let euler = beta_l * beta_l / (2.0 * pi * l * l) * (e * b * b / (12.0 * rho)).sqrt();
        let i = h * b.powi(3) / 12.0;
        free_free_timoshenko(e * i, kga, rho * b * h, rho * i, l, 0.8 * euler, euler)
    });
    // the shipped example, at three meshes
    let free = std::fs::read_to_string(deck("modes_strip_partly_free.toml")).unwrap();
    let supports = free.replace("reference = \"partly-free\"", "reference = \"supports\"");
    assert_ne!(free, supports);
    let nearest = |got: &[f64], f: f64| {
        got.iter()
            .map(|g| g / f - 1.0)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap()
    };
    let mut previous = [f64::INFINITY; 2];
    for (n, m) in [(40, 4), (80, 8), (160, 16)] {
        let sets = [
            format!("body.strip.elements=[{n}, {m}]"),
            "body.strip.modes=16".into(),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let got = frequencies(&free, &sets, "strip");
        // no rigid mode is left among the elastic ones
        assert!(got[0] > 0.9 * bending, "{got:?}");
        for k in 1..=3 {
            let e = nearest(&got, (k * k) as f64 * bending);
            eprintln!("{n} × {m}: bending mode {k}: {e:e}");
            // measured up to 9.3e-3 (40 × 4), 3.4e-3 (80 × 8), 2.0e-3 (160 × 16)
            assert!(e.abs() < 1.5e-2, "{n} × {m}, bending mode {k}: {e:e}");
        }
        for (i, f) in in_plane.iter().enumerate() {
            let e = nearest(&got, *f);
            eprintln!("{n} × {m}: in-plane mode {}: {e:e}", i + 1);
            // measured 1.8 %, 0.53 %, 0.16 % (first) and 1.9 %, 0.57 %, 0.21 % (second): from
            // above, towards the closed form
            assert!(
                e > 0.0 && e < 0.6 * previous[i],
                "{n} × {m}, in-plane mode {}: {e:e}",
                i + 1
            );
            previous[i] = e;
        }
    }
    assert!(previous.iter().all(|e| *e < 3e-3), "{previous:?}");
    let (_d, err) = bad_deck(&supports, |p| with_deck("modes", p, &[]));
    assert!(
        err.contains("3 rigid-body motion(s) free: translation along x; translation along y; rotation about z")
            && err.contains("reference = \"partly-free\""),
        "{err}"
    );
}

/// In a mechanism the supports define the body's mode basis: the paper's beam slider-crank with
/// its rod's pinned ends stated as supports runs as with `reference = "pinned-ends"` (the frame
/// sits at the node nearest the centre of mass instead of an end, so the curves agree to the
/// modal truncation: measured 1e-4 of the peak), and so does the rod held only across its ends
/// and left free along its axis (`reference = "partly-free"`).
#[test]
fn supports_define_the_mode_basis_of_a_mechanism_body() {
    let dir = tempfile::tempdir().unwrap();
    let sets = [
        "sensitivity.enabled=false",
        "finite_differences.enabled=false",
    ];
    let peak = |summary: &serde_json::Value| {
        summary["responses"]["mid_deflection"]["max"]
            .as_f64()
            .unwrap()
    };
    let mut with_ref = sets.to_vec();
    with_ref.push("body.rod.reference=\"pinned-ends\"");
    let pinned = peak(&common::run_json(
        "slider_crank_beam.toml",
        &dir.path().join("a"),
        &with_ref,
    ));
    // the beam deck with `rod` written at the top of its rod's table, run with `extra` too
    let run_rod = |name: &str, rod: &str, extra: &[&str]| {
        let text = std::fs::read_to_string(common::deck("slider_crank_beam.toml"))
            .unwrap()
            .replace("[body.rod]\n", &format!("[body.rod]\n{rod}"));
        let p = dir.path().join(format!("{name}.toml"));
        std::fs::write(&p, text).unwrap();
        let out = dir.path().join(name);
        let mut args = vec![
            "run",
            p.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ];
        for s in sets.iter().chain(extra) {
            args.extend(["--set", s]);
        }
        let o = common::run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o
    };
    let o = run_rod(
        "supported",
        "reference = \"supports\"\nsupports = [\n  { nodes = [0], fix = [\"ux\", \"uy\", \"uz\", \
         \"rx\"] },\n  { nodes = [8], fix = [\"uy\", \"uz\"] },\n]\n",
        &[],
    );
    let supported = peak(&serde_json::from_slice(&o.stdout).unwrap());
    assert!(
        (supported / pinned - 1.0).abs() < 1e-3,
        "{supported} against {pinned}"
    );
    // held only across at both ends, free along its axis (partly free): the same motion to the
    // modal truncation (measured 8.6e-4 with 4 modes, 7.0e-4 with 8); its basis check (loads
    // relieved of their rigid-body part) says that eight eigenmodes miss much of its axial
    // compliance (38 %), which the mid-span deflection hardly feels
    let o = run_rod(
        "partly_free",
        "reference = \"partly-free\"\nsupports = [{ nodes = [0, 8], fix = [\"uy\"] }]\n",
        &["body.rod.modes=8"],
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("body.rod")
            && stderr.contains("misses 38.")
            && stderr.contains("hold the body with supports"),
        "{stderr}"
    );
    let free = peak(&serde_json::from_slice(&o.stdout).unwrap());
    assert!(
        (free / pinned - 1.0).abs() < 2e-3,
        "{free} against {pinned}"
    );
    // its sensitivities to the ply angle match the run's replayed central differences
    let o = run_rod(
        "partly_free_sensitivities",
        "reference = \"partly-free\"\nsupports = [{ nodes = [0, 8], fix = [\"uy\"] }]\n",
        &[
            "body.rod.modes=8",
            "sensitivity.enabled=true",
            "finite_differences.enabled=true",
            "sensitivity.method=\"direct\"",
        ],
    );
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let fd = doc["finite_differences"][0]["max_relative_difference"]["mid_deflection"]
        .as_f64()
        .unwrap();
    // measured 2.3e-5
    assert!(fd < 1e-3, "|FD − direct| / max |direct| = {fd:e}");
}

/// The shipped example of supports (`decks/modes_plate_supports.toml`, the plate above at
/// 32 × 32 cells) against the thin-plate closed form.
#[test]
fn the_shipped_supports_deck_matches_the_closed_form() {
    let text = std::fs::read_to_string(deck("modes_plate_supports.toml")).unwrap();
    let got = frequencies(&text, &[], "plate");
    let d = 70e9 * 0.01f64.powi(3) / (12.0 * (1.0 - 0.09));
    let f = |m: f64, n: f64| std::f64::consts::PI / 2.0 * (m * m + n * n) * (d / 27.0).sqrt();
    let exact = [f(1.0, 1.0), f(1.0, 2.0), f(2.0, 1.0), f(2.0, 2.0)];
    for (i, (g, e)) in got.iter().zip(&exact).enumerate() {
        let bound = if i == 0 { 3e-3 } else { 1.2e-2 };
        assert!((g / e - 1.0).abs() < bound, "mode {}: {g} vs {e}", i + 1);
    }
}
