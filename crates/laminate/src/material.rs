//! The orthotropic material (paper §3.1, Eq. 13).

use nalgebra::{Matrix3, Matrix6};

use crate::LaminateError;

/// A linear elastic orthotropic material in its principal axes (1 = fibre, 2 = in-plane
/// transverse, 3 = through-thickness), with its density.
///
/// Poisson ratios are the major ones, `ν_ij = −ε_j / ε_i` under uniaxial stress `σ_i`; the minor
/// ones follow by reciprocity, `ν_ji = ν_ij E_j / E_i`, so the compliance is symmetric by
/// construction. Voigt order everywhere: `[11, 22, 33, 23, 13, 12]` with engineering shear
/// strains `γ_ij = 2 ε_ij`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrthotropicMaterial {
    e1: f64,
    e2: f64,
    e3: f64,
    g12: f64,
    g13: f64,
    g23: f64,
    nu12: f64,
    nu13: f64,
    nu23: f64,
    density: f64,
}

fn positive(constant: &'static str, value: f64) -> Result<f64, LaminateError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(LaminateError::NotPositive { constant, value })
    }
}

fn finite(constant: &'static str, value: f64) -> Result<f64, LaminateError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(LaminateError::NotFinite { constant, value })
    }
}

impl OrthotropicMaterial {
    /// A validated orthotropic material: moduli (Pa) and density (kg/m³) positive and finite,
    /// Poisson ratios finite, and a positive-definite compliance matrix.
    pub fn new(
        [e1, e2, e3]: [f64; 3],
        [g12, g13, g23]: [f64; 3],
        [nu12, nu13, nu23]: [f64; 3],
        density: f64,
    ) -> Result<Self, LaminateError> {
        let m = Self {
            e1: positive("E1", e1)?,
            e2: positive("E2", e2)?,
            e3: positive("E3", e3)?,
            g12: positive("G12", g12)?,
            g13: positive("G13", g13)?,
            g23: positive("G23", g23)?,
            nu12: finite("nu12", nu12)?,
            nu13: finite("nu13", nu13)?,
            nu23: finite("nu23", nu23)?,
            density: positive("density", density)?,
        };
        // Shear terms are diagonal and positive; the normal 3×3 block decides definiteness.
        let s = m.compliance();
        let normal = s.fixed_view::<3, 3>(0, 0).into_owned();
        if normal.cholesky().is_none() {
            let d1 = s[(0, 0)] * s[(1, 1)] - s[(0, 1)] * s[(0, 1)];
            let reason = if d1 <= 0.0 {
                format!(
                    "nu12 = {nu12} exceeds sqrt(E1/E2) = {:.6}",
                    (e1 / e2).sqrt()
                )
            } else {
                format!(
                    "1 − ν12ν21 − ν23ν32 − ν13ν31 − 2ν21ν32ν13 ≤ 0 with nu12 = {nu12}, \
                     nu13 = {nu13}, nu23 = {nu23}"
                )
            };
            return Err(LaminateError::NotPositiveDefinite { reason });
        }
        Ok(m)
    }

    /// A validated isotropic material (`G = E / (2(1 + ν))`).
    pub fn isotropic(e: f64, nu: f64, density: f64) -> Result<Self, LaminateError> {
        let g = e / (2.0 * (1.0 + nu));
        Self::new([e, e, e], [g, g, g], [nu, nu, nu], density)
    }

    /// The nine elastic constants `[E1, E2, E3, G12, G13, G23, ν12, ν13, ν23]`.
    pub fn constants(&self) -> [f64; 9] {
        [
            self.e1, self.e2, self.e3, self.g12, self.g13, self.g23, self.nu12, self.nu13,
            self.nu23,
        ]
    }

    /// The material with other elastic constants (order of [`Self::constants`]), the density
    /// kept; validated as [`Self::new`].
    pub fn with_constants(&self, c: [f64; 9]) -> Result<Self, LaminateError> {
        Self::new(
            [c[0], c[1], c[2]],
            [c[3], c[4], c[5]],
            [c[6], c[7], c[8]],
            self.density,
        )
    }

