//! `decks/four_bar_misaligned.toml`: a four-bar of four revolute joints whose rocker pivot is
//! tilted 0.5°, locked when its bars are rigid, starts at speed and turns by deforming. Its
//! coupler follows the planar kinematics of the aligned rigid four-bar
//! (`common::four_bar_midpoints`) within the misfit; turning far below the bars' frequencies,
//! its deformation and joint forces follow the static prestress of the locked frame, which a
//! start at that crank angle computes by least strain energy (another code path than the
//! dynamics); with every degree of freedom of the bars' meshes in their bases that start is
//! the finite-element solution of the locked frame, and the deck's bases give it.

mod common;
use common::*;

/// The results of a run of the deck with `sets`.
fn responses(dir: &tempfile::TempDir, name: &str, sets: &[&str]) -> flexsens::results::Group {
    run_results(
        &deck("four_bar_misaligned.toml"),
        &dir.path().join(name),
        sets,
    )
    .1
}

#[test]
fn the_misaligned_four_bar_turns_by_deforming_as_its_locked_frame_prescribes() {
    let dir = tempfile::tempdir().unwrap();
    let g = responses(&dir, "run", &["analysis.t_end=0.9"]);
    let times = f64s(&g, "time");
    let (x, y, z) = (
        f64s(&g, "responses/coupler_x"),
        f64s(&g, "responses/coupler_y"),
        f64s(&g, "responses/coupler_z"),
    );
    // in the plane: the aligned rigid four-bar's path, within the misfit's deformation
    let rigid = four_bar_midpoints(&times, 0.0);
    let planar = rigid
        .iter()
        .zip(x.iter().zip(&y))
        .fold(0.0f64, |m, (r, (x, y))| {
            m.max((r.x - x).abs()).max((r.y - y).abs())
        });
    assert!(planar < 5e-4, "off the planar path by {planar:e} m");
    // out of the plane: the bars bent by the misfit (a tenth of a millimetre and more)
    let deflection = z.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    assert!(deflection > 1e-4 && deflection < 1e-3, "{deflection:e} m");
    // at −36° of the crank (t = 0.9 s) the static prestress of a start there
    let at = times.iter().position(|&t| (t - 0.9).abs() < 1e-9).unwrap();
    let still = responses(
        &dir,
        "static",
        &[
            "joint.crank_drive.motion.initial=-36.0",
            "analysis.t_end=0.002",
            "analysis.output_step=0.001",
        ],
    );
    let (zs, fs) = (
        f64s(&still, "responses/coupler_z")[0],
        f64s(&still, "responses/pivot_force")[0],
    );
    let (xs, fd) = (
        f64s(&still, "responses/coupler_x")[0],
        f64s(&g, "responses/pivot_force")[at],
    );
    assert!(
        (xs - x[at]).abs() < 1e-5,
        "the same branch: {xs} against {}",
        x[at]
    );
    assert!(
        (zs / z[at] - 1.0).abs() < 0.02,
        "deflection {zs:e} against {:e}",
        z[at]
    );
    assert!(
        (fs / fd - 1.0).abs() < 0.05,
        "pivot force {fs:e} against {fd:e}"
    );
    // that static start is the finite-element solution of the locked frame: with 36
    // eigenmodes and the 12 correction modes of its joints, each bar's basis spans every
    // degree of freedom of its mesh (48 free), and the start is the same
    let mut sets = vec![
        "joint.crank_drive.motion.initial=-36.0",
        "analysis.t_end=0.002",
        "analysis.output_step=0.001",
    ];
    sets.extend([
        "body.crank.modes=36",
        "body.coupler.modes=36",
        "body.rocker.modes=36",
    ]);
    let full = responses(&dir, "full", &sets);
    let (zf, ff) = (
        f64s(&full, "responses/coupler_z")[0],
        f64s(&full, "responses/pivot_force")[0],
    );
    assert!(
        (zf / zs - 1.0).abs() < 1e-9,
        "deflection {zs:e} against the full mesh's {zf:e}"
    );
    assert!(
        (ff / fs - 1.0).abs() < 1e-5,
        "pivot force {fs:e} against the full mesh's {ff:e}"
    );
}

