//! Validation of `[body.*]`: flexible bodies meshed with beams or shells, and their modal
//! reduction settings.

use laminate::PlyStack;
use nalgebra::Vector3;
use toml::Spanned;

use super::check::{nonzero_vector, positive, required, span, vector};
use super::laminates::{LaminateModel, suggestion};
use super::raw::{RawBody, RawCoupling, RawDeck, RawMarker, RawPlane, RawSupport};
use super::sections::{self, SectionDef};
use super::{DeckError, Source};

/// How a body is meshed.
#[derive(Debug, Clone)]
pub enum BodyShape {
    Beam {
        section_name: String,
        section: SectionDef,
        start: Vector3<f64>,
        end: Vector3<f64>,
        orientation: Vector3<f64>,
        elements: usize,
    },
    ShellRectangle {
        laminate: String,
        stack: PlyStack<f64>,
        /// The material name of each ply of the stack.
        ply_materials: Vec<String>,
        length: f64,
        width: f64,
        elements: [usize; 2],
        axis: Vector3<f64>,
    },
    ShellMesh {
        laminate: String,
        stack: PlyStack<f64>,
        /// The material name of each ply of the stack.
        ply_materials: Vec<String>,
        mesh_text: String,
        file: String,
        axis: Vector3<f64>,
    },
}

/// A validated flexible body.
#[derive(Debug, Clone)]
pub struct BodyDef {
    /// The body's table in the deck (where errors found while building it point).
    pub span: std::ops::Range<usize>,
    pub shape: BodyShape,
    /// Number of modes retained.
    pub modes: usize,
    /// Number of lowest modes computed (the highest retained mode number).
    pub computed: usize,
    /// Zero-based retained modes when the deck lists mode numbers (`None`: the lowest `modes`).
    pub kept: Option<Vec<usize>>,
    pub reference: Reference,
    /// Normal of the plane the modes are restricted to.
    pub planar: Option<Vector3<f64>>,
    pub damping: Option<fem::Damping>,
    pub lumped: bool,
    /// Static correction nodes (mesh nodes).
    pub correction: Vec<usize>,
    /// The interface basis: `correction` are the nodes the joints and forces act at, and every
    /// coupling takes static correction modes too (nodes the reference condition clamps are
    /// left out).
    pub interface: bool,
    /// Distributing couplings, in the order of their nodes in the modal body.
    pub couplings: Vec<CouplingDef>,
    /// The loads the deck's joints and forces put on the body (its basis check).
    pub interfaces: Vec<InterfaceDef>,
    /// `modes = "auto"`: the fewest of [`AUTO_MODES`] eigenmodes (at least `modes`) whose basis
    /// check meets `basis_tolerance`.
    pub auto_modes: bool,
    /// The largest missed share of the static compliance before a warning.
    pub basis_tolerance: f64,
    /// Initial modal coordinates and rates, one per retained mode (zero-padded).
    pub initial_modal: Vec<f64>,
    pub initial_modal_rates: Vec<f64>,
    /// Geometric stiffening of the modal stiffness by the body's axial forces.
    pub stiffening: bool,
    pub supports: Vec<SupportDef>,
}

impl BodyDef {
    /// The body at the laminates and materials of `model` (a design moved by its variables): a
    /// beam's section at `model` ([`SectionDef::at`]), a shell's laminate from `model`;
    /// everything else as validated.
    pub fn at(&self, model: &LaminateModel) -> Result<BodyDef, section::SectionError> {
        let mut out = self.clone();
        match &mut out.shape {
            BodyShape::Beam { section, .. } => *section = section.at(model)?,
            BodyShape::ShellRectangle {
                laminate,
                stack,
                ply_materials,
                ..
            }
            | BodyShape::ShellMesh {
                laminate,
                stack,
                ply_materials,
                ..
            } => {
                let def = &model.laminates[laminate.as_str()];
                (*stack, *ply_materials) = (def.stack.clone(), def.ply_materials.clone());
            }
        }
        Ok(out)
    }
}

/// The numbers of eigenmodes `modes = "auto"` tries, in order.
pub const AUTO_MODES: [usize; 7] = [4, 8, 16, 32, 64, 128, 256];

/// The basis check's tolerance when the deck does not say (`basis_tolerance`).
pub const DEFAULT_BASIS_TOLERANCE: f64 = 0.02;

/// Reference condition as written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reference {
    CentreOfMass,
    ClampedSection,
    FreeFree,
    PinnedEnds(Option<[usize; 2]>),
    ClampedNode(usize),
    Supports,
}

/// Which nodes a support holds.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeSet {
    Nodes(Vec<usize>),
    /// The nodes with coordinate `axis` (0, 1, 2) equal to `value`.
    Plane {
        axis: usize,
        value: f64,
    },
    Inside([[f64; 3]; 2]),
}

