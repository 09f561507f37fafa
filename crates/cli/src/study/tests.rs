//! The study moved to other designs against the deck validated there.

use super::*;

/// The shipped beam and plate decks with design variables of every kind (ply angles, ply
/// thicknesses, material constants) and sections of every generator kind moved by them.
fn decks() -> Vec<(String, String)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../decks");
    let read = |n: &str| std::fs::read_to_string(dir.join(n)).unwrap();
    let beam = read("slider_crank_beam.toml");
    let plate = read("slider_crank_plate.toml");
    let thickness = "\n[design.outer]\nkind = \"ply-thickness\"\nlaminate = \"tube_wall\"\n\
                     plies = [2, 3]\n";
    let e1 = "\n[design.e1]\nkind = \"material\"\nmaterial = \"paper_composite\"\n\
              constant = \"E1\"\n";
    let tube = "[section.tube]\nshape = \"tube\"\ninner_radius = 4.529e-3\n\
                laminate = \"tube_wall\"\nelements_per_ply = 1\nelements_around = 32\n";
    assert!(beam.contains(tube));
    let boxed = beam.replace(
        tube,
        "[section.tube]\nshape = \"box\"\nwidth = 0.012\nheight = 0.01\n\
         laminate = \"tube_wall\"\nelements_per_ply = 1\n",
    );
    let solid = beam.replace(
        tube,
        "[section.tube]\nshape = \"rectangle\"\nwidth = 0.008\nheight = 0.004\n\
         material = \"paper_composite\"\nangle = 10.0\n",
    );
    let plate_t = "\n[design.t0]\nkind = \"ply-thickness\"\nlaminate = \"plate\"\n\
                   plies = [0]\n";
    vec![
        ("beam".into(), format!("{beam}{thickness}{e1}")),
        ("box".into(), format!("{boxed}{thickness}{e1}")),
        (
            "rectangle".into(),
            solid.replace("[design.theta]", "[design.unused]") + e1,
        ),
        ("plate".into(), format!("{plate}{plate_t}{e1}")),
    ]
}

/// `BodyDef::at` gives what validating the deck again with the laminates moved by a design
/// variable gives, for every variable of every deck (the finite differences' and the
/// optimiser's path to another design, which reads no deck).
#[test]
fn a_body_moved_to_a_design_is_the_body_validated_there() {
    for (what, text) in decks() {
        let src = Source::new(format!("{what}.toml"), text);
        let raw = src.parse().unwrap();
        let lam = validate_laminates(&src, &raw).unwrap();
        let design = validate_design(&src, &raw, &lam).unwrap();
        assert!(!design.variables.is_empty(), "{what}");
        for v in &design.variables {
            let mut moved = lam.clone();
            let b = if v.value == 0.0 { 0.5 } else { v.value * 1.02 };
            v.apply(&mut moved, b).unwrap();
            for (name, b) in &raw.body {
                let nominal = validate_body(&src, &raw, name, b, &lam).unwrap();
                let there = validate_body(&src, &raw, name, b, &moved).unwrap();
                let at = nominal.at(&moved).unwrap();
                let (a, t) = (format!("{at:?}"), format!("{there:?}"));
                if let Some(i) = a.bytes().zip(t.bytes()).position(|(x, y)| x != y) {
                    let from = i.saturating_sub(200);
                    panic!(
                        "{what}: body {name}, variable {}: `at` gives …{}…, validation …{}…",
                        v.name,
                        &a[from..(i + 100).min(a.len())],
                        &t[from..(i + 100).min(t.len())]
                    );
                }
                assert_eq!(a.len(), t.len());
                // (the rectangle deck keeps the beam deck's angle variable, `unused`)
                let moves = format!("{nominal:?}") != t;
                assert!(
                    moves || v.name == "unused",
                    "{what}: variable {} moves body {name}",
                    v.name
                );
            }
        }
    }
}

/// A variable moves each ply it names to its own value as written at the design, bit for bit
/// the laminate of the deck written there (`DesignVariable::overrides`): plies of different
/// angles and factors, in a plain and a symmetric laminate, angles and thicknesses.
#[test]
fn a_variable_moves_each_ply_to_the_deck_written_there() {
    for symmetric in [false, true] {
        for (kind, key) in [("ply-angle", "angle"), ("ply-thickness", "thickness")] {
            let text = format!(
                "[material.m]\nE = 70e9\nnu = 0.3\ndensity = 2700.0\n\n[laminate.l]\n\
                 symmetric = {symmetric}\nplies = [\n\
                 {{ material = \"m\", thickness = 1.0e-3, angle = 10.0 }},\n\
                 {{ material = \"m\", thickness = 2.0e-3, angle = 25.0 }},\n\
                 {{ material = \"m\", thickness = 1.5e-3, angle = -40.0 }},\n\
                 {{ material = \"m\", thickness = 0.5e-3, angle = 70.0 }},\n]\n\n\
                 [design.v]\nkind = \"{kind}\"\nlaminate = \"l\"\nplies = [0, 3]\n\
                 factors = [1.0, -2.0]\n"
            );
            let src = Source::new("plies.toml", text);
            let raw = src.parse().unwrap();
            let lam = validate_laminates(&src, &raw).unwrap();
            let design = validate_design(&src, &raw, &lam).unwrap();
            let v = &design.variables[0];
            let b = if key == "angle" {
                v.value * 1.3 + 7.0
            } else {
                v.value * 1.1
            };
            let mut moved = lam.clone();
            v.apply(&mut moved, b).unwrap();
            let there = src.edited(&v.overrides(b)).unwrap();
            let there = validate_laminates(&there, &there.parse().unwrap()).unwrap();
            let plies = |m: &LaminateModel| -> Vec<(u64, u64)> {
                m.laminates["l"]
                    .stack
                    .plies()
                    .iter()
                    .map(|p| (p.angle.to_bits(), p.thickness.to_bits()))
                    .collect()
            };
            assert_eq!(
                plies(&moved),
                plies(&there),
                "{kind}, symmetric {symmetric}"
            );
            assert_ne!(
                plies(&moved),
                plies(&lam),
                "{kind}: the variable moves the plies"
            );
        }
    }
}
