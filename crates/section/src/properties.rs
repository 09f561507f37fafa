//! Section results: stiffness, compliance, classical stiffness, mass properties and centres.

use nalgebra::{Matrix4, Matrix6, SMatrix};
use sens::Scalar;
use std::ops::Mul;

use crate::error::SectionError;

/// Everything the analysis gives about a section (SI units).
///
/// Ordering of generalised strains `[ε, γ₂, γ₃, κ₁, κ₂, κ₃]` and section forces
/// `[F₁, F₂, F₃, M₁, M₂, M₃]`, all referred to the origin of the section coordinates unless
/// stated otherwise (see the crate docs for the sign conventions). In the derivative entries
/// of [`SectionSensitivities`] every field holds the derivative of the corresponding value
/// (mass properties do not depend on ply angles: their derivatives are zero).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SectionProperties {
    /// 6×6 Timoshenko stiffness `K`, `θ = K ψ` (N, N·m, N·m²), about the origin.
    pub stiffness: Matrix6<f64>,
    /// Its inverse, the compliance `F = K⁻¹`, `ψ = F θ`.
    pub compliance: Matrix6<f64>,
    /// 4×4 classical (Euler–Bernoulli) stiffness, order `[ε, κ₁, κ₂, κ₃]` ↔ `[F₁, M₁, M₂, M₃]`,
    /// about the origin (the shear strains are left free: `F₂ = F₃ = 0`).
    pub classical_stiffness: Matrix4<f64>,
    /// Area of the section (m²).
    pub area: f64,
    /// Mass per unit length (kg/m).
    pub mass_per_length: f64,
    /// Mass centre `(x₂, x₃)` (m).
    pub mass_centre: [f64; 2],
    /// Mass moments of inertia per unit length about the mass centre (kg·m):
    /// `[I₂₂, I₃₃, I₂₃] = [∫ρ x̃₃², ∫ρ x̃₂², ∫ρ x̃₂x̃₃]` with `x̃ = x − mass centre`
    /// (`I₂₂` about the `x₂` axis; the polar inertia is `I₂₂ + I₃₃`).
    pub mass_inertia: [f64; 3],
    /// Tension (elastic) centre: where an axial force causes no bending curvature.
    pub tension_centre: [f64; 2],
    /// Shear centre: where a transverse shear force causes no twist (at a section free of
    /// bending moments).
    pub shear_centre: [f64; 2],
}

/// One named scalar result (see [`SectionProperties::entries`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    pub name: String,
    pub value: f64,
    /// SI unit of the value.
    pub unit: &'static str,
}

impl Entry {
    fn new(name: impl Into<String>, value: f64, unit: &'static str) -> Self {
        Self {
            name: name.into(),
            value,
            unit,
        }
    }
}

/// Values and derivatives with respect to design variables.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SectionSensitivities {
    /// The values.
    pub properties: SectionProperties,
    /// Names of the design variables, in the order of `derivatives`.
    pub variables: Vec<String>,
    /// `derivatives[k]`: every field differentiated with respect to design variable `k`
    /// (per radian).
    pub derivatives: Vec<SectionProperties>,
}

/// A point of the section to which the stiffness may be referred.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReferencePoint {
    Origin,
    /// A fixed point `(x₂, x₃)`.
    Point([f64; 2]),
    TensionCentre,
    ShearCentre,
    MassCentre,
}

impl ReferencePoint {
    fn of(&self, p: &SectionProperties) -> [f64; 2] {
        match *self {
            ReferencePoint::Origin => [0.0, 0.0],
            ReferencePoint::Point(q) => q,
            ReferencePoint::TensionCentre => p.tension_centre,
            ReferencePoint::ShearCentre => p.shear_centre,
            ReferencePoint::MassCentre => p.mass_centre,
        }
    }
}

impl SectionSensitivities {
    /// The 6×6 stiffness referred to `at` and its derivatives, including the motion of the
    /// point itself when it is a centre that moves with the design: with `H(p)` of
    /// [`SectionProperties::stiffness_at`] (affine in `p`),
    /// `d(H K Hᵀ) = H dK Hᵀ + dH K Hᵀ + H K dHᵀ`, `dH = H(dp) − I`.
    pub fn stiffness_about(&self, at: ReferencePoint) -> (Matrix6<f64>, Vec<Matrix6<f64>>) {
        let p = at.of(&self.properties);
        let h = force_shift(p);
        let k = self.properties.stiffness;
        let derivatives = self
            .derivatives
            .iter()
            .map(|d| {
                let dp = match at {
                    ReferencePoint::Origin
                    | ReferencePoint::Point(_)
                    | ReferencePoint::MassCentre => [0.0, 0.0],
                    _ => at.of(d),
                };
                let dh = force_shift(dp) - Matrix6::identity();
                h * d.stiffness * h.transpose() + dh * k * h.transpose() + h * k * dh.transpose()
            })
            .collect();
        (h * k * h.transpose(), derivatives)
    }
}

