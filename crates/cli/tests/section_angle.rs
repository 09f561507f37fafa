//! `kind = "section-angle"`: the material angle of a solid section as a design variable. A
//! homogeneous off-axis section under an axial force alone (its shear strains free: the
//! classical stiffness) carries it by a uniaxial stress, so its axial stiffness is the off-axis
//! modulus times the area, `EA(θ) = A / (c⁴/E1 + (1/G12 − 2ν12/E1) s²c² + s⁴/E2)`, and its
//! derivative follows; through a whole run the variable's sensitivities equal replayed central
//! differences.

mod common;
use common::*;

const MATERIAL: &str = "[material.paper_composite]\nE1 = 128.0e9\nE2 = 10.1e9\nE3 = 10.1e9\n\
    G12 = 5.36e9\nG13 = 5.36e9\nG23 = 5.36e9\nnu12 = 0.23\nnu13 = 0.23\nnu23 = 0.23\n\
    density = 1586.0\n";

/// `A · E_x(θ)` of the paper's composite (θ in degrees) over a 20 × 5 mm rectangle.
fn axial_stiffness(theta: f64) -> f64 {
    let (e1, e2, g12, nu12) = (128.0e9, 10.1e9, 5.36e9, 0.23);
    let (s, c) = theta.to_radians().sin_cos();
    let compliance =
        c.powi(4) / e1 + (1.0 / g12 - 2.0 * nu12 / e1) * s * s * c * c + s.powi(4) / e2;
    0.02 * 0.005 / compliance
}

#[test]
fn a_solid_sections_angle_moves_its_axial_stiffness_as_the_off_axis_modulus() {
    let dir = tempfile::tempdir().unwrap();
    let deck = format!(
        "{MATERIAL}\n[section.bar]\nshape = \"rectangle\"\nwidth = 0.02\nheight = 0.005\n\
         material = \"paper_composite\"\nangle = 30.0\nelements = [16, 4]\n\n\
         [design.phi]\nkind = \"section-angle\"\nsection = \"bar\"\n"
    );
    let path = dir.path().join("bar.toml");
    std::fs::write(&path, deck).unwrap();
    let j = json(&[
        "section",
        path.to_str().unwrap(),
        "--format",
        "json",
        "--derivatives",
    ]);
    let bar = &j["sections"]["bar"];
    let k11 = matrix(&bar["values"]["classical_stiffness"])[0][0];
    let exact = axial_stiffness(30.0);
    assert!(
        (k11 / exact - 1.0).abs() < 1e-9,
        "{k11:e} against {exact:e}"
    );
    let derivative = &bar["derivatives"][0];
    assert_eq!(derivative["wrt"], "phi");
    let dk11 = matrix(&derivative["values"]["classical_stiffness"])[0][0];
    let h = 1e-4;
    let d_exact = (axial_stiffness(30.0 + h) - axial_stiffness(30.0 - h)) / (2.0 * h);
    assert!(
        (dk11 / d_exact - 1.0).abs() < 1e-7,
        "{dk11:e} per degree against {d_exact:e}"
    );
}

/// The paper's beam deck with its tube replaced by a solid 20 × 5 mm rectangle of the same
/// composite at 15°, the rectangle's angle the design variable: the mid-span deflection's
/// derivative equals replayed central differences of whole runs.
#[test]
fn a_section_angle_derivative_equals_replayed_differences() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    let rectangle = "shape = \"rectangle\"\nwidth = 0.02\nheight = 0.005\n\
                     material = \"paper_composite\"\nangle = 15.0";
    let text = with_table(&text, "[section.tube]", rectangle).replace(
        "[design.theta]\n# the common angle of all plies of the tube (the paper's design variable), degrees\nlaminate = \"tube_wall\"",
        "[design.theta]\nkind = \"section-angle\"\nsection = \"tube\"",
    );
    assert!(text.contains("kind = \"section-angle\""));
    let dir = tempfile::tempdir().unwrap();
    let sets = ["analysis.t_end=0.01", "sensitivity.method=\"direct\""];
    let (_, g) = run_text(dir.path(), "rect", &text, &sets);
    let direct = f64s(&g, "sensitivities/mid_deflection");
    assert!(direct.iter().any(|x| x.abs() > 0.0));
    let err = replayed_difference(&g, "mid_deflection", "0.0001");
    assert!(err < 1e-4, "direct against replayed differences: {err:e}");
}

#[test]
fn a_section_angle_variable_needs_a_solid_section() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();
    let deck = format!("{text}\n[design.k]\nkind = \"section-angle\"\nsection = \"tube\"\n");
    let (_dir, err) = bad_deck(&deck, |p| vec!["check".into(), p.display().to_string()]);
    assert!(
        err.contains("key `design.k.section`") && err.contains("shape = \"tube\""),
        "{err}"
    );
}
