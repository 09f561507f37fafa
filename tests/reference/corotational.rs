//! Geometrically exact reference of the flexible slider-crank: a planar co-rotational
//! Euler–Bernoulli beam finite-element model, integrated by the generalised-α method with a
//! fixed step. It depends on nothing of the project (std only) and serves to check the
//! project's reduced (modal, floating-frame) model.
//!
//! # Model
//! A straight uniform rod of solid circular section (A = πd²/4, I = πd⁴/64), initially along
//! +x, meshed with equal elements; each node has the dofs (x, y, θ), θ being the absolute angle
//! of the rod's tangent (a plain angle: any number of turns). Its first node A is pinned (its
//! translations prescribed, its rotation free) to a fixed point or to the pin of a rigid crank
//! of prescribed motion ([`Drive`]); its last node B is pinned ([`FarEnd::Pinned`]), pinned to
//! a slider on the x-axis (y held, x free, carrying the slider's mass and possibly a constant
//! axial force: [`FarEnd::OnAxis`]) or free. Prescribed and held dofs are eliminated (no
//! penalty); there is no gravity and no damping other than the integrator's.
//!
//! # Element (Crisfield 1991, vol. 1, ch. 7; Battini 2002)
//! Co-rotational: the element's frame follows its chord, exactly (angle α of the chord, length
//! l). In that frame the element is the linear Euler–Bernoulli element: axial displacement
//! u = l − l0, end rotations relative to the chord θ̄ᵢ = θᵢ − α (wrapped to (−π, π]), axial
//! force N = EA u / l0, end moments M₁ = EI/l0 (4θ̄₁ + 2θ̄₂), M₂ = EI/l0 (2θ̄₁ + 4θ̄₂).
//! Internal forces f = r N + (e₃ − z/l) M₁ + (e₆ − z/l) M₂ with r = (−c, −s, 0, c, s, 0),
//! z = (s, −c, 0, −s, c, 0), and the consistent tangent K = Bᵀ K_l B + N z zᵀ / l
//! + (M₁ + M₂)(r zᵀ + z rᵀ) / l². Rigid motions of any size give no strain.
//!
//! # Mass
//! Consistent, from the element's cubic Hermite centreline written with the nodal tangent
//! vectors, r(ξ) = h₀₀ p₁ + h₀₁ p₂ + l0 (h₁₀ t(θ₁) + h₁₁ t(θ₂)), t(θ) = (cos θ, sin θ): the
//! kinetic energy ½∫ρA|ṙ|² is exactly invariant under rigid motions of any size, and for small
//! rotations it is the classical consistent beam mass (ρA l0 / 420 [156, 22l0, 54, −13l0, …]),
//! whose bending frequencies converge as h⁴ (a lumped mass converges as h²). The mass matrix
//! depends on the nodal angles, and the inertia forces ∫ρA r̈ · ∂r/∂q carry the centripetal
//! terms −l0 θ̇² t(θ); both enter Newton's iteration matrix exactly. The rotary inertia of the
//! section, ρI l0 / 2, is lumped at each end of an element (a Rayleigh beam: it lowers the
//! first pinned–pinned frequency by 0.012 % for the steel rod). The slider's mass adds to node
//! B's x-translation.
//!
//! # Integrator
//! Generalised-α (Chung & Hulbert 1993) in the form of Arnold & Brüls (2007): the equations of
//! motion hold exactly at every step, with the acceleration-like variable `a` and
//! ρ∞ = [`SPECTRAL_RADIUS`] = 0.9 (mild dissipation of the highest modes, second order);
//! full Newton on the step's nonlinear equations with the exact iteration matrix
//! M + γ' C_t + β' K_t, solved by a banded LU (5 sub- and super-diagonals, partial pivoting),
//! to increments below 1e-12 (translations relative to L, rotations in rad). The crank pin's
//! exact position, velocity and acceleration are imposed at each step; the initial
//! accelerations solve the equations of motion at t = 0.
//!
//! # Verification (tests/corotational_reference.rs; numbers measured with a 10 µs step)
//! - linear limit: the first pinned–pinned period of the steel rod is within 0.3 % of the
//!   Euler–Bernoulli 2π L² / (π² √(EI/ρA)) from 4 elements (−0.38 %, −0.013 %, +0.011 % with
//!   2, 4, 8 elements); from the Rayleigh beam's (the exact limit with rotary inertia) the
//!   error is −0.39 %, −0.025 %, −0.0011 %: h⁴ convergence;
//! - large rigid rotation: a free rod spun about A at 50 rad/s for 2.4 turns stays straight
//!   (1e-13 m stiff, 1.3e-8 m steel), its end follows L (cos ωt, sin ωt) (0.37 µm, the
//!   integrator's O(h²) phase error, stiff rod), its mean stretch is the centrifugal
//!   ρω²L³/(3E) (+0.3 %, steel) and its energy holds to 2e-7;
//! - tension stiffening: pulled by P = P_E, ω² = ω₀² (1 + P/P_E) to −0.20 % (16 elements;
//!   −0.65 % with 8: the element's geometric stiffness comes from the chords' rotations only,
//!   O(h²));
//! - foreshortening: statically loaded to L/200 on a roller, the end-to-end shortening is
//!   ½∫w′² to −0.39 % (16 elements), −0.15 % (32): the local linear element misses the
//!   shortening within each element, O(h²);
//! - energy: a free vibration of 2.5 mm between a pin and the slider keeps its energy to
//!   3.7e-7 over 0.1 s (8 elements), and the slider moves in by the first mode's
//!   foreshortening π²a²/(4L) (−0.5 %);
//! - convergence of the steel slider-crank (both drives) between [`STEEL_DISCRETISATION`] and
//!   64 elements at 0.5 µs (below);
//! - rigid limit: with E × 1e6 the slider follows R cos φ + √(L² − R² sin² φ) to 2.4e-11 m.
//!
//! # The steel slider-crank
//! R = 0.152 m, [`Rod::STEEL`] (L = 0.304 m, d = 6 mm, E = 200 GPa, ρ = 7850 kg/m³), slider
//! 0.038 kg; the rod's first pinned–pinned frequency is 808 rad/s, its first axial frequency
//! with the slider ~17 500 rad/s. With [`Drive::Constant`] the start is abrupt (the crank pin
//! accelerates at Rω² from t = 0, the rod is undeformed): it rings the rod axially, ±19 µm at
//! the slider for the whole run (no damping), and resolving that ringing's phase over 0.1 s
//! sets the step. [`STEEL_DISCRETISATION`], 32 elements and 1 µs (3 s a run of 0.1 s in a
//! test build), changes by at most 0.013 % (peak |mid-deflection|), 0.018 % of the peak
//! (histories) and 0.80 µm (slider) against 64 elements at 0.5 µs (Constant), and by 0.008 %,
//! 0.016 % and 0.08 µm (SpinUp, which alone converges to 0.06 % and 0.3 µm already with 16
//! elements at 10 µs). The answers over 0.1 s:
//! - Constant, ω = 150 rad/s: peak mid-deflection +4.888 mm at 5.45 ms; the slider sits short
//!   of the rigid mechanism's by up to 0.223 mm (at 90.6 ms; 32.6, 3.9, 97.3, 114.9 µm at 10,
//!   20, 50, 80 ms);
//! - SpinUp to 150 rad/s in 0.05 s: peak −4.049 mm at 60.9 ms; slider short by up to
//!   0.138 mm (at 60.65 ms; 29.3, 12.0, 132.7, 89.1 µm at 30, 50, 60, 100 ms).
//!
//! The slider's position includes the rod's axial strain: made axially rigid (EA × 1e4), the
//! slider moves by up to 19 µm (SpinUp) and 38 µm (Constant, with the ringing), the
//! mid-deflection by 0.04 % and 0.09 % of its peak.