/// A validated coupling: its name, nodes, point (global at the start, `None`: the centroid),
/// kind (rigid or distributing) and place in the deck.
#[derive(Debug, Clone, PartialEq)]
pub struct CouplingDef {
    pub name: String,
    pub nodes: NodeSet,
    pub point: Option<Vector3<f64>>,
    pub rigid: bool,
    pub key: String,
    pub span: std::ops::Range<usize>,
}

/// A validated support: its nodes, the local dof fixed there, and its place in the deck.
#[derive(Debug, Clone, PartialEq)]
pub struct SupportDef {
    pub nodes: NodeSet,
    pub dofs: Vec<usize>,
    pub key: String,
    pub span: std::ops::Range<usize>,
}

/// Validate one body.
pub fn validate_one(
    src: &Source,
    deck: &RawDeck,
    name: &str,
    b: &Spanned<RawBody>,
    model: &LaminateModel,
) -> Result<BodyDef, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let raw = b.get_ref();
    let table = span(b);
    let kind = required(
        src,
        table.clone(),
        &k("kind"),
        &raw.kind,
        "kind (\"beam\" or \"shell\")",
    )?;
    let specific = [
        ("section", raw.section.as_ref().map(|x| x.span())),
        ("start", raw.start.as_ref().map(|x| x.span())),
        ("end", raw.end.as_ref().map(|x| x.span())),
        ("orientation", raw.orientation.as_ref().map(|x| x.span())),
        ("laminate", raw.laminate.as_ref().map(|x| x.span())),
        ("length", raw.length.as_ref().map(|x| x.span())),
        ("width", raw.width.as_ref().map(|x| x.span())),
        ("file", raw.file.as_ref().map(|x| x.span())),
        (
            "material_axis",
            raw.material_axis.as_ref().map(|x| x.span()),
        ),
    ];
    let allowed: &[&str] = match kind.get_ref().as_str() {
        "beam" => &["section", "start", "end", "orientation"],
        "shell" => &["laminate", "length", "width", "file", "material_axis"],
        other => {
            return Err(src.error(
                span(kind),
                Some(k("kind")),
                format!(
                    "unknown body kind `{other}`: expected \"beam\" or \"shell\"{}",
                    suggestion(other, &["beam", "shell"])
                ),
            ));
        }
    };
    for (key, at) in specific {
        if at.is_some() && !allowed.contains(&key) {
            return Err(src.error(
                at,
                Some(k(key)),
                format!("this key does not apply to kind = \"{}\"", kind.get_ref()),
            ));
        }
    }
    let shape = shape(src, deck, name, raw, table.clone(), kind, model)?;
    let (modes, mut computed, kept, auto_modes) = modes(src, name, raw, table.clone())?;
    let reference = reference(src, name, raw)?;
    let beam = matches!(shape, BodyShape::Beam { .. });
    let stiffening = match &raw.stiffening {
        None => beam && STIFFENING_DEFAULT,
        Some(s) if *s.get_ref() && !beam => {
            return Err(src.error(
                span(s),
                Some(k("stiffening")),
                "geometric stiffening is available for beam bodies only (a shell's membrane \
                 stresses are not computed yet): remove the key or set it to false",
            ));
        }
        Some(s) => *s.get_ref(),
    };
    let supports = supports(src, name, raw.supports.as_deref().unwrap_or(&[]))?;
    match (&reference, supports.is_empty(), &raw.reference) {
        (Reference::Supports, true, r) => {
            return Err(src.error(
                r.as_ref().map(span).unwrap_or(table.clone()),
                Some(k("reference")),
                "reference = \"supports\" needs supports = [{ plane | nodes | box, fix }, …]",
            ));
        }
        (Reference::FreeFree, false, r) => {
            return Err(src.error(
                r.as_ref().map(span).unwrap_or(table.clone()),
                Some(k("reference")),
                "a free-free body has no supports: use reference = \"supports\"",
            ));
        }
        _ => {}
    }
    let damping = damping(src, name, raw, auto_modes, &mut computed)?;
    let lumped = match raw.mass.as_ref().map(|m| (m, m.get_ref().as_str())) {
        None | Some((_, "lumped")) => true,
        Some((_, "consistent")) => false,
        Some((m, other)) => {
            return Err(src.error(
                span(m),
                Some(k("mass")),
                format!("unknown mass matrix `{other}`: expected \"lumped\" or \"consistent\""),
            ));
        }
    };
    let planar = raw
        .planar
        .as_ref()
        .map(|p| {
            let n = nonzero_vector(src, &k("planar"), p)?;
            let axis = n.iamax();
            if n.iter().enumerate().any(|(i, x)| i != axis && *x != 0.0) {
                return Err(src.error(
                    span(p),
                    Some(k("planar")),
                    "the normal of the plane of the modes must be a global axis, e.g. [0, 0, 1]",
                ));
            }
            Ok(n.normalize())
        })
        .transpose()?;
    let initial = |key: &str, v: &Option<Spanned<Vec<f64>>>, unit: &str| {
        let mut out = vec![0.0; modes];
        let Some(v) = v else { return Ok(out) };
        if v.get_ref().len() > modes {
            return Err(src.error(
                span(v),
                Some(k(key)),
                format!(
                    "{} values for {modes} retained modes (one per retained mode, in order)",
                    v.get_ref().len()
                ),
            ));
        }
        for (i, &x) in v.get_ref().iter().enumerate() {
            if !x.is_finite() {
                return Err(src.error(
                    span(v),
                    Some(format!("{}[{i}]", k(key))),
                    format!("{x} must be a finite modal {unit}"),
                ));
            }
            out[i] = x;
        }
        Ok(out)
    };
    let couplings = couplings(src, name, raw.couplings.as_ref())?;
    let basis = match raw.basis.as_ref().map(|b| b.get_ref().as_str()) {
        // static correction needs a reference condition that holds the body
        None => reference != Reference::FreeFree,
        Some("interface") if reference == Reference::FreeFree => {
            return Err(src.error(
                span(raw.basis.as_ref().expect("given")),
                Some(k("basis")),
                "basis = \"interface\" needs a reference condition that holds the body (its \
                 static correction modes are the static responses to unit loads); a free-free \
                 body takes basis = \"modes\"",
            ));
        }
        Some("interface") => true,
        Some("modes") => false,
        Some(other) => {
            return Err(src.error(
                span(raw.basis.as_ref().expect("given")),
                Some(k("basis")),
                format!("unknown basis `{other}`: expected \"interface\" or \"modes\""),
            ));
        }
    };
    let interfaces = interface_loads(deck, name);
    let (correction, interface) = match &raw.correction {
        None if basis => (interface_nodes(&interfaces), true),
        None => (Vec::new(), false),
        Some(c) => {
            let list = c.get_ref();
            if list.is_empty() || list.iter().any(|&n| n < 0) {
                return Err(src.error(
                    span(c),
                    Some(k("correction")),
                    "a list of node indices (from 0), e.g. the nodes the body's joints act at",
                ));
            }
            (list.iter().map(|&n| n as usize).collect(), false)
        }
    };
    if auto_modes {
        for (key, v) in [
            ("initial_modal", &raw.initial_modal),
            ("initial_modal_rates", &raw.initial_modal_rates),
        ] {
            if let Some(v) = v {
                return Err(src.error(
                    span(v),
                    Some(k(key)),
                    "an initial modal state needs a stated number of modes, not modes = \"auto\"",
                ));
            }
        }
        if reference == Reference::FreeFree {
            return Err(src.error(
                raw.modes.as_ref().and_then(span),
                Some(k("modes")),
                "modes = \"auto\" chooses by the basis check, which needs a reference condition \
                 that holds the body (not free-free)",
            ));
        }
    }
    let basis_tolerance = match &raw.basis_tolerance {
        None => DEFAULT_BASIS_TOLERANCE,
        Some(t) => {
            let x = *t.get_ref();
            if !(x > 0.0 && x < 1.0) {
                return Err(src.error(
                    span(t),
                    Some(k("basis_tolerance")),
                    format!("{x} must be a share of the compliance between 0 and 1 (e.g. 0.02)"),
                ));
            }
            x
        }
    };
    let modes = if auto_modes { computed } else { modes };
    let initial_modal = initial("initial_modal", &raw.initial_modal, "coordinate (√kg·m)")?;
    let initial_modal_rates = initial(
        "initial_modal_rates",
        &raw.initial_modal_rates,
        "rate (√kg·m/s)",
    )?;
    Ok(BodyDef {
        span: b.span(),
        shape,
        modes,
        computed,
        kept,
        reference,
        planar,
        damping,
        lumped,
        correction,
        interface,
        couplings,
        interfaces,
        auto_modes,
        basis_tolerance,
        initial_modal,
        initial_modal_rates,
        stiffening,
        supports,
    })
}

