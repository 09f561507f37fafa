//! The multibody model and its equations of motion (Eq. 12), written once, generic over the
//! parameter scalar `P` (the model's data) and the evaluation scalar `S` (the state).

use std::ops::Range;
use std::sync::OnceLock;

use nalgebra::{DMatrix, DVector, Matrix3, Vector3, Vector4};
use sens::Scalar;

use crate::body::{
    Body, BodyId, FlexibleBody, ModalInvariants, Pose, RigidBody, body_dynamics, foreshortening,
    pose, vec3, vec3f,
};
use crate::eq12::BodyMass;
use crate::error::ModelError;
use crate::force::{Force, ForceId, LoadFrame, TorqueLaw};
use crate::joint::{JointId, JointKind, TimeFunction, joint_equations};
use crate::kin::{Kin, l_matrix, quat_from_matrix};
use crate::marker::{Marker, MarkerKin, Site, marker_kin};

/// Baumgarte stabilisation constants of Eq. (10a): `γ − 2αΦ̇ − β²Φ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Baumgarte {
    /// Velocity feedback α (1/s).
    pub alpha: f64,
    /// Position feedback β (1/s).
    pub beta: f64,
}

impl Default for Baumgarte {
    fn default() -> Self {
        Self {
            alpha: 1.0,
            beta: 1.0,
        }
    }
}

impl Baumgarte {
    /// No stabilisation (α = β = 0).
    pub fn off() -> Self {
        Self {
            alpha: 0.0,
            beta: 0.0,
        }
    }
}

/// A joint between markers `a` and `b`.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    pub name: String,
    pub a: Marker,
    pub b: Marker,
    pub kind: JointKind,
}

impl Joint {
    pub fn new(name: impl Into<String>, kind: JointKind, a: Marker, b: Marker) -> Self {
        Self {
            name: name.into(),
            a,
            b,
            kind,
        }
    }
}

#[derive(Clone, Debug)]
struct BodySlot<P: Scalar> {
    body: Body<P>,
    q_off: usize,
    v_off: usize,
    /// A flexible body's inertia invariants, made at the first evaluation (reset by
    /// [`Model::body_mut`]).
    invariants: OnceLock<ModalInvariants<P>>,
}

/// Bodies, joints, forces, gravity and Baumgarte constants.
///
/// The state is `q` (per body `r`, Euler parameters `p`, modal coordinates `w`) and `v` (per
/// body `ṙ`, body-frame `ω'`, `ẇ`). `P` is the scalar of the model data (`f64`, or `Dual<N>`
/// when the modal data carry design derivatives).
#[derive(Clone, Debug)]
pub struct Model<P: Scalar> {
    bodies: Vec<BodySlot<P>>,
    joints: Vec<Joint>,
    joint_rows: Vec<Range<usize>>,
    forces: Vec<Force>,
    /// Per force, the gains `[kp, kd]` of its PD law (zero for the other forces): model
    /// parameters, so that design variables can carry them ([`Model::set_gain`]).
    gains: Vec<[P; 2]>,
    /// Gravitational acceleration, global (m/s²).
    pub gravity: Vector3<f64>,
    pub baumgarte: Baumgarte,
    n_q: usize,
    n_v: usize,
    n_c: usize,
}

/// Constraint values at a state (all rows).
#[derive(Clone, Debug)]
pub struct ConstraintValues<S: Scalar> {
    /// `Φ`.
    pub phi: Vec<S>,
    /// `Φ̇ = Φ_v v + Φ_t`.
    pub phi_dot: Vec<S>,
    /// `γ = −(Φ̈ − Φ_v v̇)`.
    pub gamma: Vec<S>,
    /// `Φ_v`, `n_c × n_v`.
    pub jacobian: DMatrix<S>,
}

/// The augmented system of Eq. (12): `matrix · [v̇; λ] = rhs` with
/// `matrix = [[M, Φ_vᵀ], [Φ_v, 0]]`, `rhs = [g + s − Λw − Dẇ; γ − 2αΦ̇ − β²Φ]`, restricted to
/// the selected constraint rows.
#[derive(Clone, Debug)]
pub struct Equations<S: Scalar> {
    pub matrix: DMatrix<S>,
    pub rhs: DVector<S>,
}

/// Energies at a state (J).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energy {
    pub kinetic: f64,
    pub gravity: f64,
    pub elastic: f64,
    pub spring: f64,
}

impl Energy {
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravity + self.elastic + self.spring
    }
}

impl<P: Scalar> Default for Model<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl Model<sens::Rev> {
    /// For a model whose parameters and invariants are inputs of the tape
    /// ([`Self::map_with_invariants`]), add the adjoints of its flexible bodies' invariants in
    /// each of `adjoints` (by tape node) to the parameters they are made from
    /// ([`ModalInvariants::pull_back_to`]).
    pub(crate) fn invariants_to_parameters(&self, adjoints: &mut [Vec<f64>]) {
        for s in &self.bodies {
            if let (Body::Flexible(b), Some(inv)) = (&s.body, s.invariants.get()) {
                inv.pull_back_to(b, adjoints);
            }
        }
    }
}

impl<P: Scalar> Model<P> {
    pub fn new() -> Self {
        Self {
            bodies: Vec::new(),
            joints: Vec::new(),
            joint_rows: Vec::new(),
            forces: Vec::new(),
            gains: Vec::new(),
            gravity: Vector3::zeros(),
            baumgarte: Baumgarte::default(),
            n_q: 0,
            n_v: 0,
            n_c: 0,
        }
    }

    fn push_body(&mut self, body: Body<P>) -> BodyId {
        let nm = body.n_modes();
        self.bodies.push(BodySlot {
            body,
            q_off: self.n_q,
            v_off: self.n_v,
            invariants: OnceLock::new(),
        });
        self.n_q += 7 + nm;
        self.n_v += 6 + nm;
        BodyId(self.bodies.len() - 1)
    }

