//! A ply's thickness as a design variable (`kind = "ply-thickness"`): through laminates and
//! shells (stiffness, mass and the floating frame), against closed forms (a plate's bending
//! frequencies are proportional to its thickness) and central differences; through generated
//! beam sections (the nodes move) to the whole motion; refused, with a message, where it
//! would move a mesh file's geometry.

mod common;

use common::{direct_vs_central, matrix, report, run, with_extra};

/// `--set` overrides putting the listed plies of the tube's laminate at thickness `t` (m).
fn thickness_sets(plies: &[usize], t: f64) -> Vec<String> {
    plies
        .iter()
        .flat_map(|i| {
            [
                "--set".to_string(),
                format!("laminate.tube_wall.plies.{i}.thickness={t:?}"),
            ]
        })
        .collect()
}

#[test]
fn laminate_thickness_derivatives_match_central_differences() {
    // the two outer plies of the tube's wall, one variable (m)
    let (_dir, path) = with_extra(
        "section_composite_tube.toml",
        "\n[design.outer]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\nplies = [2, 3]\n",
    );
    let doc = report("laminate", &path, &["--derivatives".into()]);
    let d = &doc["laminates"]["tube_wall"]["derivatives"][0];
    assert_eq!(d["wrt"], "outer");
    assert_eq!(d["per"], "m");
    // one ply thicker by δ adds δ to the total and to the mass per area ρ δ … for two plies 2δ
    assert!((d["values"]["thickness"].as_f64().unwrap() - 2.0).abs() < 1e-12);
    let rho = 1586.0;
    assert!((d["values"]["mass_per_area"].as_f64().unwrap() - 2.0 * rho).abs() < 1e-9 * rho);
    let t = 0.25e-3;
    let h = 1e-3 * t;
    let at = |s: f64| {
        let sets = thickness_sets(&[2, 3], t + s);
        report("laminate", &path, &sets)
    };
    let (p, m) = (at(h), at(-h));
    for what in ["A", "B", "D", "As"] {
        let exact = matrix(&d["values"][what]);
        let (xp, xm) = (
            matrix(&p["laminates"]["tube_wall"]["values"][what]),
            matrix(&m["laminates"]["tube_wall"]["values"][what]),
        );
        // B of the single-angle wall stays zero whatever the thicknesses (dB/dt is then
        // measured against A, of the same unit)
        let max = |m: &[Vec<f64>]| m.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
        let a = matrix(&doc["laminates"]["tube_wall"]["values"]["A"]);
        let scale = if what == "B" {
            assert!(max(&exact) < 1e-9 * max(&a), "{exact:?}");
            max(&a)
        } else {
            max(&exact)
        };
        assert!(scale > 0.0, "{what}");
        for (i, row) in exact.iter().enumerate() {
            for (j, e) in row.iter().enumerate() {
                let fd = (xp[i][j] - xm[i][j]) / (2.0 * h);
                assert!((e - fd).abs() <= 1e-6 * scale, "{what}{i}{j}: {e} vs {fd}");
            }
        }
    }
}

