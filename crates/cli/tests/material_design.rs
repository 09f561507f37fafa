//! A material's elastic constant as a design variable (`kind = "material"`): through the
//! section, laminate and shell analyses and a whole run, against closed forms (stiffness and
//! frequencies scale with E at fixed ν) and central differences of command-line runs.

mod common;

use common::{bad_deck, beam_direct_vs_central, deck, matrix, report, with_deck, with_extra};

#[test]
fn isotropic_section_stiffness_is_linear_in_e() {
    let (_dir, path) = with_extra(
        "section_isotropic_rectangle.toml",
        "\n[design.modulus]\nkind = \"material\"\nmaterial = \"aluminium\"\nconstant = \"E\"\n",
    );
    let doc = report("section", &path, &["--derivatives".into()]);
    let bar = &doc["sections"]["bar"];
    let d = &bar["derivatives"][0];
    assert_eq!(d["wrt"], "modulus");
    assert_eq!(d["per"], "Pa");
    // at fixed ν every stiffness entry is proportional to E: dK/dE = K/E
    let k = matrix(&bar["values"]["stiffness"]);
    let dk = matrix(&d["values"]["stiffness"]);
    let scale = k.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs())) / 70e9;
    for i in 0..6 {
        for j in 0..6 {
            let expected = k[i][j] / 70e9;
            assert!(
                (dk[i][j] - expected).abs() <= 1e-9 * scale,
                "K{i}{j}: {} vs {expected}",
                dk[i][j]
            );
        }
    }
    // the mass does not depend on the modulus
    assert_eq!(d["values"]["mass_per_length"].as_f64().unwrap(), 0.0);
}

#[test]
fn orthotropic_constants_move_sections_and_laminates_as_central_differences_do() {
    let extra = "
[design.e1]
kind = \"material\"
material = \"paper_composite\"
constant = \"E1\"

[design.g12]
kind = \"material\"
material = \"paper_composite\"
constant = \"G12\"

[design.nu12]
kind = \"material\"
material = \"paper_composite\"
constant = \"nu12\"
";
    let (_dir, path) = with_extra("section_composite_tube.toml", extra);
    let sec = report("section", &path, &["--derivatives".into()]);
    let lam = report("laminate", &path, &["--derivatives".into()]);
    for (k, (name, constant, value, unit)) in [
        ("e1", "E1", 128.0e9, "Pa"),
        ("g12", "G12", 5.36e9, "Pa"),
        ("nu12", "nu12", 0.23, "1"),
    ]
    .into_iter()
    .enumerate()
    {
        let h = 1e-5 * value;
        let at = |s: f64, command: &str| {
            report(
                command,
                &path,
                &[
                    "--set".into(),
                    format!("material.paper_composite.{constant}={:?}", value + s),
                ],
            )
        };
        // section: the 6×6 stiffness
        let d = &sec["sections"]["rod"]["derivatives"][k];
        assert_eq!(d["wrt"], name);
        assert_eq!(d["per"], unit);
        let exact = matrix(&d["values"]["stiffness"]);
        let (p, m) = (at(h, "section"), at(-h, "section"));
        let (kp, km) = (
            matrix(&p["sections"]["rod"]["values"]["stiffness"]),
            matrix(&m["sections"]["rod"]["values"]["stiffness"]),
        );
        let scale = exact.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
        assert!(scale > 0.0, "{name}");
        for i in 0..6 {
            for j in 0..6 {
                let fd = (kp[i][j] - km[i][j]) / (2.0 * h);
                assert!(
                    (exact[i][j] - fd).abs() <= 1e-6 * scale,
                    "section {name} K{i}{j}: {} vs {fd}",
                    exact[i][j]
                );
            }
        }
        // laminate: A and D
        let d = &lam["laminates"]["tube_wall"]["derivatives"][k];
        assert_eq!(d["wrt"], name);
        let (p, m) = (at(h, "laminate"), at(-h, "laminate"));
        for what in ["A", "D"] {
            let exact = matrix(&d["values"][what]);
            let (xp, xm) = (
                matrix(&p["laminates"]["tube_wall"]["values"][what]),
                matrix(&m["laminates"]["tube_wall"]["values"][what]),
            );
            let scale = exact.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
            for i in 0..3 {
                for j in 0..3 {
                    let fd = (xp[i][j] - xm[i][j]) / (2.0 * h);
                    assert!(
                        (exact[i][j] - fd).abs() <= 1e-6 * scale,
                        "laminate {name} {what}{i}{j}: {} vs {fd}",
                        exact[i][j]
                    );
                }
            }
        }
    }
}