use std::f64::consts::PI;

/// Spectral radius at infinite frequency ρ∞ of the generalised-α method.
pub const SPECTRAL_RADIUS: f64 = 0.9;
/// Newton stops when the largest increment (translations / L, rotations in rad) is below this.
const NEWTON_TOLERANCE: f64 = 1e-12;
/// Newton iterations allowed per step.
const MAX_NEWTON_ITERATIONS: usize = 30;
/// Sub- and super-diagonals of the iteration matrices (three dofs a node, neighbours coupled).
const HALF_BAND: usize = 5;
/// Stored width of a band row (room for the fill-in of row exchanges).
const BAND_WIDTH: usize = 3 * HALF_BAND + 1;
/// The consistent mass of the cubic Hermite functions (h₀₀, h₁₀, h₀₁, h₁₁) on [0, 1]:
/// ∫ hⱼ hₖ dξ × 420.
const HERMITE_MASS: [[f64; 4]; 4] = [
    [156.0, 22.0, 54.0, -13.0],
    [22.0, 4.0, 13.0, -3.0],
    [54.0, 13.0, 156.0, -22.0],
    [-13.0, -3.0, -22.0, 4.0],
];

/// Straight, uniform rod of solid circular section (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rod {
    /// Length L (m).
    pub length: f64,
    /// Diameter d of the section (m).
    pub diameter: f64,
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
}

impl Rod {
    /// The steel rod of the reference slider-crank: 0.304 m, Ø 6 mm, 200 GPa, 7850 kg/m³.
    pub const STEEL: Rod = Rod {
        length: 0.304,
        diameter: 6.0e-3,
        youngs_modulus: 2.0e11,
        density: 7850.0,
    };

    /// Section area A = πd²/4 (m²).
    pub fn area(&self) -> f64 {
        PI * self.diameter.powi(2) / 4.0
    }

    /// Second moment of area I = πd⁴/64 (m⁴).
    pub fn second_moment(&self) -> f64 {
        PI * self.diameter.powi(4) / 64.0
    }

    /// First bending frequency of the pinned–pinned Euler–Bernoulli rod,
    /// π² √(EI/(ρA)) / L² (rad/s).
    pub fn pinned_frequency(&self) -> f64 {
        let stiffness = self.youngs_modulus * self.second_moment();
        let mass = self.density * self.area();
        PI * PI * (stiffness / mass).sqrt() / self.length.powi(2)
    }

    /// Euler load π² EI / L² (N).
    pub fn euler_load(&self) -> f64 {
        PI * PI * self.youngs_modulus * self.second_moment() / self.length.powi(2)
    }
}

/// Prescribed motion of the crank, starting at angle 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drive {
    /// Constant rate: φ = ω t (ω in rad/s).
    Constant { omega: f64 },
    /// From rest, the rate rises to ω along the cycloidal profile
    /// φ̇ = ω (τ − sin(2πτ)/(2π)), τ = t / duration, then stays ω (rad/s; duration > 0, s).
    SpinUp { omega: f64, duration: f64 },
}

