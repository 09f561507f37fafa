//! The deck keys whose value is one word of a fixed set: each set written once, here. The
//! validator that reads a key matches its words and names them in its message from this list,
//! and a test checks that `docs/decks.md` names every word in the key's section, so the
//! accepted words, the messages and the reference cannot drift apart.

use super::check::suggestion;

/// A key whose value is one of `words`.
pub struct Choices {
    /// The heading of the key's section in `docs/decks.md` (`[analysis]`).
    pub section: &'static str,
    /// The dotted key, with `NAME` for a named table (`body.NAME.basis`).
    pub key: &'static str,
    pub words: &'static [&'static str],
}

impl Choices {
    /// The words as a message lists them: `"a", "b" or "c"`.
    pub fn listed(&self) -> String {
        let quoted: Vec<String> = self.words.iter().map(|w| format!("\"{w}\"")).collect();
        match quoted.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => quoted.join(""),
        }
    }

    /// The message for an unknown word: `unknown WHAT `other`: expected "a", "b" or "c"`, with
    /// a "did you mean" when a word is close.
    pub fn unknown(&self, what: &str, other: &str) -> String {
        format!(
            "unknown {what} `{other}`: expected {}{}",
            self.listed(),
            self.suggestion(other)
        )
    }

    /// The "did you mean" for an unknown word (empty when no word is close).
    pub fn suggestion(&self, other: &str) -> String {
        let s = suggestion(other, self.words);
        if s.starts_with(", did you mean") {
            s
        } else {
            String::new()
        }
    }
}