/// An isotropic square plate: its frequencies are proportional to √E at fixed ν and density,
/// so df/dE = f / (2E).
#[test]
fn shell_frequencies_follow_the_square_root_of_e() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plate.toml");
    std::fs::write(
        &path,
        "[material.steel]
E = 210e9
nu = 0.3
density = 7850.0

[laminate.sheet]
plies = [{ material = \"steel\", thickness = 2e-3, angle = 0.0 }]

[body.plate]
kind = \"shell\"
laminate = \"sheet\"
length = 0.3
width = 0.2
elements = [6, 4]
modes = 4
reference = \"free-free\"

[design.modulus]
kind = \"material\"
material = \"steel\"
constant = \"E\"
",
    )
    .unwrap();
    let doc = report("modes", &path, &["--derivatives".into()]);
    let body = &doc["bodies"]["plate"];
    let f: Vec<f64> = body["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let d = &body["derivatives"][0];
    assert_eq!(d["wrt"], "modulus");
    assert_eq!(d["per"], "Pa");
    for (i, x) in d["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let expected = f[i] / (2.0 * 210e9);
        let got = x.as_f64().unwrap();
        assert!(
            (got - expected).abs() <= 1e-8 * expected,
            "mode {}: {got} vs {expected} Hz/Pa",
            i + 1
        );
    }
}

#[test]
fn run_sensitivities_to_e1_match_replayed_central_differences() {
    let errors = beam_direct_vs_central(
        "\n[design.e1]\nkind = \"material\"\nmaterial = \"paper_composite\"\nconstant = \"E1\"\n",
        "1e-4",
        &["e1", "theta"],
    );
    // measured 2026-11-23: 4.2e-8 for both
    for (err, scale) in errors {
        assert!(scale > 0.0);
        assert!(err < 1e-5, "{err:e}");
    }
}

#[test]
fn bad_material_variables_are_located() {
    let base = std::fs::read_to_string(deck("section_isotropic_rectangle.toml")).unwrap();
    for (table, key, words) in [
        (
            "kind = \"material\"\nmaterial = \"aluminium\"\nconstant = \"nu\"",
            "design.v.constant",
            "is isotropic",
        ),
        (
            "kind = \"material\"\nmaterial = \"alu\"\nconstant = \"E\"",
            "design.v.material",
            "undefined material `alu`",
        ),
        (
            "kind = \"material\"\nmaterial = \"aluminium\"",
            "design.v.constant",
            "missing value",
        ),
    ] {
        let text = format!("{base}\n[design.v]\n{table}\n");
        let (_dir, err) = bad_deck(&text, |p| with_deck("section", p, &[]));
        assert!(err.contains(&format!("key `{key}`")), "{err}");
        assert!(err.contains(words), "{err}");
    }
}

/// The density: the section's mass per length moves by its area, the stiffness not; a plate's
/// frequencies go as 1/√ρ; the run's sensitivities (the rod's inertia loads) against replayed
/// central differences.
#[test]
fn density_moves_masses_through_sections_shells_and_runs() {
    let (_dir, path) = with_extra(
        "section_isotropic_rectangle.toml",
        "\n[design.rho]\nkind = \"material\"\nmaterial = \"aluminium\"\nconstant = \"density\"\n",
    );
    let doc = report("section", &path, &["--derivatives".into()]);
    let d = &doc["sections"]["bar"]["derivatives"][0];
    assert_eq!(d["per"], "kg/m^3");
    let area = 0.04 * 0.0075;
    let dm = d["values"]["mass_per_length"].as_f64().unwrap();
    assert!((dm - area).abs() < 1e-12 * area, "{dm} vs {area}");
    // the mass inertia about x2 is ρ w h³/12 per length
    let di = d["values"]["mass_inertia"][0].as_f64().unwrap();
    let expected = 0.04 * 0.0075f64.powi(3) / 12.0;
    assert!(
        (di - expected).abs() < 1e-9 * expected,
        "{di} vs {expected}"
    );
    assert!(
        matrix(&d["values"]["stiffness"])
            .iter()
            .flatten()
            .all(|&x| x == 0.0)
    );

    // an isotropic plate: ω² = k/(ρ …), so df/dρ = −f/(2ρ)
    let dir = tempfile::tempdir().unwrap();
    let plate = dir.path().join("plate.toml");
    std::fs::write(
        &plate,
        "[material.steel]\nE = 210e9\nnu = 0.3\ndensity = 7850.0\n\
         [laminate.sheet]\nplies = [{ material = \"steel\", thickness = 2e-3, angle = 0.0 }]\n\
         [body.plate]\nkind = \"shell\"\nlaminate = \"sheet\"\nlength = 0.3\nwidth = 0.2\n\
         elements = [6, 4]\nmodes = 4\nreference = \"free-free\"\n\
         [design.rho]\nkind = \"material\"\nmaterial = \"steel\"\nconstant = \"density\"\n",
    )
    .unwrap();
    let doc = report("modes", &plate, &["--derivatives".into()]);
    let body = &doc["bodies"]["plate"];
    for (f, df) in body["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .zip(
            body["derivatives"][0]["values"]["frequencies"]
                .as_array()
                .unwrap(),
        )
    {
        let expected = -f.as_f64().unwrap() / (2.0 * 7850.0);
        let got = df.as_f64().unwrap();
        assert!(
            (got - expected).abs() <= 1e-8 * expected.abs(),
            "{got} vs {expected}"
        );
    }

    // the beam slider-crank: the rod's density through its section, modes and masses
    let errors = beam_direct_vs_central(
        "\n[design.rho]\nkind = \"material\"\nmaterial = \"paper_composite\"\nconstant = \"density\"\n",
        "1e-4",
        &["rho", "theta"],
    );
    for (err, scale) in errors {
        assert!(scale > 0.0);
        assert!(err < 1e-5, "{err:e}");
    }
}
