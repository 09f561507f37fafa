//! The nominal mechanism as [`Study::build`](super::Study::build) assembles it: flexible and
//! rigid bodies placed, joints and forces on their markers, the initial state.

use super::*;
use mbs::ForceId;

/// The joints and the forces of a mechanism by their deck names.
type Named = (Vec<(String, JointId)>, Vec<(String, ForceId)>);

/// The mechanism being built, body by body.
#[derive(Default)]
pub(super) struct Assembly {
    pub(super) model: Model<f64>,
    pub(super) flexible: Vec<FlexiblePart>,
    pub(super) bodies: BTreeMap<String, BodyInfo>,
    /// Body names in model order.
    pub(super) body_order: Vec<String>,
    placements: Vec<Placement>,
    /// Per flexible body: its initial modal coordinates and rates as the deck gives them.
    modal_starts: Vec<(BodyId, Vec<f64>, Vec<f64>)>,
}

impl Assembly {
    /// The flexible bodies: the modes of each mesh as given (global coordinates at t = 0).
    pub(super) fn add_flexible_bodies(
        &mut self,
        src: &Source,
        defs: &[FlexibleDef],
        request: DesignRequest,
    ) -> Result<(), CliError> {
        for FlexibleDef { name, span, def } in defs {
            let (built, analysis, modal, basis) =
                flexible_body(src, name, span.clone(), def, request, true)?;
            let nodes = modal.node_positions.clone();
            let stresses = StressInput::of((src, name), def, &built, || {
                built.design.nominal_stress_parts()
            })?;
            let body = flexible_model_body(
                name,
                &built.mesh,
                &built.props,
                &analysis,
                modal,
                (def.stiffening, stresses),
            )
            .map_err(|e| fem_error(src, name, span.clone(), e))?;
            let id = self
                .model
                .add_flexible_body(body)
                .map_err(|e| at_table(src, span.clone(), format!("body.{name}"), e))?;
            self.modal_starts.push((
                id,
                def.initial_modal.clone(),
                def.initial_modal_rates.clone(),
            ));
            self.placements.push(Placement {
                id,
                position: analysis.origin,
                rotation: Matrix3::identity(),
                velocity: Vector3::zeros(),
                angular_velocity: Vector3::zeros(),
            });
            self.bodies.insert(
                name.clone(),
                BodyInfo {
                    id,
                    position: analysis.origin,
                    rotation: Matrix3::identity(),
                    nodes: Some(nodes),
                    frequencies: analysis.frequencies_hz(),
                    couplings: def.couplings.iter().map(|c| c.name.clone()).collect(),
                    basis: Some(basis),
                },
            );
            self.body_order.push(name.clone());
            self.flexible.push(FlexiblePart {
                id,
                name: name.clone(),
                built,
                analysis,
                span: span.clone(),
                stiffening: def.stiffening,
                def: def.clone(),
            });
        }
        Ok(())
    }

    /// The rigid bodies, placed and moving as the deck gives them.
    pub(super) fn add_rigid_bodies(
        &mut self,
        src: &Source,
        defs: &[RigidDef],
    ) -> Result<(), CliError> {
        for r in defs {
            let id = self
                .model
                .add_rigid_body(RigidBody::new(r.name.clone(), r.mass, r.inertia))
                .map_err(|e| at_table(src, r.span.clone(), format!("rigid.{}", r.name), e))?;
            self.placements.push(Placement {
                id,
                position: r.position,
                rotation: r.orientation,
                velocity: r.velocity,
                angular_velocity: r.angular_velocity,
            });
            self.bodies.insert(
                r.name.clone(),
                BodyInfo {
                    id,
                    position: r.position,
                    rotation: r.orientation,
                    nodes: None,
                    frequencies: Vec::new(),
                    couplings: Vec::new(),
                    basis: None,
                },
            );
            self.body_order.push(r.name.clone());
        }
        Ok(())
    }

    /// The joints (named, in deck order) and the forces and gravity on the bodies' markers (a
    /// spring's default free length: its markers' distance as placed); returns the joints and
    /// the forces by name.
    pub(super) fn add_joints_and_forces(
        &mut self,
        src: &Source,
        joints: &[JointDef],
        forces: &ForceDefs,
    ) -> Result<Named, CliError> {
        let mut named_joints = Vec::new();
        let mut named_forces = Vec::new();
        for joint in joints {
            let id = self
                .model
                .add_joint(joint.resolve(&self.bodies))
                .map_err(|e| {
                    at_table(src, joint.span.clone(), format!("joint.{}", joint.name), e)
                })?;
            named_joints.push((joint.name.clone(), id));
        }
        let q0 = initial_state(&self.model, &self.placements).q;
        self.model.gravity += forces.gravity;
        for (name, force, span) in &forces.forces {
            let model = &self.model;
            let force = force.resolve(&self.bodies, |a, b| {
                (model.marker_position(a, &q0) - model.marker_position(b, &q0)).norm()
            });
            let id = self
                .model
                .add_force(force)
                .map_err(|e| at_table(src, span.clone(), format!("force.{name}"), e))?;
            named_forces.push((name.clone(), id));
        }
        Ok((named_joints, named_forces))
    }

    /// The initial state: the bodies as placed (the assembly moves only the rigid-body
    /// coordinates), the elastic state as the deck gives it, static correction modes (after
    /// the retained ones) at zero.
    pub(super) fn initial_state(&self) -> State {
        let mut state = initial_state(&self.model, &self.placements);
        for (id, w, wd) in &self.modal_starts {
            let n = self.model.body(*id).n_modes();
            let pad = |x: &Vec<f64>| {
                let mut x = x.clone();
                x.resize(n, 0.0);
                x
            };
            self.model.set_modal(&mut state, *id, &pad(w), &pad(wd));
        }
        state
    }
}