    pub fn add_rigid_body(&mut self, body: RigidBody<P>) -> Result<BodyId, ModelError> {
        let bad = |name: String, reason| Err(ModelError::BadBody { name, reason });
        if !(body.mass.value() > 0.0 && body.mass.value().is_finite()) {
            return bad(body.name, "mass must be positive and finite");
        }
        let j = body.inertia.map(|x| x.value());
        if !j.iter().all(|x| x.is_finite()) || (j - j.transpose()).amax() > 1e-12 * j.amax() {
            return bad(body.name, "the inertia tensor must be finite and symmetric");
        }
        // principal moments positive, each at most the sum of the other two (a real mass
        // distribution; equality for a flat body)
        let p = j.symmetric_eigenvalues();
        let sum = p.sum();
        if !(p.min() > 0.0) || p.iter().any(|&x| x > 0.5 * sum * (1.0 + 1e-9)) {
            return bad(
                body.name,
                "the principal moments of inertia must be positive and each at most the sum of \
                 the other two",
            );
        }
        Ok(self.push_body(Body::Rigid(body)))
    }

    pub fn add_flexible_body(&mut self, body: FlexibleBody<P>) -> Result<BodyId, ModelError> {
        body.modal
            .validate()
            .map_err(|e| ModelError::BadModalBody {
                name: body.name.clone(),
                source: e,
            })?;
        if !(body.modal.total_mass() > 0.0) {
            return Err(ModelError::BadBody {
                name: body.name,
                reason: "mass must be positive",
            });
        }
        if let Some(g) = &body.geometric
            && (g.n_modes != body.modal.n_modes()
                || g.field_modes > g.n_modes
                || g.nodal.len() != 3 * body.modal.n_nodes()
                || g.nodal
                    .iter()
                    .any(|k| k.nrows() != g.field_modes || k.ncols() != g.field_modes)
                || g.elements.as_ref().is_some_and(|els| {
                    els.iter().any(|e| {
                        e.parent >= body.modal.n_nodes()
                            || e.child >= body.modal.n_nodes()
                            || e.unit.nrows() != g.field_modes
                            || e.unit.ncols() != g.field_modes
                    })
                }))
        {
            return Err(ModelError::BadBody {
                name: body.name,
                reason: "its geometric stiffness was made for other modes or nodes",
            });
        }
        if let Some(g) = &body.geometric
            && !g.leaves_out_correction_products()
        {
            return Err(ModelError::BadBody {
                name: body.name,
                reason: "its geometric stiffness has products of modes past its eigenmodes",
            });
        }
        Ok(self.push_body(Body::Flexible(body)))
    }

