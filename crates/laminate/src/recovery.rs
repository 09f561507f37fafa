//! The plies' stresses and strains through the thickness of a laminate at one point of a plate
//! or shell, from its reference-surface strains, curvatures and transverse shear forces
//! (classical laminate theory; docs/failure-criteria.md).

use nalgebra::{Matrix3, Matrix6};
use sens::Scalar;

use crate::PlyStack;
use crate::rotation::{
    bond_stress_matrix, plane_stress, rotate_stiffness_of, rotation_about_normal,
};

/// Where through a ply a [`PlyPoint`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyPosition {
    Bottom,
    Middle,
    Top,
}

/// A ply's stress and strain at one height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlyPoint<S: Scalar> {
    /// The ply (from 0, bottom first).
    pub ply: usize,
    pub position: PlyPosition,
    /// Height above the reference surface (m).
    pub z: S,
    /// Stress in the ply's material axes, Voigt `[11, 22, 33, 23, 13, 12]` (Pa).
    pub stress: [S; 6],
    /// Strain in the ply's material axes (engineering shear).
    pub strain: [S; 6],
}

/// The deformation of a laminate at a point: reference-surface strains `ε⁰` and curvatures
/// `κ` (laminate axes, order `[xx, yy, xy]`, engineering shear `γ_xy`, twisting curvature
/// `2κ_xy`), and the transverse shear forces `[Q_x, Q_y]` (N/m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlateState<S: Scalar> {
    pub membrane: [S; 3],
    pub curvature: [S; 3],
    pub shear_forces: [S; 2],
}

impl<S: Scalar> PlyStack<S> {
    /// The deformation under the resultants `[Nx, Ny, Nxy, Mx, My, Mxy]` (N/m, N) and the
    /// shear forces `[Qx, Qy]` (N/m): `[ε⁰; κ] = [A B; B D]⁻¹ [N; M]`.
    pub fn state_under(&self, resultants: [S; 6], shear_forces: [S; 2]) -> PlateState<S> {
        let c_bar: Vec<Matrix6<S>> = (self.plies().iter())
            .map(|p| p.material.stiffness().map(S::from_f64))
            .collect();
        self.state_under_with_materials(resultants, shear_forces, &c_bar)
    }

    /// [`Self::state_under`] with each ply's material stiffness `C̄` given (as
    /// [`Self::ply_points_with_materials`]).
    pub fn state_under_with_materials(
        &self,
        resultants: [S; 6],
        shear_forces: [S; 2],
        c_bar: &[Matrix6<S>],
    ) -> PlateState<S> {
        let k = self.stiffness_with_materials(c_bar, &vec![S::zero(); c_bar.len()]);
        let e = solve6(&k.abd(), resultants);
        PlateState {
            membrane: [e[0], e[1], e[2]],
            curvature: [e[3], e[4], e[5]],
            shear_forces,
        }
    }

    /// Each ply's stress and strain at its bottom, middle and top under `state`.
    ///
    /// In-plane: `σ = Q̄ₖ (ε⁰ + z κ)` (plane stress, `σ33 = 0`). Transverse shear: by the
    /// equilibrium of the in-plane stresses, `τ_xz(z) = −∫ (∂σ_xx/∂x + ∂σ_xy/∂y) dz`,
    /// `τ_yz(z) = −∫ (∂σ_xy/∂x + ∂σ_yy/∂y) dz` from the bottom face, with the stresses'
    /// gradients those of the moment gradients the shear forces carry in cylindrical bending
    /// along each axis (`∂M_x/∂x = Q_x`, `∂M_y/∂y = Q_y`, the membrane forces and twisting
    /// moment constant): exact, piecewise quadratic, zero on both faces, `3Q/2h` at the middle
    /// of a homogeneous plate. Strains from the stresses by each ply's compliance.
    pub fn ply_points(&self, state: &PlateState<S>) -> Vec<PlyPoint<S>> {
        let c_bar: Vec<Matrix6<S>> = (self.plies().iter())
            .map(|p| p.material.stiffness().map(S::from_f64))
            .collect();
        self.ply_points_with_materials(state, &c_bar)
    }

