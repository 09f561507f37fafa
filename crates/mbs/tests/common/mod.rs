//! Test fixtures: rigid mechanisms and a small uniform beam reduced to a `ModalBody`
//! (3-D Euler–Bernoulli frame elements, lumped mass, dense symmetric eigen), written here
//! independently of `fem`; and a cantilever of `fem` elements with a drive about z
//! ([`fem_cantilever`], [`drive_about_z`]).

#![allow(dead_code)]

use fem::ModalBody;
use mbs::{
    FlexibleBody, Joint, JointKind, Marker, Model, MultibodySystem, RedundancyPolicy, RigidBody,
    State, TimeFunction,
};
use nalgebra::{DMatrix, Matrix3, Vector3};

/// Uniform beam along x: material and section (SI).
#[derive(Clone, Copy, Debug)]
pub struct Beam {
    pub length: f64,
    pub elements: usize,
    pub e: f64,
    pub g: f64,
    pub rho: f64,
    pub area: f64,
    /// Second moments about y and z, polar moment (m⁴).
    pub iy: f64,
    pub iz: f64,
    pub j: f64,
}

impl Beam {
    /// The composite tube of the paper's slider-crank rod (0° lay-up, isotropic equivalent):
    /// area 3.16e-5 m², outer radius 8 mm.
    pub fn slider_crank_rod(elements: usize) -> Self {
        let ro: f64 = 0.008;
        let area = 3.16e-5;
        let ri = (ro * ro - area / std::f64::consts::PI).sqrt();
        let i = std::f64::consts::PI / 4.0 * (ro.powi(4) - ri.powi(4));
        Self {
            length: 0.304,
            elements,
            e: 128e9,
            g: 5.36e9,
            rho: 1586.0,
            area,
            iy: i,
            iz: i,
            j: 2.0 * i,
        }
    }

    pub fn n_nodes(&self) -> usize {
        self.elements + 1
    }

    /// Node x-coordinates from `x0`.
    pub fn node_x(&self, x0: f64) -> Vec<f64> {
        let le = self.length / self.elements as f64;
        (0..self.n_nodes()).map(|k| x0 + k as f64 * le).collect()
    }

    /// Global stiffness (6 dof per node `[u, v, w, θx, θy, θz]`).
    pub fn stiffness(&self) -> DMatrix<f64> {
        let n = 6 * self.n_nodes();
        let mut k = DMatrix::zeros(n, n);
        let l = self.length / self.elements as f64;
        for e in 0..self.elements {
            let o = 6 * e;
            let mut add = |dofs: [usize; 2], c: f64| {
                let [a, b] = dofs;
                k[(o + a, o + a)] += c;
                k[(o + b, o + b)] += c;
                k[(o + a, o + b)] -= c;
                k[(o + b, o + a)] -= c;
            };
            add([0, 6], self.e * self.area / l);
            add([3, 9], self.g * self.j / l);
            // bending in xy (v, θz) and xz (w, θy)
            let planes = [
                ([1usize, 5, 7, 11], self.e * self.iz, 1.0),
                ([2, 4, 8, 10], self.e * self.iy, -1.0),
            ];
            for (d, ei, s) in planes {
                let c = ei / l.powi(3);
                let m = [
                    [12.0, s * 6.0 * l, -12.0, s * 6.0 * l],
                    [s * 6.0 * l, 4.0 * l * l, -s * 6.0 * l, 2.0 * l * l],
                    [-12.0, -s * 6.0 * l, 12.0, -s * 6.0 * l],
                    [s * 6.0 * l, 2.0 * l * l, -s * 6.0 * l, 4.0 * l * l],
                ];
                for i in 0..4 {
                    for j in 0..4 {
                        k[(o + d[i], o + d[j])] += c * m[i][j];
                    }
                }
            }
        }
        k
    }

    /// Lumped nodal masses and rotary inertias (tributary length).
    pub fn lumped(&self) -> (Vec<f64>, Vec<Vector3<f64>>) {
        let le = self.length / self.elements as f64;
        (0..self.n_nodes())
            .map(|k| {
                let l = if k == 0 || k == self.elements {
                    0.5 * le
                } else {
                    le
                };
                let m = self.rho * self.area * l;
                (
                    m,
                    Vector3::new(
                        self.rho * self.j * l,
                        self.rho * self.iy * l,
                        self.rho * self.iz * l,
                    ),
                )
            })
            .unzip()
    }

