//! `analysis.error_weights = "displacement"`: the deck's `atol` as a displacement, one
//! tolerance per coordinate (docs/design.md §3), against a tight run of the beam deck; a body's
//! own `atol`; bad values.

mod common;

use flexsens::results::{Attr, Group};

/// The beam deck, analysis only, with `sets`: its mid-span deflection's largest and smallest
/// values and the number of steps.
fn beam(sets: &[&str]) -> (f64, f64, u64) {
    let dir = tempfile::tempdir().unwrap();
    let deck = common::deck("slider_crank_beam.toml");
    let out = dir.path().join("out");
    let mut args = vec![
        "run",
        deck.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
        "-q",
        "--set",
        "sensitivity.enabled=false",
    ];
    for s in sets {
        args.extend(["--set", s]);
    }
    let doc = common::json(&args);
    let d = &doc["responses"]["mid_deflection"];
    (
        d["max"].as_f64().unwrap(),
        d["min"].as_f64().unwrap(),
        doc["steps"].as_u64().unwrap(),
    )
}

/// The mid-span deflection's peaks against a run at `rtol = 1e-10`, measured: the deck's
/// uniform `atol = 1e-9` within 7.7e-5 in 3 939 steps, the default displacement weights
/// (4.56e-11 m) within 1.6e-4 in 2 953 steps, 100 times looser within 2.4e-3 in 1 740; the
/// rod's own 4.56e-11 m with the others at 4.56e-9 m takes 2 969 steps.
#[test]
fn displacement_weights_reach_the_deck_accuracy_in_fewer_steps() {
    let (tmax, tmin, _) = beam(&["analysis.rtol=1e-10", "analysis.atol=1e-13"]);
    let (umax, umin, uniform) = beam(&[]);
    let disp = "analysis.error_weights=\"displacement\"";
    // the deck states uniform weights with atol = 1e-9: the displacement weights at their
    // default for this deck, 4.56e-11 m, are set explicitly
    let (dmax, dmin, displacement) = beam(&[disp, "analysis.atol=4.56e-11"]);
    let off = |a: f64, b: f64| ((a - tmax) / tmax).abs().max(((b - tmin) / tmin).abs());
    let (lmax, lmin, loose) = beam(&[disp, "analysis.atol=4.56e-9"]);
    let (_, _, rod_tight) = beam(&[disp, "analysis.atol=4.56e-9", "body.rod.atol=4.56e-11"]);
    eprintln!(
        "tight {tmax:e} {tmin:e}; uniform {} in {uniform}; displacement {} in {displacement}; \
         loose {} in {loose}; rod {rod_tight}",
        off(umax, umin),
        off(dmax, dmin),
        off(lmax, lmin)
    );
    assert!(off(umax, umin) < 1.5e-4, "uniform: {}", off(umax, umin));
    assert!(off(dmax, dmin) < 3e-4, "displacement: {}", off(dmax, dmin));
    assert!(
        (displacement as f64) < 0.85 * uniform as f64,
        "{displacement} steps against {uniform}"
    );
    assert!(loose < displacement, "{loose} against {displacement}");
    assert!(
        off(lmax, lmin) > 3.0 * off(dmax, dmin),
        "{}",
        off(lmax, lmin)
    );
    // a body's own tolerance overrides the mechanism's for its coordinates
    assert!(rod_tight > loose, "{rod_tight} against {loose}");
}

#[test]
fn the_default_displacement_tolerance_follows_rtol_and_the_size() {
    let deck = std::fs::read_to_string(common::deck("slider_crank_beam.toml")).unwrap();
    // without the deck's uniform weights and its atol: the defaults
    let text: String = deck
        .lines()
        .filter(|l| !l.starts_with("atol") && !l.starts_with("error_weights"))
        .map(|l| format!("{l}\n"))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deck.toml");
    std::fs::write(&path, &text).unwrap();
    let p = path.to_str().unwrap();
    let steps = |sets: &[&str]| {
        let out = dir.path().join("out");
        let mut args = vec!["run", p, "-o", out.to_str().unwrap(), "--json", "-q"];
        args.extend(["--set", "sensitivity.enabled=false"]);
        for s in sets {
            args.extend(["--set", s]);
        }
        common::json(&args)["steps"].as_u64().unwrap()
    };
    // the default weights are the displacement ones; the size is 0.456 m (crank and rod
    // along x): the default atol is 1e-4 · 1e-6 · 0.456 m
    let displacement = "analysis.error_weights=\"displacement\"";
    assert_eq!(steps(&[]), steps(&[displacement, "analysis.atol=4.56e-11"]));
    // with uniform weights the default atol is 1e-8
    let uniform = "analysis.error_weights=\"uniform\"";
    assert_eq!(steps(&[uniform]), steps(&[uniform, "analysis.atol=1e-8"]));
    assert_ne!(steps(&[uniform]), steps(&[]));
    assert_eq!(
        steps(&["analysis.rtol=1e-5"]),
        steps(&["analysis.rtol=1e-5", "analysis.atol=4.56e-10"])
    );
    // results.h5 records the tolerances of the last run, the default atol resolved
    steps(&["analysis.rtol=1e-5"]);
    let g = Group::read_hdf5(&dir.path().join("out/results.h5")).unwrap();
    let attrs = &g.groups["statistics"].attrs;
    let f = |k: &str| match &attrs[k] {
        Attr::F64(x) => *x,
        other => panic!("{k}: {other:?}"),
    };
    assert_eq!(f("rtol"), 1e-5);
    assert!((f("atol") / 4.56e-10 - 1.0).abs() < 1e-9, "{}", f("atol"));
    assert!(matches!(&attrs["error_weights"], Attr::Text(t) if t == "displacement"));
}

#[test]
fn bad_error_weights_and_body_tolerances_are_located() {
    let deck = std::fs::read_to_string(common::deck("slider_crank_beam.toml")).unwrap();
    let cases = [
        (
            "error_weights = \"uniform\"",
            "error_weights = \"displacment\"",
            "key `analysis.error_weights`",
            "did you mean `displacement`",
        ),
        (
            "[body.rod]\n",
            "[body.rod]\natol = -1e-9\n",
            "key `body.rod.atol`",
            "positive",
        ),
    ];
    for (at, with, key, why) in cases {
        assert!(deck.contains(at), "{at}");
        let text = deck.replace(at, with);
        let (_, err) = common::bad_deck(&text, |p| vec!["run".into(), p.display().to_string()]);
        assert!(err.contains(key) && err.contains(why), "{err}");
    }
}
