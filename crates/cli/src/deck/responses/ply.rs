//! `kind = "ply-stress"` and `kind = "ply-failure"`: a flexible body's ply stresses and
//! failure indices — a shell's laminates' plies, a beam's sections' regions
//! (docs/failure-criteria.md, "In a run").

use laminate::{Criterion, PlyPosition};
use nalgebra::Vector3;
use toml::Spanned;

use super::{SpecKind, Table, component};
use crate::deck::DeckError;
use crate::deck::check::{self, positive, span, suggestion};
use crate::deck::mechanism::PlyMap;

const POSITIONS: [&str; 3] = ["bottom", "middle", "top"];
const POSITION_OF: [PlyPosition; 3] = [PlyPosition::Bottom, PlyPosition::Middle, PlyPosition::Top];
/// Stress and then strain components, material axes (Voigt order, engineering shear strains).
const COMPONENTS: [&str; 12] = [
    "s11", "s22", "s33", "s23", "s13", "s12", "e11", "e22", "e33", "e23", "e13", "e12",
];

impl Table<'_> {
    /// The flexible body the response names, its plies and its nodes; the keys that belong to
    /// the other kind of body refused.
    fn ply_map(&self) -> Result<(String, &PlyMap, &[Vector3<f64>]), DeckError> {
        let (body, geometry) = self.body(true)?;
        let g = geometry.expect("a flexible body");
        let map = &g.plies;
        let foreign = match map.beam {
            true => [
                ("ply", self.raw.ply.as_ref().and_then(span)),
                ("position", self.raw.position.as_ref().and_then(span)),
            ],
            false => [
                ("region", self.raw.region.as_ref().and_then(span)),
                (
                    "section_point",
                    self.raw.section_point.as_ref().and_then(span),
                ),
            ],
        };
        if let Some((key, at)) = foreign.into_iter().find(|(_, s)| s.is_some()) {
            let why = match map.beam {
                true => format!(
                    "`{body}` is a beam body: its stress points are its sections' integration \
                     points, chosen by `region` and (for a stress) `section_point = [x2, x3]`, \
                     not by a ply and a position through it"
                ),
                false => format!(
                    "`{body}` is a shell body: its stress points are chosen by `ply` and \
                     `position` (a beam section's `region` and `section_point` do not apply)"
                ),
            };
            return Err(self.src.error(at, Some(self.key(key)), why));
        }
        Ok((body, map, &g.nodes[..]))
    }

    /// `element` (required for a stress): an element of the body.
    fn ply_element(&self, map: &PlyMap, required: bool) -> Result<Option<usize>, DeckError> {
        let what = "element (from 0)";
        let Some(v) = self.given("element", &self.raw.element, required, what)? else {
            return Ok(None);
        };
        let n = map.element_laminates.len();
        let e = *v.get_ref();
        if e < 0 || e as usize >= n {
            return Err(self.src.error(
                span(v),
                Some(self.key("element")),
                format!("element {e} does not exist (elements 0 to {})", n - 1),
            ));
        }
        Ok(Some(e as usize))
    }

    /// `ply` (required for a stress): a ply of one of `laminates` (from 0, bottom first); a
    /// beam body's `region` of one of its sections. A section given by its properties has no
    /// stress points and is refused.
    fn ply_index(
        &self,
        map: &PlyMap,
        laminates: &[usize],
        required: bool,
    ) -> Result<Option<usize>, DeckError> {
        let (key, field, what, parts, whole) = match map.beam {
            true => (
                "region",
                &self.raw.region,
                "region (from 0)",
                "regions",
                "section",
            ),
            false => (
                "ply",
                &self.raw.ply,
                "ply (from 0, bottom first)",
                "plies",
                "laminate",
            ),
        };
        if let Some(&l) = (laminates.iter()).find(|&&l| map.beam && map.laminates[l].1.is_empty()) {
            return Err(self.src.error(
                self.raw.body.as_ref().and_then(span),
                Some(self.key("body")),
                format!(
                    "section `{}` of the body is given by its properties: it has no stress \
                     points (a section analysed from its shape or mesh has)",
                    map.laminates[l].0
                ),
            ));
        }
        let Some(v) = self.given(key, field, required, what)? else {
            return Ok(None);
        };
        let most = (laminates.iter())
            .map(|&l| map.laminates[l].1.len())
            .max()
            .unwrap_or(0);
        let p = *v.get_ref();
        if p < 0 || p as usize >= most {
            let names: Vec<&str> = laminates.iter().map(|&l| &*map.laminates[l].0).collect();
            return Err(self.src.error(
                span(v),
                Some(self.key(key)),
                format!(
                    "{key} {p} does not exist: {whole} {} has {parts} 0 to {}",
                    names.join(", "),
                    most - 1
                ),
            ));
        }
        Ok(Some(p as usize))
    }

    /// `section_point` (a beam's stress): `[x₂, x₃]` in the section (m), finite.
    fn section_point(&self) -> Result<[f64; 2], DeckError> {
        let what = "section_point ([x2, x3], m: the region's integration point nearest to it)";
        let v = self.given("section_point", &self.raw.section_point, true, what)?;
        let v = v.expect("required");
        let p = *v.get_ref();
        if p.iter().any(|x| !x.is_finite()) {
            return Err(self.src.error(
                span(v),
                Some(self.key("section_point")),
                "[x2, x3] with finite coordinates (m)",
            ));
        }
        Ok(p)
    }

    /// `position` (required for a stress): where through the ply.
    fn ply_position(&self, required: bool) -> Result<Option<PlyPosition>, DeckError> {
        if self.raw.position.is_none() && !required {
            return Ok(None);
        }
        let i = component(
            self.src,
            &self.key("position"),
            self.raw.position.as_ref(),
            self.span.clone(),
            &POSITIONS,
        )?;
        Ok(Some(POSITION_OF[i]))
    }

    /// The value at `key` (`field`): `check::required`'s when `required`, else as given.
    fn given<'b, T>(
        &self,
        key: &str,
        field: &'b Option<Spanned<T>>,
        required: bool,
        what: &str,
    ) -> Result<Option<&'b Spanned<T>>, DeckError> {
        match required {
            true => {
                check::required(self.src, self.span.clone(), &self.key(key), field, what).map(Some)
            }
            false => Ok(field.as_ref()),
        }
    }

    /// `kind = "ply-stress"`: a stress or strain component of a ply point of a shell element,
    /// or of a section point of a beam element, with its unit.
    pub(super) fn ply_stress(&self) -> Result<(SpecKind, &'static str), DeckError> {
        let (body, map, _) = self.ply_map()?;
        let element = self.ply_element(map, true)?.expect("required");
        let laminate = map.element_laminates[element];
        let ply = self.ply_index(map, &[laminate], true)?.expect("required");
        let place = match map.beam {
            true => fem::PointPlace::Section(self.section_point()?),
            false => fem::PointPlace::Ply(self.ply_position(true)?.expect("required")),
        };
        let c = self.component(&COMPONENTS)?;
        let spec = SpecKind::PlyStress {
            body,
            element,
            ply,
            place,
            component: c % 6,
            strain: c >= 6,
        };
        Ok((spec, if c >= 6 { "1" } else { "Pa" }))
    }

    /// `box`: the elements whose nodes all lie in it (within 1e-9 of the body's size).
    fn elements_in_box(
        &self,
        map: &PlyMap,
        nodes: &[Vector3<f64>],
    ) -> Result<Option<Vec<usize>>, DeckError> {
        let Some(b) = &self.raw.inside else {
            return Ok(None);
        };
        let key = self.key("box");
        if self.raw.element.is_some() {
            return Err(self.src.error(
                span(b),
                Some(key),
                "give the elements in one way: element = N or box = [[…], […]]",
            ));
        }
        let [lo, hi] = *b.get_ref();
        if (0..3).any(|a| !(lo[a].is_finite() && hi[a].is_finite() && lo[a] <= hi[a])) {
            return Err(self.src.error(
                span(b),
                Some(key),
                "[[x0, y0, z0], [x1, y1, z1]] with finite corners, x0 ≤ x1, y0 ≤ y1, z0 ≤ z1",
            ));
        }
        let (mut min, mut max) = (nodes[0], nodes[0]);
        for p in nodes {
            min = min.inf(p);
            max = max.sup(p);
        }
        let tol = 1e-9 * (max - min).norm();
        let inside =
            |k: usize| (0..3).all(|a| nodes[k][a] >= lo[a] - tol && nodes[k][a] <= hi[a] + tol);
        let elements: Vec<usize> = (0..map.element_nodes.len())
            .filter(|&e| map.element_nodes[e].iter().all(|&k| inside(k)))
            .collect();
        if elements.is_empty() {
            return Err(self.src.error(
                span(b),
                Some(key),
                format!(
                    "no element of the body has all its nodes in the box (its nodes span [{:e},                      {:e}, {:e}] to [{:e}, {:e}, {:e}] m)",
                    min.x, min.y, min.z, max.x, max.y, max.z
                ),
            ));
        }
        Ok(Some(elements))
    }

    /// `kind = "ply-failure"`: a failure index at a ply point, or over the points selected.
    pub(super) fn ply_failure(&self) -> Result<SpecKind, DeckError> {
        let (body, map, nodes) = self.ply_map()?;
        let elements = match self.elements_in_box(map, nodes)? {
            Some(list) => Some(list),
            None => self.ply_element(map, false)?.map(|e| vec![e]),
        };
        let mut laminates: Vec<usize> = match &elements {
            Some(list) => list.iter().map(|&e| map.element_laminates[e]).collect(),
            None => map.element_laminates.clone(),
        };
        laminates.sort_unstable();
        laminates.dedup();
        let ply = self.ply_index(map, &laminates, false)?;
        let position = self.ply_position(false)?;
        let criterion = self.criterion()?;
        let rho = (self.raw.rho.as_ref())
            .map(|r| positive(self.src, &self.key("rho"), r, "1"))
            .transpose()?;
        if rho.is_some() && matches!(criterion, Criterion::Hashin | Criterion::HashinFibre) {
            self.src.warn(
                self.raw.criterion.as_ref().and_then(span),
                Some(self.key("criterion")),
                "Hashin's fibre index jumps where σ11 changes sign under shear (its tension form \
                 counts the shear, its compression form does not), so this aggregate is not \
                 differentiable in the design where a point's σ11 crosses zero \
                 (docs/failure-criteria.md, \"In a run\"); for a constraint an optimiser \
                 differentiates, use tsai-wu or hashin-matrix",
            );
        }
        // every ply selected needs its material's strengths
        for &l in &laminates {
            let (name, plies) = &map.laminates[l];
            for (p, (material, strength)) in plies.iter().enumerate() {
                if strength.is_some() || ply.is_some_and(|q| q != p) {
                    continue;
                }
                let what = match map.beam {
                    true => format!("region {p} of section `{name}`"),
                    false => format!("ply {p} of laminate `{name}`"),
                };
                let why = match material.is_empty() {
                    true => format!(
                        "{what} has its material from the mesh file, which states no \
                         strengths: make the region of a [material.*] of the deck with Xt, Xc, \
                         Yt, Yc and S12 (Pa)"
                    ),
                    false => format!(
                        "{what} is of material `{material}`, which states no strengths: give \
                         Xt, Xc, Yt, Yc and S12 in [material.{material}] (Pa)"
                    ),
                };
                return Err(self.src.error(
                    self.raw.criterion.as_ref().and_then(span),
                    Some(self.key("criterion")),
                    why,
                ));
            }
        }
        Ok(SpecKind::PlyFailure {
            body,
            elements,
            ply,
            position,
            criterion,
            rho,
        })
    }

    /// `criterion`: a failure criterion by its name.
    fn criterion(&self) -> Result<Criterion, DeckError> {
        let names: Vec<&str> = Criterion::ALL.iter().map(|c| c.name()).collect();
        let what = format!("criterion ({})", names.join(", "));
        let key = self.key("criterion");
        let c = check::required(
            self.src,
            self.span.clone(),
            &key,
            &self.raw.criterion,
            &what,
        )?;
        Criterion::from_name(c.get_ref()).ok_or_else(|| {
            self.src.error(
                span(c),
                Some(self.key("criterion")),
                format!(
                    "unknown criterion `{}`: expected one of {}{}",
                    c.get_ref(),
                    names.join(", "),
                    suggestion(c.get_ref(), &names)
                ),
            )
        })
    }
}