/// A node set written as `nodes = [...]`, `plane = { x = … }` or `box = [[…], […]]` (one of
/// them) in the table `key` at `whole`.
fn node_set(
    src: &Source,
    key: &str,
    whole: std::ops::Range<usize>,
    nodes: &Option<Spanned<Vec<i64>>>,
    plane: &Option<Spanned<RawPlane>>,
    inside: &Option<Spanned<[[f64; 3]; 2]>>,
) -> Result<NodeSet, DeckError> {
    let sk = |k: &str| format!("{key}.{k}");
    Ok(match (nodes, plane, inside) {
        (Some(n), None, None) => {
            let list = n.get_ref();
            if list.is_empty() || list.iter().any(|&x| x < 0) {
                return Err(src.error(
                    span(n),
                    Some(sk("nodes")),
                    "a list of node indices (from 0)",
                ));
            }
            NodeSet::Nodes(list.iter().map(|&x| x as usize).collect())
        }
        (None, Some(p), None) => {
            let pr = p.get_ref();
            let given: Vec<(usize, f64)> = [pr.x, pr.y, pr.z]
                .iter()
                .enumerate()
                .filter_map(|(a, v)| v.map(|v| (a, v)))
                .collect();
            match given.as_slice() {
                [(axis, value)] if value.is_finite() => NodeSet::Plane {
                    axis: *axis,
                    value: *value,
                },
                _ => {
                    return Err(src.error(
                        span(p),
                        Some(sk("plane")),
                        "one finite coordinate of a plane normal to a global axis, e.g. \
                         { x = 0.0 }",
                    ));
                }
            }
        }
        (None, None, Some(b)) => {
            let [lo, hi] = *b.get_ref();
            if (0..3).any(|a| !(lo[a].is_finite() && hi[a].is_finite() && lo[a] <= hi[a])) {
                return Err(src.error(
                    span(b),
                    Some(sk("box")),
                    "[[x0, y0, z0], [x1, y1, z1]] with finite corners, x0 ≤ x1, y0 ≤ y1, \
                     z0 ≤ z1",
                ));
            }
            NodeSet::Inside([lo, hi])
        }
        _ => {
            return Err(src.error(
                Some(whole),
                Some(key.to_string()),
                "give the nodes in one way: nodes = [...], plane = { x = … } or box = [[…], \
                 […]]",
            ));
        }
    })
}

