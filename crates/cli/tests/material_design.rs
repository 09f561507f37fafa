//! A material's elastic constant as a design variable (`kind = "material"`): through the
//! section, laminate and shell analyses and a whole run, against closed forms (stiffness and
//! frequencies scale with E at fixed ν) and central differences of command-line runs.

mod common;

use common::{
    bad_deck, beam_direct_vs_central, deck, direct_vs_central_of, matrix, report, with_deck,
    with_extra,
};

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
            "kind = \"material\"\nmaterial = \"aluminium\"\nconstant = \"G12\"",
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

/// An isotropic material's Poisson ratio at fixed E (`constant = "nu"`): the shear moduli
/// follow, `G = E/(2(1 + ν))`, not linearly. The rectangle's extension and bending stiffnesses
/// do not move; its torsion stiffness goes as G (`dGJ/dν = −GJ/(1 + ν)`, the Saint-Venant `J`
/// of a homogeneous section not depending on ν); every entry against central differences of
/// `--set material.aluminium.nu`; the spin-up beam's tip deflection against replayed central
/// differences of whole runs.
#[test]
fn isotropic_poisson_ratio_moves_the_shear_moduli() {
    let (_dir, path) = with_extra(
        "section_isotropic_rectangle.toml",
        "\n[design.poisson]\nkind = \"material\"\nmaterial = \"aluminium\"\nconstant = \"nu\"\n",
    );
    let doc = report("section", &path, &["--derivatives".into()]);
    let bar = &doc["sections"]["bar"];
    let d = &bar["derivatives"][0];
    assert_eq!(d["wrt"], "poisson");
    assert_eq!(d["per"], "1");
    let k = matrix(&bar["values"]["stiffness"]);
    let dk = matrix(&d["values"]["stiffness"]);
    let nu = 0.33;
    for i in [0, 4, 5] {
        assert!(dk[i][i].abs() <= 1e-9 * k[i][i], "K{i}{i}: {}", dk[i][i]);
    }
    let expected = -k[3][3] / (1.0 + nu);
    assert!(
        (dk[3][3] - expected).abs() <= 1e-9 * expected.abs(),
        "dGJ/dnu {} vs {expected}",
        dk[3][3]
    );
    // Central differences at h and h/2 extrapolated (Richardson: error O(h⁴)): at h = 2e-3 the
    // truncation is about 1e-10 of the entries and the section's round-off (about 1e-12 of
    // them) about 1e-9; a plain central difference has no step with both below 1e-7 (the
    // round-off alone is 1e-7 at h = 1e-5, where its truncation is 3e-10)
    let h = 2e-3;
    let at = |x: f64| {
        matrix(
            &report(
                "section",
                &path,
                &["--set".into(), format!("material.aluminium.nu={x:?}")],
            )["sections"]["bar"]["values"]["stiffness"],
        )
    };
    let central = |h: f64| {
        let (plus, minus) = (at(nu + h), at(nu - h));
        let mut d = [[0.0; 6]; 6];
        for i in 0..6 {
            for j in 0..6 {
                d[i][j] = (plus[i][j] - minus[i][j]) / (2.0 * h);
            }
        }
        d
    };
    let (coarse, fine) = (central(h), central(h / 2.0));
    for i in 0..6 {
        for j in 0..6 {
            let fd = (4.0 * fine[i][j] - coarse[i][j]) / 3.0;
            let scale = (k[i][i] * k[j][j]).sqrt();
            assert!(
                (dk[i][j] - fd).abs() <= 1e-7 * scale,
                "K{i}{j}: {} vs central differences {fd}",
                dk[i][j]
            );
        }
    }
    // the shear stiffnesses fall with ν (G does), but not as G: the shear correction rises
    // the shear stiffnesses fall with ν: along the width nearly as G (Cowper's coefficient
    // hardly moves), through the thickness four times faster (the anticlastic warping of a
    // wide rectangle, see the deck)
    let g = -1.0 / (1.0 + nu);
    assert!(
        (dk[1][1] / k[1][1] - g).abs() < 1e-2 * g.abs(),
        "{}",
        dk[1][1] / k[1][1]
    );
    assert!(dk[2][2] / k[2][2] < 3.0 * g, "{}", dk[2][2] / k[2][2]);

    // a laminate (shells' path): A₁₁ = Et/(1 − ν²), A₆₆ = Gt = Et/(2(1 + ν)),
    // D₁₁ = Et³/(12(1 − ν²))
    let dir = tempfile::tempdir().unwrap();
    let sheet = dir.path().join("sheet.toml");
    std::fs::write(
        &sheet,
        "[material.steel]\nE = 210e9\nnu = 0.3\ndensity = 7850.0\n\
         [laminate.sheet]\nplies = [{ material = \"steel\", thickness = 2e-3, angle = 0.0 }]\n\
         [design.poisson]\nkind = \"material\"\nmaterial = \"steel\"\nconstant = \"nu\"\n",
    )
    .unwrap();
    let lam = report("laminate", &sheet, &["--derivatives".into()]);
    let d = &lam["laminates"]["sheet"]["derivatives"][0]["values"];
    let (e, nu, t): (f64, f64, f64) = (210e9, 0.3, 2e-3);
    let q = 1.0 - nu * nu;
    for (got, expected, what) in [
        (
            matrix(&d["A"])[0][0],
            e * t * 2.0 * nu / (q * q),
            "dA11/dnu",
        ),
        (
            matrix(&d["A"])[2][2],
            -e * t / (2.0 * (1.0 + nu) * (1.0 + nu)),
            "dA66/dnu",
        ),
        (
            matrix(&d["D"])[0][0],
            e * t.powi(3) / 12.0 * 2.0 * nu / (q * q),
            "dD11/dnu",
        ),
    ] {
        assert!(
            (got - expected).abs() <= 1e-9 * expected.abs(),
            "{what}: {got} vs {expected}"
        );
    }

    // ν moves the beam only through its shear stiffness: the tip moves by ~5e-6 m per unit
    // ν, so differences of whole runs need a large step (1 % of ν) to rise above the runs'
    // round-off (2e-4 at 0.1 %, 1.4e-3 at 0.01 %, so about 2e-5 at 1 %: 3.3e-6 and 1.1e-5
    // measured with two orderings of the section's factorisation, whose round-off, 2e-12 of
    // the stiffness, is the same size)
    let errors = direct_vs_central_of(
        "spin_up_beam.toml",
        "\n[design.poisson]\nkind = \"material\"\nmaterial = \"aluminium\"\nconstant = \"nu\"\n\
         [finite_differences]\nscheme = \"central\"\nsizes = [1e-2]\nsteps = \"replay\"\n",
        "1e-2",
        &["poisson"],
        "tip_deflection",
        "2.0",
    );
    for (err, scale) in errors {
        assert!(scale > 0.0);
        assert!(err < 3e-5, "{err:e}");
    }
}