    /// Modal body with `n_modes` modes, the nodes at `x0 + k·le` on the body x-axis, the six
    /// dof of node `clamped` fixed for the eigenproblem; `damping_ratio` for every mode.
    pub fn modal_body(
        &self,
        x0: f64,
        clamped: usize,
        n_modes: usize,
        damping_ratio: f64,
    ) -> ModalBody<f64> {
        let k = self.stiffness();
        let (masses, inertias) = self.lumped();
        let nn = self.n_nodes();
        let mdiag: Vec<f64> = (0..6 * nn)
            .map(|i| {
                if i % 6 < 3 {
                    masses[i / 6]
                } else {
                    inertias[i / 6][i % 6 - 3]
                }
            })
            .collect();
        let free: Vec<usize> = (0..6 * nn).filter(|&i| i / 6 != clamped).collect();
        let nf = free.len();
        // M^{-1/2} K M^{-1/2}
        let a = DMatrix::from_fn(nf, nf, |i, j| {
            k[(free[i], free[j])] / (mdiag[free[i]] * mdiag[free[j]]).sqrt()
        });
        let eig = a.symmetric_eigen();
        let mut order: Vec<usize> = (0..nf).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
        let mut modes = DMatrix::zeros(6 * nn, n_modes);
        let mut eigenvalues = Vec::new();
        let mut damping = Vec::new();
        for (c, &i) in order.iter().take(n_modes).enumerate() {
            let lam = eig.eigenvalues[i];
            for (r, &dof) in free.iter().enumerate() {
                modes[(dof, c)] = eig.eigenvectors[(r, i)] / mdiag[dof].sqrt();
            }
            eigenvalues.push(lam);
            damping.push(2.0 * damping_ratio * lam.sqrt());
        }
        ModalBody {
            node_positions: self
                .node_x(x0)
                .iter()
                .map(|&x| Vector3::new(x, 0.0, 0.0))
                .collect(),
            node_masses: masses,
            node_inertias: inertias,
            modes,
            eigenvalues,
            modal_damping: damping,
            stiffness_matrix: None,
            damping_matrix: None,
        }
    }
}

/// Slender-rod inertia about the centre (rod along x).
pub fn rod_inertia(m: f64, l: f64) -> Matrix3<f64> {
    let t = m * l * l / 12.0;
    Matrix3::from_diagonal(&Vector3::new(0.05 * t, t, t))
}

pub const CRANK: f64 = 0.152;
pub const ROD: f64 = 0.304;

/// Slider-crank in the xy-plane, crank about the global z-axis at the origin driven at
/// `omega` (rad/s) from angle 0, slider on the x-axis. Returns the model, state at t = 0 (not
/// yet assembled) and the slider's body id. With `flexible_rod = Some(n_modes)` the rod is the
/// fixture's beam clamped at its centre node with joints at its end nodes.
pub fn slider_crank(omega: f64, flexible_rod: Option<usize>) -> (Model<f64>, State, mbs::BodyId) {
    slider_crank_framed(omega, flexible_rod.map(|n| (n, 5)))
}

