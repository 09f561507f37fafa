//! The adjoint of a flexible body's data in the model with respect to its modal body's: what
//! the updated modes' eigenvector derivatives are contracted with when the adjoint method
//! leaves them out of the chunks' bodies ([`super::dual_chunks::DualChunks::with`]).
//!
//! The model's flexible body is made from its modal body (modes, eigenvalues, modal damping,
//! modal stiffness and damping) by [`crate::study::flexible_model_body`], which adds its
//! second-order field and its plies' modal stresses, made from the modes. That build is
//! recorded once on the reverse-mode tape with the modal body's data as inputs (the element
//! properties and the plies constant: the chunks' bodies carry their tangents), the built
//! body's data are seeded with the backward sweep's adjoints of the model's data, and the
//! sweep back gives the adjoint of each datum of the modal body: what
//! `fem::eigenvector_adjoints` reads.

use std::cell::RefCell;

use fem::ModalBody;
use mbs::{Body, Model};
use sens::{Rev, Tape};

use crate::deck::Source;
use crate::error::CliError;
use crate::study::{FlexiblePart, StressInput};

/// Per objective, the adjoint of each datum of `part`'s modal body (a body of its shape), from
/// the adjoints `data` of the data of `model` (per objective, in `Model::map`'s order): the
/// swept model, the values of a chunk's (whose layout, e.g. a modal stiffness matrix with
/// correction modes, the nominal model's need not have).
pub(crate) fn modal_body_adjoints(
    src: &Source,
    model: &Model<f64>,
    part: &FlexiblePart,
    data: &[Vec<f64>],
) -> Result<Vec<ModalBody<f64>>, CliError> {
    let Body::Flexible(body) = model.body(part.id) else {
        unreachable!("a flexible part is a flexible body of the model");
    };
    let modal = &body.modal;
    let base = Tape::len();
    let input = |x: &f64| Rev::input(*x);
    let taped = ModalBody {
        node_positions: modal.node_positions.clone(),
        node_masses: modal
            .node_masses
            .iter()
            .map(|&m| Rev::constant(m))
            .collect(),
        node_inertias: (modal.node_inertias.iter())
            .map(|v| v.map(Rev::constant))
            .collect(),
        modes: modal.modes.map(Rev::input),
        eigenvalues: modal.eigenvalues.iter().map(input).collect(),
        modal_damping: modal.modal_damping.iter().map(input).collect(),
        stiffness_matrix: (modal.stiffness_matrix.as_ref()).map(|k| Box::new(k.map(Rev::input))),
        damping_matrix: (modal.damping_matrix.as_ref()).map(|c| Box::new(c.map(Rev::input))),
    };
    let built = &part.built;
    let lift = |x: f64| Rev::constant(x);
    let stresses = StressInput::of((src, &part.name), &part.def, built, || {
        (built.design.nominal_stress_parts()).map(|parts| parts.map(&lift))
    })?;
    let rebuilt = crate::study::flexible_model_body(
        &part.name,
        &built.mesh,
        &built.props.map(&lift),
        &part.analysis,
        taped.clone(),
        (part.stiffening, stresses),
    )
    .map_err(|e| crate::study::flexible::fem_error(src, &part.name, part.span.clone(), e))?;
    let mut model = model.map(Rev::constant);
    *model.body_mut(part.id) = Body::Flexible(rebuilt);
    // the model's data, in the order their adjoints are
    let handles = RefCell::new(Vec::new());
    let _ = model.map(|x: Rev| {
        handles.borrow_mut().push(x);
        0.0
    });
    let handles = handles.into_inner();
    let adjoints = data
        .iter()
        .map(|data| {
            assert_eq!(
                data.len(),
                handles.len(),
                "the adjoints of another model's data"
            );
            let mut adjoints = vec![0.0; Tape::len()];
            for (h, &a) in handles.iter().zip(data) {
                if a != 0.0 {
                    h.seed(&mut adjoints, a);
                }
            }
            Tape::backpropagate(&mut adjoints, base);
            let of = |x: &Rev| x.adjoint(&adjoints);
            ModalBody {
                node_positions: taped.node_positions.clone(),
                node_masses: vec![0.0; taped.node_masses.len()],
                node_inertias: vec![nalgebra::Vector3::zeros(); taped.node_inertias.len()],
                modes: taped.modes.map(|x| of(&x)),
                eigenvalues: taped.eigenvalues.iter().map(of).collect(),
                modal_damping: taped.modal_damping.iter().map(of).collect(),
                stiffness_matrix: (taped.stiffness_matrix.as_ref())
                    .map(|k| Box::new(k.map(|x| of(&x)))),
                damping_matrix: (taped.damping_matrix.as_ref())
                    .map(|c| Box::new(c.map(|x| of(&x)))),
            }
        })
        .collect();
    drop(model);
    Tape::rewind(base);
    Ok(adjoints)
}