impl Drive {
    /// Crank angle φ (rad), rate φ̇ (rad/s) and acceleration φ̈ (rad/s²) at time t ≥ 0.
    pub fn crank_angle(&self, t: f64) -> [f64; 3] {
        match *self {
            Drive::Constant { omega } => [omega * t, omega, 0.0],
            Drive::SpinUp { omega, duration } if t < duration => {
                let tau = t / duration;
                let (sin, cos) = (2.0 * PI * tau).sin_cos();
                [
                    omega * duration * (tau * tau / 2.0 + (cos - 1.0) / (4.0 * PI * PI)),
                    omega * (tau - sin / (2.0 * PI)),
                    omega / duration * (1.0 - cos),
                ]
            }
            Drive::SpinUp { omega, duration } => {
                [omega * (duration / 2.0 + t - duration), omega, 0.0]
            }
        }
    }
}

/// The slider-crank: rigid crank of prescribed motion about the origin, flexible rod from the
/// crank pin A to the slider B, slider on the x-axis (no gravity).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliderCrank {
    /// Crank length R (m).
    pub crank: f64,
    /// The connecting rod.
    pub rod: Rod,
    /// Slider mass (kg).
    pub slider_mass: f64,
    /// The crank's motion.
    pub drive: Drive,
}

impl SliderCrank {
    /// The steel slider-crank: R = 0.152 m, [`Rod::STEEL`], slider 0.038 kg.
    pub fn steel(drive: Drive) -> Self {
        Self {
            crank: 0.152,
            rod: Rod::STEEL,
            slider_mass: 0.038,
            drive,
        }
    }

    /// Slider position of the rigid mechanism at time t, R cos φ + √(L² − R² sin² φ) (m).
    pub fn rigid_slider_x(&self, t: f64) -> f64 {
        let phi = self.drive.crank_angle(t)[0];
        let (sin, cos) = phi.sin_cos();
        self.crank * cos + (self.rod.length.powi(2) - (self.crank * sin).powi(2)).sqrt()
    }
}

/// Mesh and time step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Discretisation {
    /// Number of equal elements (even: the mid-length point is a node).
    pub elements: usize,
    /// Fixed time step (s).
    pub step: f64,
}

/// The converged discretisation of the steel slider-crank (module docs): 32 elements, 1 µs.
pub const STEEL_DISCRETISATION: Discretisation = Discretisation {
    elements: 32,
    step: 1.0e-6,
};

/// Outputs on the output grid (SI units).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// Times (s).
    pub t: Vec<f64>,
    /// Signed distance of the rod's mid-length node from the chord A–B, positive on the left
    /// of A → B (m).
    pub mid_deflection: Vec<f64>,
    /// x of the rod's last node B (the slider) (m).
    pub slider_x: Vec<f64>,
    /// End-to-end distance |B − A| (m).
    pub rod_chord: Vec<f64>,
    /// Kinetic energy of rod and slider plus the rod's strain energy (J).
    pub energy: Vec<f64>,
}

/// Support of the rod's last node B in the beam problems ([`beam`], [`static_beam`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FarEnd {
    /// Both translations held.
    Pinned,
    /// On the x-axis: y held; x free, carrying a point mass (kg) and pulled along +x by a
    /// constant force (N).
    OnAxis { mass: f64, force: f64 },
    /// No support.
    Free,
}

/// Initial motion of a beam problem; the rod starts straight along +x from the origin,
/// stretched by the far end's force (its static equilibrium).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BeamStart {
    /// Transverse velocity in the first pinned–pinned mode, `mid_velocity` · sin(π s / L)
    /// (m/s), with the matching rotation rates.
    FirstMode { mid_velocity: f64 },
    /// Rigid rotation about A at `rate` (rad/s).
    Spin { rate: f64 },
}

/// A rod pinned at the origin (near end A) with its far end B supported by [`FarEnd`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beam {
    /// The rod.
    pub rod: Rod,
    /// Support of B.
    pub far_end: FarEnd,
    /// Initial motion.
    pub start: BeamStart,
}

/// Static equilibrium of a beam problem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticDeflection {
    /// Mid-length deflection from the chord A–B, positive on the left of A → B (m).
    pub mid_deflection: f64,
    /// End-to-end distance |B − A| (m).
    pub chord: f64,
}

/// Simulates the slider-crank from t = 0 (crank angle 0, rod straight along +x, velocities
/// those of the rigid mechanism) to `t_end`, recording every `output_step` from t = 0.
///
/// # Panics
/// If the element count is odd or zero, if the step or `output_step` is not positive, if
/// `t_end` or `output_step` is not a multiple of the step, or if Newton's iteration fails to
/// converge (a step far too long).
pub fn slider_crank(
    model: &SliderCrank,
    disc: &Discretisation,
    t_end: f64,
    output_step: f64,
) -> History {
    let problem = Problem {
        rod: model.rod,
        elements: disc.elements,
        near: NearEnd::Crank {
            radius: model.crank,
            drive: model.drive,
        },
        far: FarEnd::OnAxis {
            mass: model.slider_mass,
            force: 0.0,
        },
        load: 0.0,
    };
    problem.check();
    let rate = model.drive.crank_angle(0.0)[1];
    let length = model.rod.length;
    let state = problem.straight_state(model.crank, |s| {
        let speed = model.crank * rate;
        ([0.0, speed * (1.0 - s / length)], -speed / length)
    });
    problem.simulate(state, disc.step, t_end, output_step)
}

/// Simulates a beam problem from t = 0 to `t_end`, recording every `output_step`.
///
/// # Panics
/// As [`slider_crank`].
pub fn beam(beam: &Beam, disc: &Discretisation, t_end: f64, output_step: f64) -> History {
    let problem = Problem {
        rod: beam.rod,
        elements: disc.elements,
        near: NearEnd::Fixed,
        far: beam.far_end,
        load: 0.0,
    };
    problem.check();
    let length = problem.stretched_length();
    let state = match beam.start {
        BeamStart::FirstMode { mid_velocity } => problem.straight_state(0.0, |s| {
            let k = PI / length;
            (
                [0.0, mid_velocity * (k * s).sin()],
                mid_velocity * k * (k * s).cos(),
            )
        }),
        BeamStart::Spin { rate } => problem.straight_state(0.0, |s| ([0.0, rate * s], rate)),
    };
    problem.simulate(state, disc.step, t_end, output_step)
}

