//! `flexsens report`: the paper's §5 figures and the summary, on a short run of the beam deck.

mod common;

use common::{bad_deck, deck, run, with_deck};

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

#[test]
fn report_writes_every_figure_and_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let beam = deck("slider_crank_beam.toml");
    let o = run(&[
        "report",
        beam.to_str().unwrap(),
        "--layups",
        "0,30",
        "-o",
        out.to_str().unwrap(),
        "--set",
        "analysis.t_end=0.002",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("lay-up [30°]"), "{stdout}");

    let mut stems = vec!["displacement".to_string()];
    for a in ["0", "30"] {
        for f in ["integrators", "modes", "perturbations"] {
            stems.push(format!("{f}_{a}deg"));
        }
    }
    for stem in &stems {
        let svg = std::fs::read_to_string(out.join(format!("{stem}.svg"))).unwrap();
        assert!(
            svg.starts_with("<svg"),
            "{stem}.svg: {}",
            &svg[..svg.len().min(80)]
        );
        assert!(svg.contains("time [s]"), "{stem}.svg has its time axis");
        let png = std::fs::read(out.join(format!("{stem}.png"))).unwrap();
        assert!(
            png.len() > 1000 && png.starts_with(PNG_SIGNATURE),
            "{stem}.png"
        );
    }
    let svg = std::fs::read_to_string(out.join("integrators_30deg.svg")).unwrap();
    assert!(
        svg.contains("d(deflection)/dθ ["),
        "sensitivity axis with its unit"
    );
    // no partial files are left behind
    for e in std::fs::read_dir(&out).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.starts_with('.'), "{name}");
    }

    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(md.contains("## Natural frequencies"), "{md}");
    assert!(
        md.contains("f1 [Hz]") && md.contains("df1/dtheta [Hz/deg]"),
        "{md}"
    );
    assert!(md.contains("| [0°] |") && md.contains("| [30°] |"), "{md}");
    assert!(md.contains("central 1e-4, replay"), "{md}");

    let js: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let freqs = js["frequencies"].as_array().unwrap();
    assert_eq!(freqs.len(), 2, "one row per lay-up");
    let f0 = freqs[0]["frequencies_hz"].as_array().unwrap();
    let f30 = freqs[1]["frequencies_hz"].as_array().unwrap();
    assert_eq!(f0.len(), 4, "the deck keeps four modes");
    // fibres along the tube stiffen it: the [0°] rod is the stiffest
    assert!(f0[0].as_f64().unwrap() > f30[0].as_f64().unwrap());
    // the direct sensitivities agree with central differences on the same steps; at 0° the
    // derivative of a single-angle lay-up vanishes (even in the angle)
    let rows = js["relative_differences"].as_array().unwrap();
    assert_eq!(rows[0]["direct_vanishes"], true, "{}", rows[0]);
    assert!(
        rows[0]["absolute"]["central 1e-4, replay"]
            .as_f64()
            .unwrap()
            < 1e-8
    );
    assert_eq!(rows[1]["direct_vanishes"], false, "{}", rows[1]);
    assert!(
        rows[1]["relative"]["central 1e-4, replay"]
            .as_f64()
            .unwrap()
            < 1e-3
    );
    assert_eq!(js["files"].as_array().unwrap().len(), 2 * stems.len());
}

#[test]
fn report_rejects_bad_input() {
    let text = std::fs::read_to_string(deck("slider_crank_beam.toml")).unwrap();

    // no design variable: everything from [design.theta] up to [analysis] removed
    let (head, rest) = text.split_once("[design.theta]").unwrap();
    let (_, analysis) = rest.split_once("[analysis]").unwrap();
    let no_design = format!("{head}[analysis]{analysis}");
    let (_d, err) = bad_deck(&no_design, |p| {
        with_deck("report", p, &["--layups", "0,15"])
    });
    assert!(err.contains("no design variable"), "{err}");

    // no mid-node-deflection response
    let no_mid = text.replace(
        "kind = \"mid-node-deflection\"",
        "kind = \"position\"\ncomponent = \"y\"",
    );
    let (_d, err) = bad_deck(&no_mid, |p| with_deck("report", p, &["--layups", "0,15"]));
    assert!(err.contains("mid-node-deflection"), "{err}");

    // bad lay-up lists
    for layups in ["0,abc", "0,,15", "15,15"] {
        let (d, err) = bad_deck(&text, |p| with_deck("report", p, &["--layups", layups]));
        assert!(err.contains("--layups"), "{layups}: {err}");
        assert!(
            std::fs::read_dir(d.path()).unwrap().count() == 1,
            "nothing written for {layups}"
        );
    }
}