    fn check_marker(&self, m: &Marker, owner: &str) -> Result<(), ModelError> {
        let bad = |reason: &'static str| ModelError::BadMarker {
            owner: owner.to_string(),
            reason,
        };
        let ortho = m.axes.transpose() * m.axes - Matrix3::identity();
        // written so that NaN axes fail too
        if !(ortho.amax() <= 1e-9 && m.axes.determinant() > 0.0) {
            return Err(bad("marker axes are not a right-handed orthonormal triad"));
        }
        if let Site::Point(p) = &m.site
            && !p.iter().all(|x| x.is_finite())
        {
            return Err(bad("the marker point is not finite"));
        }
        match (m.body, &m.site) {
            (None, Site::Node(_)) => Err(bad("a ground marker cannot sit at an FE node")),
            (None, Site::Point(_)) => Ok(()),
            (Some(b), site) => {
                let slot = self.bodies.get(b.0).ok_or(bad("unknown body"))?;
                match (site, &slot.body) {
                    (Site::Point(_), _) => Ok(()),
                    (Site::Node(_), Body::Rigid(_)) => {
                        Err(bad("FE nodes exist only on flexible bodies"))
                    }
                    (Site::Node(k), Body::Flexible(f)) => {
                        if *k < f.modal.n_nodes() {
                            Ok(())
                        } else {
                            Err(bad("node index out of range"))
                        }
                    }
                }
            }
        }
    }

    pub fn add_joint(&mut self, joint: Joint) -> Result<JointId, ModelError> {
        self.check_marker(&joint.a, &joint.name)?;
        self.check_marker(&joint.b, &joint.name)?;
        if let JointKind::AngleDriver(TimeFunction::SmoothRamp { t0, t1, .. })
        | JointKind::DistanceDriver(TimeFunction::SmoothRamp { t0, t1, .. }) = &joint.kind
            && !(t1 > t0)
        {
            return Err(ModelError::BadMarker {
                owner: joint.name,
                reason: "a smooth ramp needs t1 > t0",
            });
        }
        if joint.a.body == joint.b.body {
            return Err(ModelError::BadMarker {
                owner: joint.name,
                reason: "a joint must connect two different bodies (or a body and the ground)",
            });
        }
        let n = joint.kind.n_equations();
        self.joint_rows.push(self.n_c..self.n_c + n);
        self.n_c += n;
        self.joints.push(joint);
        Ok(JointId(self.joints.len() - 1))
    }

    pub fn add_force(&mut self, force: Force) -> Result<ForceId, ModelError> {
        for m in force.markers() {
            self.check_marker(m, "force")?;
        }
        if let Force::PointForce { marker, .. } | Force::PointTorque { marker, .. } = &force
            && marker.body.is_none()
        {
            return Err(ModelError::BadMarker {
                owner: "force".into(),
                reason: "a point force or torque must act on a body, not the ground",
            });
        }
        if let Force::PointForce {
            load: crate::Load::Table { times, values },
            ..
        }
        | Force::PointTorque {
            load: crate::Load::Table { times, values },
            ..
        } = &force
            && (times.is_empty()
                || times.len() != values.len()
                || times.windows(2).any(|w| !(w[1] > w[0])))
        {
            return Err(ModelError::BadMarker {
                owner: "force".into(),
                reason: "load table needs strictly increasing times, one value per time",
            });
        }
        if let Force::SpringDamper {
            stiffness,
            damping,
            free_length,
            ..
        } = &force
            && ![*stiffness, *damping, *free_length]
                .iter()
                .all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(ModelError::BadMarker {
                owner: "spring-damper".into(),
                reason: "stiffness, damping and free length must be finite and non-negative",
            });
        }
        if let Force::JointTorque { a, b, law } | Force::JointForce { a, b, law } = &force {
            check_joint_torque(a, b, law)?;
        }
        let gains = force.pd_gains().unwrap_or([0.0; 2]).map(P::from_f64);
        self.forces.push(force);
        self.gains.push(gains);
        Ok(ForceId(self.forces.len() - 1))
    }

    /// Set gain `which` (0: `kp`, 1: `kd`) of the PD law of actuator `force` (a design
    /// variable's value, or its dual); `false` if `force` is no PD actuator.
    pub fn set_gain(&mut self, force: ForceId, which: usize, value: P) -> bool {
        let pd = self.forces.get(force.0).and_then(Force::pd_gains).is_some();
        if pd && which < 2 {
            self.gains[force.0][which] = value;
        }
        pd && which < 2
    }

    /// Replace the motion of driver `joint` (an angle or distance driver); `false`, with
    /// nothing changed, for any other joint.
    pub fn set_motion(&mut self, joint: JointId, motion: TimeFunction) -> bool {
        match &mut self.joints[joint.0].kind {
            JointKind::AngleDriver(f) | JointKind::DistanceDriver(f) => {
                *f = motion;
                true
            }
            _ => false,
        }
    }

    /// Times where a force table or a driver's motion has a kink, sorted and unique: the
    /// integrator lands on them ([`crate::OdeSystem::breakpoints`]).
    pub fn breakpoints(&self) -> Vec<f64> {
        let mut t: Vec<f64> = self
            .forces
            .iter()
            .flat_map(|f| f.breakpoints())
            .chain(self.joints.iter().flat_map(|j| match &j.kind {
                JointKind::AngleDriver(f) | JointKind::DistanceDriver(f) => f.breakpoints(),
                _ => Vec::new(),
            }))
            .filter(|x| x.is_finite())
            .collect();
        t.sort_by(f64::total_cmp);
        t.dedup();
        t
    }

    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }
    pub fn body(&self, id: BodyId) -> &Body<P> {
        &self.bodies[id.0].body
    }
    /// Mutable access to a body's parameters (e.g. to seed design tangents in the modal data).
    /// The number of modes must not change: it fixes the state layout.
    pub fn body_mut(&mut self, id: BodyId) -> &mut Body<P> {
        let slot = &mut self.bodies[id.0];
        slot.invariants = OnceLock::new();
        &mut slot.body
    }
    pub fn body_ids(&self) -> impl Iterator<Item = BodyId> + use<P> {
        (0..self.bodies.len()).map(BodyId)
    }
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }
    /// The joint named `name`.
    pub fn joint_id(&self, name: &str) -> Option<JointId> {
        self.joints.iter().position(|j| j.name == name).map(JointId)
    }

    pub fn joint(&self, id: JointId) -> &Joint {
        &self.joints[id.0]
    }
    /// Rows of joint `id` in the constraint vector.
    pub fn joint_rows(&self, id: JointId) -> Range<usize> {
        self.joint_rows[id.0].clone()
    }
    /// The joint that owns constraint row `row`.
    pub fn joint_of_row(&self, row: usize) -> JointId {
        JointId(
            self.joint_rows
                .iter()
                .position(|r| r.contains(&row))
                .expect("row in range"),
        )
    }
    /// The bodies of each joint and each force (the ground left out): the bodies whose
    /// states meet in one of their equations.
    pub(crate) fn couplings(&self) -> Vec<Vec<usize>> {
        let bodies = |ms: &[&Marker]| -> Vec<usize> {
            let mut b: Vec<usize> = ms.iter().filter_map(|m| m.body.map(|id| id.0)).collect();
            b.sort_unstable();
            b.dedup();
            b
        };
        self.joints
            .iter()
            .map(|j| bodies(&[&j.a, &j.b]))
            .chain(self.forces.iter().map(|f| bodies(&f.markers())))
            .collect()
    }
    /// Number of position coordinates.
    pub fn n_q(&self) -> usize {
        self.n_q
    }
    /// Number of velocity variables.
    pub fn n_v(&self) -> usize {
        self.n_v
    }
    /// Number of constraint equations.
    pub fn n_constraints(&self) -> usize {
        self.n_c
    }
    /// Coordinates `(r, p, w)` of body `id` within `q`.
    pub fn q_range(&self, id: BodyId) -> Range<usize> {
        let s = &self.bodies[id.0];
        s.q_off..s.q_off + 7 + s.body.n_modes()
    }
    /// Velocity variables `(ṙ, ω', ẇ)` of body `id` within `v`.
    pub fn v_range(&self, id: BodyId) -> Range<usize> {
        let s = &self.bodies[id.0];
        s.v_off..s.v_off + 6 + s.body.n_modes()
    }

    /// The same model with its parameters converted (e.g. `Dual<N>` → `f64` by value).
    pub fn map<Q: Scalar>(&self, f: impl Fn(P) -> Q) -> Model<Q> {
        Model {
            bodies: self
                .bodies
                .iter()
                .map(|s| BodySlot {
                    body: s.body.map(&f),
                    q_off: s.q_off,
                    v_off: s.v_off,
                    invariants: OnceLock::new(),
                })
                .collect(),
            joints: self.joints.clone(),
            joint_rows: self.joint_rows.clone(),
            forces: self.forces.clone(),
            gains: self.gains.iter().map(|g| g.map(&f)).collect(),
            gravity: self.gravity,
            baumgarte: self.baumgarte,
            n_q: self.n_q,
            n_v: self.n_v,
            n_c: self.n_c,
        }
    }

    /// [`Model::map`] with the flexible bodies' inertia invariants (made from the data, cached
    /// at the first evaluation) converted too rather than made again from the converted data:
    /// `f` visits the data in [`Model::map`]'s order, then each flexible body's invariants in
    /// the bodies' order. On the reverse-mode tape the invariants are then inputs of their own
    /// ([`crate::TapedModel`]), their derivatives those of this model's.
    pub fn map_with_invariants<Q: Scalar>(&self, f: impl Fn(P) -> Q) -> Model<Q> {
        let out = self.map(&f);
        for (s, o) in self.bodies.iter().zip(&out.bodies) {
            if let Body::Flexible(b) = &s.body {
                let inv = s
                    .invariants
                    .get_or_init(|| ModalInvariants::new(&b.modal, b.geometric.as_deref()));
                let _ = o.invariants.set(inv.map(&f));
            }
        }
        out
    }

    /// The number of parameters [`Self::map`] visits (those [`Self::map_with_invariants`]
    /// visits first).
    pub(crate) fn n_parameters(&self) -> usize {
        let count = std::cell::Cell::new(0);
        let _ = self.map(|x| {
            count.set(count.get() + 1);
            x.value()
        });
        count.get()
    }

    /// The model with its parameters as plain values.
    pub fn values(&self) -> Model<f64> {
        self.map(|x| x.value())
    }

    /// A state at rest: every body frame at the origin with identity orientation.
    pub fn rest_state(&self) -> State {
        let mut q = vec![0.0; self.n_q];
        for s in &self.bodies {
            q[s.q_off + 3] = 1.0;
        }
        State {
            q,
            v: vec![0.0; self.n_v],
        }
    }

    /// Set the pose of body `id`: origin `r` (m) and rotation `a` (body → global).
    pub fn set_pose(&self, state: &mut State, id: BodyId, r: Vector3<f64>, a: &Matrix3<f64>) {
        let o = self.bodies[id.0].q_off;
        state.q[o..o + 3].copy_from_slice(r.as_slice());
        state.q[o + 3..o + 7].copy_from_slice(quat_from_matrix(a).as_slice());
    }

    /// Set the velocity of body `id`: `ṙ` (global, m/s) and `ω'` (body components, rad/s).
    pub fn set_velocity(
        &self,
        state: &mut State,
        id: BodyId,
        rd: Vector3<f64>,
        omega: Vector3<f64>,
    ) {
        let o = self.bodies[id.0].v_off;
        state.v[o..o + 3].copy_from_slice(rd.as_slice());
        state.v[o + 3..o + 6].copy_from_slice(omega.as_slice());
    }

    /// Set the modal coordinates and velocities of flexible body `id`.
    pub fn set_modal(&self, state: &mut State, id: BodyId, w: &[f64], wd: &[f64]) {
        let s = &self.bodies[id.0];
        let m = s.body.n_modes();
        state.q[s.q_off + 7..s.q_off + 7 + m].copy_from_slice(w);
        state.v[s.v_off + 6..s.v_off + 6 + m].copy_from_slice(wd);
    }

    fn slot_of(&self, m: &Marker) -> Option<(&Body<P>, usize, usize)> {
        m.body.map(|b| {
            let s = &self.bodies[b.0];
            (&s.body, s.q_off, s.v_off)
        })
    }

    pub(crate) fn marker<S: Scalar + From<P>>(&self, m: &Marker, q: &[S], v: &[S]) -> MarkerKin<S> {
        let pose = m.body.map(|b| pose(&q[self.bodies[b.0].q_off..]));
        marker_kin(m, self.slot_of(m), pose.as_ref(), q, v)
    }

    /// The torque (N·m) of the actuator `force` ([`Force::JointTorque`]) at `(t, q, v)` and
    /// the rate (rad/s) of the relative angle it turns (the angle driver's measure), or the
    /// force (N) of a [`Force::JointForce`] and the rate (m/s) of the displacement it drives:
    /// their product is the actuator's power. `None` if `force` is not an actuator.
    pub fn actuator<S: Scalar + From<P>>(
        &self,
        force: ForceId,
        t: f64,
        q: &[S],
        v: &[S],
    ) -> Option<(S, S)> {
        let gains = lift_gains(self.gains.get(force.0)?);
        match self.forces.get(force.0)? {
            Force::JointTorque { a, b, law } => {
                let (ka, kb) = (self.marker(a, q, v), self.marker(b, q, v));
                let tau = joint_torque(&ka, &kb, law, gains, t);
                Some((tau, relative_angle(&ka, &kb).2))
            }
            Force::JointForce { a, b, law } => {
                let (ka, kb) = (self.marker(a, q, v), self.marker(b, q, v));
                let (force, _, rate) = joint_force(&ka, &kb, law, gains, t);
                Some((force, rate))
            }
            _ => None,
        }
    }

    /// `q̇` from `(q, v)`: `ṙ`, `ṗ = ½ L(p)ᵀ ω'`, `ẇ`.
    pub fn kinematic_rates<S: Scalar + From<P>>(&self, q: &[S], v: &[S], qdot: &mut [S]) {
        for s in &self.bodies {
            let (qo, vo) = (s.q_off, s.v_off);
            qdot[qo..qo + 3].copy_from_slice(&v[vo..vo + 3]);
            let p = Vector4::new(q[qo + 3], q[qo + 4], q[qo + 5], q[qo + 6]);
            let pd = l_matrix(&p).transpose() * vec3(&v[vo + 3..vo + 6]) * S::from_f64(0.5);
            for i in 0..4 {
                qdot[qo + 3 + i] = pd[i];
            }
            for j in 0..s.body.n_modes() {
                qdot[qo + 7 + j] = v[vo + 6 + j];
            }
        }
    }

    /// Constraint equations of all joints at `(t, q, v)`, as kinematic quantities.
    pub(crate) fn constraint_kin<S: Scalar + From<P>>(
        &self,
        t: f64,
        q: &[S],
        v: &[S],
    ) -> Vec<Kin<S>> {
        let mut out = Vec::with_capacity(self.n_c);
        // each body's pose once (a body carries several markers)
        let poses: Vec<Pose<S>> = self.bodies.iter().map(|s| pose(&q[s.q_off..])).collect();
        let marker = |m: &Marker| {
            let pose = m.body.map(|b| &poses[b.0]);
            marker_kin(m, self.slot_of(m), pose, q, v)
        };
        for j in &self.joints {
            let a = marker(&j.a);
            let b = marker(&j.b);
            joint_equations(&j.kind, &a, &b, t, &mut out);
        }
        out
    }

    /// `Φ`, `Φ̇`, `γ` and `Φ_v` of all constraint rows.
    pub fn constraints<S: Scalar + From<P>>(
        &self,
        t: f64,
        q: &[S],
        v: &[S],
    ) -> ConstraintValues<S> {
        self.constraint_values(&self.constraint_kin(t, q, v))
    }

    /// [`Model::constraints`] from the rows' kinematics ([`Model::constraint_kin`]).
    pub(crate) fn constraint_values<S: Scalar>(&self, k: &[Kin<S>]) -> ConstraintValues<S> {
        let mut jac = DMatrix::zeros(self.n_c, self.n_v);
        for (i, row) in k.iter().enumerate() {
            for (c, &x) in row.jac.iter() {
                jac[(i, c)] = x;
            }
        }
        ConstraintValues {
            phi: k.iter().map(|x| x.val).collect(),
            phi_dot: k.iter().map(|x| x.rate).collect(),
            gamma: k.iter().map(|x| -x.quad).collect(),
            jacobian: jac,
        }
    }

    /// Mass matrix `M` (`n_v × n_v`, one block per body) and generalised forces
    /// `g + s − Λw − Dẇ` (applied forces, gravity, quadratic-velocity terms, modal stiffness
    /// and damping).
    pub fn mass_and_forces<S: Scalar + From<P>>(
        &self,
        t: f64,
        q: &[S],
        v: &[S],
    ) -> (BodyMass<S>, Vec<S>) {
        let mut m = BodyMass::zeros(self.bodies.iter().map(|s| 6 + s.body.n_modes()));
        let mut f = vec![S::zero(); self.n_v];
        for (b, s) in self.bodies.iter().enumerate() {
            body_dynamics(
                &s.body,
                &s.invariants,
                &q[s.q_off..],
                &v[s.v_off..],
                &self.gravity,
                m.block_mut(b),
                0,
                &mut f[s.v_off..],
            );
        }
        for (force, gains) in self.forces.iter().zip(&self.gains) {
            self.apply_force(force, gains, t, q, v, &mut f);
        }
        (m, f)
    }

    fn apply_force<S: Scalar + From<P>>(
        &self,
        force: &Force,
        gains: &[P; 2],
        t: f64,
        q: &[S],
        v: &[S],
        f: &mut [S],
    ) {
        match force {
            Force::PointForce {
                marker,
                load,
                frame,
            } => {
                let k = self.marker(marker, q, v);
                let l: Vector3<S> = vec3f(&load.at(t));
                let fg = match frame {
                    LoadFrame::Global => l,
                    LoadFrame::Body => k.a * l,
                };
                for (i, j) in k.point.jac.iter() {
                    f[i] += j.dot(&fg);
                }
            }
            Force::PointTorque {
                marker,
                load,
                frame,
            } => {
                let k = self.marker(marker, q, v);
                let l: Vector3<S> = vec3f(&load.at(t));
                let tb = match frame {
                    LoadFrame::Global => k.a.transpose() * l,
                    LoadFrame::Body => l,
                };
                body_torque(&k, &tb, f);
            }
            Force::JointTorque { a, b, law } => {
                let ka = self.marker(a, q, v);
                let kb = self.marker(b, q, v);
                let tau = joint_torque(&ka, &kb, law, lift_gains(gains), t);
                let n = ka.axis(2).val * tau;
                if !kb.is_ground() {
                    body_torque(&kb, &(kb.a.transpose() * n), f);
                }
                if !ka.is_ground() {
                    body_torque(&ka, &(ka.a.transpose() * -n), f);
                }
            }
            Force::JointForce { a, b, law } => {
                let ka = self.marker(a, q, v);
                let kb = self.marker(b, q, v);
                let (force, n, _) = joint_force(&ka, &kb, law, lift_gains(gains), t);
                let fn_ = n * force;
                for (i, j) in kb.point.jac.iter() {
                    f[i] += j.dot(&fn_);
                }
                for (i, j) in ka.point.jac.iter() {
                    f[i] -= j.dot(&fn_);
                }
            }
            Force::SpringDamper {
                a,
                b,
                stiffness,
                damping,
                free_length,
            } => {
                let ka = self.marker(a, q, v);
                let kb = self.marker(b, q, v);
                let d = kb.point.sub(&ka.point);
                let l = d.val.dot(&d.val).sqrt();
                let ld = d.val.dot(&d.rate) / l;
                let tension = (l - S::from_f64(*free_length)) * *stiffness + ld * *damping;
                let dir = d.val / l;
                for (i, j) in d.jac.iter() {
                    f[i] -= tension * j.dot(&dir);
                }
            }
        }
    }

    /// The augmented system of Eq. (12) at `(t, q, v)` for constraint rows `rows`.
    pub fn equations<S: Scalar + From<P>>(
        &self,
        t: f64,
        q: &[S],
        v: &[S],
        rows: &[usize],
    ) -> Equations<S> {
        let k = self.constraint_kin(t, q, v);
        self.equations_with(t, q, v, &k, rows)
    }

    /// As [`Model::equations`], with the constraint kinematics `k` of all rows already
    /// evaluated at `(t, q, v)` ([`Model::constraint_kin`]).
    pub(crate) fn equations_with<S: Scalar + From<P>>(
        &self,
        t: f64,
        q: &[S],
        v: &[S],
        k: &[Kin<S>],
        rows: &[usize],
    ) -> Equations<S> {
        let (m, f) = self.mass_and_forces(t, q, v);
        self.assemble(&m, &f, k, rows)
    }

    /// Eq. (12) from its blocks: the mass matrix, generalised forces and constraint
    /// kinematics (any scalar; the blocks must not depend on `P`).
    pub(crate) fn assemble<S: Scalar>(
        &self,
        m: &BodyMass<S>,
        f: &[S],
        k: &[Kin<S>],
        rows: &[usize],
    ) -> Equations<S> {
        self.assemble_as(m, f, k, rows, |x| x)
    }

    /// [`Model::assemble`] converting every entry with `conv` (e.g. the values of dual
    /// blocks), the same operations on the converted entries.
    pub(crate) fn assemble_as<S: Scalar, T: Scalar>(
        &self,
        m: &BodyMass<S>,
        f: &[S],
        k: &[Kin<S>],
        rows: &[usize],
        conv: impl Fn(S) -> T,
    ) -> Equations<T> {
        let nv = self.n_v;
        let n = nv + rows.len();
        let mut matrix = DMatrix::zeros(n, n);
        for (o, block) in m.blocks() {
            for j in 0..block.ncols() {
                for i in 0..block.nrows() {
                    matrix[(o + i, o + j)] = conv(block[(i, j)]);
                }
            }
        }
        for (r, &row) in rows.iter().enumerate() {
            for (col, &x) in k[row].jac.iter() {
                let x = conv(x);
                matrix[(nv + r, col)] = x;
                matrix[(col, nv + r)] = x;
            }
        }
        let rhs = DVector::from_vec(self.rhs_as(f, k, rows, conv));
        Equations { matrix, rhs }
    }

    /// The right-hand side of Eq. (12) (see [`Model::assemble`]), every entry converted with
    /// `conv`: `[g + s − Λw − Dẇ; γ − 2αΦ̇ − β²Φ]` on the rows `rows`.
    pub(crate) fn rhs_as<S: Scalar, T: Scalar>(
        &self,
        f: &[S],
        k: &[Kin<S>],
        rows: &[usize],
        conv: impl Fn(S) -> T,
    ) -> Vec<T> {
        let two_alpha = T::from_f64(2.0 * self.baumgarte.alpha);
        let beta2 = T::from_f64(self.baumgarte.beta * self.baumgarte.beta);
        let mut rhs: Vec<T> = f.iter().map(|&x| conv(x)).collect();
        rhs.extend(rows.iter().map(|&row| {
            let c = &k[row];
            -conv(c.quad) - two_alpha * conv(c.rate) - beta2 * conv(c.val)
        }));
        rhs
    }

    /// The residual `rhs − matrix · x̂` of Eq. (12) with `x̂ = [v̇; λ]` held fixed: evaluated on
    /// `Dual<N>` its tangents are the right-hand side of Eq. (40) (see [`sens::solve_tangents`]).
    pub fn residual<S: Scalar + From<P>>(
        &self,
        t: f64,
        q: &[S],
        v: &[S],
        rows: &[usize],
        x_hat: &[f64],
    ) -> Vec<S> {
        let (m, f) = self.mass_and_forces(t, q, v);
        let k = self.constraint_kin(t, q, v);
        self.residual_from(&m, &f, &k, rows, x_hat)
    }

    /// [`Model::residual`] from the blocks of Eq. (12) (see [`Model::assemble`]): applied to x̂
    /// without assembling the augmented matrix (the operations of `rhs − matrix · x̂` on its
    /// nonzero entries, in the same order).
    pub(crate) fn residual_from<S: Scalar>(
        &self,
        m: &BodyMass<S>,
        f: &[S],
        k: &[Kin<S>],
        rows: &[usize],
        x_hat: &[f64],
    ) -> Vec<S> {
        let nv = self.n_v;
        let mut out = Vec::with_capacity(nv + rows.len());
        // `r − Σ a_j x̂_j` over the nonzero `x̂_j`: one node on the reverse-mode tape
        let (mut a, mut x) = (Vec::new(), Vec::new());
        let mut minus_products = |r: S, entries: &mut dyn Iterator<Item = (S, f64)>| {
            a.clear();
            x.clear();
            for (aj, xj) in entries.filter(|&(_, xj)| xj != 0.0) {
                a.push(aj);
                x.push(xj);
            }
            S::sub_scaled(r, &a, &x)
        };
        for (o, block) in m.blocks() {
            for i in 0..block.nrows() {
                let row = &mut (0..block.ncols()).map(|j| (block[(i, j)], x_hat[o + j]));
                out.push(minus_products(f[o + i], row));
            }
        }
        for (a, &row) in rows.iter().enumerate() {
            let lambda = x_hat[nv + a];
            if lambda != 0.0 {
                for (col, &x) in k[row].jac.iter() {
                    out[col] -= x * lambda;
                }
            }
        }
        let two_alpha = S::from_f64(2.0 * self.baumgarte.alpha);
        let beta2 = S::from_f64(self.baumgarte.beta * self.baumgarte.beta);
        for &row in rows {
            let c = &k[row];
            let r = -c.quad - two_alpha * c.rate - beta2 * c.val;
            let jac = &mut c.jac.iter().map(|(col, &x)| (x, x_hat[col]));
            out.push(minus_products(r, jac));
        }
        out
    }
}