/// As [`slider_crank`], with the flexible rod's `(modes, clamped node)`: its body frame sits at
/// that node of the 10-element rod (5: the centre).
pub fn slider_crank_framed(
    omega: f64,
    flexible_rod: Option<(usize, usize)>,
) -> (Model<f64>, State, mbs::BodyId) {
    let mut model = Model::new();
    let crank = model
        .add_rigid_body(RigidBody::new("crank", 0.38, rod_inertia(0.38, CRANK)))
        .unwrap();
    let beam = Beam::slider_crank_rod(10);
    let le = ROD / beam.elements as f64;
    let frame_x = match flexible_rod {
        Some((_, node)) => node as f64 * le,
        None => ROD / 2.0,
    };
    let (rod, rod_a, rod_b) = match flexible_rod {
        None => {
            let rod = model
                .add_rigid_body(RigidBody::new("rod", 0.2, rod_inertia(0.2, ROD)))
                .unwrap();
            (
                rod,
                Marker::on(rod, Vector3::new(-ROD / 2.0, 0.0, 0.0)),
                Marker::on(rod, Vector3::new(ROD / 2.0, 0.0, 0.0)),
            )
        }
        Some((n, node)) => {
            let modal = beam.modal_body(-frame_x, node, n, 0.01);
            let rod = model
                .add_flexible_body(FlexibleBody::new("rod", modal))
                .unwrap();
            (rod, Marker::node(rod, 0), Marker::node(rod, beam.elements))
        }
    };
    let slider = model
        .add_rigid_body(RigidBody::new("slider", 0.1, Matrix3::identity() * 1e-4))
        .unwrap();
    let x_axis = Vector3::x();
    let joints = [
        Joint::new(
            "crank pivot",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()),
            Marker::on(crank, Vector3::new(-CRANK / 2.0, 0.0, 0.0)),
        ),
        Joint::new(
            "crank driver",
            JointKind::AngleDriver(TimeFunction::ConstantSpeed {
                initial: 0.0,
                rate: omega,
            }),
            Marker::ground(Vector3::zeros()),
            Marker::on(crank, Vector3::new(-CRANK / 2.0, 0.0, 0.0)),
        ),
        Joint::new(
            "crank pin",
            JointKind::Revolute,
            Marker::on(crank, Vector3::new(CRANK / 2.0, 0.0, 0.0)),
            rod_a,
        ),
        Joint::new(
            "wrist pin",
            JointKind::Revolute,
            rod_b,
            Marker::on(slider, Vector3::zeros()),
        ),
        Joint::new(
            "slide",
            JointKind::Translational,
            Marker::ground(Vector3::zeros()).with_axis(x_axis),
            Marker::on(slider, Vector3::zeros()).with_axis(x_axis),
        ),
    ];
    for j in joints {
        model.add_joint(j).unwrap();
    }
    let mut state = model.rest_state();
    let id = Matrix3::identity();
    model.set_pose(&mut state, crank, Vector3::new(CRANK / 2.0, 0.0, 0.0), &id);
    model.set_pose(
        &mut state,
        rod,
        Vector3::new(CRANK + frame_x, 0.0, 0.0),
        &id,
    );
    model.set_pose(&mut state, slider, Vector3::new(CRANK + ROD, 0.0, 0.0), &id);
    // rough initial velocities; assembly makes them consistent
    model.set_velocity(
        &mut state,
        crank,
        Vector3::new(0.0, omega * CRANK / 2.0, 0.0),
        Vector3::new(0.0, 0.0, omega),
    );
    (model, state, slider)
}

/// `n` beams of 0.304 m (6 elements, `modes` modes, frame at the middle node) in a line along
/// x, the first pinned to the ground at the origin, each pinned to the end node of the one
/// before, all pins about z; gravity along −y, every mode damped by `zeta`.
pub fn chain(n: usize, modes: usize, zeta: f64) -> (Model<f64>, State) {
    let beam = Beam::slider_crank_rod(6);
    let l = beam.length;
    let mut model = Model::new();
    model.gravity = Vector3::new(0.0, -9.81, 0.0);
    let mut bodies: Vec<mbs::BodyId> = Vec::new();
    for i in 0..n {
        let modal = beam.modal_body(-l / 2.0, 3, modes, zeta);
        let b = model
            .add_flexible_body(FlexibleBody::new(format!("beam {i}"), modal))
            .unwrap();
        let a = match bodies.last() {
            None => Marker::ground(Vector3::zeros()),
            Some(&p) => Marker::node(p, beam.elements),
        };
        model
            .add_joint(Joint::new(
                format!("pin {i}"),
                JointKind::Revolute,
                a,
                Marker::node(b, 0),
            ))
            .unwrap();
        bodies.push(b);
    }
    let mut state = model.rest_state();
    for (i, &b) in bodies.iter().enumerate() {
        let x = (i as f64 + 0.5) * l;
        model.set_pose(
            &mut state,
            b,
            Vector3::new(x, 0.0, 0.0),
            &Matrix3::identity(),
        );
    }
    (model, state)
}

/// System with redundant equations removed and a consistent initial state.
pub fn assembled(model: Model<f64>, mut state: State) -> (MultibodySystem, State) {
    let mut sys = MultibodySystem::new(model, &state, RedundancyPolicy::Remove).unwrap();
    sys.assemble(0.0, &mut state, 1e-13).unwrap();
    (sys, state)
}