/// The 6×6 map `θ_P = H θ_O` of section forces about the origin to forces about `p`.
fn force_shift(p: [f64; 2]) -> Matrix6<f64> {
    let [y, z] = p;
    let mut h = Matrix6::identity();
    // M^P = M^O − p × F with p = (0, y, z).
    h[(3, 1)] = z;
    h[(3, 2)] = -y;
    h[(4, 0)] = -z;
    h[(5, 0)] = y;
    h
}

/// The 6×6 stiffness about the origin of a section whose axial and bending stiffnesses
/// `EA`, `EI₂`, `EI₃` act about its tension centre `t` and its shear and torsion stiffnesses
/// `GA₂`, `GA₃`, `GJ` about its shear centre `s`, without couplings there (`diagonal` in the
/// order of the strains: `[EA, GA₂, GA₃, GJ, EI₂, EI₃]`): the strain energy
/// `½ (EA ε_t² + GA₂ γ₂ₛ² + GA₃ γ₃ₛ² + GJ κ₁² + EI₂ κ₂² + EI₃ κ₃²)` with the axial strain at
/// `t`, `ε_t = ε + t₃ κ₂ − t₂ κ₃`, and the shear strains at `s`, `γ₂ₛ = γ₂ − s₃ κ₁`,
/// `γ₃ₛ = γ₃ + s₂ κ₁` (the strains of [`SectionProperties::stiffness_at`] at those points).
pub fn stiffness_from_centres(
    diagonal: [f64; 6],
    tension_centre: [f64; 2],
    shear_centre: [f64; 2],
) -> Matrix6<f64> {
    let [t2, t3] = tension_centre;
    let [s2, s3] = shear_centre;
    // rows: the strains at the centres as functions of the strains at the origin
    let mut g = Matrix6::identity();
    g[(0, 4)] = t3;
    g[(0, 5)] = -t2;
    g[(1, 3)] = -s3;
    g[(2, 3)] = s2;
    g.transpose() * Matrix6::from_diagonal(&nalgebra::Vector6::from(diagonal)) * g
}

impl SectionProperties {
    /// A section given by its properties instead of analysed: the 6×6 `stiffness` about the
    /// origin (symmetric and positive definite, to 1e-9 of its largest entry), the mass per
    /// length, the mass centre and the mass inertias `[I₂₂, I₃₃, I₂₃]` about it (positive
    /// definite). The compliance, the classical stiffness and the centres follow from the
    /// stiffness as for an analysed section; the area is unknown (NaN).
    pub fn given(
        stiffness: Matrix6<f64>,
        mass_per_length: f64,
        mass_centre: [f64; 2],
        mass_inertia: [f64; 3],
    ) -> Result<Self, SectionError> {
        let bad = |what: String| Err(SectionError::InvalidInput(what));
        let finite = stiffness.iter().all(|x| x.is_finite())
            && mass_per_length.is_finite()
            && mass_centre
                .iter()
                .chain(&mass_inertia)
                .all(|x| x.is_finite());
        if !finite {
            return bad("the section's properties must be finite numbers".into());
        }
        let asymmetry = (stiffness - stiffness.transpose()).amax();
        if asymmetry > 1e-9 * stiffness.amax() {
            return bad(format!(
                "the stiffness matrix is not symmetric (entries differ by {asymmetry:e} from \
                 their transposes)"
            ));
        }
        let stiffness = (stiffness + stiffness.transpose()) / 2.0;
        if stiffness.cholesky().is_none() {
            return bad(
                "the stiffness matrix is not positive definite (a section stores energy under \
                 every strain)"
                    .into(),
            );
        }
        let [i22, i33, i23] = mass_inertia;
        if mass_per_length <= 0.0 {
            return bad(format!(
                "mass per length {mass_per_length} must be positive (kg/m)"
            ));
        }
        if !(i22 > 0.0 && i33 > 0.0 && i22 * i33 > i23 * i23) {
            return bad(format!(
                "the mass inertias [{i22}, {i33}, {i23}] must be positive definite (I22 > 0, \
                 I33 > 0, I22 I33 > I23²; kg·m)"
            ));
        }
        let Some(compliance) = stiffness.try_inverse() else {
            return bad("the stiffness matrix cannot be inverted".into());
        };
        let Some(p) = Props::from_compliance(compliance) else {
            return bad("the stiffness matrix cannot be inverted".into());
        };
        Ok(SectionProperties {
            stiffness,
            compliance,
            classical_stiffness: p.classical,
            area: f64::NAN,
            mass_per_length,
            mass_centre,
            mass_inertia,
            tension_centre: p.tension_centre,
            shear_centre: p.shear_centre,
        })
    }

