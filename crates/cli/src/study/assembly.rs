//! The nominal mechanism as `Study::validate` builds it: flexible and rigid bodies placed,
//! joints, forces and the initial state.

use super::*;

/// The nominal mechanism as validation builds it, body by body.
#[derive(Default)]
pub(super) struct Mechanism {
    pub(super) model: Model<f64>,
    pub(super) flexible: Vec<FlexiblePart>,
    pub(super) bodies: BTreeMap<String, BodyInfo>,
    /// Body names in model order.
    pub(super) body_order: Vec<String>,
    placements: Vec<Placement>,
    /// Per flexible body: its initial modal coordinates and rates as the deck gives them.
    modal_starts: Vec<(BodyId, Vec<f64>, Vec<f64>)>,
}

impl Mechanism {
    /// The flexible bodies: the modes of each mesh as given (global coordinates at t = 0).
    pub(super) fn add_flexible_bodies(
        &mut self,
        src: &Source,
        raw: &RawDeck,
        laminates: &LaminateModel,
        request: DesignRequest,
    ) -> Result<(), CliError> {
        for (name, b) in &raw.body {
            let def = validate_body(src, raw, name, b, laminates)?;
            let (built, analysis, modal, basis) =
                flexible_body(src, name, b.span(), &def, request, true)?;
            let nodes = modal.node_positions.clone();
            let body = flexible_model_body(
                name,
                &built.mesh,
                &analysis.couplings,
                modal,
                def.stiffening,
            )
            .map_err(|e| fem_error(src, name, b.span(), e))?;
            let id = self
                .model
                .add_flexible_body(body)
                .map_err(|e| at_table(src, b.span(), format!("body.{name}"), e))?;
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
                span: b.span(),
                stiffening: def.stiffening,
                def,
            });
        }
        Ok(())
    }

    /// The rigid bodies, placed and moving as the deck gives them.
    pub(super) fn add_rigid_bodies(&mut self, src: &Source, raw: &RawDeck) -> Result<(), CliError> {
        for r in mechanism::rigid_bodies(src, raw)? {
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
            self.body_order.push(r.name);
        }
        Ok(())
    }

    /// The joints (named, in deck order) and the forces and gravity (a spring's free length
    /// from its markers' distance as placed).
    pub(super) fn add_joints_and_forces(
        &mut self,
        src: &Source,
        raw: &RawDeck,
    ) -> Result<Vec<(String, JointId)>, CliError> {
        let mut named_joints = Vec::new();
        for joint in mechanism::joints(src, raw, &self.bodies)? {
            let name = joint.name.clone();
            let id = self
                .model
                .add_joint(joint)
                .map_err(|e| at_table(src, raw.joint[&name].span(), format!("joint.{name}"), e))?;
            named_joints.push((name, id));
        }
        let q0 = initial_state(&self.model, &self.placements).q;
        let model = &self.model;
        let mechanism::ForceDefs { gravity, forces } =
            mechanism::forces(src, raw, &self.bodies, |a, b| {
                (model.marker_position(a, &q0) - model.marker_position(b, &q0)).norm()
            })?;
        self.model.gravity += gravity;
        for (name, force) in forces {
            self.model
                .add_force(force)
                .map_err(|e| at_table(src, raw.force[&name].span(), format!("force.{name}"), e))?;
        }
        Ok(named_joints)
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