    /// The material with another density (kg/m³), validated as [`Self::new`].
    pub fn with_density(&self, density: f64) -> Result<Self, LaminateError> {
        let c = self.constants();
        Self::new(
            [c[0], c[1], c[2]],
            [c[3], c[4], c[5]],
            [c[6], c[7], c[8]],
            density,
        )
    }

    /// The derivative of the stiffness `C̄` for a change `dc` of the elastic constants (order
    /// of [`Self::constants`]): `dC̄ = −C̄ dS̄ C̄` on the normal block, `dG` on the shear
    /// diagonal.
    pub fn stiffness_derivative(&self, dc: &[f64; 9]) -> Matrix6<f64> {
        let [e1, e2, e3, _, _, _, n12, n13, n23] = self.constants();
        let [de1, de2, de3, dg12, dg13, dg23, dn12, dn13, dn23] = *dc;
        let mut ds = Matrix3::zeros();
        ds[(0, 0)] = -de1 / (e1 * e1);
        ds[(1, 1)] = -de2 / (e2 * e2);
        ds[(2, 2)] = -de3 / (e3 * e3);
        ds[(0, 1)] = -dn12 / e1 + n12 * de1 / (e1 * e1);
        ds[(0, 2)] = -dn13 / e1 + n13 * de1 / (e1 * e1);
        ds[(1, 2)] = -dn23 / e2 + n23 * de2 / (e2 * e2);
        ds[(1, 0)] = ds[(0, 1)];
        ds[(2, 0)] = ds[(0, 2)];
        ds[(2, 1)] = ds[(1, 2)];
        let c = self.stiffness();
        let cn: Matrix3<f64> = c.fixed_view::<3, 3>(0, 0).into_owned();
        let mut d = Matrix6::zeros();
        d.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-(cn * ds * cn)));
        d[(3, 3)] = dg23;
        d[(4, 4)] = dg13;
        d[(5, 5)] = dg12;
        d
    }

    /// `[E1, E2, E3]` (Pa).
    pub fn young_moduli(&self) -> [f64; 3] {
        [self.e1, self.e2, self.e3]
    }
    /// `[G12, G13, G23]` (Pa).
    pub fn shear_moduli(&self) -> [f64; 3] {
        [self.g12, self.g13, self.g23]
    }
    /// Major Poisson ratios `[ν12, ν13, ν23]`.
    pub fn poisson_ratios(&self) -> [f64; 3] {
        [self.nu12, self.nu13, self.nu23]
    }
    /// Density (kg/m³).
    pub fn density(&self) -> f64 {
        self.density
    }

    /// The 6×6 compliance `S̄` in material axes (1/Pa), `ε = S̄ σ`.
    pub fn compliance(&self) -> Matrix6<f64> {
        let mut s = Matrix6::zeros();
        s[(0, 0)] = 1.0 / self.e1;
        s[(1, 1)] = 1.0 / self.e2;
        s[(2, 2)] = 1.0 / self.e3;
        s[(0, 1)] = -self.nu12 / self.e1;
        s[(0, 2)] = -self.nu13 / self.e1;
        s[(1, 2)] = -self.nu23 / self.e2;
        s[(1, 0)] = s[(0, 1)];
        s[(2, 0)] = s[(0, 2)];
        s[(2, 1)] = s[(1, 2)];
        s[(3, 3)] = 1.0 / self.g23;
        s[(4, 4)] = 1.0 / self.g13;
        s[(5, 5)] = 1.0 / self.g12;
        s
    }

    /// The 6×6 stiffness `C̄` in material axes (Pa), Eq. (13): `σ = C̄ ε`.
    pub fn stiffness(&self) -> Matrix6<f64> {
        let s = self.compliance();
        // The normal block is positive definite (checked at construction).
        let normal: Matrix3<f64> = s.fixed_view::<3, 3>(0, 0).into_owned();
        let c_normal = normal
            .cholesky()
            .expect("compliance validated positive definite at construction")
            .inverse();
        let mut c = Matrix6::zeros();
        c.fixed_view_mut::<3, 3>(0, 0).copy_from(&c_normal);
        c[(3, 3)] = self.g23;
        c[(4, 4)] = self.g13;
        c[(5, 5)] = self.g12;
        c
    }
}
