//! A flexible body of the model from its modes: its second-order field and its plies'
//! stresses, and which bodies' ply stresses the deck's responses read.

use std::collections::BTreeMap;

use mbs::FlexibleBody;

use super::flexible::{Built, StressParts};
use super::{DesignDef, FlexibleDef, RawDeck, ResponseSpec, Source, mechanism};
use crate::deck::bodies::BodyDef;
use crate::error::CliError;

/// What a flexible body's ply stresses are built from: its laminates or sections in the
/// design's scalar ([`super::flexible::Design::stress_parts`]), its element options' membrane,
/// its plies' (regions') strengths.
pub(crate) struct StressInput<'a, S: sens::Scalar> {
    pub(crate) parts: StressParts<S>,
    pub(crate) membrane: fem::Membrane,
    pub(crate) strengths: &'a [Vec<Option<laminate::PlyStrength>>],
}

impl<'a, S: sens::Scalar> StressInput<'a, S> {
    /// The ply stresses' input of the body `name` (`def`, built as `built`, from the deck
    /// `src`), when a response reads them (`parts`: its laminates or sections in the design's
    /// scalar, asked for only then; its failure is the body's computation error).
    pub(crate) fn of(
        (src, name): (&Source, &str),
        def: &'a BodyDef,
        built: &Built,
        parts: impl FnOnce() -> Result<StressParts<S>, section::SectionError>,
    ) -> Result<Option<Self>, CliError> {
        let Some(strengths) = &def.ply_strengths else {
            return Ok(None);
        };
        let parts = parts().map_err(|e| {
            CliError::computation(src, format!("body `{name}`: its plies' stresses: {e}"))
        })?;
        Ok(Some(StressInput {
            parts,
            membrane: built.options.element.membrane,
            strengths,
        }))
    }
}

/// The multibody body of a flexible body's modes `modal` (of `analysis`, on the mesh `mesh`
/// with the element properties `props` in the design's scalar), with its second-order field
/// when `stiffening` (measured from the node at the body frame) and its plies' stresses when
/// `stresses` says what they are made of.
pub(crate) fn flexible_model_body<S: sens::Scalar>(
    name: &str,
    mesh: &fem::Mesh,
    props: &fem::Properties<S>,
    analysis: &fem::ModalAnalysis,
    modal: fem::ModalBody<S>,
    (stiffening, stresses): (bool, Option<StressInput<S>>),
) -> Result<FlexibleBody<S>, fem::FemError> {
    let mut body = FlexibleBody::new(name, modal);
    if let Some(input) = stresses {
        let modal = match &input.parts {
            StressParts::Shell(plies) => {
                fem::shell_modal_stresses(mesh, plies, input.membrane, &body.modal)?
            }
            StressParts::Beam(sections) => {
                let planar = analysis.options.element.planar_axis;
                fem::beam_modal_stresses(mesh, (props, planar), sections, &body.modal)?
            }
        };
        body = body.with_ply_stresses(mbs::PlyStresses {
            modal,
            strengths: input.strengths.to_vec(),
        });
    }
    if !stiffening {
        return Ok(body);
    }
    let clamp = body
        .modal
        .closest_node(&nalgebra::Vector3::zeros())
        .unwrap_or(0);
    let g = fem::second_order_field(mesh, props, analysis, &body.modal, clamp)?
        .with_couplings(&analysis.couplings);
    Ok(body.with_geometric_stiffness(g))
}

/// The flexible bodies whose ply stresses a response reads get their plies' strengths (and
/// so are built with their ply stresses). A ply strain or a maximum-strain index is refused on
/// a body whose material a design variable moves: its strains are the stresses through the
/// nominal compliance, whose derivative it would miss.
pub(super) fn ply_responses(
    src: &Source,
    raw: &RawDeck,
    specs: &[ResponseSpec],
    places: &BTreeMap<String, mechanism::BodyPlace>,
    design: &DesignDef,
    bodies: &mut [FlexibleDef],
) -> Result<(), CliError> {
    for spec in specs {
        let Some((body, nominal_compliance)) = spec.ply_body() else {
            continue;
        };
        let map = &(places[body].flexible.as_ref())
            .expect("validated as a flexible body")
            .plies;
        let def = &mut (bodies.iter_mut().find(|b| b.name == body))
            .expect("validated body")
            .def;
        def.ply_strengths.get_or_insert_with(|| {
            (map.laminates.iter())
                .map(|(_, plies)| plies.iter().map(|(_, s)| *s).collect())
                .collect()
        });
        let Some([what, key, instead]) = nominal_compliance.filter(|_| design.enabled) else {
            continue;
        };
        let materials = map
            .laminates
            .iter()
            .flat_map(|(_, p)| p.iter().map(|(m, _)| m));
        for m in materials {
            if let Some(v) = (design.variables.iter()).find(|v| v.material_links(m).is_some()) {
                return Err(src
                    .error(
                        raw.response.get(&spec.name).map(|r| r.span()),
                        Some(format!("response.{}.{key}", spec.name)),
                        format!(
                            "design variable `{}` moves the material `{m}` of body `{body}`: \
                             {what} takes the strains through the nominal compliance and would \
                             miss their derivative along it; {instead} or leave the material \
                             fixed",
                            v.name
                        ),
                    )
                    .into());
            }
        }
    }
    Ok(())
}
