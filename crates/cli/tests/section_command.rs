//! `flexsens section` end to end: shipped decks, closed forms through the command line,
//! derivatives against central differences, bad input.

mod common;
use common::*;

#[test]
fn shipped_section_decks_run_in_every_format() {
    for name in [
        "section_composite_tube.toml",
        "section_isotropic_rectangle.toml",
    ] {
        let p = deck(name);
        for format in ["table", "json", "csv"] {
            let o = run(&[
                "section",
                p.to_str().unwrap(),
                "--format",
                format,
                "--derivatives",
            ]);
            assert!(
                o.status.success(),
                "{name} {format}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            assert!(!o.stdout.is_empty());
        }
    }
}

#[test]
fn isotropic_rectangle_through_the_command_line_matches_beam_theory() {
    let p = deck("section_isotropic_rectangle.toml");
    let doc = json(&["section", p.to_str().unwrap(), "--format", "json"]);
    let v = &doc["sections"]["bar"]["values"];
    let k = |i: usize, j: usize| v["stiffness"][i][j].as_f64().unwrap();
    let (e, b, h) = (70e9, 0.04, 0.0075);
    let rel = |a: f64, b: f64| ((a - b) / b).abs();
    assert!(rel(k(0, 0), e * b * h) < 1e-8);
    assert!(
        rel(k(4, 4), e * b * h.powi(3) / 12.0) < 1e-8,
        "EI22 about x2 uses the height"
    );
    assert!(rel(k(5, 5), e * h * b.powi(3) / 12.0) < 1e-8);
    // Saint-Venant torsion constant J = b h³ (1/3 − 0.21 (h/b)(1 − (h/b)⁴/12)) (Roark), ~0.5 %
    let g = e / (2.0 * 1.33);
    let r = h / b;
    let j = b * h.powi(3) * (1.0 / 3.0 - 0.21 * r * (1.0 - r.powi(4) / 12.0));
    assert!(rel(k(3, 3), g * j) < 5e-3, "GJ {} vs {}", k(3, 3), g * j);
    assert!(rel(v["mass_per_length"].as_f64().unwrap(), 2700.0 * b * h) < 1e-12);
    assert_eq!(doc["sections"]["bar"]["units"]["stiffness"][3][5], "N*m^2");
    assert_eq!(doc["sections"]["bar"]["units"]["stiffness"][0][3], "N*m");
}

#[test]
fn composite_tube_has_the_papers_area_and_extension_twist_coupling() {
    let p = deck("section_composite_tube.toml");
    let doc = json(&["section", p.to_str().unwrap(), "--format", "json"]);
    let v = &doc["sections"]["rod"]["values"];
    let area = v["area"].as_f64().unwrap();
    assert!((area - 3.16e-5).abs() < 0.01 * 3.16e-5, "area {area}");
    // 15° plies: the extension–twist coupling K14 is nonzero; at 0° it vanishes
    let k14 = v["stiffness"][0][3].as_f64().unwrap();
    assert!(k14.abs() > 1e-4 * v["stiffness"][0][0].as_f64().unwrap() * 1e-3);
    let mut args = vec![
        "section".to_string(),
        p.to_str().unwrap().to_string(),
        "--format".into(),
        "json".into(),
    ];
    for i in 0..4 {
        args.push("--set".into());
        args.push(format!("laminate.tube_wall.plies.{i}.angle=0"));
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let zero = json(&args);
    let z = &zero["sections"]["rod"]["values"]["stiffness"];
    assert!(z[0][3].as_f64().unwrap().abs() < 1e-9 * z[0][0].as_f64().unwrap());
}

#[test]
fn command_line_derivatives_match_central_differences_of_command_line_runs() {
    let p = deck("section_composite_tube.toml");
    let p = p.to_str().unwrap();
    let doc = json(&["section", p, "--format", "json", "--derivatives"]);
    let d = &doc["sections"]["rod"]["derivatives"];
    assert_eq!(d.as_array().unwrap().len(), 4, "one derivative per ply");
    assert_eq!(d[2]["wrt"], "tube_wall.plies.2.angle");
    // central difference in degrees on ply 2, converted to per radian
    let h = 1e-3;
    let at = |angle: f64| {
        json(&[
            "section",
            p,
            "--format",
            "json",
            "--set",
            &format!("laminate.tube_wall.plies.2.angle={angle}"),
        ])
    };
    let (plus, minus) = (at(15.0 + h), at(15.0 - h));
    for (i, j) in [(0, 0), (0, 3), (3, 3), (1, 1), (4, 4), (1, 4), (2, 5)] {
        let kp = plus["sections"]["rod"]["values"]["stiffness"][i][j]
            .as_f64()
            .unwrap();
        let km = minus["sections"]["rod"]["values"]["stiffness"][i][j]
            .as_f64()
            .unwrap();
        let fd = (kp - km) / (2.0 * h.to_radians());
        let exact = d[2]["values"]["stiffness"][i][j].as_f64().unwrap();
        assert!(
            (exact - fd).abs() <= 1e-6 * exact.abs(),
            "K{i}{j}: {exact} vs {fd}"
        );
    }
}

fn expect_bad(text: &str, line: usize, key: &str, words: &str) {
    let (_dir, err) = bad_deck(text, |p| with_deck("section", p, &[]));
    assert!(
        err.contains(&format!("bad.toml:{line}:")),
        "line {line} in: {err}"
    );
    assert!(err.contains(key), "key {key} in: {err}");
    assert!(err.contains(words), "'{words}' in: {err}");
}

const ALU: &str = "[material.alu]\nE = 70e9\nnu = 0.33\ndensity = 2700\n\n";

#[test]
fn bad_sections_are_located() {
    expect_bad(
        &format!("{ALU}[section.s]\nshape = \"rectangel\"\n"),
        7,
        "section.s.shape",
        "did you mean `rectangle`",
    );
    expect_bad(
        &format!(
            "{ALU}[section.s]\nshape = \"rectangle\"\nwidth = 0.01\nheight = -0.01\nmaterial = \"alu\"\n"
        ),
        9,
        "section.s.height",
        "positive",
    );
    expect_bad(
        &format!(
            "{ALU}[section.s]\nshape = \"rectangle\"\nwidth = 0.01\nheight = 0.01\nmaterial = \"steel\"\n"
        ),
        10,
        "section.s.material",
        "undefined material `steel`",
    );
    expect_bad(
        &format!(
            "{ALU}[section.s]\nshape = \"rectangle\"\nwidth = 0.01\nheight = 0.01\nmaterial = \"alu\"\ninner_radius = 0.1\n"
        ),
        11,
        "section.s.inner_radius",
        "does not apply to shape = \"rectangle\"",
    );
    expect_bad(
        &format!("{ALU}[section.s]\nshape = \"tube\"\ninner_radius = 0.01\nlaminate = \"skin\"\n"),
        9,
        "section.s.laminate",
        "undefined laminate `skin`",
    );
    expect_bad(
        &format!(
            "{ALU}[section.s]\nshape = \"tube\"\ninner_radius = 0.01\nplies = [{{ material = \"alu\", thickness = 1e-3, angle = 0, elements = 0 }}]\n"
        ),
        9,
        "section.s.plies[0].elements",
        "at least 1",
    );
    expect_bad(
        &format!("{ALU}[section.s]\nshape = \"mesh\"\nfile = \"missing.msh\"\nregions = {{}}\n"),
        8,
        "section.s.file",
        "cannot read the mesh",
    );
}

#[test]
fn a_mesh_file_is_read_relative_to_the_deck_and_its_errors_name_the_mesh_line() {
    let dir = tempfile::tempdir().unwrap();
    // one 8-node quadrilateral, 10 mm square, in the simple format
    let mesh = "region solid alu 0 tangent 0\n\
                node 1 -0.005 -0.005\nnode 2 0.005 -0.005\nnode 3 0.005 0.005\nnode 4 -0.005 0.005\n\
                node 5 0 -0.005\nnode 6 0.005 0\nnode 7 0 0.005\nnode 8 -0.005 0\n\
                element quad8 solid 1 2 3 4 5 6 7 8\n";
    std::fs::write(dir.path().join("square.txt"), mesh).unwrap();
    let deck = format!("{ALU}[section.s]\nshape = \"mesh\"\nfile = \"square.txt\"\n");
    std::fs::write(dir.path().join("d.toml"), &deck).unwrap();
    let o = run(&[
        "section",
        dir.path().join("d.toml").to_str().unwrap(),
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let ea = doc["sections"]["s"]["values"]["stiffness"][0][0]
        .as_f64()
        .unwrap();
    assert!((ea - 70e9 * 1e-4).abs() < 1e-8 * ea);
    std::fs::write(
        dir.path().join("square.txt"),
        mesh.replace("node 6 0.005 0", "node 6 0.005 zero"),
    )
    .unwrap();
    let o = run(&["section", dir.path().join("d.toml").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("square.txt:7"), "{err}");
}

/// `shape = "circle"`: a solid rod needs no tube with a tiny hole. Through the command line
/// against the closed forms of a solid circle (a circle does not warp in torsion), and the
/// element counts checked with a message that names the key.
#[test]
fn solid_circle_through_the_command_line_matches_the_closed_forms() {
    let text = r#"
[material.steel]
E = 210.0e9
nu = 0.3
density = 7850.0

[section.rod]
shape = "circle"
radius = 0.005
material = "steel"
elements = [24, 6]
"#;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rod.toml");
    std::fs::write(&path, text).unwrap();
    let doc = json(&["section", path.to_str().unwrap(), "--format", "json"]);
    let v = &doc["sections"]["rod"]["values"];
    let k = |i: usize| v["stiffness"][i][i].as_f64().unwrap();
    let (e, g, r) = (210e9, 210e9 / 2.6, 0.005f64);
    let (a, i) = (
        std::f64::consts::PI * r * r,
        std::f64::consts::PI * r.powi(4) / 4.0,
    );
    let rel = |x: f64, y: f64| ((x - y) / y).abs();
    assert!(rel(k(0), e * a) < 5e-5, "EA {}", k(0));
    assert!(rel(k(4), e * i) < 5e-5 && rel(k(5), e * i) < 5e-5, "EI");
    assert!(rel(k(3), 2.0 * g * i) < 5e-5, "GJ {}", k(3));
    assert!(rel(v["mass_per_length"].as_f64().unwrap(), 7850.0 * a) < 5e-5);
    for (elements, message) in [
        ("[10, 2]", "a multiple of 4"),
        ("[16]", "[around the rim, from the core to the rim]"),
    ] {
        let bad = text.replace("elements = [24, 6]", &format!("elements = {elements}"));
        let (_, err) = bad_deck(&bad, |p| with_deck("section", p, &[]));
        assert!(err.contains("section.rod.elements"), "{err}");
        assert!(err.contains(message), "{err}");
    }
}

/// `shape = "channel"`: the box without its right wall; its shear centre lies outside the web,
/// and a right wall is refused with its key.
#[test]
fn channel_sections_are_open_and_refuse_a_right_wall() {
    let deck = r#"
[material.al]
E = 70.0e9
nu = 0.3
density = 2700.0

[laminate.skin]
plies = [{ material = "al", thickness = 0.001, angle = 0.0 }]

[section.c]
shape = "channel"
width = 0.05
height = 0.06
laminate = "skin"
elements_per_ply = 2
elements = [32, 32]
"#;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.toml");
    std::fs::write(&p, deck).unwrap();
    let doc = json(&["section", p.to_str().unwrap(), "--format", "json"]);
    let sc = doc["sections"]["c"]["values"]["shear_centre"][0]
        .as_f64()
        .unwrap();
    // 3b²/(h + 6b) outside the web (crates/section/tests/box_and_warping.rs: to 8e-4)
    let (b, h) = (0.05 - 0.0005, 0.06 - 0.001);
    let expected = -0.025 + 0.0005 - 3.0 * b * b / (h + 6.0 * b);
    assert!((sc - expected).abs() < 1e-4, "{sc} against {expected}");
    let walls = deck.replace(
        "laminate = \"skin\"\nelements_per_ply",
        "walls = { top = \"skin\", bottom = \"skin\", left = \"skin\", right = \"skin\" }\nelements_per_ply",
    );
    let (_d, err) = bad_deck(&walls, |q| with_deck("section", q, &[]));
    assert!(
        err.contains("section.c.walls.right") && err.contains("open"),
        "{err}"
    );
}

/// `shape = "i-beam"`: an aluminium I through the command line against its closed-form
/// bending stiffnesses (exact for a homogeneous section) and a thin-walled flange thickness
/// derivative; its walls are top, bottom and web, and a web belongs to it alone.
#[test]
fn i_beam_sections_through_the_command_line() {
    let deck = r#"
[material.al]
E = 70.0e9
nu = 0.3
density = 2700.0

[laminate.flange]
plies = [{ material = "al", thickness = 0.004, angle = 0.0 }]

[laminate.web]
plies = [{ material = "al", thickness = 0.003, angle = 0.0 }]

[section.i]
shape = "i-beam"
width = 0.05
height = 0.08
walls = { top = "flange", bottom = "flange", web = "web" }
elements_per_ply = 2

[design.tf]
kind = "ply-thickness"
laminate = "flange"
"#;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("i.toml");
    std::fs::write(&p, deck).unwrap();
    let doc = json(&[
        "section",
        p.to_str().unwrap(),
        "--format",
        "json",
        "--derivatives",
    ]);
    let s = &doc["sections"]["i"];
    let k = |i: usize| s["values"]["stiffness"][i][i].as_f64().unwrap();
    let (b, h, tf, tw, e) = (0.05f64, 0.08f64, 0.004f64, 0.003f64, 70e9);
    let hw = h - 2.0 * tf;
    let i22 = (b * h.powi(3) - (b - tw) * hw.powi(3)) / 12.0;
    let i33 = (2.0 * tf * b.powi(3) + hw * tw.powi(3)) / 12.0;
    assert!(
        (k(4) / (e * i22) - 1.0).abs() < 1e-9,
        "{}",
        k(4) / (e * i22)
    );
    assert!(
        (k(5) / (e * i33) - 1.0).abs() < 1e-9,
        "{}",
        k(5) / (e * i33)
    );
    // both flanges thicker, inwards: dA/dt = 2(b − tw)
    let d = &s["derivatives"][0];
    assert_eq!(d["wrt"], "tf");
    let dm = d["values"]["mass_per_length"].as_f64().unwrap();
    assert!((dm / (2700.0 * 2.0 * (b - tw)) - 1.0).abs() < 1e-9, "{dm}");
    for (from, to, key, words) in [
        (
            "web = \"web\" }",
            "web = \"web\", left = \"web\" }",
            "section.i.walls.left",
            "top, bottom and web",
        ),
        (
            "shape = \"i-beam\"",
            "shape = \"box\"",
            "section.i.walls.web",
            "only an I beam",
        ),
        (
            "web = \"web\" }",
            "}",
            "section.i.walls.web",
            "missing value",
        ),
    ] {
        let (_d, err) = bad_deck(&deck.replace(from, to), |q| with_deck("section", q, &[]));
        assert!(err.contains(key) && err.contains(words), "{err}");
    }
}

#[test]
fn a_loaded_rectangle_bends_as_beam_theory_and_a_loaded_tube_fails_its_plies_consistently() {
    // the isotropic bar (40 × 7.5 mm) bent about x₂ with an axial force: σ11 = N/A ± M h/2I
    let p = deck("section_isotropic_rectangle.toml");
    let doc = json(&[
        "section",
        p.to_str().unwrap(),
        "--format",
        "json",
        "--load",
        "F1=3000,M2=12",
    ]);
    let v = &doc["sections"]["bar"]["values"];
    let (b, h) = (0.04f64, 0.0075f64);
    let (a, i22) = (b * h, b * h.powi(3) / 12.0);
    // one region: one row, written as a vector
    let extremes: Vec<f64> = (v["region_stress_extremes"].as_array().unwrap().iter())
        .map(|x| x.as_f64().unwrap())
        .collect();
    // the extremes are at the integration points nearest the faces, within the outer
    // elements: between the face value and that one element in
    let (lo, hi) = (
        3000.0 / a - 12.0 * h / 2.0 / i22,
        3000.0 / a + 12.0 * h / 2.0 / i22,
    );
    assert!(
        extremes[1] <= hi && extremes[1] > 0.8 * hi,
        "{extremes:?} vs {hi}"
    );
    assert!(
        extremes[0] >= lo && extremes[0] < 0.8 * lo,
        "{extremes:?} vs {lo}"
    );
    assert!(
        v.get("region_failure_index").is_none(),
        "no strengths, no indices"
    );
    // the composite tube with strengths: the max-stress index of each region is its largest
    // stress ratio, the reserve factor the least over the regions
    let t = deck("section_composite_tube.toml");
    let strengths = [
        "material.paper_composite.Xt=1.5e9",
        "material.paper_composite.Xc=1.2e9",
        "material.paper_composite.Yt=4e7",
        "material.paper_composite.Yc=2.46e8",
        "material.paper_composite.S12=6.8e7",
    ];
    let mut args = vec!["section", t.to_str().unwrap(), "--format", "json"];
    for s in &strengths {
        args.extend(["--set", s]);
    }
    args.extend(["--load", "F1=1000,M1=2"]);
    let doc = json(&args);
    let v = &doc["sections"]["rod"]["values"];
    let (ext, fi) = (
        matrix(&v["region_stress_extremes"]),
        matrix(&v["region_failure_index"]),
    );
    let mut least = f64::INFINITY;
    for (e, f) in ext.iter().zip(&fi) {
        // σ11 by sign against Xt, Xc; σ22 against Yt, Yc; τ12 against S12 (τ13, τ23 zero in a
        // thin wall's plane-stress state: the default S13 = S23 = S12)
        let ratio = [
            e[1].max(0.0) / 1.5e9,
            (-e[0]).max(0.0) / 1.2e9,
            e[3].max(0.0) / 4e7,
            (-e[2]).max(0.0) / 2.46e8,
            e[4] / 6.8e7,
            e[5] / 6.8e7,
            e[6] / 6.8e7,
        ]
        .into_iter()
        .fold(0.0f64, f64::max);
        assert!((f[0] - ratio).abs() < 1e-12 * ratio, "{f:?} vs {ratio}");
        least = least.min(1.0 / f[0]);
    }
    let rf = v["reserve_factor"][0].as_f64().unwrap();
    assert!((rf - least).abs() < 1e-12 * least, "{rf} vs {least}");
}

#[test]
fn loaded_stress_extremes_and_failure_index_derivatives_equal_central_differences_of_the_command() {
    // the composite tube with strengths under mixed forces: each quantity's derivative along
    // ply 2's angle is its active point's (per radian)
    let t = deck("section_composite_tube.toml");
    let base = [
        "--set",
        "material.paper_composite.Xt=1.5e9",
        "--set",
        "material.paper_composite.Xc=1.2e9",
        "--set",
        "material.paper_composite.Yt=4e7",
        "--set",
        "material.paper_composite.Yc=2.46e8",
        "--set",
        "material.paper_composite.S12=6.8e7",
        "--load",
        "F1=1000,F2=30,M1=2,M2=-3",
    ];
    let run_at = |angle: f64, derivatives: bool| {
        let set = format!("laminate.tube_wall.plies.2.angle={angle}");
        let mut args = vec![
            "section",
            t.to_str().unwrap(),
            "--format",
            "json",
            "--set",
            &set,
        ];
        args.extend(base);
        if derivatives {
            args.push("--derivatives");
        }
        json(&args)["sections"]["rod"].clone()
    };
    let nominal = run_at(15.0, true);
    let block = &nominal["derivatives"][2];
    assert_eq!(block["wrt"], "tube_wall.plies.2.angle");
    let h = 1e-4;
    let (plus, minus) = (run_at(15.0 + h, false), run_at(15.0 - h, false));
    for q in ["region_stress_extremes", "region_failure_index"] {
        let (exact, vp, vm) = (
            matrix(&block["values"][q]),
            matrix(&plus["values"][q]),
            matrix(&minus["values"][q]),
        );
        let mut scale = 0.0f64;
        let mut worst = 0.0f64;
        for r in 0..exact.len() {
            for c in 0..exact[r].len() {
                let fd = (vp[r][c] - vm[r][c]) / (2.0 * h.to_radians());
                scale = scale.max(fd.abs());
                worst = worst.max((exact[r][c] - fd).abs());
            }
        }
        eprintln!("{q}: largest difference {worst:.2e} of {scale:.2e}");
        assert!(
            scale > 0.0 && worst < 1e-5 * scale,
            "{q}: {worst:e} of {scale:e}"
        );
    }
}