    /// The mass per length, mass centre and inertias `[I₂₂, I₃₃, I₂₃]` about it of a rigid
    /// section's 6×6 mass matrix about the origin (as [`Self::mass_matrix`] writes it): its
    /// translation block `m I`, its coupling block `m [c]ₓ`, its rotation block the inertias
    /// about the origin with the polar one their sum. An error says which part of that
    /// structure the matrix lacks (to 1e-9 of its largest entry).
    pub fn mass_of_matrix(mm: &Matrix6<f64>) -> Result<(f64, [f64; 2], [f64; 3]), SectionError> {
        let bad = |what: &str| {
            Err(SectionError::InvalidInput(format!(
                "the mass matrix is not a rigid section's: {what}"
            )))
        };
        if !mm.iter().all(|x| x.is_finite()) {
            return bad("its entries must be finite numbers");
        }
        let tol = 1e-9 * mm.amax();
        let m = mm[(0, 0)];
        if m <= 0.0 {
            return bad("its mass per length (entry 1,1) must be positive");
        }
        let (c2, c3) = (-mm[(5, 0)] / m, mm[(4, 0)] / m);
        let (j22, j33, j23) = (mm[(4, 4)], mm[(5, 5)], -mm[(4, 5)]);
        let mut rigid = Matrix6::zeros();
        for i in 0..3 {
            rigid[(i, i)] = m;
        }
        let s = nalgebra::Matrix3::new(0.0, -c3, c2, c3, 0.0, 0.0, -c2, 0.0, 0.0) * m;
        rigid.fixed_view_mut::<3, 3>(0, 3).copy_from(&s.transpose());
        rigid.fixed_view_mut::<3, 3>(3, 0).copy_from(&s);
        rigid[(3, 3)] = j22 + j33;
        rigid[(4, 4)] = j22;
        rigid[(5, 5)] = j33;
        rigid[(4, 5)] = -j23;
        rigid[(5, 4)] = -j23;
        if let Some(k) = (0..36).find(|&k| (mm[(k / 6, k % 6)] - rigid[(k / 6, k % 6)]).abs() > tol)
        {
            return bad(&format!(
                "entry ({}, {}) is {:e} where the mass per length {m:e}, the mass centre \
                 ({c2:e}, {c3:e}) m and the inertias of entries (5, 5), (6, 6) and (5, 6) make \
                 it {:e} (the translation block m I, the coupling m [c]x, the polar inertia \
                 (4, 4) the sum of (5, 5) and (6, 6))",
                k / 6 + 1,
                k % 6 + 1,
                mm[(k / 6, k % 6)],
                rigid[(k / 6, k % 6)]
            ));
        }
        Ok((
            m,
            [c2, c3],
            [j22 - m * c3 * c3, j33 - m * c2 * c2, j23 - m * c2 * c3],
        ))
    }

    /// The 6×6 stiffness referred to the point `p` (generalised strains and forces of a beam
    /// whose reference axis passes through `p`): `K_P = H K Hᵀ`.
    pub fn stiffness_at(&self, p: [f64; 2]) -> Matrix6<f64> {
        let h = force_shift(p);
        h * self.stiffness * h.transpose()
    }

    /// The 4×4 classical stiffness referred to the point `p`.
    pub fn classical_stiffness_at(&self, p: [f64; 2]) -> Matrix4<f64> {
        let [y, z] = p;
        let mut h = Matrix4::identity();
        h[(2, 0)] = -z;
        h[(3, 0)] = y;
        h * self.classical_stiffness * h.transpose()
    }