/// A body's mesh: a beam along its section, or a shell of a laminate (a rectangle, or a mesh
/// file).
fn shape(
    src: &Source,
    deck: &RawDeck,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
    kind: &Spanned<String>,
    model: &LaminateModel,
) -> Result<BodyShape, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let elements_value = raw.elements.as_ref();
    Ok(match kind.get_ref().as_str() {
        "beam" => {
            let sname = required(
                src,
                table.clone(),
                &k("section"),
                &raw.section,
                "section (a [section.*] name)",
            )?;
            let s = deck.section.get(sname.get_ref()).ok_or_else(|| {
                let known: Vec<&str> = deck.section.keys().map(String::as_str).collect();
                src.error(
                    span(sname),
                    Some(k("section")),
                    format!(
                        "undefined section `{}`{}",
                        sname.get_ref(),
                        suggestion(sname.get_ref(), &known)
                    ),
                )
            })?;
            let section = sections::validate_one(src, sname.get_ref(), s, model)?;
            let start = vector(
                src,
                &k("start"),
                required(
                    src,
                    table.clone(),
                    &k("start"),
                    &raw.start,
                    "start [x, y, z] (m)",
                )?,
            )?;
            let end = vector(
                src,
                &k("end"),
                required(src, table.clone(), &k("end"), &raw.end, "end [x, y, z] (m)")?,
            )?;
            let axis = end - start;
            // below a nanometre (or a billionth of the coordinates) a length is round-off, and
            // the element matrices would not be finite
            let negligible = 1e-9 * start.norm().max(end.norm()).max(1.0);
            if axis.norm() <= negligible {
                return Err(src.error(
                    raw.end.as_ref().map(|e| e.span()),
                    Some(k("end")),
                    format!(
                        "the beam's length |end − start| = {:e} m is zero or negligible (at \
                         least {negligible:e} m)",
                        axis.norm()
                    ),
                ));
            }
            let orientation = match &raw.orientation {
                Some(o) => nonzero_vector(src, &k("orientation"), o)?,
                None if axis.normalize().cross(&Vector3::y()).norm() > 1e-6 => Vector3::y(),
                None => Vector3::z(),
            };
            if orientation.normalize().cross(&axis.normalize()).norm() < 1e-6 {
                return Err(src.error(
                    raw.orientation.as_ref().map(|o| o.span()),
                    Some(k("orientation")),
                    "must not be parallel to the beam axis",
                ));
            }
            let elements = match elements_value {
                None => 10,
                Some(e) => element_count(e.get_ref(), 1).ok_or_else(|| {
                    elements_error(
                        src,
                        name,
                        raw,
                        &format!(
                            "a whole number of beam elements, from 1 to the limit of {} \
                         (--max-elements raises it)",
                            crate::limits::get().elements
                        ),
                    )
                })?,
            };
            BodyShape::Beam {
                section_name: sname.get_ref().clone(),
                section,
                start,
                end,
                orientation,
                elements,
            }
        }
        _ => shell_shape(src, name, raw, table, model)?,
    })
}