macro_rules! choices {
    ($($(#[$doc:meta])* $name:ident: $section:literal, $key:literal, [$($w:literal),+ $(,)?];)+) => {
        $($(#[$doc])* pub const $name: Choices = Choices {
            section: $section,
            key: $key,
            words: &[$($w),+],
        };)+
        /// Every key of this module.
        pub const ALL: &[&Choices] = &[$(&$name),+];
    };
}

choices! {
    LAMINATE_REFERENCE: "[laminate.NAME]", "laminate.NAME.reference",
        ["mid-plane", "bottom", "top", "offset"];
    SECTION_SHAPE: "[section.NAME]", "section.NAME.shape",
        ["rectangle", "circle", "tube", "box", "channel", "i-beam", "mesh", "properties"];
    MESH_FORMAT: "[section.NAME]", "section.NAME.format", ["gmsh", "simple"];
    WALL_FRAME: "[section.NAME]", "section.NAME.regions.frame",
        ["tangent", "radial", "xi", "eta"];
    BODY_KIND: "[body.NAME]", "body.NAME.kind", ["beam", "shell"];
    BODY_REFERENCE: "[body.NAME]", "body.NAME.reference", [
        "centre-of-mass",
        "clamped-section",
        "free-free",
        "pinned-ends",
        "clamped-node",
        "supports",
        "partly-free",
    ];
    BODY_MASS: "[body.NAME]", "body.NAME.mass", ["lumped", "consistent"];
    BODY_BASIS: "[body.NAME]", "body.NAME.basis", ["interface", "modes"];
    COUPLING_KIND: "[body.NAME]", "body.NAME.couplings.NAME.kind", ["distributing", "rigid"];
    JOINT_KIND: "[joint.NAME]", "joint.NAME.kind", [
        "spherical",
        "revolute",
        "universal",
        "cylindrical",
        "translational",
        "fixed",
        "angle-driver",
        "distance-driver",
    ];
    MOTION_KIND: "[joint.NAME]", "joint.NAME.motion.kind",
        ["constant-speed", "polynomial", "ramp", "spin-up"];
    FORCE_KIND: "[force.NAME]", "force.NAME.kind",
        ["gravity", "point-force", "point-torque", "spring-damper", "joint-torque", "joint-force"];
    CONTROL_KIND: "[force.NAME]", "force.NAME.control.kind", ["pd"];
    FORCE_FRAME: "[force.NAME]", "force.NAME.frame", ["global", "body"];
    RESPONSE_KIND: "[response.NAME]", "response.NAME.kind", [
        "position",
        "velocity",
        "point-position",
        "point-velocity",
        "point-acceleration",
        "nodal-displacement",
        "mid-node-deflection",
        "reaction",
        "modal",
        "energy",
        "constraint-violation",
        "actuator-torque",
        "actuator-force",
        "actuator-power",
        "ply-stress",
        "ply-failure",
    ];
    INTEGRATOR: "[analysis]", "analysis.integrator", ["adaptive", "fixed"];
    ERROR_WEIGHTS: "[analysis]", "analysis.error_weights", ["uniform", "displacement"];
    REDUNDANT: "[analysis]", "analysis.redundant", ["remove", "reselect", "error"];
    DESIGN_KIND: "[design.NAME]", "design.NAME.kind",
        ["ply-angle", "ply-thickness", "material", "rigid-mass", "rigid-inertia", "section-property", "section-angle", "actuator-gain"];
    ACTUATOR_GAIN: "[design.NAME]", "design.NAME.gain", ["kp", "kd"];
    INERTIA_AXIS: "[design.NAME]", "design.NAME.axis", ["x", "y", "z"];
    OBJECTIVE_KIND: "[objective.NAME]", "objective.NAME.kind",
        ["integral", "mean", "rms", "max", "min", "final", "ks", "at"];
    SENSITIVITY_METHOD: "[sensitivity]", "sensitivity.method",
        ["direct", "simultaneous", "corrector", "adjoint", "auto"];
    SENSITIVITY_MODES: "[sensitivity]", "sensitivity.modes", ["updated", "fixed"];
    FD_SCHEME: "[finite_differences]", "finite_differences.scheme", ["forward", "central"];
    FD_PERTURBATION: "[finite_differences]", "finite_differences.perturbation",
        ["relative", "absolute"];
    FD_STEPS: "[finite_differences]", "finite_differences.steps",
        ["replay", "adaptive", "both"];
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The text of the section of `docs/decks.md` under the heading containing `heading`, to
    /// the next heading of the same or a higher level.
    fn docs_section(heading: &str) -> String {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/decks.md");
        let docs = std::fs::read_to_string(path).unwrap();
        let mut out = String::new();
        let mut level = None;
        for line in docs.lines() {
            let hashes = line.chars().take_while(|&c| c == '#').count();
            if hashes > 0 {
                match level {
                    Some(l) if hashes <= l => break,
                    None if line.contains(&format!("`{heading}`")) => level = Some(hashes),
                    _ => {}
                }
            }
            if level.is_some() {
                out.push_str(line);
                out.push('\n');
            }
        }
        assert!(!out.is_empty(), "docs/decks.md has no section `{heading}`");
        out
    }

    /// Every word of every key is named (quoted) in the key's section of the reference, and
    /// the key itself too (its last part, in backticks, alone or as `key = …`).
    #[test]
    fn the_reference_names_every_word_of_every_key() {
        for c in ALL {
            let text = docs_section(c.section);
            let last = c.key.rsplit('.').next().unwrap();
            assert!(
                text.contains(&format!("`{last}`")) || text.contains(&format!("`{last} = ")),
                "docs/decks.md {}: no key `{last}`",
                c.section
            );
            for w in c.words {
                assert!(
                    text.contains(&format!("\"{w}\"")),
                    "docs/decks.md {}: `{}` does not name \"{w}\"",
                    c.section,
                    c.key
                );
            }
        }
    }

    #[test]
    fn words_are_listed_as_a_sentence() {
        assert_eq!(BODY_MASS.listed(), "\"lumped\" or \"consistent\"");
        assert_eq!(REDUNDANT.listed(), "\"remove\", \"reselect\" or \"error\"");
        assert_eq!(
            INTEGRATOR.unknown("integrator", "fixd"),
            "unknown integrator `fixd`: expected \"adaptive\" or \"fixed\", did you mean `fixed`?"
        );
    }
}