    /// Polar mass moment of inertia per unit length about the mass centre (kg·m).
    pub fn polar_mass_inertia(&self) -> f64 {
        self.mass_inertia[0] + self.mass_inertia[1]
    }

    /// The 6×6 mass matrix per unit length about the origin, conjugate to the velocities
    /// `[u̇₁, u̇₂, u̇₃, φ̇₁, φ̇₂, φ̇₃]` of the section's rigid motion.
    pub fn mass_matrix(&self) -> Matrix6<f64> {
        let m = self.mass_per_length;
        let [c2, c3] = self.mass_centre;
        let [i22, i33, i23] = self.mass_inertia;
        // Inertia about the origin: parallel axes.
        let (j22, j33, j23) = (i22 + m * c3 * c3, i33 + m * c2 * c2, i23 + m * c2 * c3);
        let mut mm = Matrix6::zeros();
        for i in 0..3 {
            mm[(i, i)] = m;
        }
        // Kinetic energy of u = t + φ × p: the coupling block is m [c]ₓᵀ.
        let s = nalgebra::Matrix3::new(0.0, -c3, c2, c3, 0.0, 0.0, -c2, 0.0, 0.0) * m;
        mm.fixed_view_mut::<3, 3>(0, 3).copy_from(&s.transpose());
        mm.fixed_view_mut::<3, 3>(3, 0).copy_from(&s);
        mm[(3, 3)] = j22 + j33;
        mm[(4, 4)] = j22;
        mm[(5, 5)] = j33;
        mm[(4, 5)] = -j23;
        mm[(5, 4)] = -j23;
        mm
    }

    /// Every scalar result with a stable name and its SI unit, in a fixed order: `K11 … K66`
    /// (row-major, 1-based, all 36), `Kc11 … Kc44`, area, mass per length, mass centre,
    /// mass inertias, tension centre, shear centre. For tables, JSON and CSV; for a derivative
    /// entry of [`SectionSensitivities`] append "/rad" to the unit.
    pub fn entries(&self) -> Vec<Entry> {
        const UNIT: [&str; 3] = ["N", "N*m", "N*m^2"];
        let mut v = Vec::with_capacity(36 + 16 + 12);
        for i in 0..6 {
            for j in 0..6 {
                let u = UNIT[usize::from(i >= 3) + usize::from(j >= 3)];
                v.push(Entry::new(
                    format!("K{}{}", i + 1, j + 1),
                    self.stiffness[(i, j)],
                    u,
                ));
            }
        }
        for i in 0..4 {
            for j in 0..4 {
                let u = UNIT[usize::from(i >= 1) + usize::from(j >= 1)];
                v.push(Entry::new(
                    format!("Kc{}{}", i + 1, j + 1),
                    self.classical_stiffness[(i, j)],
                    u,
                ));
            }
        }
        v.push(Entry::new("area", self.area, "m^2"));
        v.push(Entry::new("mass_per_length", self.mass_per_length, "kg/m"));
        v.push(Entry::new("mass_centre_x2", self.mass_centre[0], "m"));
        v.push(Entry::new("mass_centre_x3", self.mass_centre[1], "m"));
        v.push(Entry::new("mass_inertia_22", self.mass_inertia[0], "kg*m"));
        v.push(Entry::new("mass_inertia_33", self.mass_inertia[1], "kg*m"));
        v.push(Entry::new("mass_inertia_23", self.mass_inertia[2], "kg*m"));
        v.push(Entry::new("tension_centre_x2", self.tension_centre[0], "m"));
        v.push(Entry::new("tension_centre_x3", self.tension_centre[1], "m"));
        v.push(Entry::new("shear_centre_x2", self.shear_centre[0], "m"));
        v.push(Entry::new("shear_centre_x3", self.shear_centre[1], "m"));
        v
    }

    pub(crate) fn from_props<S: Scalar>(
        p: &Props<S>,
        mass: &MassProperties<S>,
        f: impl Fn(S) -> f64,
    ) -> Self {
        let (c2, c3) = if mass.m.value() > 0.0 {
            (mass.m2 / mass.m, mass.m3 / mass.m)
        } else {
            (S::zero(), S::zero())
        };
        SectionProperties {
            stiffness: p.stiffness.map(&f),
            compliance: p.compliance.map(&f),
            classical_stiffness: p.classical.map(&f),
            area: f(mass.area),
            mass_per_length: f(mass.m),
            mass_centre: [f(c2), f(c3)],
            mass_inertia: [
                f(mass.m33 - mass.m * c3 * c3),
                f(mass.m22 - mass.m * c2 * c2),
                f(mass.m23 - mass.m * c2 * c3),
            ],
            tension_centre: p.tension_centre.map(&f),
            shear_centre: p.shear_centre.map(&f),
        }
    }
}