/// A shell body's mesh: a rectangle or a mesh file, of a laminate.
fn shell_shape(
    src: &Source,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
    model: &LaminateModel,
) -> Result<BodyShape, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let elements_value = raw.elements.as_ref();
    let lname = required(
        src,
        table.clone(),
        &k("laminate"),
        &raw.laminate,
        "laminate (a [laminate.*] name)",
    )?;
    let def = shell_laminate(src, name, lname, model)?;
    let (stack, ply_materials) = (def.stack.clone(), def.ply_materials.clone());
    let axis = raw
        .material_axis
        .as_ref()
        .map(|a| nonzero_vector(src, &k("material_axis"), a))
        .transpose()?
        .unwrap_or(Vector3::x());
    Ok(match &raw.file {
        Some(f) => {
            for (key, v) in [("length", &raw.length), ("width", &raw.width)] {
                if let Some(v) = v {
                    return Err(src.error(
                        span(v),
                        Some(k(key)),
                        "a shell read from a file takes its size from the mesh",
                    ));
                }
            }
            if let Some(e) = elements_value {
                return Err(src.error(
                    span(e),
                    Some(k("elements")),
                    "a shell read from a file takes its elements from the mesh",
                ));
            }
            let path = src
                .file
                .parent()
                .unwrap_or(std::path::Path::new("."))
                .join(f.get_ref());
            let mesh_text = crate::limits::read_text(&path).map_err(|e| {
                src.error(
                    span(f),
                    Some(k("file")),
                    format!("cannot read the mesh {}: {e}", path.display()),
                )
            })?;
            BodyShape::ShellMesh {
                laminate: lname.get_ref().clone(),
                stack,
                ply_materials: ply_materials.clone(),
                mesh_text,
                file: path.display().to_string(),
                axis,
            }
        }
        None => {
            let length = positive(
                src,
                &k("length"),
                required(
                    src,
                    table.clone(),
                    &k("length"),
                    &raw.length,
                    "length along x (m), or file",
                )?,
                "m",
            )?;
            let width = positive(
                src,
                &k("width"),
                required(
                    src,
                    table.clone(),
                    &k("width"),
                    &raw.width,
                    "width along y (m)",
                )?,
                "m",
            )?;
            let elements = match elements_value {
                None => {
                    let nx = 16usize;
                    [nx, ((nx as f64 * width / length).round() as usize).max(2)]
                }
                Some(e) => match e.get_ref().as_array().map(|a| a.as_slice()) {
                    Some([a, b]) => [
                        element_count(a, 1).ok_or_else(|| {
                            elements_error(
                                src,
                                name,
                                raw,
                                &format!(
                                    "[along x, along y], whole numbers from 1 to the limit \
                                 of {} (--max-elements raises it)",
                                    crate::limits::get().elements
                                ),
                            )
                        })?,
                        element_count(b, 1).ok_or_else(|| {
                            elements_error(
                                src,
                                name,
                                raw,
                                &format!(
                                    "[along x, along y], whole numbers from 1 to the limit \
                                 of {} (--max-elements raises it)",
                                    crate::limits::get().elements
                                ),
                            )
                        })?,
                    ],
                    _ => {
                        return Err(elements_error(
                            src,
                            name,
                            raw,
                            "[along x, along y] for a shell rectangle",
                        ));
                    }
                },
            };
            super::check::mesh_size(
                src,
                &k("elements"),
                elements_value.map(|e| e.span()),
                elements[0].saturating_mul(elements[1]),
            )?;
            BodyShape::ShellRectangle {
                laminate: lname.get_ref().clone(),
                stack,
                ply_materials: ply_materials.clone(),
                length,
                width,
                elements,
                axis,
            }
        }
    })
}

/// The laminate a shell body names.
fn shell_laminate<'m>(
    src: &Source,
    name: &str,
    lname: &Spanned<String>,
    model: &'m LaminateModel,
) -> Result<&'m super::laminates::LaminateDef, DeckError> {
    model.laminates.get(lname.get_ref()).ok_or_else(|| {
        let known: Vec<&str> = model.laminates.keys().map(String::as_str).collect();
        src.error(
            span(lname),
            Some(format!("body.{name}.laminate")),
            format!(
                "undefined laminate `{}`{}",
                lname.get_ref(),
                suggestion(lname.get_ref(), &known)
            ),
        )
    })
}

/// A count of elements or modes: a whole number from `min` up to the element limit.
fn element_count(v: &toml::Value, min: i64) -> Option<usize> {
    v.as_integer()
        .filter(|&n| n >= min && n <= crate::limits::get().elements as i64)
        .map(|n| n as usize)
}

/// The error of a malformed `elements` value of body `name`.
fn elements_error(src: &Source, name: &str, raw: &RawBody, what: &str) -> DeckError {
    src.error(
        raw.elements.as_ref().map(|e| e.span()),
        Some(format!("body.{name}.elements")),
        format!("expected {what}"),
    )
}