impl Model<f64> {
    /// Kinetic, gravitational, elastic and spring energies at `(t, q, v)`.
    pub fn energy(&self, t: f64, q: &[f64], v: &[f64]) -> Energy {
        self.energy_with_mass(q, v, &self.mass_and_forces(t, q, v).0)
    }

    /// [`Model::energy`] with the mass matrix `m` at the state.
    pub(crate) fn energy_with_mass(&self, q: &[f64], v: &[f64], m: &BodyMass<f64>) -> Energy {
        let kinetic = 0.5 * v.iter().zip(m.mul(v)).map(|(a, b)| a * b).sum::<f64>();
        let mut gravity = 0.0;
        let mut elastic = 0.0;
        for s in &self.bodies {
            let ps = pose(&q[s.q_off..]);
            match &s.body {
                Body::Rigid(b) => gravity -= b.mass * self.gravity.dot(&ps.r),
                Body::Flexible(b) => {
                    let nm = b.modal.n_modes();
                    let w = &q[s.q_off + 7..s.q_off + 7 + nm];
                    for k in 0..b.modal.n_nodes() {
                        let mut u = b.modal.node_positions[k];
                        for j in 0..nm {
                            u += crate::body::mode_vec::<f64, f64>(&b.modal, k, j, false) * w[j];
                        }
                        let x = ps.r + ps.a * u;
                        gravity -= b.modal.node_masses[k] * self.gravity.dot(&x);
                    }
                    for j in 0..nm {
                        elastic += 0.5
                            * match &b.modal.stiffness_matrix {
                                None => b.modal.eigenvalues[j] * w[j] * w[j],
                                Some(k) => (0..nm).map(|l| k[(j, l)] * w[j] * w[l]).sum(),
                            };
                    }
                }
            }
        }
        let mut spring = 0.0;
        for force in &self.forces {
            if let Force::SpringDamper {
                a,
                b,
                stiffness,
                free_length,
                ..
            } = force
            {
                let ka = self.marker(a, q, v);
                let kb = self.marker(b, q, v);
                let l = (kb.point.val - ka.point.val).norm();
                spring += 0.5 * stiffness * (l - free_length).powi(2);
            }
        }
        Energy {
            kinetic,
            gravity,
            elastic,
            spring,
        }
    }