/// Static equilibrium of a rod pinned at the origin, its far end supported by `far_end`
/// (not free), under a uniform dead load `load` (N/m) along +y, by Newton in five load
/// increments.
///
/// # Panics
/// If the element count is odd or zero, if the far end is free, or if Newton fails.
pub fn static_beam(rod: &Rod, far_end: FarEnd, load: f64, elements: usize) -> StaticDeflection {
    assert!(
        far_end != FarEnd::Free,
        "a free far end has no static equilibrium"
    );
    let problem = Problem {
        rod: *rod,
        elements,
        near: NearEnd::Fixed,
        far: far_end,
        load: 0.0,
    };
    problem.check();
    let mut state = problem.straight_state(0.0, |_| ([0.0; 2], 0.0));
    const INCREMENTS: usize = 5;
    for k in 1..=INCREMENTS {
        let loaded = Problem {
            load: load * k as f64 / INCREMENTS as f64,
            ..problem
        };
        if let Err(message) = loaded.equilibrium(&mut state.q) {
            panic!("static equilibrium at load increment {k}: {message}");
        }
    }
    StaticDeflection {
        mid_deflection: problem.mid_deflection(&state.q),
        chord: problem.chord(&state.q),
    }
}

/// Motion of the rod's first node.
#[derive(Clone, Copy, Debug, PartialEq)]
enum NearEnd {
    /// Pinned at the origin.
    Fixed,
    /// Pinned to the crank pin (R cos φ, R sin φ).
    Crank { radius: f64, drive: Drive },
}

/// A discretised problem.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Problem {
    rod: Rod,
    elements: usize,
    near: NearEnd,
    far: FarEnd,
    /// Uniform dead load along +y (N/m).
    load: f64,
}

/// Section and element constants.
#[derive(Clone, Copy, Debug)]
struct Section {
    /// Undeformed element length (m).
    l0: f64,
    /// EA (N).
    axial: f64,
    /// EI (N m²).
    bending: f64,
    /// ρA (kg/m).
    line_mass: f64,
    /// Rotary inertia lumped at each element end, ρ I l0 / 2 (kg m²).
    rotary: f64,
}

/// Coefficients of the iteration matrix: d(acceleration), d(velocity), d(position) per unit
/// change of the unknown accelerations.
#[derive(Clone, Copy, Debug)]
struct Coefficients {
    acc: f64,
    vel: f64,
    pos: f64,
}

/// Positions, velocities, accelerations and the generalised-α variable `a`, all dofs.
#[derive(Clone, Debug)]
struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    acc: Vec<f64>,
    a: Vec<f64>,
}

impl Problem {
    fn check(&self) {
        assert!(
            self.elements >= 2 && self.elements.is_multiple_of(2),
            "the element count must be even and positive (mid-length node), got {}",
            self.elements
        );
    }

    fn dofs(&self) -> usize {
        3 * (self.elements + 1)
    }

    fn section(&self) -> Section {
        let rod = &self.rod;
        let l0 = rod.length / self.elements as f64;
        Section {
            l0,
            axial: rod.youngs_modulus * rod.area(),
            bending: rod.youngs_modulus * rod.second_moment(),
            line_mass: rod.density * rod.area(),
            rotary: rod.density * rod.second_moment() * l0 / 2.0,
        }
    }

    /// Far end's point mass (kg) and axial force (N).
    fn far_load(&self) -> (f64, f64) {
        match self.far {
            FarEnd::OnAxis { mass, force } => (mass, force),
            FarEnd::Pinned | FarEnd::Free => (0.0, 0.0),
        }
    }

    /// Length of the straight rod in equilibrium with the far end's force.
    fn stretched_length(&self) -> f64 {
        let rod = &self.rod;
        rod.length * (1.0 + self.far_load().1 / (rod.youngs_modulus * rod.area()))
    }

    /// Whether dof i is prescribed (A's translations) or held (B's, per [`FarEnd`]).
    fn held(&self, i: usize) -> bool {
        let far = 3 * self.elements;
        i < 2
            || match self.far {
                FarEnd::Pinned => i == far || i == far + 1,
                FarEnd::OnAxis { .. } => i == far + 1,
                FarEnd::Free => false,
            }
    }

    /// Free dof numbers (`None` for prescribed or held dofs) and their count.
    fn free_dofs(&self) -> (Vec<Option<usize>>, usize) {
        let mut count = 0;
        let map = (0..self.dofs())
            .map(|i| {
                (!self.held(i)).then(|| {
                    count += 1;
                    count - 1
                })
            })
            .collect();
        (map, count)
    }

    /// Straight rod along +x from (x0, 0), stretched by the far force, with the velocity
    /// `(translation, rotation rate)` of the point at distance s from A.
    fn straight_state(&self, x0: f64, velocity: impl Fn(f64) -> ([f64; 2], f64)) -> State {
        let n = self.dofs();
        let mut state = State {
            q: vec![0.0; n],
            v: vec![0.0; n],
            acc: vec![0.0; n],
            a: vec![0.0; n],
        };
        let length = self.stretched_length();
        for node in 0..=self.elements {
            let s = length * node as f64 / self.elements as f64;
            state.q[3 * node] = x0 + s;
            let (translation, rotation) = velocity(s);
            state.v[3 * node] = translation[0];
            state.v[3 * node + 1] = translation[1];
            state.v[3 * node + 2] = rotation;
        }
        state
    }

