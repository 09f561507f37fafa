//! Elastic assembly: where the rigid-body coordinates alone cannot meet the joints (a
//! misaligned joint locks the frame), the start deforms the flexible bodies at the least
//! strain energy the joints allow. A cantilever whose tip is pinned 1 mm off its line takes
//! the closed-form tip force of a Timoshenko cantilever, and its strain energy; the assembled
//! state is an equilibrium of the dynamics (held, it stays), and its sensitivities are the
//! closed form's derivatives; a misfit beyond what the joints allow elastically names the
//! joint.

mod common;
use common::*;

const EI: f64 = 100.0;
const GA: f64 = 1.0e6;
const L: f64 = 1.0;

/// A 1 m beam welded to the ground at its start, its tip pinned (spherical joint) to a ground
/// point `misfit` m above its end, with or without its second-order field; `extra` appended.
fn cantilever(misfit: f64, stiffening: bool, extra: &str) -> String {
    format!(
        "[section.bar]\nshape = \"properties\"\nEA = 1.0e8\nGA2 = {GA:e}\nGA3 = {GA:e}\n\
         GJ = 50.0\nEI2 = {EI:e}\nEI3 = {EI:e}\nmass_per_length = 1.0\n\
         inertia = [1.0e-6, 1.0e-6]\n\n\
         [body.beam]\nkind = \"beam\"\nsection = \"bar\"\nstart = [0.0, 0.0, 0.0]\n\
         end = [{L}, 0.0, 0.0]\nelements = 10\nreference = \"clamped-node\"\nmodes = 4\n\
         damping = {{ beta = 1.0e-4 }}\nstiffening = {stiffening}\n\n\
         [joint.weld]\nkind = \"fixed\"\na = {{ body = \"ground\", point = [0.0, 0.0, 0.0] }}\n\
         b = {{ body = \"beam\", node = 0 }}\n\n\
         [joint.pin]\nkind = \"spherical\"\n\
         a = {{ body = \"ground\", point = [{L}, 0.0, {misfit:e}] }}\n\
         b = {{ body = \"beam\", node = 10 }}\n\n\
         [response.tip]\nkind = \"nodal-displacement\"\nbody = \"beam\"\nnode = 10\n\
         component = \"uz\"\n\n\
         [response.pin_force]\nkind = \"reaction\"\njoint = \"pin\"\ncomponent = \"fz\"\n\n\
         [response.pin_tension]\nkind = \"reaction\"\njoint = \"pin\"\ncomponent = \"fx\"\n\n\
         [analysis]\nt_end = 0.01\n{extra}"
    )
}