    /// The spring–dampers (indices among the forces, in the order added) whose two points
    /// coincide at `q`: their line of action is undefined there.
    pub fn zero_length_springs(&self, q: &[f64]) -> Vec<usize> {
        self.forces
            .iter()
            .enumerate()
            .filter_map(|(i, f)| match f {
                Force::SpringDamper { a, b, .. } => {
                    let d = self.marker_position(b, q) - self.marker_position(a, q);
                    (d.norm() == 0.0).then_some(i)
                }
                _ => None,
            })
            .collect()
    }

    /// The angle drivers that hold their bodies half a turn from their angle at `t`, `q`:
    /// `ρ cos(f − θ) < 0` (their equation `ρ sin(f − θ) = 0` holds at `θ = f + π` too).
    pub(crate) fn reversed_drivers(&self, t: f64, q: &[f64]) -> Vec<JointId> {
        let v = vec![0.0; self.n_v];
        (self.joints.iter().enumerate())
            .filter_map(|(i, j)| {
                let JointKind::AngleDriver(f) = &j.kind else {
                    return None;
                };
                let (a, b) = (self.marker(&j.a, q, &v), self.marker(&j.b, q, &v));
                let b1 = b.axis(0).val;
                let (c, s) = (a.axis(0).val.dot(&b1), a.axis(1).val.dot(&b1));
                let (sf, cf) = f.eval(t)[0].sin_cos();
                (c * cf + s * sf < 0.0).then_some(JointId(i))
            })
            .collect()
    }