    /// Sets the prescribed and held dofs' velocities, accelerations (and `a`) at time t, and
    /// the crank pin's position; held positions keep their initial values.
    fn prescribe(&self, t: f64, state: &mut State) {
        for i in (0..self.dofs()).filter(|&i| self.held(i)) {
            state.v[i] = 0.0;
            state.acc[i] = 0.0;
        }
        if let NearEnd::Crank { radius, drive } = self.near {
            let [phi, rate, accel] = drive.crank_angle(t);
            let (sin, cos) = phi.sin_cos();
            state.q[0] = radius * cos;
            state.q[1] = radius * sin;
            state.v[0] = -radius * sin * rate;
            state.v[1] = radius * cos * rate;
            state.acc[0] = -radius * (cos * rate * rate + sin * accel);
            state.acc[1] = radius * (cos * accel - sin * rate * rate);
        }
        for i in (0..self.dofs()).filter(|&i| self.held(i)) {
            state.a[i] = state.acc[i];
        }
    }

    fn mid_deflection(&self, q: &[f64]) -> f64 {
        let (a, b, m) = (0, 3 * self.elements, 3 * (self.elements / 2));
        let (ex, ey) = (q[b] - q[a], q[b + 1] - q[a + 1]);
        let chord = ex.hypot(ey);
        (ex * (q[m + 1] - q[a + 1]) - ey * (q[m] - q[a])) / chord
    }

    fn chord(&self, q: &[f64]) -> f64 {
        let b = 3 * self.elements;
        (q[b] - q[0]).hypot(q[b + 1] - q[1])
    }

    /// Kinetic energy of rod and far-end mass plus strain energy (J).
    fn energy(&self, q: &[f64], v: &[f64]) -> f64 {
        let section = self.section();
        let mut total = 0.0;
        for e in 0..self.elements {
            let q6 = element_slice(q, e);
            let v6 = element_slice(v, e);
            total += kinetic_energy(&section, &q6, &v6);
            let mut f = [0.0; 6];
            let mut k = [[0.0; 6]; 6];
            total += internal_forces(&section, &q6, 0.0, &mut f, &mut k);
        }
        let b = 3 * self.elements;
        total + 0.5 * self.far_load().0 * (v[b].powi(2) + v[b + 1].powi(2))
    }

    /// Residual (inertia + internal − external forces) of all dofs into `residual`, and its
    /// Jacobian with respect to the free accelerations into `jacobian`.
    fn assemble(
        &self,
        state: &State,
        coefficients: Coefficients,
        free: &[Option<usize>],
        residual: &mut [f64],
        jacobian: &mut BandMatrix,
    ) {
        let section = self.section();
        residual.fill(0.0);
        jacobian.clear();
        for e in 0..self.elements {
            let q6 = element_slice(&state.q, e);
            let v6 = element_slice(&state.v, e);
            let acc6 = element_slice(&state.acc, e);
            let mut f = [0.0; 6];
            let mut k = [[0.0; 6]; 6];
            internal_forces(&section, &q6, coefficients.pos, &mut f, &mut k);
            inertia_forces(&section, &q6, &v6, &acc6, coefficients, &mut f, &mut k);
            dead_load(&section, self.load, &q6, coefficients.pos, &mut f, &mut k);
            for i in 0..6 {
                residual[3 * e + i] += f[i];
                let Some(row) = free[3 * e + i] else { continue };
                for j in 0..6 {
                    if let Some(column) = free[3 * e + j] {
                        jacobian.add(row, column, k[i][j]);
                    }
                }
            }
        }
        let b = 3 * self.elements;
        let (mass, force) = self.far_load();
        residual[b] += mass * state.acc[b] - force;
        if let Some(row) = free[b] {
            jacobian.add(row, row, mass * coefficients.acc);
        }
    }

    /// Static equilibrium by Newton from `q` (velocities and accelerations zero).
    fn equilibrium(&self, q: &mut [f64]) -> Result<(), String> {
        let n = self.dofs();
        let (free, count) = self.free_dofs();
        let mut state = State {
            q: q.to_vec(),
            v: vec![0.0; n],
            acc: vec![0.0; n],
            a: vec![0.0; n],
        };
        let coefficients = Coefficients {
            acc: 0.0,
            vel: 0.0,
            pos: 1.0,
        };
        let mut residual = vec![0.0; n];
        let mut jacobian = BandMatrix::new(count);
        let mut rhs = vec![0.0; count];
        for _ in 0..MAX_NEWTON_ITERATIONS {
            self.assemble(&state, coefficients, &free, &mut residual, &mut jacobian);
            gather(&free, &residual, &mut rhs);
            jacobian.solve(&mut rhs)?;
            let mut largest: f64 = 0.0;
            for (i, f) in free.iter().enumerate() {
                if let Some(f) = *f {
                    state.q[i] += rhs[f];
                    largest = largest.max(rhs[f].abs() / self.scale(i));
                }
            }
            if largest <= NEWTON_TOLERANCE {
                q.copy_from_slice(&state.q);
                return Ok(());
            }
        }
        Err(format!(
            "no convergence in {MAX_NEWTON_ITERATIONS} iterations"
        ))
    }

    /// Scale of dof i in the convergence test: L for translations, 1 rad for rotations.
    fn scale(&self, i: usize) -> f64 {
        if i % 3 == 2 { 1.0 } else { self.rod.length }
    }

