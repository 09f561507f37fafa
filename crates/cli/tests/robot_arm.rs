//! The shipped 3-D robot arm (`decks/robot_arm_composite.toml`): at rest after its swing, the
//! payload's height is the static deflection of its two cantilevered composite links under
//! their weight and the payload's, plus the elbow motor's droop (a PD law holds a torque with
//! an error of torque / kp) — the closed forms of Timoshenko cantilevers with the section
//! stiffnesses `flexsens section` gives; the height's sensitivities to each link's lay-up are
//! the closed form's derivatives through the sections' stiffness derivatives, and equal the
//! run's replayed central differences.

mod common;
use common::*;

const G: f64 = 9.81;
const PAYLOAD: f64 = 0.5;
const KP_ELBOW: f64 = 2000.0;
const L1: f64 = 0.5;
const L2: f64 = 0.4;

/// A link's compliances in the plane of gravity (x–z): `1/EI2` (bending about y) and `1/GA3`
/// (shear along z), and its mass per length.
#[derive(Clone, Copy)]
struct Link {
    bending: f64,
    shear: f64,
    mass: f64,
}

/// The payload's height at rest: the forearm (length `L2`) a cantilever under its weight and
/// the payload's from the elbow, the upper arm (`L1`) one under its weight, the elbow's force
/// and moment; the elbow droops by the moment over `kp`; the payload drops by the upper arm's
/// tip deflection, its tip rotation and the droop over the forearm, and the forearm's
/// deflection.
fn height(upper: Link, fore: Link) -> f64 {
    let (q1, q2, p) = (upper.mass * G, fore.mass * G, PAYLOAD * G);
    let fore_deflection = (q2 * L2.powi(4) / 8.0 + p * L2.powi(3) / 3.0) * fore.bending
        + (q2 * L2 * L2 / 2.0 + p * L2) * fore.shear;
    let (moment, force) = (q2 * L2 * L2 / 2.0 + p * L2, q2 * L2 + p);
    let upper_deflection =
        (q1 * L1.powi(4) / 8.0 + force * L1.powi(3) / 3.0 + moment * L1 * L1 / 2.0) * upper.bending
            + (q1 * L1 * L1 / 2.0 + force * L1) * upper.shear;
    let upper_rotation =
        (q1 * L1.powi(3) / 6.0 + force * L1 * L1 / 2.0 + moment * L1) * upper.bending;
    -(upper_deflection + (upper_rotation + moment / KP_ELBOW) * L2 + fore_deflection)
}

/// The elbow's moment at rest.
fn elbow_moment(fore: Link) -> f64 {
    let q2 = fore.mass * G;
    q2 * L2 * L2 / 2.0 + PAYLOAD * G * L2
}

/// Each section's link and, per design variable, the derivative of its compliances
/// (`d(1/k)/db = −(dk/db)/k²`; the mass does not move with an angle).
fn links() -> Vec<(Link, Vec<(String, Link)>)> {
    let path = deck("robot_arm_composite.toml");
    let j = json(&[
        "section",
        path.to_str().unwrap(),
        "--format",
        "json",
        "--derivatives",
    ]);
    ["upper_tube", "fore_box"]
        .iter()
        .map(|name| {
            let s = &j["sections"][name];
            let k = matrix(&s["values"]["stiffness"]);
            // nothing couples bending in the plane of gravity to its shear
            assert!(k[2][4].abs() < 1e-9 * k[4][4], "{name}: {}", k[2][4]);
            let link = Link {
                bending: 1.0 / k[4][4],
                shear: 1.0 / k[2][2],
                mass: s["values"]["mass_per_length"].as_f64().unwrap(),
            };
            let derivatives = s["derivatives"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| {
                    let dk = matrix(&d["values"]["stiffness"]);
                    let wrt = d["wrt"].as_str().unwrap().to_string();
                    let change = Link {
                        bending: -dk[4][4] / (k[4][4] * k[4][4]),
                        shear: -dk[2][2] / (k[2][2] * k[2][2]),
                        mass: 0.0,
                    };
                    (wrt, change)
                })
                .collect();
            (link, derivatives)
        })
        .collect()
}

/// The closed form's derivative along `change` of one link (`upper` or not).
fn height_derivative(upper: Link, fore: Link, change: Link, of_upper: bool) -> f64 {
    let h = 1e-6;
    let step = |l: Link, s: f64| Link {
        bending: l.bending + s * change.bending,
        shear: l.shear + s * change.shear,
        mass: l.mass,
    };
    let at = |s: f64| {
        if of_upper {
            height(step(upper, s), fore)
        } else {
            height(upper, step(fore, s))
        }
    };
    // linear in the compliances: the central difference is exact to round-off
    (at(h) - at(-h)) / (2.0 * h)
}

#[test]
fn the_arm_at_rest_deflects_as_its_cantilevers_and_so_do_its_sensitivities() {
    let all = links();
    let (upper, fore) = (all[0].0, all[1].0);
    let dir = tempfile::tempdir().unwrap();
    let (j, g) = run_results(
        &deck("robot_arm_composite.toml"),
        &dir.path().join("out"),
        &[],
    );
    let last = |r: &str| *f64s(&g, &format!("responses/{r}")).last().unwrap();
    let exact = height(upper, fore);
    let z = last("payload_z");
    assert!(
        (z / exact - 1.0).abs() < 1e-3,
        "height {z:e} against {exact:e}"
    );
    let torque = last("elbow_torque");
    let moment = elbow_moment(fore);
    assert!(
        (torque.abs() / moment - 1.0).abs() < 1e-4,
        "elbow torque {torque} against {moment}"
    );
    // and the arm has swung: the payload is 60° round
    let y = last("payload_y");
    assert!(
        (y / (0.9 * 60f64.to_radians().sin()) - 1.0).abs() < 1e-2,
        "{y}"
    );
    // the final height's gradient against the closed form's, per degree
    let objective = j["objectives"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["name"] == "final_height")
        .unwrap();
    let names: Vec<String> = j["design"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["name"].as_str().unwrap().to_string())
        .collect();
    for (i, link) in all.iter().enumerate() {
        for (wrt, change) in &link.1 {
            let exact = height_derivative(upper, fore, *change, i == 0);
            let k = names.iter().position(|n| n == wrt).unwrap();
            let got = objective["gradient"][k].as_f64().unwrap();
            assert!(
                (got / exact - 1.0).abs() < 5e-3,
                "d height / d {wrt}: {got:e} against {exact:e}"
            );
        }
    }
    // the histories' sensitivities against replayed central differences
    let direct = f64s(&g, "sensitivities/payload_z");
    let fd = f64s(
        &g,
        "finite_differences/central_relative_0.001_replay/payload_z",
    );
    let err = worst_difference(&direct, &fd);
    assert!(err < 2e-3, "direct against replayed differences: {err:e}");
}