    /// Global position of a marker point (m).
    pub fn marker_position(&self, m: &Marker, q: &[f64]) -> Vector3<f64> {
        let v = vec![0.0; self.n_v];
        self.marker(m, q, &v).point.val
    }

    /// Global position, velocity of a marker point (m, m/s).
    pub fn marker_velocity(
        &self,
        m: &Marker,
        q: &[f64],
        v: &[f64],
    ) -> (Vector3<f64>, Vector3<f64>) {
        let k = self.marker(m, q, v);
        (k.point.val, k.point.rate)
    }

    /// Nodal displacements `u' = X w` of flexible body `id` (body frame; per node translation
    /// and rotation), with the second-order part `½ Q(w, w)` of the translations when the body
    /// has one. Empty for rigid bodies.
    pub fn nodal_displacements(&self, id: BodyId, q: &[f64]) -> Vec<[f64; 6]> {
        let s = &self.bodies[id.0];
        let Body::Flexible(b) = &s.body else {
            return Vec::new();
        };
        let nm = b.modal.n_modes();
        let w = &q[s.q_off + 7..s.q_off + 7 + nm];
        (0..b.modal.n_nodes())
            .map(|k| {
                let mut u: [f64; 6] = std::array::from_fn(|i| {
                    (0..nm).map(|j| b.modal.modes[(6 * k + i, j)] * w[j]).sum()
                });
                if let Some(g) = &b.geometric {
                    let half = foreshortening(g, k, w);
                    for i in 0..3 {
                        u[i] += half[i];
                    }
                }
                u
            })
            .collect()
    }

