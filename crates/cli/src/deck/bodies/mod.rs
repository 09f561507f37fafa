//! Validation of `[body.*]`: flexible bodies meshed with beams or shells, and their modal
//! reduction settings.

use laminate::PlyStack;
use nalgebra::Vector3;
use toml::Spanned;

use super::check::suggestion;
use super::check::{nonzero_vector, positive, required, span, vector};
use super::laminates::LaminateModel;
use super::raw::{RawBody, RawCoupling, RawDeck, RawMarker, RawPlane, RawSupport};
use super::sections::{self, SectionDef};
use super::{DeckError, Source};

mod beam;
mod reduction;
mod regions;
mod sets;
mod shape;

pub use reduction::CORRECTION_DAMPING_DEFAULT;
use reduction::{correction_damping, damping, modes, reference};
pub use sets::{InterfaceDef, InterfaceSite, interface_loads};
use sets::{couplings, interface_nodes, supports};
use shape::{element_count, shell_shape};

/// How a body is meshed.
#[derive(Debug, Clone)]
pub enum BodyShape {
    /// A straight beam from `start` to `end` of `segments` in order (one over the whole length
    /// unless the deck gives `segments`), each of a section of `sections` (its `property`; the
    /// sections by name, each once, in the order the segments first use them).
    Beam {
        sections: Vec<(String, SectionDef)>,
        segments: Vec<fem::BeamSegment>,
        start: Vector3<f64>,
        end: Vector3<f64>,
        orientation: Vector3<f64>,
    },
    ShellRectangle {
        laminates: ShellLaminates,
        length: f64,
        width: f64,
        elements: [usize; 2],
        axis: Vector3<f64>,
    },
    ShellMesh {
        laminates: ShellLaminates,
        mesh_text: String,
        file: String,
        axis: Vector3<f64>,
    },
}

/// A laminate of a shell body: its name, its stack and the material name of each ply.
#[derive(Debug, Clone)]
pub struct ShellLaminate {
    pub name: String,
    pub stack: PlyStack<f64>,
    pub ply_materials: Vec<String>,
}

impl ShellLaminate {
    /// The laminate `name` as the deck defines it.
    pub fn of(name: &str, def: &crate::deck::laminates::LaminateDef) -> Self {
        ShellLaminate {
            name: name.to_string(),
            stack: def.stack.clone(),
            ply_materials: def.ply_materials.clone(),
        }
    }
}

/// The laminates of a shell body: its own (`laminate`, the first), then those of its
/// `regions` (each once, in the order the regions first name them), and the regions in order
/// (a later region wins where two overlap).
#[derive(Debug, Clone)]
pub struct ShellLaminates {
    pub laminates: Vec<ShellLaminate>,
    pub regions: Vec<RegionDef>,
}

/// A region of a shell body: the elements it holds, laminated with `laminate` (an index of
/// [`ShellLaminates::laminates`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RegionDef {
    pub laminate: usize,
    pub elements: ElementSet,
    pub key: String,
    pub span: std::ops::Range<usize>,
}

/// The elements of a region: listed, or those whose nodes all lie in a node set (a plane or a
/// box).
#[derive(Debug, Clone, PartialEq)]
pub enum ElementSet {
    Elements(Vec<usize>),
    Within(NodeSet),
}

impl BodyShape {
    /// The number of elements of a beam (`None` for a shell).
    pub fn beam_elements(&self) -> Option<usize> {
        match self {
            BodyShape::Beam { segments, .. } => Some(segments.iter().map(|s| s.elements).sum()),
            _ => None,
        }
    }
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
    /// Damping of the correction modes (`correction_damping`).
    pub correction_damping: fem::CorrectionDamping,
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
    /// `atol`: the integrator's absolute tolerance for the body's coordinates, as
    /// `analysis.atol`.
    pub atol: Option<f64>,
    /// Initial modal coordinates and rates, one per retained mode (zero-padded).
    pub initial_modal: Vec<f64>,
    pub initial_modal_rates: Vec<f64>,
    /// Geometric stiffening of the modal stiffness by the body's axial forces.
    pub stiffening: bool,
    pub supports: Vec<SupportDef>,
    /// The strengths of each ply of each of a shell body's laminates (`None` where its
    /// material states none), when a response reads the body's ply stresses: the body is then
    /// built with them (`None`: no response does).
    pub ply_strengths: Option<Vec<Vec<Option<laminate::PlyStrength>>>>,
}

