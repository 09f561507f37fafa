//! Values of the mechanism tables: angles, rates and quantities with units, rotations and
//! inertias.

use super::*;

/// An angle: a number in degrees, or a string `"<number> deg|rad"`; radians out.
pub fn angle(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<f64, DeckError> {
    quantity(
        src,
        key,
        v,
        &[("deg", std::f64::consts::PI / 180.0), ("rad", 1.0)],
        "degrees",
    )
}

/// An angular rate: a number in deg/s, or a string `"<number> deg/s|rad/s|rpm"`; rad/s out.
pub fn angular_rate(src: &Source, key: &str, v: &Spanned<toml::Value>) -> Result<f64, DeckError> {
    let deg = std::f64::consts::PI / 180.0;
    quantity(
        src,
        key,
        v,
        &[
            ("deg/s", deg),
            ("rad/s", 1.0),
            ("rpm", std::f64::consts::PI / 30.0),
        ],
        "deg/s",
    )
}

pub fn quantity(
    src: &Source,
    key: &str,
    v: &Spanned<toml::Value>,
    units: &[(&str, f64)],
    default: &str,
) -> Result<f64, DeckError> {
    let bad = |m: String| src.error(span(v), Some(key.to_string()), m);
    let x = match v.get_ref() {
        toml::Value::Float(x) => *x * units[0].1,
        toml::Value::Integer(i) => *i as f64 * units[0].1,
        toml::Value::String(s) => {
            let (num, unit) = s
                .trim()
                .split_once(char::is_whitespace)
                .unwrap_or((s.as_str(), ""));
            let factor = units.iter().find(|(u, _)| *u == unit.trim()).map(|(_, f)| *f).ok_or_else(|| {
                let known: Vec<&str> = units.iter().map(|(u, _)| *u).collect();
                bad(format!("`{s}`: expected a number ({default}) or \"<number> <unit>\" with a unit of {}", known.join(", ")))
            })?;
            num.parse::<f64>()
                .map_err(|_| bad(format!("`{num}` is not a number")))?
                * factor
        }
        other => {
            return Err(bad(format!(
                "expected a number ({default}) or a string with a unit, found {}",
                other.type_str()
            )));
        }
    };
    if x.is_finite() {
        Ok(x)
    } else {
        Err(bad(format!("{x} must be finite")))
    }
}

pub fn rotation(
    src: &Source,
    key: &str,
    r: &Spanned<RawRotation>,
) -> Result<Matrix3<f64>, DeckError> {
    let raw = r.get_ref();
    let axis = direction(
        src,
        &format!("{key}.axis"),
        required(
            src,
            span(r),
            &format!("{key}.axis"),
            &raw.axis,
            "axis [x, y, z]",
        )?,
    )?;
    let a = angle(
        src,
        &format!("{key}.angle"),
        required(
            src,
            span(r),
            &format!("{key}.angle"),
            &raw.angle,
            "angle (degrees)",
        )?,
    )?;
    Ok(*Rotation3::from_axis_angle(&Unit::new_normalize(axis), a).matrix())
}

pub fn inertia(
    src: &Source,
    key: &str,
    v: &Spanned<toml::Value>,
) -> Result<Matrix3<f64>, DeckError> {
    let bad = || {
        src.error(
            span(v),
            Some(key.into()),
            "expected [Ixx, Iyy, Izz] or a 3×3 matrix [[…], […], […]] (kg·m²)",
        )
    };
    let num = |x: &toml::Value| x.as_float().or_else(|| x.as_integer().map(|i| i as f64));
    let arr = v.get_ref().as_array().ok_or_else(bad)?;
    let m = if arr.len() == 3 && arr.iter().all(|x| num(x).is_some()) {
        Matrix3::from_diagonal(&Vector3::new(
            num(&arr[0]).unwrap_or(0.0),
            num(&arr[1]).unwrap_or(0.0),
            num(&arr[2]).unwrap_or(0.0),
        ))
    } else if arr.len() == 3 {
        let mut m = Matrix3::zeros();
        for (i, row) in arr.iter().enumerate() {
            let row = row.as_array().filter(|r| r.len() == 3).ok_or_else(bad)?;
            for (j, x) in row.iter().enumerate() {
                m[(i, j)] = num(x).ok_or_else(bad)?;
            }
        }
        m
    } else {
        return Err(bad());
    };
    let symmetric = (m - m.transpose()).abs().max() <= 1e-12 * m.abs().max();
    let pd = m.cholesky().is_some();
    if !(m.iter().all(|x| x.is_finite()) && symmetric && pd) {
        return Err(src.error(
            span(v),
            Some(key.into()),
            "the inertia must be symmetric positive definite",
        ));
    }
    Ok(m)
}