    /// An upper bound of the largest nodal translation of flexible body `id` at `q` (body
    /// frame; [`ModalInvariants::deformation_bound`]), cheap whatever the number of nodes;
    /// `None` for rigid bodies.
    pub(crate) fn deformation_bound(&self, id: BodyId, q: &[f64]) -> Option<f64> {
        let s = &self.bodies[id.0];
        let Body::Flexible(b) = &s.body else {
            return None;
        };
        let nm = b.modal.n_modes();
        let inv = s
            .invariants
            .get_or_init(|| ModalInvariants::new(&b.modal, b.geometric.as_deref()));
        Some(inv.deformation_bound(&q[s.q_off + 7..s.q_off + 7 + nm]))
    }

    /// Orientation (body → global) of body `id`.
    pub fn rotation_of(&self, id: BodyId, q: &[f64]) -> Matrix3<f64> {
        pose(&q[self.bodies[id.0].q_off..]).a
    }
}

/// Positions and velocities of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
}

impl State {
    /// `y = [q; v]`.
    pub fn to_vec(&self) -> Vec<f64> {
        let mut y = self.q.clone();
        y.extend_from_slice(&self.v);
        y
    }
    /// Split `y = [q; v]` after `n_q` entries.
    pub fn from_vec(y: &[f64], n_q: usize) -> Self {
        Self {
            q: y[..n_q].to_vec(),
            v: y[n_q..].to_vec(),
        }
    }
}