/// A body's retained modes: their number, the number of lowest modes computed, the retained
/// ones when the deck lists mode numbers (zero-based), and whether `modes = "auto"`.
#[allow(clippy::type_complexity)]
fn modes(
    src: &Source,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
) -> Result<(usize, usize, Option<Vec<usize>>, bool), DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let modes_value = required(
        src,
        table.clone(),
        &k("modes"),
        &raw.modes,
        "modes (number of elastic modes retained, or a list of mode numbers)",
    )?;
    let modes_error = |m: String| src.error(span(modes_value), Some(k("modes")), m);
    let auto_modes = modes_value.get_ref().as_str() == Some("auto");
    let (modes, computed, kept) = match modes_value.get_ref() {
        v @ toml::Value::Integer(n) => match element_count(v, 1) {
            Some(n) => (n, n, None),
            None => {
                return Err(modes_error(format!(
                    "{n} must be a whole number of at least 1"
                )));
            }
        },
        toml::Value::String(w) if w == "auto" => (AUTO_MODES[0], AUTO_MODES[0], None),
        toml::Value::Array(list) => {
            let numbers: Option<Vec<usize>> = list.iter().map(|v| element_count(v, 1)).collect();
            match numbers {
                Some(n) if !n.is_empty() && n.windows(2).all(|w| w[1] > w[0]) => {
                    let last = *n.last().expect("non-empty");
                    (n.len(), last, Some(n.iter().map(|i| i - 1).collect()))
                }
                _ => {
                    return Err(modes_error(
                        "a list of mode numbers needs whole numbers from 1, strictly ascending, \
                         e.g. [1, 2, 5]"
                            .into(),
                    ));
                }
            }
        }
        _ => {
            return Err(modes_error(
                "expected a number of modes (e.g. 4), a list of mode numbers (e.g. [1, 2, 5]) \
                 or \"auto\""
                    .into(),
            ));
        }
    };
    Ok((modes, computed, kept, auto_modes))
}

/// A body's reference condition (and `pinned` or `clamped`, given only with theirs).
fn reference(src: &Source, name: &str, raw: &RawBody) -> Result<Reference, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let reference = match raw.reference.as_ref().map(|r| (r, r.get_ref().as_str())) {
        None | Some((_, "centre-of-mass")) => Reference::CentreOfMass,
        Some((_, "clamped-section")) => Reference::ClampedSection,
        Some((_, "free-free")) => Reference::FreeFree,
        Some((_, "pinned-ends")) => Reference::PinnedEnds(match &raw.pinned {
            None => None,
            Some(p) => {
                let [a, b] = *p.get_ref();
                if a < 0 || b < 0 || a == b {
                    return Err(src.error(
                        span(p),
                        Some(k("pinned")),
                        "two different node indices (from 0) are needed",
                    ));
                }
                Some([a as usize, b as usize])
            }
        }),
        Some((_, "clamped-node")) => Reference::ClampedNode(match &raw.clamped {
            None => 0,
            Some(c) if *c.get_ref() >= 0 => *c.get_ref() as usize,
            Some(c) => {
                return Err(src.error(
                    span(c),
                    Some(k("clamped")),
                    "a node index (from 0) is needed",
                ));
            }
        }),
        Some((_, "supports")) => Reference::Supports,
        Some((r, other)) => {
            let choices = [
                "centre-of-mass",
                "clamped-section",
                "free-free",
                "pinned-ends",
                "clamped-node",
                "supports",
            ];
            return Err(src.error(
                span(r),
                Some(k("reference")),
                format!(
                    "unknown reference condition `{other}`: expected one of {}{}",
                    choices.join(", "),
                    suggestion(other, &choices)
                ),
            ));
        }
    };
    if let (Some(p), false) = (&raw.pinned, matches!(reference, Reference::PinnedEnds(_))) {
        return Err(src.error(
            span(p),
            Some(k("pinned")),
            "pinned is only used with reference = \"pinned-ends\"",
        ));
    }
    if let (Some(c), false) = (&raw.clamped, matches!(reference, Reference::ClampedNode(_))) {
        return Err(src.error(
            span(c),
            Some(k("clamped")),
            "clamped is only used with reference = \"clamped-node\"",
        ));
    }
    Ok(reference)
}