/// The start of `deck` checked and run: the strain energy `check` reports, the stderr of the
/// run and its results.
fn assembled(deck: &str) -> (f64, String, flexsens::results::Group) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("misfit.toml");
    std::fs::write(&path, deck).unwrap();
    let out = run(&["check", path.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = text
        .lines()
        .find(|l| l.starts_with("start: assembled with the flexible bodies deformed"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        line.contains("at `pin`") || line.contains("at `weld`"),
        "{line}"
    );
    let energy: f64 = line
        .split("strain energy ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    let results = dir.path().join("out");
    let o = run(&[
        "run",
        path.to_str().unwrap(),
        "-o",
        results.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{stderr}");
    let g = flexsens::results::Group::read_hdf5(&results.join("results.h5")).unwrap();
    (energy, stderr, g)
}

/// The misfit of 1 mm is taken up by the linear beam as the closed form says: the tip force
/// `F = δ / (L³/3EI + L/GA)` (the pin's reaction), the strain energy `F δ / 2` (what `check`
/// reports), the tip at the pin; run, the prestressed beam stays where it was assembled (an
/// equilibrium of the dynamics, whose forces are another code path than the assembly's
/// energy).
#[test]
fn a_misfit_cantilever_takes_the_closed_form_force() {
    let delta = 1e-3;
    let force = delta / (L.powi(3) / (3.0 * EI) + L / GA);
    let (energy, stderr, g) = assembled(&cantilever(delta, false, ""));
    let exact = 0.5 * force * delta;
    assert!(
        (energy / exact - 1.0).abs() < 1e-3,
        "{energy:e} J against {exact:e} J"
    );
    assert!(
        stderr.contains("the start deforms the flexible bodies"),
        "{stderr}"
    );
    for z in f64s(&g, "responses/tip") {
        assert!(
            (z / delta - 1.0).abs() < 1e-6,
            "tip at {z:e} against {delta:e}"
        );
    }
    for f in f64s(&g, "responses/pin_force") {
        assert!(
            (f.abs() / force - 1.0).abs() < 1e-6,
            "pin force {f:e} against {force:e}"
        );
    }
}

/// With its second-order field the pinned tip cannot foreshorten: the beam is stretched by the
/// shortening of its bent shape, `u = 3δ²/5L` for the cubic of a tip load, which takes a
/// tension `EA u / L` (60 N here, 200 times the transverse force) and its energy.
#[test]
fn a_stiffened_misfit_cantilever_is_stretched_by_its_foreshortening() {
    let (delta, ea) = (1e-3, 1.0e8);
    let (energy, _, g) = assembled(&cantilever(delta, true, ""));
    let u = 3.0 * delta * delta / (5.0 * L);
    let tension = ea * u / L;
    for f in f64s(&g, "responses/pin_tension") {
        assert!(
            (f.abs() / tension - 1.0).abs() < 1e-2,
            "tension {f:e} against {tension:e}"
        );
    }
    let bending = 0.5 * delta * delta / (L.powi(3) / (3.0 * EI) + L / GA);
    let exact = bending + 0.5 * tension * u;
    assert!(
        (energy / exact - 1.0).abs() < 1e-2,
        "{energy:e} J against {exact:e} J"
    );
}

/// A pin 0.3 m off the beam's line is beyond its small deformations: the start fails naming
/// the joint, and says the misfit may be more than the modes can take.
#[test]
fn a_misfit_beyond_the_modes_names_the_joint() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("far.toml");
    std::fs::write(&path, cantilever(0.3, true, "")).unwrap();
    let o = run(&["check", path.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot be met even with the flexible bodies deformed: joint `pin`")
            && err.contains("more than the bodies' modes can take up"),
        "{err}"
    );
}

/// The prestress's sensitivities: the pin's force `F = δ / (L³/3EI + L/GA)` differentiated
/// through the start (its optimality conditions), against the closed form's derivatives with
/// respect to `EI2` and `GA3`, and against replayed central differences (the `GA3` one, 3e-8 of
/// the force per 0.01 %, is below what the assembly's tolerance resolves).
#[test]
fn the_prestress_sensitivities_are_the_closed_forms() {
    let design = "[design.ei]\nkind = \"section-property\"\nsection = \"bar\"\nentry = \"EI2\"\n\n\
                  [design.ga]\nkind = \"section-property\"\nsection = \"bar\"\nentry = \"GA3\"\n\n\
                  [objective.force]\nresponse = \"pin_force\"\nkind = \"at\"\ntime = 0.0\n\n\
                  [sensitivity]\nmethod = \"direct\"\n\n[finite_differences]\n\
                  scheme = \"central\"\nsizes = [0.0001]\nsteps = \"replay\"\n\n[analysis]";
    let deck = cantilever(1e-3, false, "").replace("[analysis]", design);
    let doc = run_deck_json(&deck);
    let delta = 1e-3;
    let compliance = L.powi(3) / (3.0 * EI) + L / GA;
    let force = delta / compliance;
    let exact = [
        ("ei", force * force / delta * L.powi(3) / (3.0 * EI * EI)),
        ("ga", force * force / delta * L / (GA * GA)),
    ];
    let names: Vec<&str> = doc["design"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["name"].as_str().unwrap())
        .collect();
    let objective = &doc["objectives"][0];
    assert!((objective["value"].as_f64().unwrap() / force - 1.0).abs() < 1e-6);
    for (name, e) in exact {
        let k = names.iter().position(|n| *n == name).unwrap();
        let got = objective["gradient"][k].as_f64().unwrap();
        assert!(
            (got / e - 1.0).abs() < 1e-6,
            "{name}: {got:e} against {e:e}"
        );
    }
    // the force's history against replayed differences, both variables: within 1e-6 of the
    // largest derivative (the GA3 one is below what the differences resolve)
    let fd = &doc["finite_differences"][0]["max_absolute"]["pin_force"];
    let (difference, size) = (
        fd["difference"].as_f64().unwrap(),
        fd["sensitivity"].as_f64().unwrap(),
    );
    assert!(difference < 1e-6 * size, "{difference:e} against {size:e}");
}