/// Closed-form slider position, velocity, acceleration at crank angle `th`, constant `omega`.
pub fn slider_exact(th: f64, omega: f64) -> [f64; 3] {
    let (s, c) = th.sin_cos();
    let (r, l) = (CRANK, ROD);
    let d = (l * l - r * r * s * s).sqrt();
    let x = r * c + d;
    let dx = -r * s - r * r * s * c / d;
    let ddx = -r * c - r * r * (c * c - s * s) / d - r.powi(4) * s * s * c * c / d.powi(3);
    [x, omega * dx, omega * omega * ddx]
}

/// Advance `q` along `q' = rates(q, v)` with `v` fixed, by `s` (RK4, 20 sub-steps).
pub fn flow(model: &Model<f64>, q: &[f64], v: &[f64], s: f64) -> Vec<f64> {
    let n = 20;
    let h = s / n as f64;
    let mut q = q.to_vec();
    let f = |q: &[f64]| {
        let mut d = vec![0.0; q.len()];
        model.kinematic_rates(q, v, &mut d);
        d
    };
    for _ in 0..n {
        let k1 = f(&q);
        let q2: Vec<f64> = q.iter().zip(&k1).map(|(a, b)| a + 0.5 * h * b).collect();
        let k2 = f(&q2);
        let q3: Vec<f64> = q.iter().zip(&k2).map(|(a, b)| a + 0.5 * h * b).collect();
        let k3 = f(&q3);
        let q4: Vec<f64> = q.iter().zip(&k3).map(|(a, b)| a + h * b).collect();
        let k4 = f(&q4);
        for i in 0..q.len() {
            q[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    q
}

/// A uniform beam along x of `fem` elements (1 m, unit mass per length, shear- and axially
/// stiff: Euler–Bernoulli), flapwise `EI = ei[0]` (bending in x–z) and chordwise `ei[1]`,
/// clamped at its root node, reduced to `modes` modes; with its geometric stiffness when
/// `stiffened`.
pub fn fem_cantilever(
    elements: usize,
    modes: usize,
    ei: [f64; 2],
    stiffened: bool,
) -> FlexibleBody<f64> {
    use fem::{BeamSection, Mesh, ModalOptions, Properties, ReferenceCondition};
    let mesh = Mesh::straight_beam(Vector3::zeros(), Vector3::x(), elements, 0, Vector3::y())
        .expect("a straight beam");
    let stiff = 1e7;
    let props = Properties {
        sections: vec![BeamSection::diagonal(
            [stiff, stiff, stiff, stiff, ei[0], ei[1]],
            1.0,
            1e-9,
            1e-9,
        )],
        laminates: vec![],
    };
    let mut options = ModalOptions::new(modes);
    options.reference = ReferenceCondition::ClampedNode(0);
    let analysis = fem::modal_analysis(&mesh, &props, &options).expect("modes");
    let modal = fem::modal_body(&mesh, &props, &analysis).expect("a modal body");
    let body = FlexibleBody::new("beam", modal.clone());
    match stiffened {
        true => body.with_geometric_stiffness(
            fem::geometric_stiffness(&mesh, &modal, 0).expect("geometric stiffness"),
        ),
        false => body,
    }
}

/// Turn `body` about the global z axis through the origin: a revolute joint (`bearing`) and an
/// angle driver (`motor`) of `motion`, which is returned.
pub fn drive_about_z<P: sens::Scalar>(
    model: &mut Model<P>,
    body: mbs::BodyId,
    motion: TimeFunction,
) -> mbs::JointId {
    let z = Vector3::z();
    model
        .add_joint(Joint::new(
            "bearing",
            JointKind::Revolute,
            Marker::ground(Vector3::zeros()).with_axis(z),
            Marker::on(body, Vector3::zeros()).with_axis(z),
        ))
        .expect("the bearing");
    model
        .add_joint(Joint::new(
            "motor",
            JointKind::AngleDriver(motion),
            Marker::ground(Vector3::zeros()).with_axes(Vector3::x(), Vector3::y()),
            Marker::on(body, Vector3::zeros()).with_axes(Vector3::x(), Vector3::y()),
        ))
        .expect("the motor")
}
