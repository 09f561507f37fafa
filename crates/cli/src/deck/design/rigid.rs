//! Rigid-mass and rigid-inertia variables: a rigid body's mass or one of its principal
//! inertias.

use super::*;

/// A rigid body's mass or principal inertia as a design variable.
pub(super) fn rigid_variable(
    src: &Source,
    raw: &RawDeck,
    name: &str,
    d: &Spanned<RawDesign>,
    kind: &str,
) -> Result<DesignVariable, DeckError> {
    let k = |s: &str| format!("design.{name}.{s}");
    let rd = d.get_ref();
    let body = required(
        src,
        span(d),
        &k("body"),
        &rd.body,
        "body (a rigid body's name)",
    )?;
    let rigid = super::super::mechanism::rigid_bodies(src, raw)?;
    let Some(r) = rigid.iter().find(|r| r.name == *body.get_ref()) else {
        let known: Vec<&str> = rigid.iter().map(|r| r.name.as_str()).collect();
        let what = if raw.body.contains_key(body.get_ref()) {
            " (a flexible body: its mass comes from its laminates)".to_string()
        } else {
            suggestion(body.get_ref(), &known)
        };
        return Err(src.error(
            span(body),
            Some(k("body")),
            format!("undefined rigid body `{}`{what}", body.get_ref()),
        ));
    };
    let body = body.get_ref().clone();
    Ok(if kind == "rigid-mass" {
        DesignVariable {
            name: name.to_string(),
            value: r.mass,
            target: Target::RigidMass { body },
            unit: "kg",
        }
    } else {
        let axis = required(
            src,
            span(d),
            &k("axis"),
            &rd.axis,
            "axis (\"x\", \"y\" or \"z\")",
        )?;
        let axis = choice(
            src,
            &k("axis"),
            Some(axis),
            super::super::keys::INERTIA_AXIS.words,
        )?
        .map_or(0, |a| (a.as_bytes()[0] - b'x') as usize);
        let off = (0..3).any(|j| j != axis && r.inertia[(axis, j)] != 0.0);
        if off {
            return Err(src.error(
                rd.axis.as_ref().and_then(span),
                Some(k("axis")),
                "the inertia has products of inertia on this axis: a principal moment is a \
                 design variable only where the tensor is diagonal",
            ));
        }
        // the entry as written: [Ixx, Iyy, Izz] or a 3×3 matrix
        let matrix = raw.rigid[&body]
            .get_ref()
            .inertia
            .as_ref()
            .and_then(|v| v.get_ref().as_array())
            .is_some_and(|a| a.first().is_some_and(toml::Value::is_array));
        let key = if matrix {
            format!("rigid.{body}.inertia.{axis}.{axis}")
        } else {
            format!("rigid.{body}.inertia.{axis}")
        };
        DesignVariable {
            name: name.to_string(),
            value: r.inertia[(axis, axis)],
            target: Target::RigidInertia { body, axis, key },
            unit: "kg*m^2",
        }
    })
}
