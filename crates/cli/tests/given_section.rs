//! `shape = "properties"`: a beam section given by its stiffness and mass properties instead of
//! analysed. Given the paper's tube's own analysed properties, it is that tube: the same
//! modes and the same run. Given by its stiffnesses about centres off the axis, it couples as
//! the strain energy says; bad properties are located.

mod common;
use common::*;

/// The beam deck with its tube section replaced by `table` (the body of a `[section.tube]`).
fn beam_deck_with_section(table: &str) -> String {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    with_table(&text, "[section.tube]", table)
}

/// The values `flexsens section` reports for the beam deck's tube.
fn tube_values() -> serde_json::Value {
    let j = json(&[
        "section",
        deck("slider_crank_beam.toml").to_str().unwrap(),
        "--format",
        "json",
    ]);
    j["sections"]["tube"]["values"].clone()
}

/// The tube's analysed properties as a `shape = "properties"` table (full precision).
fn tube_as_properties() -> String {
    let v = &tube_values();
    let rows: Vec<String> = matrix(&v["stiffness"])
        .iter()
        .map(|r| {
            let r: Vec<String> = r.iter().map(|x| format!("{x:e}")).collect();
            format!("[{}]", r.join(", "))
        })
        .collect();
    let pair = |k: &str| {
        let x: Vec<String> = v[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| format!("{:e}", x.as_f64().unwrap()))
            .collect();
        format!("[{}]", x.join(", "))
    };
    format!(
        "shape = \"properties\"\nstiffness = [{}]\nmass_per_length = {:e}\nmass_centre = {}\n\
         inertia = {}\n",
        rows.join(", "),
        v["mass_per_length"].as_f64().unwrap(),
        pair("mass_centre"),
        pair("mass_inertia")
    )
}

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> String {
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

/// The modes' frequencies (Hz) of `deck`.
fn frequencies(deck: &str) -> Vec<f64> {
    let j = json(&["modes", deck, "--format", "json"]);
    j["bodies"]["rod"]["values"]["frequencies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The run's mid-span deflection history (no sensitivities).
fn deflection(dir: &tempfile::TempDir, deck: &str, out: &str) -> Vec<f64> {
    let out = dir.path().join(out);
    json(&[
        "run",
        deck,
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--set",
        "analysis.t_end=0.01",
        "--set",
        "sensitivity.enabled=false",
        "--set",
        "finite_differences.enabled=false",
    ]);
    let g = flexsens::results::Group::read_hdf5(&out.join("results.h5")).unwrap();
    f64s(&g, "responses/mid_deflection")
}

#[test]
fn a_section_given_by_the_tubes_properties_is_the_tube() {
    let dir = tempfile::tempdir().unwrap();
    let analysed = deck("slider_crank_beam.toml").display().to_string();
    let given = write(
        &dir,
        "given.toml",
        &beam_deck_with_section(&tube_as_properties()),
    );
    // it has no points to recover stresses at
    let o = run(&["section", &given, "--load", "F1=1"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.code() == Some(2) && err.contains("no points to recover stresses"),
        "{err}"
    );
    let (fa, fg) = (frequencies(&analysed), frequencies(&given));
    assert_eq!(fa.len(), fg.len());
    for (a, g) in fa.iter().zip(&fg) {
        assert!((a - g).abs() <= 1e-12 * a, "{a} Hz against {g} Hz");
    }
    let (a, g) = (
        deflection(&dir, &analysed, "a"),
        deflection(&dir, &given, "g"),
    );
    assert_eq!(a.len(), g.len());
    let peak = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(peak > 1e-4);
    // the same model to round-off (the modes to 1e-12): the adaptive runs agree to well within
    // their tolerance (measured 7e-8 of the peak, from a step sequence that round-off moved)
    let d = worst_difference(&a, &g);
    assert!(d <= 1e-6 * peak, "{d:e} of {peak:e}");
}

/// The stiffness `flexsens section` reports about the origin for a section given by `EA … EI3`
/// about centres off the axis, against the closed form of the strain energy with the axial
/// strain at the tension centre `t` (`ε + t₃κ₂ − t₂κ₃`) and the shear strains at the shear
/// centre `s` (`γ₂ − s₃κ₁`, `γ₃ + s₂κ₁`): `K₁₆ = −t₂ EA`, `K₁₅ = t₃ EA`, `K₆₆ = EI₃ + t₂² EA`,
/// `K₃₄ = s₂ GA₃`, `K₂₄ = −s₃ GA₂`, `K₄₄ = GJ + s₂² GA₃ + s₃² GA₂`; at the origin the values
/// are the diagonal, each key in its place.
#[test]
fn stiffnesses_about_offset_centres_couple_as_the_strain_energy_says() {
    let dir = tempfile::tempdir().unwrap();
    let (ea, ga2, ga3, gj, ei2, ei3) = (2.1e7, 7.0e6, 6.0e6, 150.0, 110.0, 2600.0);
    let stiffness = |t: [f64; 2], s: [f64; 2]| {
        let deck = format!(
            "[section.bar]\nshape = \"properties\"\nEA = {ea:e}\nGA2 = {ga2:e}\nGA3 = {ga3:e}\n\
             GJ = {gj:e}\nEI2 = {ei2:e}\nEI3 = {ei3:e}\ntension_centre = [{:e}, {:e}]\n\
             shear_centre = [{:e}, {:e}]\nmass_per_length = 0.54\ninertia = [2.5e-6, 7.2e-5]\n",
            t[0], t[1], s[0], s[1]
        );
        let path = write(&dir, "bar.toml", &deck);
        let j = json(&["section", &path, "--format", "json"]);
        matrix(&j["sections"]["bar"]["values"]["stiffness"])
    };
    let k = stiffness([0.0, 0.0], [0.0, 0.0]);
    for (i, v) in [ea, ga2, ga3, gj, ei2, ei3].iter().enumerate() {
        for j in 0..6 {
            let expected = if i == j { *v } else { 0.0 };
            assert_eq!(k[i][j], expected, "K{}{}", i + 1, j + 1);
        }
    }
    let (t, s) = ([0.005, -0.002], [-0.008, 0.003]);
    let k = stiffness(t, s);
    let close = |got: f64, expected: f64| (got - expected).abs() <= 1e-12 * expected.abs();
    for (got, expected, what) in [
        (k[0][5], -t[0] * ea, "K16"),
        (k[0][4], t[1] * ea, "K15"),
        (k[5][5], ei3 + t[0] * t[0] * ea, "K66"),
        (k[4][4], ei2 + t[1] * t[1] * ea, "K55"),
        (k[4][5], -t[0] * t[1] * ea, "K56"),
        (k[2][3], s[0] * ga3, "K34"),
        (k[1][3], -s[1] * ga2, "K24"),
        (k[3][3], gj + s[0] * s[0] * ga3 + s[1] * s[1] * ga2, "K44"),
        (k[0][0], ea, "K11"),
        (k[1][1], ga2, "K22"),
    ] {
        assert!(close(got, expected), "{what}: {got:e} against {expected:e}");
    }
}

#[test]
fn properties_that_are_no_section_are_located() {
    let good = tube_as_properties();
    for (edit, key, says) in [
        (
            good.replace("mass_per_length = ", "mass_per_length = -"),
            "section.tube.mass_per_length",
            "must be a positive",
        ),
        (
            good.replacen("stiffness = [[", "stiffness = [[-", 1),
            "section.tube",
            "not positive definite",
        ),
        (format!("{good}EA = 1e7\n"), "section.tube.EA", "not both"),
        (
            good.replace("inertia = [", "inertia = [1.0, "),
            "section.tube.inertia",
            "[I22, I33, I23]",
        ),
        (
            "shape = \"properties\"\nEA = 1e7\nmass_per_length = 1.0\ninertia = [1e-6, 1e-6]\n"
                .to_string(),
            "section.tube.GA2",
            "GA2",
        ),
        (
            format!("{good}width = 0.01\n"),
            "section.tube.width",
            "does not apply",
        ),
    ] {
        let (_dir, err) = bad_deck(&beam_deck_with_section(&edit), |p| {
            vec!["check".into(), p.display().to_string()]
        });
        assert!(
            err.contains(&format!("key `{key}`")) && err.contains(says),
            "{key}: {err}"
        );
    }
}

/// The steel slider-crank of `examples/time_to_accuracy` with its 6 mm rod given by the closed
/// forms of a solid circle (`EA = EπR²`, `EI = EπR⁴/4`, `GJ = GπR⁴/2`, `GA = κGπR²` with
/// Timoshenko's `κ = 6(1 + ν)/(7 + 6ν)`), the rod's `EI3` and mass per length as design
/// variables, 20 ms.
fn steel_rod_by_closed_forms() -> String {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/time_to_accuracy/steel_slider_crank.toml"),
    )
    .unwrap();
    let (r, e, nu, rho) = (3e-3, 2.0e11, 0.3, 7850.0);
    let g = e / (2.0 * (1.0 + nu));
    let pi = std::f64::consts::PI;
    let (a, i) = (pi * r * r, pi * r.powi(4) / 4.0);
    let kappa = 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu);
    let table = format!(
        "shape = \"properties\"\nEA = {:e}\nGA2 = {:e}\nGA3 = {:e}\nGJ = {:e}\n\
         EI2 = {:e}\nEI3 = {:e}\nmass_per_length = {:e}\ninertia = [{:e}, {:e}]",
        e * a,
        kappa * g * a,
        kappa * g * a,
        g * 2.0 * i,
        e * i,
        e * i,
        rho * a,
        rho * i,
        rho * i
    );
    let design = "[design.ei]\nkind = \"section-property\"\nsection = \"rod\"\nentry = \"EI3\"\n\n\
         [design.mass]\nkind = \"section-property\"\nsection = \"rod\"\n\
         entry = \"mass_per_length\"\n\n[objective.peak]\nresponse = \"mid_deflection\"\n\
         kind = \"max\"\n\n[sensitivity]\nmethod = \"direct\"\n\n[finite_differences]\n\
         scheme = \"central\"\nsizes = [0.0001]\nsteps = \"replay\"\n\n[analysis]";
    with_table(&text, "[section.rod]", &table).replace("[analysis]", design)
}

/// The rod given by closed forms is the analysed 6 mm circle (first frequency within 1e-4);
/// the derivatives with respect to its `EI3` and mass per length equal replayed central
/// differences of whole runs (measured 3.3e-6 of the largest) and have the physics' signs
/// and sizes: the peak deflection, an inertial load over a bending stiffness, falls as `EI3`
/// rises and grows with the mass, each at about the power one (−1.11 and +1.23 here, the
/// rest the dynamics of the sudden start).
#[test]
fn section_property_derivatives_equal_replayed_differences() {
    let dir = tempfile::tempdir().unwrap();
    let given = write(&dir, "steel.toml", &steel_rod_by_closed_forms());
    let analysed = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/time_to_accuracy/steel_slider_crank.toml");
    let (fg, fa) = (frequencies(&given), frequencies(analysed.to_str().unwrap()));
    assert!(
        (fg[0] / fa[0] - 1.0).abs() < 1e-4,
        "{} against {} Hz",
        fg[0],
        fa[0]
    );
    let out = dir.path().join("out");
    let j = json(&[
        "run",
        &given,
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--set",
        "analysis.t_end=0.02",
    ]);
    let g = flexsens::results::Group::read_hdf5(&out.join("results.h5")).unwrap();
    let direct = f64s(&g, "sensitivities/mid_deflection");
    let fd = f64s(
        &g,
        "finite_differences/central_relative_0.0001_replay/mid_deflection",
    );
    for v in 0..2 {
        let col = |x: &[f64]| -> Vec<f64> { x.iter().skip(v).step_by(2).copied().collect() };
        let (d, f) = (col(&direct), col(&fd));
        // relative to the largest derivative
        let err = worst_difference(&d, &f);
        assert!(err < 1e-4, "variable {v}: {err:e}");
    }
    let peak = &j["objectives"][0];
    let value = peak["value"].as_f64().unwrap();
    let gradient: Vec<f64> = peak["gradient"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let nominal: Vec<f64> = j["design"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["value"].as_f64().unwrap())
        .collect();
    let elasticity = |k: usize| gradient[k] * nominal[k] / value;
    assert!(
        (-1.3..-0.9).contains(&elasticity(0)),
        "EI3: {}",
        elasticity(0)
    );
    assert!(
        (0.9..1.4).contains(&elasticity(1)),
        "mass: {}",
        elasticity(1)
    );
}

#[test]
fn section_property_variables_are_checked() {
    let deck = steel_rod_by_closed_forms();
    let variable =
        "\n[design.k]\nkind = \"section-property\"\nsection = \"tube\"\nentry = \"EI3\"\n";
    for (edit, key, says) in [
        (
            deck.replacen("entry = \"EI3\"", "entry = \"EI4\"", 1),
            "design.ei.entry",
            "unknown entry `EI4`",
        ),
        (
            deck.replacen(
                "section = \"rod\"\nentry = \"EI3\"",
                "section = \"tube\"\nentry = \"EI3\"",
                1,
            ),
            "design.ei.section",
            "undefined section",
        ),
        (
            deck.replacen("entry = \"EI3\"", "entry = \"EI3\"\nlaminate = \"x\"", 1),
            "design.ei.laminate",
            "does not apply",
        ),
        (
            format!(
                "{}{variable}",
                beam_deck_with_section(&tube_as_properties())
            ),
            "design.k.entry",
            "given by its 6×6 stiffness",
        ),
        (
            format!(
                "{}{variable}",
                std::fs::read_to_string(common::deck("slider_crank_beam.toml")).unwrap()
            ),
            "design.k.section",
            "is analysed",
        ),
    ] {
        let (_dir, err) = bad_deck(&edit, |p| vec!["check".into(), p.display().to_string()]);
        assert!(
            err.contains(&format!("key `{key}`")) && err.contains(says),
            "{key}: {err}"
        );
    }
}

/// The tube given with its mass as a 6×6 mass matrix (the one the section's own mass
/// properties make, `section::SectionProperties::mass_matrix`) is the tube: the same modes to
/// 1e-12; a mass matrix of no rigid section is refused at its key.
#[test]
fn a_mass_matrix_gives_the_sections_mass() {
    let dir = tempfile::tempdir().unwrap();
    let v = &tube_values();
    let numbers = |key: &str| -> Vec<f64> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (c, i) = (numbers("mass_centre"), numbers("mass_inertia"));
    let p = section::SectionProperties {
        mass_per_length: v["mass_per_length"].as_f64().unwrap(),
        mass_centre: [c[0], c[1]],
        mass_inertia: [i[0], i[1], i[2]],
        ..Default::default()
    };
    let rows = |mm: &nalgebra::Matrix6<f64>| -> String {
        let rows: Vec<String> = (0..6)
            .map(|r| {
                let row: Vec<String> = (0..6).map(|c| format!("{:e}", mm[(r, c)])).collect();
                format!("[{}]", row.join(", "))
            })
            .collect();
        rows.join(", ")
    };
    let mm = p.mass_matrix();
    let with_matrix = |matrix: &str| {
        let table = tube_as_properties();
        let stiffness = table
            .lines()
            .find(|l| l.starts_with("stiffness"))
            .unwrap()
            .to_string();
        format!("shape = \"properties\"\n{stiffness}\nmass_matrix = [{matrix}]\n")
    };
    let given = write(
        &dir,
        "mass_matrix.toml",
        &beam_deck_with_section(&with_matrix(&rows(&mm))),
    );
    let analysed = deck("slider_crank_beam.toml").display().to_string();
    for (a, g) in frequencies(&analysed).iter().zip(frequencies(&given)) {
        assert!((a - g).abs() <= 1e-12 * a, "{a} Hz against {g} Hz");
    }
    // its mass entries are not design variables (a sweep would write them beside it)
    let variable = "\n[design.m]\nkind = \"section-property\"\nsection = \"tube\"\n\
                    entry = \"mass_per_length\"\n";
    let (_dir, err) = bad_deck(
        &format!(
            "{}{variable}",
            beam_deck_with_section(&with_matrix(&rows(&mm)))
        ),
        |p| vec!["check".into(), p.display().to_string()],
    );
    assert!(
        err.contains("key `design.m.entry`") && err.contains("mass matrix"),
        "{err}"
    );
    // a polar inertia that is not the sum of the other two
    let mut polar = mm;
    polar[(3, 3)] *= 1.1;
    let (_dir, err) = bad_deck(&beam_deck_with_section(&with_matrix(&rows(&polar))), |p| {
        vec!["check".into(), p.display().to_string()]
    });
    assert!(
        err.contains("key `section.tube.mass_matrix`") && err.contains("not a rigid section's"),
        "{err}"
    );
}
