//! The ply stress and failure responses of a flexible body ([`crate::Response::PlyStress`],
//! [`crate::Response::PlyFailure`]): the stresses `P E w` of [`fem::stress`] at the body's
//! modal coordinates, and a failure criterion on them (docs/failure-criteria.md, "In a run").

use fem::PointPlace;
use laminate::{Criterion, PlyPosition};
use sens::Scalar;

use crate::body::{FlexibleBody, PlyStresses};

/// Which ply points a failure response covers: `None` is every element, ply or position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PlySelection<'a> {
    pub elements: Option<&'a [usize]>,
    pub ply: Option<usize>,
    pub position: Option<PlyPosition>,
}

/// Below this, `exp(ρ (FI − max))` of a point is left out of the aggregate (`e⁻⁴⁰ ≈ 4e-18`
/// of the largest term: beneath the value's rounding).
const KS_CUTOFF: f64 = 40.0;

fn stresses_of<P: Scalar>(f: &FlexibleBody<P>) -> Result<&PlyStresses<P>, String> {
    f.stresses.as_deref().ok_or_else(|| {
        format!(
            "body `{}` has no ply stresses (built for its responses)",
            f.name
        )
    })
}

/// The element's position in the body's stresses and the index of the point of `ply` at
/// `place` in its laminate (a section's: its region `ply`'s point nearest to `place`).
fn point_of<P: Scalar>(
    s: &PlyStresses<P>,
    element: usize,
    ply: usize,
    place: PointPlace,
) -> Result<(usize, usize), String> {
    let i = (s.modal.element_index(element))
        .ok_or_else(|| format!("element {element} has no ply stresses in the body"))?;
    let lam = &s.modal.laminates[s.modal.elements[i].laminate];
    let distance = |p: PointPlace| match (p, place) {
        (PointPlace::Section(a), PointPlace::Section(b)) => Some((a[0] - b[0]).hypot(a[1] - b[1])),
        (a, b) => (a == b).then_some(0.0),
    };
    let k = (lam.points.iter().enumerate())
        .filter(|(_, p)| p.ply == ply)
        .filter_map(|(k, p)| Some((k, distance(p.place)?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
        .ok_or_else(|| {
            format!(
                "element {element}'s laminate or section has no point of ply (region) {ply} \
                 at {place:?} (plies 0 to {})",
                lam.materials.len().saturating_sub(1)
            )
        })?;
    Ok((i, k))
}

/// Component `component` of the stress of `ply` at `place` of element `element` (material
/// axes, Pa) at the modal coordinates `w`; with `strain`, of the strain (engineering shear),
/// `ε = C⁻¹ σ` through the ply's nominal compliance (a design variable that moves the material
/// moves `σ`, not `C⁻¹`: its caller refuses such a variable).
pub(crate) fn ply_stress<P: Scalar, S: Scalar + From<P>>(
    f: &FlexibleBody<P>,
    w: &[S],
    (element, ply, place): (usize, usize, PointPlace),
    (component, strain): (usize, bool),
) -> Result<S, String> {
    let s = stresses_of(f)?;
    if component > 5 {
        return Err(format!(
            "stress component {component} out of range (0 to 5)"
        ));
    }
    let (i, k) = point_of(s, element, ply, place)?;
    let d = s.modal.deformation(i, w);
    let stress = s.modal.stress(i, k, &d);
    if !strain {
        return Ok(stress[component]);
    }
    let lam = &s.modal.laminates[s.modal.elements[i].laminate];
    let compliance = lam.materials[lam.points[k].ply].compliance();
    Ok((0..6).fold(S::zero(), |e, c| e + stress[c] * compliance[(component, c)]))
}

/// The failure index under `criterion` over the points of `selection`: their largest (`rho`
/// `None`) with the derivatives of the point where it is, or their Kreisselmeier–Steinhauser
/// aggregate `max + ln Σ exp(ρ (FI_k − max)) / ρ`. The points are scanned on values; only the
/// largest (or those within `KS_CUTOFF/ρ` of it) are evaluated in `S`.
pub(crate) fn ply_failure<P: Scalar, S: Scalar + From<P>>(
    f: &FlexibleBody<P>,
    w: &[S],
    selection: PlySelection<'_>,
    criterion: Criterion,
    rho: Option<f64>,
) -> Result<S, String> {
    let s = stresses_of(f)?;
    let m = &s.modal;
    // every station of the selected elements
    let elements: Vec<usize> = match selection.elements {
        Some(list) => {
            let mut out = Vec::new();
            for &e in list {
                let stations = m.element_stations(e);
                if stations.is_empty() {
                    return Err(format!("element {e} has no ply stresses in the body"));
                }
                out.extend(stations);
            }
            out
        }
        None => (0..m.elements.len()).collect(),
    };
    let wv: Vec<f64> = w.iter().map(|x| x.value()).collect();
    // (element, point, index) of every selected point with a strength
    let mut values: Vec<(usize, usize, f64)> = Vec::new();
    for &i in &elements {
        let l = m.elements[i].laminate;
        let lam = &m.laminates[l];
        let d = m.deformation_value(i, &wv);
        for (k, p) in lam.points.iter().enumerate() {
            if selection.ply.is_some_and(|q| q != p.ply)
                || selection
                    .position
                    .is_some_and(|q| p.place != PointPlace::Ply(q))
            {
                continue;
            }
            let strength = s.strengths[l][p.ply]
                .as_ref()
                .ok_or_else(|| format!("ply {} of laminate {l} has no strengths", p.ply))?;
            let stress = m.stress_value(i, k, &d);
            let fi = criterion.index(&lam.materials[p.ply], strength, &stress);
            values.push((i, k, fi));
        }
    }
    if let Some(ply) = selection.ply
        && values.is_empty()
    {
        return Err(format!("no selected laminate has a ply {ply}"));
    }
    let Some(&(i0, k0, largest)) = values.iter().max_by(|a, b| a.2.total_cmp(&b.2)) else {
        return Err("no ply point selected".into());
    };
    // the index in S, the element's deformation formed once for its points (`values` holds
    // them element by element)
    let mut deformed: Option<(usize, [S; fem::stress::DEFORMATION])> = None;
    let mut index = |i: usize, k: usize| -> S {
        let d = match deformed {
            Some((e, d)) if e == i => d,
            _ => {
                let d = m.deformation(i, w);
                deformed = Some((i, d));
                d
            }
        };
        let l = m.elements[i].laminate;
        let p = &m.laminates[l].points[k];
        let strength = s.strengths[l][p.ply].as_ref().expect("checked above");
        criterion.index(
            &m.laminates[l].materials[p.ply],
            strength,
            &m.stress(i, k, &d),
        )
    };
    let Some(rho) = rho else {
        return Ok(if S::PLAIN {
            S::from_f64(largest)
        } else {
            index(i0, k0)
        });
    };
    // the sum over the points near the largest, shifted by the largest's value (a constant:
    // the aggregate's derivative does not depend on the shift)
    let near = values.iter().filter(|v| rho * (v.2 - largest) > -KS_CUTOFF);
    let sum = if S::PLAIN {
        // values alone: the scan's
        S::from_f64(near.map(|v| (rho * (v.2 - largest)).exp()).sum())
    } else {
        near.fold(S::zero(), |sum, &(i, k, _)| {
            sum + ((index(i, k) - S::from_f64(largest)) * rho).exp()
        })
    };
    Ok(S::from_f64(largest) + sum.ln() * (1.0 / rho))
}
