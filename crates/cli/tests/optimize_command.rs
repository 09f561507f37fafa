//! `flexsens optimize`: SLSQP with the exact gradients of the whole chain. Against answers
//! known by theory: a unidirectional tube's bending frequency is largest with its fibres
//! along the axis (0°, by symmetry and monotony of the axial modulus); a plate of least mass
//! whose frequency must reach a bound (f ∝ t and m ∝ t) sits on that bound, and the
//! multiplier of the bound is the derivative of the optimal mass with respect to it, checked
//! against central differences of whole optimisations.

mod common;

use std::path::{Path, PathBuf};

use common::{deck, run};

/// The tube rod of `modes_beam_rod.toml`, coarser (fast), all plies at 40°, one angle variable
/// in [−60°, 75°] (not symmetric about the optimum), maximising the first frequency.
fn tube_deck(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(deck("modes_beam_rod.toml"))
        .unwrap()
        .replace("elements_around = 48", "elements_around = 16")
        .replace("modes = 4", "modes = 2")
        .replace("modes = [1, 4]", "modes = [1, 2]")
        .replace("angle = 15.0", "angle = 40.0")
        + "\n[design.theta]\nlaminate = \"tube_wall\"\nlower = -60.0\nupper = 75.0\n\n\
           [optimize]\nmaximize = \"frequency.rod.1\"\n";
    let path = dir.join("tube.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn optimize(path: &Path, out: &Path, extra: &[&str]) -> (String, String, Option<i32>) {
    let mut args = vec![
        "optimize".to_string(),
        path.display().to_string(),
        "-o".into(),
        out.display().to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run(&args);
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        o.status.code(),
    )
}

/// The value printed for `name = VALUE UNIT` in the summary.
fn summary_value(text: &str, name: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{name} = ")))
        .unwrap_or_else(|| panic!("no `{name}` in\n{text}"));
    line.split('=')
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn a_tube_frequency_is_largest_with_fibres_along_the_axis() {
    let dir = tempfile::tempdir().unwrap();
    let path = tube_deck(dir.path());
    let out = dir.path().join("out");
    let (text, err, code) = optimize(&path, &out, &["--quiet"]);
    assert_eq!(code, Some(0), "{text}\n{err}");
    let theta = summary_value(&text, "theta");
    assert!(theta.abs() < 1e-4, "θ* = {theta} deg\n{text}");
    assert!(!text.contains("bound)"), "θ* is inside its bounds\n{text}");
    // with the optimum outside the bounds the optimiser stops at (near) the bound, and says so
    let (bounded, err, code) = optimize(
        &path,
        &dir.path().join("bounded"),
        &["--quiet", "--set", "design.theta.lower=10.0"],
    );
    assert_eq!(code, Some(0), "{bounded}\n{err}");
    let at = summary_value(&bounded, "theta");
    assert!((at - 10.0).abs() < 1e-4, "θ* = {at} deg\n{bounded}");
    assert!(
        bounded
            .lines()
            .any(|l| l.trim_start().starts_with("theta = ") && l.ends_with("(at its lower bound)")),
        "{bounded}"
    );
    // the optimum deck is a deck: its frequency is the one reported, and its derivative there
    // vanishes (the run of `modes --derivatives` on it)
    let f = summary_value(
        &text.replace("optimum (", "\n").replace("): ", "\n"),
        "frequency.rod.1",
    );
    let o = run(&[
        "modes",
        &out.join("optimum.toml").display().to_string(),
        "--format",
        "json",
        "--derivatives",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let f1 = doc["bodies"]["rod"]["values"]["frequencies"][0]
        .as_f64()
        .unwrap();
    assert!((f1 - f).abs() < 1e-9 * f, "{f1} vs {f}");
    let df = doc["bodies"]["rod"]["derivatives"][0]["values"]["frequencies"][0]
        .as_f64()
        .unwrap();
    assert!(df.abs() < 1e-6 * f, "df/dθ = {df} Hz/deg at the optimum");
    // every evaluation is logged, the last ones stationary
    let csv = std::fs::read_to_string(out.join("iterations.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.starts_with("start,evaluation,theta [deg],frequency.rod.1 [Hz],max_violation"),
        "{header}"
    );
    assert!(csv.lines().count() > 3);
    for f in ["convergence.svg", "convergence.png"] {
        assert!(std::fs::metadata(out.join(f)).unwrap().len() > 1000, "{f}");
    }
}

/// A steel plate of least mass whose first free-free frequency is at least `f_min`.
fn plate_deck(dir: &Path, f_min: f64) -> PathBuf {
    let text = format!(
        "[material.steel]\nE = 210e9\nnu = 0.3\ndensity = 7800.0\n\n\
         [laminate.sheet]\nplies = [{{ material = \"steel\", thickness = 2e-3, angle = 0.0 }}]\n\n\
         [body.plate]\nkind = \"shell\"\nlaminate = \"sheet\"\nlength = 0.3\nwidth = 0.2\n\
         elements = [12, 8]\nmodes = 1\nreference = \"free-free\"\n\n\
         [design.t]\nkind = \"ply-thickness\"\nlaminate = \"sheet\"\nlower = 0.5e-3\nupper = 5e-3\n\n\
         [optimize]\nminimize = \"mass.plate\"\n\n\
         [[optimize.constraint]]\nquantity = \"frequency.plate.1\"\nmin = {f_min:?}\n"
    );
    let path = dir.join(format!("plate_{f_min}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn the_lightest_plate_meets_its_frequency_bound_and_the_multiplier_is_dm_over_df() {
    let dir = tempfile::tempdir().unwrap();
    let solve = |f_min: f64| {
        let path = plate_deck(dir.path(), f_min);
        let out = dir.path().join(format!("out_{f_min:?}"));
        let (text, err, code) = optimize(&path, &out, &["--quiet"]);
        assert_eq!(code, Some(0), "{text}\n{err}");
        let mass = summary_value(
            &text.replace("optimum (", "\n").replace("): ", "\n"),
            "mass.plate",
        );
        let t = summary_value(&text, "t");
        let line = text
            .lines()
            .find(|l| l.contains("multiplier dF*/d(bound) = "))
            .unwrap();
        let lambda: f64 = line.rsplit("= ").next().unwrap().trim().parse().unwrap();
        let f = summary_value(&text, "frequency.plate.1");
        (mass, t, lambda, f)
    };
    let (m, t, lambda, f) = solve(150.0);
    // on the bound, with the thickness of the closed form (f ∝ t): t* = t0 f_min / f(t0),
    // f(t0) read from the nominal evaluation, to the Mindlin correction (0.3 %)
    assert!((f - 150.0).abs() < 1e-6 * 150.0, "f(t*) = {f}");
    let rho_area = 7800.0 * 0.3 * 0.2;
    assert!(
        (m - rho_area * t).abs() < 1e-9 * m,
        "m = ρ A t: {m} vs {}",
        rho_area * t
    );
    let csv = std::fs::read_to_string(dir.path().join("out_150.0/iterations.csv")).unwrap();
    let f0: f64 = csv
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .nth(4)
        .unwrap()
        .parse()
        .unwrap();
    let t_closed = 2e-3 * 150.0 / f0;
    assert!(
        (t - t_closed).abs() < 3e-3 * t_closed,
        "t* = {t} vs {t_closed}"
    );
    // the multiplier is dm*/df_min: against central differences of the optimum (h = 1 Hz;
    // m*(f_min) is nearly linear, so the difference is accurate to well below 1e-4)
    let (m_plus, ..) = solve(151.0);
    let (m_minus, ..) = solve(149.0);
    let central = (m_plus - m_minus) / 2.0;
    assert!(
        (lambda - central).abs() < 1e-4 * central.abs(),
        "λ = {lambda:e}, central differences {central:e}"
    );
    // and of the size of the closed form's ρ A t*/f_min
    assert!(
        (lambda - m / 150.0).abs() < 5e-3 * lambda,
        "{lambda} vs {}",
        m / 150.0
    );
    // the laminate's mass per area, ρ t, has the same optimum
    let areal = std::fs::read_to_string(plate_deck(dir.path(), 150.0))
        .unwrap()
        .replace(
            "minimize = \"mass.plate\"",
            "minimize = \"areal_mass.sheet\"",
        );
    let path = dir.path().join("areal.toml");
    std::fs::write(&path, areal).unwrap();
    let (text, err, code) = optimize(&path, &dir.path().join("areal"), &["--quiet"]);
    assert_eq!(code, Some(0), "{text}\n{err}");
    let t_areal = summary_value(&text, "t");
    let mu = summary_value(
        &text.replace("optimum (", "\n").replace("): ", "\n"),
        "areal_mass.sheet",
    );
    assert!((t_areal - t).abs() < 1e-6 * t, "{t_areal} vs {t}");
    assert!((mu - 7800.0 * t_areal).abs() < 1e-9 * mu, "{mu}");
}

/// The rows of `iterations.csv`: (evaluation, θ, frequency, largest violation, stationarity).
fn tube_rows(out: &Path) -> Vec<(usize, f64, f64, f64, f64)> {
    let csv = std::fs::read_to_string(out.join("iterations.csv")).unwrap();
    csv.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let x = |i: usize| c[i].parse::<f64>().unwrap();
            (c[1].parse().unwrap(), x(2), x(3), x(4), x(6))
        })
        .collect()
}

/// SLSQP's own test (the objective's relative change) keeps the tube's run going nine
/// evaluations past the optimum, each within 1e-14 of it; `kkt_tolerance` ends the run at the
/// first feasible evaluation whose stationarity meets it — the same evaluations up to there.
#[test]
fn the_kkt_tolerance_ends_the_run_at_its_first_stationary_feasible_design() {
    let dir = tempfile::tempdir().unwrap();
    let path = tube_deck(dir.path());
    let (full_out, kkt_out) = (dir.path().join("full"), dir.path().join("kkt"));
    let (text, err, code) = optimize(&path, &full_out, &["--quiet"]);
    assert_eq!(code, Some(0), "{text}\n{err}");
    let full = tube_rows(&full_out);
    let tol = 1e-5;
    let (text, err, code) = optimize(
        &path,
        &kkt_out,
        &[
            "--quiet",
            "--set",
            &format!("optimize.kkt_tolerance={tol:e}"),
        ],
    );
    assert_eq!(code, Some(0), "{text}\n{err}");
    assert!(
        text.contains("converged (KKT stationarity") && text.contains("kkt_tolerance 1e-5"),
        "{text}"
    );
    let stopped = tube_rows(&kkt_out);
    // the first stationary evaluation of the full run, and nothing after it
    let first = full
        .iter()
        .position(|r| r.3 <= 1e-6 && r.4 <= tol)
        .expect("a stationary evaluation");
    assert!(first + 1 < full.len(), "SLSQP's own stop came no later");
    assert_eq!(stopped.len(), first + 1, "{text}");
    assert_eq!(&full[..=first], &stopped[..]);
    // where the optimum is: fibres along the axis
    let theta = summary_value(&text, "theta");
    assert!(theta.abs() < 1e-4, "θ* = {theta} deg\n{text}");
}

#[test]
fn bad_optimize_tables_are_refused_with_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(tube_deck(dir.path())).unwrap();
    for (edit, key, says) in [
        (
            base.replace("lower = -60.0\n", ""),
            "design.theta.lower",
            "flexsens optimize needs both bounds",
        ),
        (
            base.replace(
                "maximize = \"frequency.rod.1\"",
                "maximize = \"frequency.rood.1\"",
            ),
            "optimize.maximize",
            "did you mean `rod`",
        ),
        (
            base.replace(
                "maximize = \"frequency.rod.1\"",
                "maximize = \"stiffness.rod\"",
            ),
            "optimize.maximize",
            "expected \"objective.NAME\"",
        ),
        (
            base.replace("[optimize]\n", "[optimize]\nminimize = \"mass.rod\"\n"),
            "optimize",
            "exactly one of minimize and maximize",
        ),
        (
            base.clone() + "starts = [[80.0]]\n",
            "optimize.starts[0]",
            "within its bounds",
        ),
        (
            base.clone() + "kkt_tolerance = -1e-3\n",
            "optimize.kkt_tolerance",
            "must be a positive, finite number",
        ),
        (
            base.clone()
                + "[[optimize.constraint]]\nquantity = \"mass.rod\"\nmin = 1.0\nmax = 2.0\n",
            "optimize.constraint[0]",
            "exactly one of min, max and equals",
        ),
        (
            base.replace("lower = -60.0", "lower = 50.0"),
            "design.theta",
            "lies outside [lower, upper]",
        ),
        // bounds the model cannot take: a ply of no thickness, a material with a negative
        // modulus
        (
            base.clone()
                + "\n[design.wall]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\n\
                   plies = [0]\nlower = 0.0\nupper = 0.5e-3\n",
            "design.wall.lower",
            "not physical",
        ),
        (
            base.clone()
                + "\n[design.stiff]\nkind = \"material\"\nmaterial = \"paper_composite\"\n\
                   constant = \"E1\"\nlower = -1e9\nupper = 1e12\n",
            "design.stiff.lower",
            "not physical",
        ),
        (
            std::fs::read_to_string(deck("slider_crank_rigid.toml")).unwrap()
                + "\n[design.m]\nkind = \"rigid-mass\"\nbody = \"slider\"\nlower = -1.0\n\
                   upper = 1.0\n\n[optimize]\nminimize = \"mass.slider\"\n",
            "design.m.lower",
            "mass of rigid body `slider` must be positive",
        ),
    ] {
        let (_d, err) = common::bad_deck(&edit, |p| common::with_deck("optimize", p, &[]));
        assert!(
            err.contains(&format!("key `{key}`")) && err.contains(says),
            "{key}: {err}"
        );
    }
}

/// Ctrl-C stops the optimiser; the best feasible design so far is written and the exit code
/// is 130.
#[test]
fn an_interrupted_optimisation_writes_its_best_design() {
    let dir = tempfile::tempdir().unwrap();
    let path = tube_deck(dir.path());
    let out = dir.path().join("out");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(["optimize", &path.display().to_string(), "-o"])
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // wait for the second evaluation's progress line, then interrupt
    let stderr = child.stderr.take().unwrap();
    let mut lines = std::io::BufRead::lines(std::io::BufReader::new(stderr));
    for line in lines.by_ref() {
        if line.unwrap().contains("evaluation 2") {
            break;
        }
    }
    let ok = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "kill -INT");
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let o = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(130), "{text}\n{rest:?}");
    assert!(text.contains("interrupted"), "{text}");
    assert!(out.join("iterations.csv").exists());
    // the deck says what it is, and still reads as a deck
    let optimum = std::fs::read_to_string(out.join("optimum.toml")).unwrap();
    assert!(
        optimum.starts_with("# flexsens optimize was interrupted"),
        "{optimum}"
    );
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_flexsens"))
        .args(["check", &out.join("optimum.toml").display().to_string()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `optimize --shard I/N` as separate processes and `merge` give what one optimisation writes:
/// the same iterations, the same optimum deck and the same summary.
#[test]
fn sharded_starts_merge_into_the_single_optimisation() {
    let dir = tempfile::tempdir().unwrap();
    let path = tube_deck(dir.path());
    let text = std::fs::read_to_string(&path).unwrap() + "starts = [[-30.0], [60.0]]\n";
    std::fs::write(&path, text).unwrap();
    let single = dir.path().join("single");
    let (one, err, code) = optimize(&path, &single, &["--quiet", "-j", "1"]);
    assert_eq!(code, Some(0), "{one}\n{err}");
    for i in 1..=2 {
        let (t, err, code) = optimize(
            &path,
            &dir.path().join(format!("shard_{i}")),
            &["--quiet", "--shard", &format!("{i}/2")],
        );
        assert_eq!(code, Some(0), "{t}\n{err}");
    }
    let merged = dir.path().join("merged");
    let o = run(&[
        "merge",
        &dir.path().join("shard_2").display().to_string(),
        &dir.path().join("shard_1").display().to_string(),
        "-o",
        &merged.display().to_string(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for f in ["iterations.csv", "optimum.toml"] {
        assert_eq!(
            std::fs::read_to_string(single.join(f)).unwrap(),
            std::fs::read_to_string(merged.join(f)).unwrap(),
            "{f}"
        );
    }
    assert_eq!(
        one.replace(&single.display().to_string(), "OUT"),
        text.replace(&merged.display().to_string(), "OUT")
    );
    assert!(one.contains("start 3: converged"), "{one}");
}

/// An objective without a gradient cannot be optimised: refused at the first evaluation, with
/// the reason, not optimised on a zero gradient.
#[test]
fn an_objective_without_a_gradient_is_refused() {
    let o = run(&[
        "optimize",
        &deck("optimize_beam_layup.toml").display().to_string(),
        "-o",
        &tempfile::tempdir().unwrap().path().display().to_string(),
        "--set",
        "analysis.t_end=0.001",
        "--set",
        "sensitivity.enabled=false",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("objective.rms_deflection has no gradient"),
        "{err}"
    );
}

/// A deck that reads a mesh file: its optimum deck, written in the output directory, names the
/// mesh by an absolute path and runs from there.
#[test]
fn the_optimum_deck_of_a_meshed_body_reads_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/shell.msh");
    std::fs::copy(&mesh, dir.path().join("plate.msh")).unwrap();
    let text = std::fs::read_to_string(plate_deck(dir.path(), 150.0))
        .unwrap()
        .replace(
            "length = 0.3\nwidth = 0.2\nelements = [12, 8]\n",
            "file = \"plate.msh\"\n",
        );
    let path = dir.path().join("meshed.toml");
    std::fs::write(&path, text).unwrap();
    let out = dir.path().join("out");
    let (text, err, code) = optimize(&path, &out, &["--quiet"]);
    assert_eq!(code, Some(0), "{text}\n{err}");
    let optimum = std::fs::read_to_string(out.join("optimum.toml")).unwrap();
    let absolute = std::fs::canonicalize(dir.path().join("plate.msh")).unwrap();
    assert!(
        optimum.contains(&format!("file = \"{}\"", absolute.display())),
        "{optimum}"
    );
    let o = run(&["modes", &out.join("optimum.toml").display().to_string()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A problem without a feasible design exits 1 and leaves none of an earlier optimisation's
/// files in its directory (its optimum deck and run would look like this one's).
#[test]
fn an_infeasible_problem_leaves_no_earlier_optimum() {
    let dir = tempfile::tempdir().unwrap();
    // f ∝ t for a free plate: 100 times the frequency of the thickest plate allowed
    let path = plate_deck(dir.path(), 1e6);
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    for f in [
        "results.h5",
        "history.csv",
        "optimum.toml",
        "iterations.csv",
    ] {
        std::fs::write(out.join(f), "an earlier optimisation's").unwrap();
    }
    let (text, err, code) = optimize(&path, &out, &["--quiet"]);
    assert_eq!(code, Some(1), "{text}{err}");
    assert!(
        format!("{text}{err}").contains("no feasible design"),
        "{text}{err}"
    );
    for f in ["results.h5", "history.csv", "optimum.toml"] {
        assert!(!out.join(f).exists(), "{f} was left");
    }
    // this optimisation's own record of its evaluations is there
    let rows = std::fs::read_to_string(out.join("iterations.csv")).unwrap();
    assert!(
        rows.lines().count() > 1 && !rows.contains("earlier"),
        "{rows}"
    );
}