    fn record(&self, t: f64, state: &State, history: &mut History) {
        history.t.push(t);
        history.mid_deflection.push(self.mid_deflection(&state.q));
        history.slider_x.push(state.q[3 * self.elements]);
        history.rod_chord.push(self.chord(&state.q));
        history.energy.push(self.energy(&state.q, &state.v));
    }

    /// Integrates from `state` at t = 0 to `t_end`.
    fn simulate(&self, mut state: State, step: f64, t_end: f64, output_step: f64) -> History {
        let steps = whole_multiple(t_end, step, "t_end");
        assert!(output_step > 0.0, "the output step must be positive");
        let per_output = whole_multiple(output_step, step, "output_step");
        let mut integrator = Integrator::new(self, step);
        self.prescribe(0.0, &mut state);
        if let Err(message) = integrator.initial_accelerations(&mut state) {
            panic!("initial accelerations: {message}");
        }
        let mut history = History::default();
        self.record(0.0, &state, &mut history);
        for n in 1..=steps {
            let t = n as f64 * step;
            if let Err(message) = integrator.advance(&mut state, t) {
                panic!("step to t = {t} s: {message}");
            }
            if n % per_output == 0 {
                self.record(t, &state, &mut history);
            }
        }
        history
    }
}

/// The integer ratio `value / step`, or a panic naming `what` if it is not one.
fn whole_multiple(value: f64, step: f64, what: &str) -> usize {
    assert!(step > 0.0, "the step must be positive, got {step} s");
    assert!(value >= 0.0, "{what} must not be negative, got {value} s");
    let ratio = (value / step).round();
    assert!(
        (ratio * step - value).abs() <= 1e-6 * step,
        "{what} = {value} s is not a multiple of the step {step} s"
    );
    ratio as usize
}

/// The six dofs of element e.
fn element_slice(all: &[f64], e: usize) -> [f64; 6] {
    let mut out = [0.0; 6];
    out.copy_from_slice(&all[3 * e..3 * e + 6]);
    out
}

/// Free entries of `all`, negated, into `free_values`.
fn gather(free: &[Option<usize>], all: &[f64], free_values: &mut [f64]) {
    for (i, f) in free.iter().enumerate() {
        if let Some(f) = *f {
            free_values[f] = -all[i];
        }
    }
}

/// `x` wrapped to (−π, π].
fn wrap(x: f64) -> f64 {
    x - 2.0 * PI * (x / (2.0 * PI)).round()
}

/// Adds the co-rotational element's internal forces to `f` and `scale` × its tangent stiffness
/// to `k`; returns its strain energy.
fn internal_forces(
    section: &Section,
    q: &[f64; 6],
    scale: f64,
    f: &mut [f64; 6],
    k: &mut [[f64; 6]; 6],
) -> f64 {
    let (dx, dy) = (q[3] - q[0], q[4] - q[1]);
    let l = dx.hypot(dy);
    let (c, s) = (dx / l, dy / l);
    let alpha = dy.atan2(dx);
    let bar1 = wrap(q[2] - alpha);
    let bar2 = wrap(q[5] - alpha);
    let l0 = section.l0;
    let u = l - l0;
    let axial = section.axial / l0;
    let bending = section.bending / l0;
    let normal = axial * u;
    let moment1 = bending * (4.0 * bar1 + 2.0 * bar2);
    let moment2 = bending * (2.0 * bar1 + 4.0 * bar2);
    let r = [-c, -s, 0.0, c, s, 0.0];
    let z = [s, -c, 0.0, -s, c, 0.0];
    let mut b1 = [0.0; 6];
    let mut b2 = [0.0; 6];
    for i in 0..6 {
        b1[i] = -z[i] / l;
        b2[i] = -z[i] / l;
    }
    b1[2] += 1.0;
    b2[5] += 1.0;
    for i in 0..6 {
        f[i] += r[i] * normal + b1[i] * moment1 + b2[i] * moment2;
        for j in 0..6 {
            let material = axial * r[i] * r[j]
                + bending
                    * (4.0 * b1[i] * b1[j]
                        + 2.0 * (b1[i] * b2[j] + b2[i] * b1[j])
                        + 4.0 * b2[i] * b2[j]);
            let geometric = normal * z[i] * z[j] / l
                + (moment1 + moment2) * (r[i] * z[j] + z[i] * r[j]) / (l * l);
            k[i][j] += scale * (material + geometric);
        }
    }
    0.5 * axial * u * u + 2.0 * bending * (bar1 * bar1 + bar1 * bar2 + bar2 * bar2)
}

/// Tangent t(θ) and normal n(θ) of the nodes' rotations.
fn nodal_frames(q: &[f64; 6]) -> [([f64; 2], [f64; 2]); 2] {
    [q[2], q[5]].map(|theta| {
        let (sin, cos) = theta.sin_cos();
        ([cos, sin], [-sin, cos])
    })
}