/// The torque `tb` (body components) on the body of marker `k`: its angular-velocity rows and,
/// at an FE node, the node's rotation modes.
fn body_torque<S: Scalar>(k: &MarkerKin<S>, tb: &Vector3<S>, f: &mut [S]) {
    for i in 0..3 {
        f[k.v_off + 3 + i] += tb[i];
    }
    for (j, x) in k.node_rot_modes.iter().enumerate() {
        f[k.v_off + 6 + j] += x.dot(tb);
    }
}

/// The torque of an actuator between the markers `ka`, `kb` at `t` ([`TorqueLaw`]).
/// The gains `[kp, kd]` of a model with parameters `P` in the scalar `S` of an evaluation.
fn lift_gains<P: Scalar, S: Scalar + From<P>>(g: &[P; 2]) -> [S; 2] {
    [S::from(g[0]), S::from(g[1])]
}

fn joint_torque<S: Scalar>(
    ka: &MarkerKin<S>,
    kb: &MarkerKin<S>,
    law: &TorqueLaw,
    [kp, kd]: [S; 2],
    t: f64,
) -> S {
    match law {
        TorqueLaw::Table { times, values } => S::from_f64(TorqueLaw::table_at(times, values, t)),
        TorqueLaw::Pd { motion, .. } => {
            let (c, s, theta_dot) = relative_angle(ka, kb);
            let [fv, fd, _] = motion.eval(t);
            let (sf, cf) = (S::from_f64(fv.sin()), S::from_f64(fv.cos()));
            // f − θ in (−π, π]
            let error = (c * sf - s * cf).atan2(c * cf + s * sf);
            error * kp + (S::from_f64(fd) - theta_dot) * kd
        }
    }
}

/// A joint force actuator's force `F` (N), its direction `n` (`ka`'s third axis) and the rate
/// of the displacement `x = n · (x_B − x_A)` it drives (the distance driver's measure):
/// tabulated, or `kp (f − x) + kd (ḟ − ẋ)` with the model's `gains`.
fn joint_force<S: Scalar>(
    ka: &MarkerKin<S>,
    kb: &MarkerKin<S>,
    law: &TorqueLaw,
    [kp, kd]: [S; 2],
    t: f64,
) -> (S, Vector3<S>, S) {
    let n = ka.axis(2);
    let x = n.dot(&kb.point.sub(&ka.point));
    let force = match law {
        TorqueLaw::Table { times, values } => S::from_f64(TorqueLaw::table_at(times, values, t)),
        TorqueLaw::Pd { motion, .. } => {
            let [fv, fd, _] = motion.eval(t);
            (S::from_f64(fv) - x.val) * kp + (S::from_f64(fd) - x.rate) * kd
        }
    };
    (force, n.val, x.rate)
}

/// The angle `θ` of `kb`'s first axis from `ka`'s first about `ka`'s third, the angle driver's
/// measure: `(ρ cos θ, ρ sin θ, θ̇)` with `ρ cos θ = e1A·e1B`, `ρ sin θ = e2A·e1B` and
/// `θ̇ = (c ṡ − s ċ)/ρ²`.
fn relative_angle<S: Scalar>(ka: &MarkerKin<S>, kb: &MarkerKin<S>) -> (S, S, S) {
    let b1 = kb.axis(0);
    let c = ka.axis(0).dot(&b1);
    let s = ka.axis(1).dot(&b1);
    let rate = (c.val * s.rate - s.val * c.rate) / (c.val * c.val + s.val * s.val);
    (c.val, s.val, rate)
}

/// An actuator's markers and law, checked: two bodies, a finite table with increasing times,
/// finite non-negative gains.
fn check_joint_torque(a: &Marker, b: &Marker, law: &TorqueLaw) -> Result<(), ModelError> {
    let bad = |reason| {
        Err(ModelError::BadMarker {
            owner: "joint actuator".into(),
            reason,
        })
    };
    if a.body == b.body {
        return bad("an actuator acts between two different bodies (or a body and the ground)");
    }
    match law {
        TorqueLaw::Table { times, values } => {
            if times.is_empty()
                || times.len() != values.len()
                || times.windows(2).any(|w| !(w[1] > w[0]))
                || !times.iter().chain(values).all(|x| x.is_finite())
            {
                return bad(
                    "an actuator's table needs finite, strictly increasing times, one value per time",
                );
            }
        }
        TorqueLaw::Pd { kp, kd, .. } => {
            if !(kp.is_finite() && kd.is_finite() && *kp >= 0.0 && *kd >= 0.0) {
                return bad("the gains kp and kd must be finite and non-negative");
            }
        }
    }
    Ok(())
}
