//! Every key the deck reader accepts is documented in `docs/decks.md`, in the section of
//! its table: the keys are read from the serde structs themselves, so a key added to the
//! reader and not to the reference fails here.

use serde::de::{self, Deserialize, Deserializer, Visitor};

use super::*;

/// The field list a derived `Deserialize` passes to `deserialize_struct`.
#[derive(Debug)]
struct Fields(Vec<&'static str>);

impl std::fmt::Display for Fields {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.0)
    }
}

impl std::error::Error for Fields {}

impl de::Error for Fields {
    fn custom<T: std::fmt::Display>(_: T) -> Self {
        Fields(Vec::new())
    }
}

struct Grab;

impl<'de> Deserializer<'de> for Grab {
    type Error = Fields;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Fields> {
        Err(Fields(Vec::new()))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, Fields> {
        Err(Fields(fields.to_vec()))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
        byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map enum
        identifier ignored_any
    }
}

fn fields<'de, T: Deserialize<'de>>() -> Vec<&'static str> {
    match T::deserialize(Grab) {
        Err(Fields(f)) => f,
        Ok(_) => unreachable!("Grab never yields a value"),
    }
}

/// The text of the section of `docs/decks.md` under the heading containing `heading`, up
/// to the next heading of the same or a higher level.
fn section<'a>(doc: &'a str, heading: &str) -> &'a str {
    let start = doc
        .match_indices('#')
        .map(|(i, _)| i)
        .find(|&i| {
            (i == 0 || doc.as_bytes()[i - 1] == b'\n')
                && doc[i..].lines().next().is_some_and(|l| l.contains(heading))
        })
        .unwrap_or_else(|| panic!("no heading with {heading} in docs/decks.md"));
    let level = doc[start..].bytes().take_while(|&b| b == b'#').count();
    let body = &doc[start..];
    let end = body
        .match_indices("\n#")
        .map(|(i, _)| i)
        .find(|&i| body[i + 1..].bytes().take_while(|&b| b == b'#').count() <= level)
        .unwrap_or(body.len());
    &body[..end]
}

#[test]
fn every_deck_key_is_documented_in_the_section_of_its_table() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/decks.md"))
        .unwrap();
    let tables: Vec<(&str, Vec<&'static str>)> = vec![
        ("## Top level", fields::<RawDeck>()),
        ("[material.NAME]", fields::<RawMaterial>()),
        ("[laminate.NAME]", fields::<RawLaminate>()),
        ("[laminate.NAME]", fields::<RawPly>()),
        ("[section.NAME]", fields::<RawSection>()),
        ("[section.NAME]", fields::<RawSectionPly>()),
        ("[section.NAME]", fields::<RawWalls>()),
        ("[section.NAME]", fields::<RawRegion>()),
        ("[body.NAME]", fields::<RawBody>()),
        ("[body.NAME]", fields::<RawDamping>()),
        ("[body.NAME]", fields::<RawSupport>()),
        ("[body.NAME]", fields::<RawPlane>()),
        ("[body.NAME]", fields::<RawSegment>()),
        ("[body.NAME]", fields::<RawShellRegion>()),
        ("[body.NAME]", fields::<RawCoupling>()),
        ("[rigid.NAME]", fields::<RawRigid>()),
        ("[rigid.NAME]", fields::<RawRotation>()),
        ("### Markers", fields::<RawMarker>()),
        ("[joint.NAME]", fields::<RawJoint>()),
        ("[joint.NAME]", fields::<RawMotion>()),
        ("[force.NAME]", fields::<RawForce>()),
        ("[force.NAME]", fields::<RawTable>()),
        ("[response.NAME]", fields::<RawResponse>()),
        ("[analysis]", fields::<RawAnalysis>()),
        ("[design.NAME]", fields::<RawDesign>()),
        ("[objective.NAME]", fields::<RawObjective>()),
        ("[sensitivity]", fields::<RawSensitivity>()),
        ("[finite_differences]", fields::<RawFiniteDifferences>()),
        ("[optimize]", fields::<RawOptimize>()),
        ("[optimize]", fields::<RawConstraint>()),
        ("[operating]", fields::<RawOperating>()),
    ];
    let mut missing = Vec::new();
    for (heading, keys) in &tables {
        assert!(!keys.is_empty(), "no fields read for {heading}");
        let text = section(&doc, heading);
        for key in keys {
            // a key is documented as a word of its section (in a table row or a `{ … }`)
            let documented = text.match_indices(key).any(|(i, _)| {
                let before = text[..i].chars().next_back();
                let after = text[i + key.len()..].chars().next();
                let word = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
                !word(before) && !word(after)
            });
            if !documented {
                missing.push(format!("{heading}: `{key}`"));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "undocumented deck keys:\n{}",
        missing.join("\n")
    );
}

/// A value of the wrong type where the reader expects a table is reported as a table of the
/// deck, never by the reader's type name (`struct RawPly`).
#[test]
fn type_errors_name_tables_not_reader_types() {
    for (text, expected) in [
        (
            "[laminate.l]\nplies = [1]\n",
            "expected a ply table { material, thickness, angle }",
        ),
        (
            "[joint.pin]\nkind = \"revolute\"\na = 3\n",
            "expected a marker table",
        ),
        ("analysis = 3\n", "expected a table"),
    ] {
        let e = crate::deck::Source::new("t.toml", text)
            .parse()
            .expect_err(text)
            .to_string();
        assert!(e.contains(expected) && !e.contains("Raw"), "{text}: {e}");
    }
}
