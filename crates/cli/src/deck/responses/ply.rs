//! `kind = "ply-stress"` and `kind = "ply-failure"`: a shell body's ply stresses and failure
//! indices (docs/failure-criteria.md, "In a run").

use laminate::{Criterion, PlyPosition};
use nalgebra::Vector3;
use toml::Spanned;

use super::{SpecKind, Table, component};
use crate::deck::DeckError;
use crate::deck::check::{self, positive, span, suggestion};
use crate::deck::mechanism::ShellPlyMap;

const POSITIONS: [&str; 3] = ["bottom", "middle", "top"];
const POSITION_OF: [PlyPosition; 3] = [PlyPosition::Bottom, PlyPosition::Middle, PlyPosition::Top];
/// Stress components, material axes (Voigt order).
const STRESS: [&str; 6] = ["s11", "s22", "s33", "s23", "s13", "s12"];

impl Table<'_> {
    /// The shell body the response names, its plies and its nodes.
    fn shell_plies(&self) -> Result<(String, &ShellPlyMap, &[Vector3<f64>]), DeckError> {
        let (body, geometry) = self.body(true)?;
        let nodes = geometry.map_or(&[][..], |g| &g.nodes[..]);
        let map = geometry.and_then(|g| g.plies.as_ref()).ok_or_else(|| {
            self.src.error(
                self.raw.body.as_ref().and_then(span),
                Some(self.key("body")),
                format!(
                    "`{body}` is a beam body: ply stresses are recovered in shell bodies (a beam \
                     section's stresses under given forces: `flexsens section --load`)"
                ),
            )
        })?;
        Ok((body, map, nodes))
    }

    /// `element` (required for a stress): a shell element of the body.
    fn ply_element(&self, map: &ShellPlyMap, required: bool) -> Result<Option<usize>, DeckError> {
        let what = "element (a shell element, from 0)";
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

    /// `ply` (required for a stress): a ply of one of `laminates` (from 0, bottom first).
    fn ply_index(
        &self,
        map: &ShellPlyMap,
        laminates: &[usize],
        required: bool,
    ) -> Result<Option<usize>, DeckError> {
        let what = "ply (from 0, bottom first)";
        let Some(v) = self.given("ply", &self.raw.ply, required, what)? else {
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
                Some(self.key("ply")),
                format!(
                    "ply {p} does not exist: laminate {} has plies 0 to {}",
                    names.join(", "),
                    most - 1
                ),
            ));
        }
        Ok(Some(p as usize))
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

    /// `kind = "ply-stress"`: a stress component of a ply point of a shell element.
    pub(super) fn ply_stress(&self) -> Result<SpecKind, DeckError> {
        let (body, map, _) = self.shell_plies()?;
        let element = self.ply_element(map, true)?.expect("required");
        let laminate = map.element_laminates[element];
        let ply = self.ply_index(map, &[laminate], true)?.expect("required");
        let position = self.ply_position(true)?.expect("required");
        let component = self.component(&STRESS)?;
        Ok(SpecKind::PlyStress {
            body,
            element,
            ply,
            position,
            component,
        })
    }

    /// `box`: the shell elements whose nodes all lie in it (within 1e-9 of the body's size).
    fn elements_in_box(
        &self,
        map: &ShellPlyMap,
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
        let (body, map, nodes) = self.shell_plies()?;
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
        // every ply selected needs its material's strengths
        for &l in &laminates {
            let (name, plies) = &map.laminates[l];
            for (p, (material, strength)) in plies.iter().enumerate() {
                if strength.is_none() && ply.is_none_or(|q| q == p) {
                    return Err(self.src.error(
                        self.raw.criterion.as_ref().and_then(span),
                        Some(self.key("criterion")),
                        format!(
                            "ply {p} of laminate `{name}` is of material `{material}`, which \
                             states no strengths: give Xt, Xc, Yt, Yc and S12 in \
                             [material.{material}] (Pa)"
                        ),
                    ));
                }
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