/// An angle driver's equation holds half a turn from its angle too: a start whose driver
/// angle is more than a quarter turn from the mechanism as drawn, which the assembly would
/// reach on the wrong side, is refused naming the driver (here the spatial four-bar started
/// at t = 0.6 s, its crank due at 216° and drawn at 0°).
#[test]
fn a_start_half_a_turn_from_its_driver_is_refused() {
    let deck = deck("four_bar_spatial.toml");
    let o = run(&[
        "check",
        deck.to_str().unwrap(),
        "--set",
        "analysis.t_start=0.6",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("angle driver `crank_drive` would hold its body half a turn from its angle"),
        "{err}"
    );
    // a quarter turn on, it assembles
    let o = run(&[
        "check",
        deck.to_str().unwrap(),
        "--set",
        "analysis.t_start=0.2",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The start's elastic rates move with the design (the least kinetic energy that meets the
/// joints depends on the masses): the sensitivities to the bars' density, through that start
/// and 20 ms of the run, equal replayed central differences of whole runs.
#[test]
fn sensitivities_through_the_elastic_rates_of_the_start_equal_differences() {
    let text = std::fs::read_to_string(deck("four_bar_misaligned.toml")).unwrap()
        + "\n[design.rho]\nkind = \"material\"\nmaterial = \"al\"\nconstant = \"density\"\n\n\
           [sensitivity]\nmethod = \"direct\"\n\n[finite_differences]\nscheme = \"central\"\n\
           sizes = [0.0001]\nsteps = \"replay\"\n";
    let dir = tempfile::tempdir().unwrap();
    let (_, g) = run_text(dir.path(), "rho", &text, &["analysis.t_end=0.02"]);
    for r in ["coupler_x", "coupler_z", "pivot_force"] {
        let direct = f64s(&g, &format!("sensitivities/{r}"));
        assert!(direct.iter().any(|x| x.abs() > 0.0), "{r}");
        let err = replayed_difference(&g, r, "0.0001");
        assert!(
            err < 1e-4,
            "{r}: direct against replayed differences {err:e}"
        );
    }
}

/// Through that start the adjoint method gives the direct method's gradients: the start's
/// elastic rates take in the modes' derivatives, so the adjoint contracts the initial state's
/// adjoint with the chunks' initial sensitivities, made with the eigenvector derivatives
/// (which it otherwise leaves to the adjoint of the eigenproblem).
#[test]
fn the_adjoint_through_the_elastic_rates_of_the_start_gives_the_direct_gradients() {
    let text = std::fs::read_to_string(deck("four_bar_misaligned.toml")).unwrap()
        + "\n[design.rho]\nkind = \"material\"\nmaterial = \"al\"\nconstant = \"density\"\n\n\
           [objective.coupler_final]\nresponse = \"coupler_z\"\nkind = \"final\"\n\n\
           [objective.pivot_peak]\nresponse = \"pivot_force\"\nkind = \"max\"\n";
    let dir = tempfile::tempdir().unwrap();
    let gradients = |method: &str| {
        let set = format!("sensitivity.method=\"{method}\"");
        let sets = [
            "analysis.t_end=0.02",
            &set,
            "finite_differences.enabled=false",
        ];
        let (summary, _) = run_text(dir.path(), method, &text, &sets);
        (summary["objectives"].as_array().unwrap().iter())
            .map(|o| o["gradient"][0].as_f64().unwrap())
            .collect::<Vec<_>>()
    };
    let (direct, adjoint) = (gradients("direct"), gradients("adjoint"));
    assert_eq!(direct.len(), 2);
    for (d, a) in direct.iter().zip(&adjoint) {
        assert!(
            *d != 0.0 && (d - a).abs() <= 1e-8 * d.abs(),
            "adjoint {a:e} vs direct {d:e}"
        );
    }
}