/// Integrals `∫ρ`, `∫ρx₂`, … over the section (in any scalar: a dual density carries the
/// derivatives with respect to material densities).
#[derive(Clone, Copy, Debug)]
pub(crate) struct MassProperties<S: Scalar = f64> {
    pub area: S,
    pub m: S,
    pub m2: S,
    pub m3: S,
    pub m22: S,
    pub m33: S,
    pub m23: S,
}

impl<S: Scalar> Default for MassProperties<S> {
    fn default() -> Self {
        let z = S::zero();
        Self {
            area: z,
            m: z,
            m2: z,
            m3: z,
            m22: z,
            m33: z,
            m23: z,
        }
    }
}

impl<R: Scalar> MassProperties<R> {
    /// `Σ_r ρ_r I_r` over regions with unit-density integrals `I_r` (this for one region), in
    /// the scalar of the densities (the integrals are `f64`, or dual when nodes move).
    pub fn scaled_sum<S>(regions: &[MassProperties<R>], density: &[S]) -> MassProperties<S>
    where
        S: Scalar + Mul<R, Output = S> + From<R>,
    {
        let mut out = MassProperties::<S>::default();
        for (i, &rho) in regions.iter().zip(density) {
            out.area += S::from(i.area);
            out.m += rho * i.m;
            out.m2 += rho * i.m2;
            out.m3 += rho * i.m3;
            out.m22 += rho * i.m22;
            out.m33 += rho * i.m33;
            out.m23 += rho * i.m23;
        }
        out
    }
}

/// The stiffness-derived results, generic so that duals carry their derivatives.
pub(crate) struct Props<S: Scalar> {
    pub stiffness: Matrix6<S>,
    pub compliance: Matrix6<S>,
    pub classical: Matrix4<S>,
    pub tension_centre: [S; 2],
    pub shear_centre: [S; 2],
}

/// Inverse of a small matrix of `Scalar`s: the `f64` inverse of the value, refined by one
/// Newton step `K₀(2I − A K₀)`, which is exact to first order in the tangents.
pub(crate) fn inverse<S: Scalar, const D: usize>(a: &SMatrix<S, D, D>) -> Option<SMatrix<S, D, D>> {
    let a0: SMatrix<f64, D, D> = a.map(|x| x.value());
    let k0 = a0.try_inverse()?;
    if !k0.iter().all(|x| x.is_finite()) {
        return None;
    }
    let k = k0.map(S::from_f64);
    let two_i: SMatrix<S, D, D> =
        SMatrix::from_fn(|i, j| S::from_f64(if i == j { 2.0 } else { 0.0 }));
    Some(k * (two_i - a * k))
}

impl<S: Scalar> Props<S> {
    pub fn from_compliance(f: Matrix6<S>) -> Option<Self> {
        let k = inverse(&f)?;
        const CL: [usize; 4] = [0, 3, 4, 5];
        let fc: Matrix4<S> = SMatrix::from_fn(|i, j| f[(CL[i], CL[j])]);
        let classical = inverse(&fc)?;
        // Tension centre: F₁ applied at (y, z) gives M₂ = z F₁, M₃ = −y F₁; no κ₂, κ₃:
        //   F₄₀ + F₄₄ z − F₄₅ y = 0,  F₅₀ + F₅₄ z − F₅₅ y = 0.
        let (a11, a12, b1) = (-f[(4, 5)], f[(4, 4)], -f[(4, 0)]);
        let (a21, a22, b2) = (-f[(5, 5)], f[(5, 4)], -f[(5, 0)]);
        let det = a11 * a22 - a12 * a21;
        let yt = (b1 * a22 - a12 * b2) / det;
        let zt = (a11 * b2 - b1 * a21) / det;
        // Shear centre: (F₂, F₃) at (y, z) gives M₁ = y F₃ − z F₂; no κ₁.
        let ys = -f[(3, 2)] / f[(3, 3)];
        let zs = f[(3, 1)] / f[(3, 3)];
        Some(Props {
            stiffness: k,
            compliance: f,
            classical,
            tension_centre: [yt, zt],
            shear_centre: [ys, zs],
        })
    }
}