/// A thin isotropic plate's bending frequencies are proportional to its thickness:
/// df/dt = f/t, to the transverse-shear correction of the Mindlin element (0.3 % here); the
/// derivative itself against central differences of command-line runs.
#[test]
fn plate_frequencies_grow_with_the_thickness() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plate.toml");
    std::fs::write(
        &path,
        "[material.steel]\nE = 210e9\nnu = 0.3\ndensity = 7850.0\n\
         [laminate.sheet]\nplies = [{ material = \"steel\", thickness = 2e-3, angle = 0.0 }]\n\
         [body.plate]\nkind = \"shell\"\nlaminate = \"sheet\"\nlength = 0.3\nwidth = 0.2\n\
         elements = [12, 8]\nmodes = 4\nreference = \"free-free\"\n\
         [design.t]\nkind = \"ply-thickness\"\nlaminate = \"sheet\"\n",
    )
    .unwrap();
    let doc = report("modes", &path, &["--derivatives".into()]);
    let body = &doc["bodies"]["plate"];
    let d = &body["derivatives"][0];
    assert_eq!(d["per"], "m");
    let freqs = |doc: &serde_json::Value| -> Vec<f64> {
        doc["bodies"]["plate"]["values"]["frequencies"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let h = 2e-6;
    let at = |t: f64| {
        report(
            "modes",
            &path,
            &[
                "--set".into(),
                format!("laminate.sheet.plies.0.thickness={t:?}"),
            ],
        )
    };
    let (fp, fm) = (freqs(&at(2e-3 + h)), freqs(&at(2e-3 - h)));
    for (i, (f, df)) in freqs(&doc)
        .iter()
        .zip(d["values"]["frequencies"].as_array().unwrap())
        .enumerate()
    {
        let got = df.as_f64().unwrap();
        let expected = f / 2e-3;
        assert!(
            (got - expected).abs() <= 1e-2 * expected,
            "mode {}: {got} vs {expected} Hz/m",
            i + 1
        );
        let fd = (fp[i] - fm[i]) / (2.0 * h);
        assert!(
            (got - fd).abs() <= 1e-5 * got,
            "mode {}: {got} vs central differences {fd}",
            i + 1
        );
    }
}

#[test]
fn plate_deck_thickness_sensitivities_match_replayed_central_differences() {
    let errors = direct_vs_central(
        "slider_crank_plate.toml",
        "\n[design.t0]\nkind = \"ply-thickness\"\nlaminate = \"plate\"\nplies = [0]\n",
        "1e-4",
        &["t0", "theta"],
    );
    for (err, scale) in errors {
        assert!(scale > 0.0);
        assert!(err < 1e-5, "{err:e}");
    }
}

/// The outer two plies of the paper's tube thicker (one variable, m): `flexsens section
/// --derivatives` against central differences of command-line runs (`--set` on both plies),
/// and the mass per length against the closed form `dm/dt = 2 · 2πρ r_o` (thickening either
/// ply moves the outer surface out by `dt`).
#[test]
fn section_thickness_derivatives_match_central_differences() {
    let extra =
        "\n[design.outer]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\nplies = [2, 3]\n";
    let (_dir, path) = with_extra("section_composite_tube.toml", extra);
    let doc = report("section", &path, &["--derivatives".into()]);
    let d = &doc["sections"]["rod"]["derivatives"][0];
    assert_eq!(d["wrt"], "outer");
    assert_eq!(d["per"], "m");
    let t = 0.25e-3;
    let h = 1e-3 * t;
    let at = |s: f64| {
        let sets = thickness_sets(&[2, 3], t + s);
        report("section", &path, &sets)
    };
    let (plus, minus) = (at(h), at(-h));
    let k = |doc: &serde_json::Value, i: usize, j: usize| {
        doc["sections"]["rod"]["values"]["stiffness"][i][j]
            .as_f64()
            .unwrap()
    };
    for (i, j) in [
        (0, 0),
        (0, 3),
        (3, 3),
        (1, 1),
        (4, 4),
        (5, 5),
        (1, 4),
        (2, 5),
    ] {
        let fd = (k(&plus, i, j) - k(&minus, i, j)) / (2.0 * h);
        let exact = d["values"]["stiffness"][i][j].as_f64().unwrap();
        let scale = exact
            .abs()
            .max(1e-3 * (k(&doc, i, i) * k(&doc, j, j)).sqrt() / t);
        assert!(
            (exact - fd).abs() <= 1e-6 * scale,
            "K{i}{j}: {exact} vs {fd}"
        );
    }
    // a thicker wall stiffens in extension, bending and torsion
    for i in [0, 3, 4, 5] {
        assert!(
            d["values"]["stiffness"][i][i].as_f64().unwrap() > 0.0,
            "K{i}{i}"
        );
    }
    let ro = 4.529e-3 + 4.0 * t;
    let dm = d["values"]["mass_per_length"].as_f64().unwrap();
    let exact = 2.0 * 2.0 * std::f64::consts::PI * 1586.0 * ro;
    // the mesh's polygonal circles (64 around): 1e-5
    assert!((dm - exact).abs() < 1e-5 * exact, "dm/dt {dm} vs {exact}");
}

/// A ply thickness on the paper's beam deck moves the rod's section, its modes and the whole
/// motion: direct sensitivities of the mid-span deflection against replayed central
/// differences of whole runs.
#[test]
fn beam_deck_thickness_sensitivities_match_replayed_central_differences() {
    let errors = direct_vs_central(
        "slider_crank_beam.toml",
        "\n[design.t]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\n",
        "1e-4",
        &["theta", "t"],
    );
    for (err, scale) in errors {
        assert!(scale > 0.0);
        assert!(err < 1e-5, "{err:e}");
    }
}

/// A thin outer ply (0.08 mm) with its thickness and the plies' modulus `E1` as variables, every
/// derivative against replayed central differences of whole runs. (Both change the whole rod
/// alike, so its halves' repeated pairs stay together and take no Dailey terms; a thin ply of
/// one half, which splits them, is in `tailored_bodies.rs`.)
#[test]
fn thin_ply_and_modulus_sensitivities_match_replayed_central_differences() {
    let text = std::fs::read_to_string(common::deck("slider_crank_beam.toml")).unwrap();
    let outer = "{ material = \"paper_composite\", thickness = 0.25e-3, angle = 15.0 },\n]";
    assert!(text.contains(outer));
    let text = text.replacen(
        outer,
        "{ material = \"paper_composite\", thickness = 0.08e-3, angle = 15.0 },\n]",
        1,
    ) + "\n[design.t3]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\nplies = [3]\n\
         \n[design.e1]\nkind = \"material\"\nmaterial = \"paper_composite\"\nconstant = \"E1\"\n";
    let dir = tempfile::tempdir().unwrap();
    let (path, out) = (dir.path().join("thin.toml"), dir.path().join("out"));
    std::fs::write(&path, text).unwrap();
    let (path, out) = (path.display().to_string(), out.display().to_string());
    common::json(&[
        "run",
        &path,
        "-o",
        &out,
        "--json",
        "--set",
        "analysis.t_end=0.003",
        "--set",
        "sensitivity.method=\"direct\"",
        "--set",
        "finite_differences.scheme=central",
        "--set",
        "finite_differences.sizes=[1e-4]",
    ]);
    let results = std::path::Path::new(&out).join("results.h5");
    let g = flexsens::results::Group::read_hdf5(&results).unwrap();
    // variables in name order: e1, t3, theta
    let errors = common::replayed_differences(&g, "mid_deflection", "0.0001", 3);
    eprintln!("replayed differences (e1, t3, theta): {errors:?}");
    for e in errors {
        assert!(e < 1e-5, "{e:e}");
    }
}

/// A mesh file's geometry is fixed: a ply thickness that would move it is refused, naming
/// the variable and the section.
#[test]
fn a_thickness_that_would_move_a_mesh_file_section_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.toml");
    let mesh =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../section/tests/data/tube_q8.msh");
    std::fs::write(
        &path,
        format!(
            "[material.ud]\nE1 = 128.0e9\nE2 = 10.1e9\nE3 = 10.1e9\nG12 = 5.36e9\n\
             G13 = 5.36e9\nG23 = 3.9e9\nnu12 = 0.23\nnu13 = 0.23\nnu23 = 0.3\n\
             density = 1586.0\n\
             [laminate.wall]\nplies = [\n  {{ material = \"ud\", thickness = 0.5e-3, angle = 30.0 }},\n  \
             {{ material = \"ud\", thickness = 0.5e-3, angle = -30.0 }},\n]\n\
             [section.tube]\nshape = \"mesh\"\nfile = \"{}\"\n\
             regions.inner = {{ laminate = \"wall\", ply = 0, frame = \"radial\" }}\n\
             regions.outer = {{ laminate = \"wall\", ply = 1, frame = \"radial\" }}\n\
             [design.t]\nkind = \"ply-thickness\"\nlaminate = \"wall\"\nplies = [1]\n",
            mesh.display()
        ),
    )
    .unwrap();
    let o = run(&["section", path.to_str().unwrap(), "--derivatives"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("`t` moves the thickness of ply 1 of laminate `wall`")
            && err.contains("not of a mesh file"),
        "{err}"
    );
}

/// The rod's frequencies with a thicker wall (one variable moving all four plies, m):
/// `flexsens modes --derivatives` against central differences of command-line runs. The
/// rod's bending pairs are repeated; a thicker round tube keeps them so (no split), and their
/// derivatives are the same within a pair.
#[test]
fn beam_frequency_thickness_derivatives_match_central_differences() {
    let (_dir, path) = with_extra(
        "modes_beam_rod.toml",
        "\n[design.t]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\n",
    );
    let freqs = |doc: &serde_json::Value, key: &str| -> Vec<f64> {
        let body = &doc["bodies"]["rod"];
        let v = if key == "values" {
            &body["values"]["frequencies"]
        } else {
            &body["derivatives"][0]["values"]["frequencies"]
        };
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let doc = report("modes", &path, &["--derivatives".into()]);
    assert_eq!(doc["bodies"]["rod"]["derivatives"][0]["per"], "m");
    let (f, df) = (freqs(&doc, "values"), freqs(&doc, "derivatives"));
    let t = 0.25e-3;
    let h = 1e-3 * t;
    let at = |s: f64| {
        let sets = thickness_sets(&[0, 1, 2, 3], t + s);
        freqs(&report("modes", &path, &sets), "values")
    };
    let (plus, minus) = (at(h), at(-h));
    for i in 0..f.len() {
        let fd = (plus[i] - minus[i]) / (2.0 * h);
        assert!(
            (df[i] - fd).abs() <= 1e-6 * f[i] / t,
            "mode {}: {} vs central differences {fd} Hz/m",
            i + 1,
            df[i]
        );
        // thin-walled tube: f ∝ sqrt(EI/m) grows with the radius of gyration
        assert!(df[i] > 0.0, "mode {}", i + 1);
    }
}