impl BodyDef {
    /// The body at the laminates and materials of `model` (a design moved by its variables): a
    /// beam's section at `model` ([`SectionDef::at`]), a shell's laminate from `model`;
    /// everything else as validated.
    pub fn at(&self, model: &LaminateModel) -> Result<BodyDef, section::SectionError> {
        let mut out = self.clone();
        match &mut out.shape {
            BodyShape::Beam { sections, .. } => {
                for (_, section) in sections {
                    *section = section.at(model)?;
                }
            }
            BodyShape::ShellRectangle { laminates, .. }
            | BodyShape::ShellMesh { laminates, .. } => {
                for l in &mut laminates.laminates {
                    let def = &model.laminates[l.name.as_str()];
                    (l.stack, l.ply_materials) = (def.stack.clone(), def.ply_materials.clone());
                }
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
    /// Supports that hold some rigid motions; the others stay free, as in free-free.
    PartlyFree,
}

impl Reference {
    /// Whether the reference condition holds every rigid motion (static shapes `K⁻¹ f` exist).
    pub fn holds_body(&self) -> bool {
        !matches!(self, Reference::FreeFree | Reference::PartlyFree)
    }
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
    let kind = kind(src, name, raw, table.clone())?;
    let shape = shape(src, deck, name, raw, table.clone(), kind, model)?;
    let (modes, mut computed, kept, auto_modes) = modes(src, name, raw, table.clone())?;
    let reference = reference(src, name, raw)?;
    let stiffening = stiffening(raw);
    let supports = supports(src, name, raw.supports.as_deref().unwrap_or(&[]))?;
    check_supports(src, name, raw, table.clone(), &reference, &supports)?;
    let damping = damping(src, name, raw, auto_modes, &mut computed)?;
    let correction_damping = correction_damping(src, name, raw)?;
    let lumped = lumped(src, name, raw)?;
    let planar = planar(src, name, raw)?;
    let couplings = couplings(src, name, raw.couplings.as_ref())?;
    let basis = basis(src, name, raw, &reference)?;
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
        check_auto_modes(src, name, raw)?;
    }
    let basis_tolerance = basis_tolerance(src, name, raw)?;
    let atol = raw
        .atol
        .as_ref()
        .map(|a| positive(src, &format!("body.{name}.atol"), a, "m, or state units"))
        .transpose()?;
    let initial_modal = initial_modal_state(
        src,
        name,
        "initial_modal",
        &raw.initial_modal,
        modes,
        "coordinate (√kg·m)",
    )?;
    let initial_modal_rates = initial_modal_state(
        src,
        name,
        "initial_modal_rates",
        &raw.initial_modal_rates,
        modes,
        "rate (√kg·m/s)",
    )?;
    let modes = if auto_modes { computed } else { modes };
    Ok(BodyDef {
        span: b.span(),
        shape,
        modes,
        computed,
        kept,
        reference,
        planar,
        damping,
        correction_damping,
        lumped,
        correction,
        interface,
        couplings,
        interfaces,
        auto_modes,
        basis_tolerance,
        atol,
        initial_modal,
        initial_modal_rates,
        stiffening,
        supports,
        ply_strengths: None,
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
    Ok(match kind.get_ref().as_str() {
        "beam" => beam::beam_shape(src, deck, name, raw, table, model)?,
        _ => shell_shape(src, name, raw, table, model)?,
    })
}

/// The body's `kind` (`"beam"` or `"shell"`), with the keys of the other kind refused.
fn kind<'a>(
    src: &Source,
    name: &str,
    raw: &'a RawBody,
    table: Option<std::ops::Range<usize>>,
) -> Result<&'a Spanned<String>, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    let kind = required(
        src,
        table,
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
        ("segments", raw.segments.as_ref().map(|x| x.span())),
        ("regions", raw.regions.as_ref().map(|x| x.span())),
    ];
    let allowed: &[&str] = match kind.get_ref().as_str() {
        "beam" => &["section", "start", "end", "orientation", "segments"],
        "shell" => &[
            "laminate",
            "length",
            "width",
            "file",
            "material_axis",
            "regions",
        ],
        other => {
            return Err(src.error(
                span(kind),
                Some(k("kind")),
                super::keys::BODY_KIND.unknown("body kind", other),
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
    Ok(kind)
}

/// Geometric stiffening (the second-order field): on by default ([`STIFFENING_DEFAULT`]).
fn stiffening(raw: &RawBody) -> bool {
    raw.stiffening
        .as_ref()
        .map_or(STIFFENING_DEFAULT, |s| *s.get_ref())
}

/// `reference = "supports"` needs supports; a free-free body has none.
fn check_supports(
    src: &Source,
    name: &str,
    raw: &RawBody,
    table: Option<std::ops::Range<usize>>,
    reference: &Reference,
    supports: &[SupportDef],
) -> Result<(), DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    match (reference, supports.is_empty(), &raw.reference) {
        (Reference::Supports | Reference::PartlyFree, true, r) => {
            let word = if *reference == Reference::Supports {
                "supports"
            } else {
                "partly-free"
            };
            return Err(src.error(
                r.as_ref().map(span).unwrap_or(table.clone()),
                Some(k("reference")),
                format!(
                    "reference = \"{word}\" needs supports = [{{ plane | nodes | box, fix }}, …] \
                     (a body nothing holds is reference = \"free-free\")"
                ),
            ));
        }
        (Reference::FreeFree, false, r) => {
            return Err(src.error(
                r.as_ref().map(span).unwrap_or(table.clone()),
                Some(k("reference")),
                "a free-free body has no supports: use reference = \"supports\" (the supports \
                 hold every rigid motion) or \"partly-free\" (the motions they leave free stay \
                 free)",
            ));
        }
        _ => {}
    }
    Ok(())
}

/// The mass matrix: lumped (the default) or consistent.
fn lumped(src: &Source, name: &str, raw: &RawBody) -> Result<bool, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    Ok(match raw.mass.as_ref().map(|m| (m, m.get_ref().as_str())) {
        None | Some((_, "lumped")) => true,
        Some((_, "consistent")) => false,
        Some((m, other)) => {
            return Err(src.error(
                span(m),
                Some(k("mass")),
                super::keys::BODY_MASS.unknown("mass matrix", other),
            ));
        }
    })
}

/// The normal of the plane the modes are kept in (`planar`), a global axis.
fn planar(src: &Source, name: &str, raw: &RawBody) -> Result<Option<Vector3<f64>>, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    raw.planar
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
        .transpose()
}

/// An initial modal state (`key`: `initial_modal` or `initial_modal_rates`), one value per
/// retained mode (the rest zero).
fn initial_modal_state(
    src: &Source,
    name: &str,
    key: &str,
    v: &Option<Spanned<Vec<f64>>>,
    modes: usize,
    unit: &str,
) -> Result<Vec<f64>, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
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
}

/// The basis: static correction at the interfaces (the default for a body a reference
/// condition holds) or the eigenmodes alone.
fn basis(
    src: &Source,
    name: &str,
    raw: &RawBody,
    reference: &Reference,
) -> Result<bool, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    Ok(match raw.basis.as_ref().map(|b| b.get_ref().as_str()) {
        // static correction needs a reference condition that holds the body
        None => reference.holds_body(),
        Some("interface") if !reference.holds_body() => {
            return Err(src.error(
                span(raw.basis.as_ref().expect("given")),
                Some(k("basis")),
                "basis = \"interface\" needs a reference condition that holds every rigid \
                 motion (its static correction modes are the static responses to unit loads); a \
                 free-free or partly-free body takes basis = \"modes\"",
            ));
        }
        Some("interface") => true,
        Some("modes") => false,
        Some(other) => {
            return Err(src.error(
                span(raw.basis.as_ref().expect("given")),
                Some(k("basis")),
                super::keys::BODY_BASIS.unknown("basis", other),
            ));
        }
    })
}

/// `modes = "auto"` needs no initial modal state.
fn check_auto_modes(src: &Source, name: &str, raw: &RawBody) -> Result<(), DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
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
    Ok(())
}

/// The share of the static compliance the basis may miss before a warning (`basis_tolerance`).
fn basis_tolerance(src: &Source, name: &str, raw: &RawBody) -> Result<f64, DeckError> {
    let k = |key: &str| format!("body.{name}.{key}");
    Ok(match &raw.basis_tolerance {
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
    })
}

/// Whether flexible bodies are stiffened when the deck does not say
/// (docs/geometric-stiffening.md).
pub const STIFFENING_DEFAULT: bool = true;