/// A body's damping: Rayleigh coefficients, or ratios at two modes (which `computed`, the
/// number of modes computed, then includes with `modes = "auto"`).
fn damping(
    src: &Source,
    name: &str,
    raw: &RawBody,
    auto_modes: bool,
    computed: &mut usize,
) -> Result<Option<fem::Damping>, DeckError> {
    let dk = |key: &str| format!("body.{name}.damping.{key}");
    Ok(match &raw.damping {
        None => None,
        Some(d) if d.get_ref().alpha.is_some() || d.get_ref().beta.is_some() => {
            let rd = d.get_ref();
            if let Some(m) = &rd.modes {
                return Err(src.error(
                    span(m),
                    Some(dk("modes")),
                    "give either modes and ratios, or alpha and beta, not both",
                ));
            }
            if let Some(r) = &rd.ratios {
                return Err(src.error(
                    span(r),
                    Some(dk("ratios")),
                    "give either modes and ratios, or alpha and beta, not both",
                ));
            }
            let coefficient = |key: &str, v: &Option<Spanned<f64>>, unit: &str| {
                let Some(v) = v else { return Ok(0.0) };
                let x = *v.get_ref();
                if x.is_finite() && x >= 0.0 {
                    Ok(x)
                } else {
                    Err(src.error(
                        span(v),
                        Some(dk(key)),
                        format!("{x} must be a finite coefficient ≥ 0 ({unit})"),
                    ))
                }
            };
            Some(fem::Damping::Coefficients {
                alpha: coefficient("alpha", &rd.alpha, "1/s")?,
                beta: coefficient("beta", &rd.beta, "s")?,
            })
        }
        Some(d) => {
            let m = required(
                src,
                span(d),
                &dk("modes"),
                &d.get_ref().modes,
                "modes = [i, j] (counted from 1)",
            )?;
            let r = required(
                src,
                span(d),
                &dk("ratios"),
                &d.get_ref().ratios,
                "ratios = [ζi, ζj]",
            )?;
            let [i, j] = *m.get_ref();
            if auto_modes && i >= 1 && j >= 1 {
                // the automatic choice computes at least the modes the fit refers to
                *computed = (*computed).max(i.max(j) as usize);
            }
            if i < 1 || j < 1 || i == j || i as usize > *computed || j as usize > *computed {
                return Err(src.error(
                    span(m),
                    Some(dk("modes")),
                    format!("two different mode numbers, between 1 and {computed}, are needed"),
                ));
            }
            let ratios = *r.get_ref();
            for (n, z) in ratios.iter().enumerate() {
                if !(z.is_finite() && *z >= 0.0) {
                    return Err(src.error(
                        span(r),
                        Some(format!("{}[{n}]", dk("ratios"))),
                        format!("{z} must be a finite damping ratio ≥ 0"),
                    ));
                }
            }
            Some(fem::Damping::Ratios(fem::RayleighDamping {
                modes: [i as usize - 1, j as usize - 1],
                ratios,
            }))
        }
    })
}

/// Validate `[body.NAME.couplings]`.
fn couplings(
    src: &Source,
    name: &str,
    raw: Option<&std::collections::BTreeMap<String, Spanned<RawCoupling>>>,
) -> Result<Vec<CouplingDef>, DeckError> {
    let mut out = Vec::new();
    for (cname, c) in raw.into_iter().flatten() {
        let key = format!("body.{name}.couplings.{cname}");
        let r = c.get_ref();
        let nodes = node_set(src, &key, c.span(), &r.nodes, &r.plane, &r.inside)?;
        let point = r
            .point
            .as_ref()
            .map(|p| vector(src, &format!("{key}.point"), p))
            .transpose()?;
        let rigid = match &r.kind {
            None => false,
            Some(kind) => match kind.get_ref().as_str() {
                "distributing" => false,
                "rigid" => true,
                other => {
                    return Err(src.error(
                        Some(kind.span()),
                        Some(format!("{key}.kind")),
                        format!(
                            "unknown coupling kind `{other}`: expected \"distributing\" (RBE3, \
                             the default) or \"rigid\" (RBE2)"
                        ),
                    ));
                }
            },
        };
        out.push(CouplingDef {
            name: cname.clone(),
            nodes,
            point,
            rigid,
            key,
            span: c.span(),
        });
    }
    Ok(out)
}

/// The nodes among `interfaces` (joints and forces with `node = k`), each once.
fn interface_nodes(interfaces: &[InterfaceDef]) -> Vec<usize> {
    let mut nodes: Vec<usize> = interfaces
        .iter()
        .filter_map(|i| match i.site {
            InterfaceSite::Node(k) => Some(k),
            InterfaceSite::Coupling(_) => None,
        })
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    nodes
}

/// Where a joint or force acts on a flexible body.
#[derive(Debug, Clone, PartialEq)]
pub enum InterfaceSite {
    Node(usize),
    Coupling(String),
}

/// The loads a joint or force puts on a flexible body: forces and moments along these
/// directions (global axes at the start, which are the mesh's).
#[derive(Debug, Clone, PartialEq)]
pub struct InterfaceDef {
    pub site: InterfaceSite,
    pub forces: Vec<Vector3<f64>>,
    pub moments: Vec<Vector3<f64>>,
}