/// Adds the element's inertia forces ∫ρA r̈ · ∂r/∂q (plus the lumped rotary inertia) to `f`,
/// and their derivative with respect to the accelerations (through `coefficients`) to `k`.
fn inertia_forces(
    section: &Section,
    q: &[f64; 6],
    v: &[f64; 6],
    acc: &[f64; 6],
    coefficients: Coefficients,
    f: &mut [f64; 6],
    k: &mut [[f64; 6]; 6],
) {
    let Coefficients {
        acc: c_acc,
        vel: c_vel,
        pos: c_pos,
    } = coefficients;
    let l0 = section.l0;
    let frames = nodal_frames(q);
    // r̈ = Σ h_slot · amplitude[slot]; slots (p₁, θ₁, p₂, θ₂); tangent: d amplitude / d dofs
    let mut amplitude = [[0.0; 2]; 4];
    let mut tangent = [[[0.0; 6]; 2]; 4];
    for node in 0..2 {
        let (p, th) = (3 * node, 3 * node + 2);
        let (t, n) = frames[node];
        let (rate, accel) = (v[th], acc[th]);
        amplitude[2 * node] = [acc[p], acc[p + 1]];
        tangent[2 * node][0][p] = c_acc;
        tangent[2 * node][1][p + 1] = c_acc;
        for d in 0..2 {
            amplitude[2 * node + 1][d] = l0 * (accel * n[d] - rate * rate * t[d]);
            tangent[2 * node + 1][d][th] = l0
                * (c_acc * n[d]
                    - c_vel * 2.0 * rate * t[d]
                    - c_pos * (accel * t[d] + rate * rate * n[d]));
        }
    }
    let mass = section.line_mass * l0 / 420.0;
    let mut g = [[0.0; 2]; 4];
    let mut dg = [[[0.0; 6]; 2]; 4];
    for j in 0..4 {
        for slot in 0..4 {
            let h = mass * HERMITE_MASS[j][slot];
            for d in 0..2 {
                g[j][d] += h * amplitude[slot][d];
                for col in 0..6 {
                    dg[j][d][col] += h * tangent[slot][d][col];
                }
            }
        }
    }
    for node in 0..2 {
        let (p, th) = (3 * node, 3 * node + 2);
        let (t, n) = frames[node];
        let (gp, gr) = (g[2 * node], g[2 * node + 1]);
        f[p] += gp[0];
        f[p + 1] += gp[1];
        f[th] += l0 * (n[0] * gr[0] + n[1] * gr[1]) + section.rotary * acc[th];
        for col in 0..6 {
            k[p][col] += dg[2 * node][0][col];
            k[p + 1][col] += dg[2 * node][1][col];
            k[th][col] += l0 * (n[0] * dg[2 * node + 1][0][col] + n[1] * dg[2 * node + 1][1][col]);
        }
        k[th][th] += section.rotary * c_acc - c_pos * l0 * (t[0] * gr[0] + t[1] * gr[1]);
    }
}

/// Kinetic energy of the element (consistent translational part and lumped rotary inertia).
fn kinetic_energy(section: &Section, q: &[f64; 6], v: &[f64; 6]) -> f64 {
    let l0 = section.l0;
    let frames = nodal_frames(q);
    let mut amplitude = [[0.0; 2]; 4];
    for node in 0..2 {
        let n = frames[node].1;
        let rate = v[3 * node + 2];
        amplitude[2 * node] = [v[3 * node], v[3 * node + 1]];
        amplitude[2 * node + 1] = [l0 * rate * n[0], l0 * rate * n[1]];
    }
    let mut twice = 0.0;
    for j in 0..4 {
        for slot in 0..4 {
            let dot = amplitude[j][0] * amplitude[slot][0] + amplitude[j][1] * amplitude[slot][1];
            twice += section.line_mass * l0 / 420.0 * HERMITE_MASS[j][slot] * dot;
        }
    }
    twice += section.rotary * (v[2] * v[2] + v[5] * v[5]);
    0.5 * twice
}

/// Subtracts the consistent forces of a uniform dead load `load` (N/m, along +y) from `f`,
/// and `scale` × their derivative from `k` (the nodal moments follow the nodal rotations).
fn dead_load(
    section: &Section,
    load: f64,
    q: &[f64; 6],
    scale: f64,
    f: &mut [f64; 6],
    k: &mut [[f64; 6]; 6],
) {
    if load == 0.0 {
        return;
    }
    let l0 = section.l0;
    let moment = load * l0 * l0 / 12.0;
    let (sin1, cos1) = q[2].sin_cos();
    let (sin2, cos2) = q[5].sin_cos();
    f[1] -= load * l0 / 2.0;
    f[4] -= load * l0 / 2.0;
    f[2] -= moment * cos1;
    f[5] += moment * cos2;
    k[2][2] += scale * moment * sin1;
    k[5][5] -= scale * moment * sin2;
}

/// The generalised-α method (Arnold & Brüls form) on a problem.
struct Integrator<'a> {
    problem: &'a Problem,
    step: f64,
    alpha_m: f64,
    alpha_f: f64,
    beta: f64,
    gamma: f64,
    free: Vec<Option<usize>>,
    residual: Vec<f64>,
    rhs: Vec<f64>,
    jacobian: BandMatrix,
}