    /// [`Self::ply_points`] with each ply's material stiffness `C̄` (material axes) given, e.g.
    /// duals whose tangents are derivatives with respect to material constants (as
    /// [`Self::stiffness_with_materials`]); the strains are the stresses through the inverse of
    /// the given `C̄`.
    pub fn ply_points_with_materials(
        &self,
        state: &PlateState<S>,
        c_bar: &[Matrix6<S>],
    ) -> Vec<PlyPoint<S>> {
        assert_eq!(c_bar.len(), self.plies().len(), "one stiffness per ply");
        let z = self.interfaces();
        let k = self.stiffness_with_materials(c_bar, &vec![S::zero(); c_bar.len()]);
        let abd = k.abd();
        // strain gradients of a unit moment gradient along x (M_x) and y (M_y)
        let gradient = |row: usize, q: S| -> [S; 6] {
            let mut r = [S::zero(); 6];
            r[row] = q;
            solve6(&abd, r)
        };
        let (gx, gy) = (
            gradient(3, state.shear_forces[0]),
            gradient(4, state.shear_forces[1]),
        );
        let c: Vec<Matrix6<S>> = (self.plies().iter().zip(c_bar))
            .map(|(p, c)| rotate_stiffness_of(c, &rotation_about_normal(p.angle)))
            .collect();
        let q: Vec<Matrix3<S>> = c.iter().map(plane_stress).collect();
        // ∫ from z0 to z1 of Q̄ (a + z b) dz = Q̄ (a (z1 − z0) + b (z1² − z0²)/2)
        let integral = |q: &Matrix3<S>, g: &[S; 6], z0: S, z1: S| -> [S; 3] {
            let (h1, h2) = (z1 - z0, (z1 * z1 - z0 * z0) * 0.5);
            let mut g1 = [S::zero(); 6];
            for i in 0..3 {
                g1[i] = g[i] * h1 + g[i + 3] * h2;
            }
            std::array::from_fn(|i| q[(i, 0)] * g1[0] + q[(i, 1)] * g1[1] + q[(i, 2)] * g1[2])
        };
        let mut below = [S::zero(); 2];
        let mut out = Vec::with_capacity(3 * self.plies().len());
        for (i, ply) in self.plies().iter().enumerate() {
            let (z0, z1) = (z[i], z[i + 1]);
            let shear_at = |zz: S| -> [S; 2] {
                let (ix, iy) = (integral(&q[i], &gx, z0, zz), integral(&q[i], &gy, z0, zz));
                [below[0] - ix[0] - iy[2], below[1] - ix[2] - iy[1]]
            };
            let to_material = bond_stress_matrix(&rotation_about_normal(ply.angle).transpose());
            for (position, zz) in [
                (PlyPosition::Bottom, z0),
                (PlyPosition::Middle, (z0 + z1) * 0.5),
                (PlyPosition::Top, z1),
            ] {
                let e = [
                    state.membrane[0] + zz * state.curvature[0],
                    state.membrane[1] + zz * state.curvature[1],
                    state.membrane[2] + zz * state.curvature[2],
                ];
                let s: [S; 3] = std::array::from_fn(|r| {
                    q[i][(r, 0)] * e[0] + q[i][(r, 1)] * e[1] + q[i][(r, 2)] * e[2]
                });
                let [txz, tyz] = shear_at(zz);
                let laminate = [s[0], s[1], S::zero(), tyz, txz, s[2]];
                let stress: [S; 6] = std::array::from_fn(|r| {
                    (0..6).fold(S::zero(), |acc, c| acc + to_material[(r, c)] * laminate[c])
                });
                let strain = solve6(&c_bar[i], stress);
                out.push(PlyPoint {
                    ply: i,
                    position,
                    z: zz,
                    stress,
                    strain,
                });
            }
            below = shear_at(z1);
        }
        out
    }
}

/// `a x = b` by Gaussian elimination with partial pivoting on the values.
fn solve6<S: Scalar>(a: &Matrix6<S>, b: [S; 6]) -> [S; 6] {
    let mut m = *a;
    let mut x = b;
    for col in 0..6 {
        let p = (col..6)
            .max_by(|&i, &j| {
                m[(i, col)]
                    .value()
                    .abs()
                    .total_cmp(&m[(j, col)].value().abs())
            })
            .expect("rows remain");
        m.swap_rows(col, p);
        x.swap(col, p);
        for r in col + 1..6 {
            let f = m[(r, col)] / m[(col, col)];
            for c in col..6 {
                let v = m[(col, c)];
                m[(r, c)] -= f * v;
            }
            let v = x[col];
            x[r] -= f * v;
        }
    }
    for col in (0..6).rev() {
        let mut s = x[col];
        for c in col + 1..6 {
            s -= m[(col, c)] * x[c];
        }
        x[col] = s / m[(col, col)];
    }
    x
}