/// The loads the deck's joints and forces put on body `name` (markers at a node or coupling
/// of it): a joint's reactions in the directions it constrains (a revolute joint takes no
/// moment about its axis, a spherical one no moment, a translational one no force along its
/// axis, a driver only its own direction), a point force or torque and a spring–damper in
/// every direction. Markers the mechanism validation will reject are left out.
pub fn interface_loads(deck: &RawDeck, name: &str) -> Vec<InterfaceDef> {
    let xyz = vec![Vector3::x(), Vector3::y(), Vector3::z()];
    // the two directions normal to a joint axis: the e1, e2 of its marker
    let normal_to = |a: Vector3<f64>| -> Vec<Vector3<f64>> {
        let a = a.try_normalize(0.0).unwrap_or(Vector3::z());
        let axes = mbs::Marker::ground(Vector3::zeros()).with_axis(a).axes;
        vec![axes.column(0).into_owned(), axes.column(1).into_owned()]
    };
    let site = |m: &Spanned<RawMarker>| -> Option<(InterfaceSite, Vector3<f64>)> {
        let m = m.get_ref();
        if m.body.as_ref()?.get_ref() != name {
            return None;
        }
        let axis = m
            .axis
            .as_ref()
            .map_or(Vector3::z(), |a| Vector3::from(*a.get_ref()));
        match (&m.node, &m.coupling) {
            (Some(n), None) if *n.get_ref() >= 0 => {
                Some((InterfaceSite::Node(*n.get_ref() as usize), axis))
            }
            (None, Some(c)) => Some((InterfaceSite::Coupling(c.get_ref().clone()), axis)),
            _ => None,
        }
    };
    let mut out = Vec::new();
    for j in deck.joint.values() {
        let j = j.get_ref();
        let kind = j.kind.as_ref().map_or("", |k| k.get_ref().as_str());
        for m in [&j.a, &j.b].into_iter().flatten() {
            let Some((site, axis)) = site(m) else {
                continue;
            };
            let (forces, moments) = match kind {
                "spherical" => (xyz.clone(), vec![]),
                "revolute" | "universal" => (xyz.clone(), normal_to(axis)),
                "cylindrical" => (normal_to(axis), normal_to(axis)),
                "translational" => (normal_to(axis), xyz.clone()),
                "angle-driver" => (vec![], vec![axis]),
                "distance-driver" => (xyz.clone(), vec![]),
                _ => (xyz.clone(), xyz.clone()),
            };
            out.push(InterfaceDef {
                site,
                forces,
                moments,
            });
        }
    }
    for f in deck.force.values() {
        let f = f.get_ref();
        let kind = f.kind.as_ref().map_or("", |k| k.get_ref().as_str());
        for m in [&f.at, &f.a, &f.b].into_iter().flatten() {
            let Some((site, _)) = site(m) else {
                continue;
            };
            let (forces, moments) = match kind {
                "point-torque" => (vec![], xyz.clone()),
                _ => (xyz.clone(), vec![]),
            };
            out.push(InterfaceDef {
                site,
                forces,
                moments,
            });
        }
    }
    out
}

/// The dof names of a support's `fix` list, in the order of the nodal dof.
const DOF_NAMES: [&str; 6] = ["ux", "uy", "uz", "rx", "ry", "rz"];

/// Validate `supports = [ … ]` of body `name`.
fn supports(
    src: &Source,
    name: &str,
    raw: &[Spanned<RawSupport>],
) -> Result<Vec<SupportDef>, DeckError> {
    let mut out = Vec::new();
    for (i, s) in raw.iter().enumerate() {
        let key = format!("body.{name}.supports[{i}]");
        let sk = |k: &str| format!("{key}.{k}");
        let r = s.get_ref();
        let nodes = node_set(src, &key, s.span(), &r.nodes, &r.plane, &r.inside)?;
        let fix = required(
            src,
            span(s),
            &sk("fix"),
            &r.fix,
            "fix (\"clamped\", \"pinned\" or a list of dof)",
        )?;
        let bad_fix = || {
            src.error(
                span(fix),
                Some(sk("fix")),
                format!(
                    "expected \"clamped\", \"pinned\" or a list of dof names from {}",
                    DOF_NAMES.join(", ")
                ),
            )
        };
        let dofs: Vec<usize> = match fix.get_ref() {
            toml::Value::String(w) if w == "clamped" => (0..6).collect(),
            toml::Value::String(w) if w == "pinned" => (0..3).collect(),
            toml::Value::Array(list) if !list.is_empty() => {
                let mut d = Vec::new();
                for v in list {
                    let n = v
                        .as_str()
                        .and_then(|w| DOF_NAMES.iter().position(|x| *x == w));
                    match n {
                        Some(n) if !d.contains(&n) => d.push(n),
                        _ => return Err(bad_fix()),
                    }
                }
                d
            }
            _ => return Err(bad_fix()),
        };
        out.push(SupportDef {
            nodes,
            dofs,
            key,
            span: s.span(),
        });
    }
    Ok(out)
}

/// Whether beam bodies are stiffened when the deck does not say (docs/geometric-stiffening.md).
pub const STIFFENING_DEFAULT: bool = true;