impl<'a> Integrator<'a> {
    fn new(problem: &'a Problem, step: f64) -> Self {
        let rho = SPECTRAL_RADIUS;
        let alpha_m = (2.0 * rho - 1.0) / (rho + 1.0);
        let alpha_f = rho / (rho + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        let (free, count) = problem.free_dofs();
        Self {
            problem,
            step,
            alpha_m,
            alpha_f,
            beta: 0.25 * (gamma + 0.5).powi(2),
            gamma,
            free,
            residual: vec![0.0; problem.dofs()],
            rhs: vec![0.0; count],
            jacobian: BandMatrix::new(count),
        }
    }

    /// The Newton increment of the free accelerations at `state` (into `rhs`): the residual of
    /// the equations of motion and their Jacobian for the step's `coefficients`, solved.
    fn newton_increment(
        &mut self,
        state: &State,
        coefficients: Coefficients,
    ) -> Result<(), String> {
        self.problem.assemble(
            state,
            coefficients,
            &self.free,
            &mut self.residual,
            &mut self.jacobian,
        );
        gather(&self.free, &self.residual, &mut self.rhs);
        self.jacobian.solve(&mut self.rhs)
    }

    /// Solves the equations of motion at the current state for the free accelerations
    /// (linear in them); sets `a` = accelerations.
    fn initial_accelerations(&mut self, state: &mut State) -> Result<(), String> {
        for (i, f) in self.free.iter().enumerate() {
            if f.is_some() {
                state.acc[i] = 0.0;
            }
        }
        let coefficients = Coefficients {
            acc: 1.0,
            vel: 0.0,
            pos: 0.0,
        };
        self.newton_increment(state, coefficients)?;
        for (i, f) in self.free.iter().enumerate() {
            if let Some(f) = *f {
                state.acc[i] = self.rhs[f];
            }
        }
        state.a.copy_from_slice(&state.acc);
        Ok(())
    }

    /// One step to time `t` (the state is at t − step), by Newton on the accelerations.
    fn advance(&mut self, state: &mut State, t: f64) -> Result<(), String> {
        let h = self.step;
        let ratio = (1.0 - self.alpha_f) / (1.0 - self.alpha_m);
        let coefficients = Coefficients {
            acc: 1.0,
            vel: h * self.gamma * ratio,
            pos: h * h * self.beta * ratio,
        };
        let old = state.clone();
        self.problem.prescribe(t, state);
        for _ in 0..MAX_NEWTON_ITERATIONS {
            self.update(&old, state);
            self.newton_increment(state, coefficients)?;
            let mut largest: f64 = 0.0;
            for (i, f) in self.free.iter().enumerate() {
                if let Some(f) = *f {
                    state.acc[i] += self.rhs[f];
                    let increment = coefficients.pos * self.rhs[f];
                    largest = largest.max(increment.abs() / self.problem.scale(i));
                }
            }
            if largest <= NEWTON_TOLERANCE {
                self.update(&old, state);
                return Ok(());
            }
        }
        Err(format!(
            "Newton did not converge in {MAX_NEWTON_ITERATIONS} iterations"
        ))
    }

    /// The free dofs' `a`, positions and velocities from their accelerations.
    fn update(&self, old: &State, state: &mut State) {
        let h = self.step;
        let (am, af) = (self.alpha_m, self.alpha_f);
        for (i, f) in self.free.iter().enumerate() {
            if f.is_none() {
                continue;
            }
            let a = ((1.0 - af) * state.acc[i] + af * old.acc[i] - am * old.a[i]) / (1.0 - am);
            state.a[i] = a;
            state.q[i] =
                old.q[i] + h * old.v[i] + h * h * ((0.5 - self.beta) * old.a[i] + self.beta * a);
            state.v[i] = old.v[i] + h * ((1.0 - self.gamma) * old.a[i] + self.gamma * a);
        }
    }
}

/// Square band matrix with [`HALF_BAND`] sub- and super-diagonals, stored by rows (row i holds
/// columns i − HALF_BAND ..= i + 2·HALF_BAND, the extra ones for the fill-in of pivoting).
#[derive(Clone, Debug)]
struct BandMatrix {
    rows: Vec<[f64; BAND_WIDTH]>,
}

impl BandMatrix {
    fn new(n: usize) -> Self {
        Self {
            rows: vec![[0.0; BAND_WIDTH]; n],
        }
    }

    fn clear(&mut self) {
        self.rows.iter_mut().for_each(|r| r.fill(0.0));
    }

    /// Adds `value` at (i, j), |i − j| ≤ HALF_BAND.
    fn add(&mut self, i: usize, j: usize, value: f64) {
        self.rows[i][j + HALF_BAND - i] += value;
    }

    /// Solves A x = b in place of b by Gaussian elimination with partial pivoting
    /// (destroys A).
    fn solve(&mut self, b: &mut [f64]) -> Result<(), String> {
        let n = self.rows.len();
        for k in 0..n {
            let last_row = (k + HALF_BAND).min(n - 1);
            // columns k ..= last_column, at offset `HALF_BAND + column − row` in a row
            let width = (k + 2 * HALF_BAND).min(n - 1) - k + 1;
            let mut pivot = k;
            for i in k + 1..=last_row {
                if self.rows[i][HALF_BAND + k - i].abs()
                    > self.rows[pivot][HALF_BAND + k - pivot].abs()
                {
                    pivot = i;
                }
            }
            if pivot != k {
                let (upper, lower) = self.rows.split_at_mut(pivot);
                let offset = HALF_BAND + k - pivot;
                upper[k][HALF_BAND..HALF_BAND + width]
                    .swap_with_slice(&mut lower[0][offset..offset + width]);
                b.swap(k, pivot);
            }
            let (upper, lower) = self.rows.split_at_mut(k + 1);
            let pivot_row = &upper[k][HALF_BAND..HALF_BAND + width];
            let diagonal = pivot_row[0];
            if diagonal == 0.0 || !diagonal.is_finite() {
                return Err(format!("singular iteration matrix (column {k})"));
            }
            for (r, row) in lower[..last_row - k].iter_mut().enumerate() {
                let offset = HALF_BAND - 1 - r;
                let row = &mut row[offset..offset + width];
                let factor = row[0] / diagonal;
                if factor == 0.0 {
                    continue;
                }
                for (x, p) in row[1..].iter_mut().zip(&pivot_row[1..]) {
                    *x -= factor * p;
                }
                b[k + 1 + r] -= factor * b[k];
            }
        }
        for k in (0..n).rev() {
            let width = (k + 2 * HALF_BAND).min(n - 1) - k + 1;
            let row = &self.rows[k][HALF_BAND..HALF_BAND + width];
            let sum: f64 = row[1..]
                .iter()
                .zip(&b[k + 1..k + width])
                .map(|(a, x)| a * x)
                .sum();
            b[k] = (b[k] - sum) / row[0];
        }
        Ok(())
    }
}
