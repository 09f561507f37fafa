//! Rotation of the stiffness to other axes (Eqs. 14–15, 50), plane-stress reduction and the
//! transverse-shear pair.

use nalgebra::{Matrix2, Matrix3, Matrix6};
use sens::Scalar;

/// The rotation matrix `R` whose columns are the material axes 1, 2, 3 expressed in the laminate
/// axes x, y, z, for a ply whose fibre direction is at angle `theta` (radians) from the x axis,
/// measured about the normal z.
pub fn rotation_about_normal<S: Scalar>(theta: S) -> Matrix3<S> {
    let (s, c) = theta.sin_cos();
    let z = S::zero();
    let o = S::one();
    Matrix3::new(c, -s, z, s, c, z, z, z, o)
}

/// The Bond stress-transformation matrix `T` of a rotation `R` (columns: the new material axes in
/// the target frame), so that in Voigt order `[11, 22, 33, 23, 13, 12]` the stresses transform as
/// `σ = T σ̄` and, with engineering shear strains, the stiffness as `C = T C̄ Tᵀ` (Eq. 14).
pub fn bond_stress_matrix<S: Scalar>(r: &Matrix3<S>) -> Matrix6<S> {
    // Voigt index → tensor index pair.
    const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];
    let mut t = Matrix6::zeros();
    for (a, &(i, j)) in PAIRS.iter().enumerate() {
        for (b, &(k, l)) in PAIRS.iter().enumerate() {
            // σ_ij = R_ik R_jl σ̄_kl summed over the symmetric pair (k, l).
            t[(a, b)] = if k == l {
                r[(i, k)] * r[(j, l)]
            } else {
                r[(i, k)] * r[(j, l)] + r[(i, l)] * r[(j, k)]
            };
        }
    }
    t
}

/// The stiffness `C = T C̄ Tᵀ` of a material with stiffness `c_bar` in its own axes, seen in the
/// frame in which its axes are the columns of `r` (Eqs. 14–15).
pub fn rotate_stiffness<S: Scalar>(c_bar: &Matrix6<f64>, r: &Matrix3<S>) -> Matrix6<S> {
    rotate_stiffness_of(&c_bar.map(S::from_f64), r)
}

/// [`rotate_stiffness`] of a material stiffness in the same scalar (e.g. a dual `C̄` whose
/// tangents are derivatives with respect to material constants).
pub fn rotate_stiffness_of<S: Scalar>(c_bar: &Matrix6<S>, r: &Matrix3<S>) -> Matrix6<S> {
    let t = bond_stress_matrix(r);
    t * c_bar * t.transpose()
}

/// Closed-form derivative of `C(θ) = T(θ) C̄ T(θ)ᵀ` for a rotation about the normal (Eq. 50):
/// `dC/dθ = T' C̄ Tᵀ + T C̄ T'ᵀ`. An independent cross-check of the dual-number path.
pub fn rotated_stiffness_angle_derivative(c_bar: &Matrix6<f64>, theta: f64) -> Matrix6<f64> {
    let r = rotation_about_normal(theta);
    let (s, c) = theta.sin_cos();
    let dr = Matrix3::new(-s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0);
    // T is bilinear in R: dT = B(dR, R) + B(R, dR) with B the bilinear form of bond_stress_matrix.
    const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];
    let mut dt = Matrix6::zeros();
    for (a, &(i, j)) in PAIRS.iter().enumerate() {
        for (b, &(k, l)) in PAIRS.iter().enumerate() {
            let term = |p: usize, q: usize| dr[(i, p)] * r[(j, q)] + r[(i, p)] * dr[(j, q)];
            dt[(a, b)] = if k == l {
                term(k, l)
            } else {
                term(k, l) + term(l, k)
            };
        }
    }
    let t = bond_stress_matrix(&r);
    dt * c_bar * t.transpose() + t * c_bar * dt.transpose()
}

/// Plane-stress reduced stiffness `Q̄` (3×3, order `[xx, yy, xy]`, engineering shear) from a 3-D
/// stiffness rotated about the normal: `Q̄_ij = C_ij − C_i3 C_3j / C_33` for `i, j ∈ {1, 2, 6}`
/// (the condition `σ_zz = 0`; a rotation about the normal leaves `σ_zz` uncoupled from the
/// transverse shears).
pub fn plane_stress<S: Scalar>(c: &Matrix6<S>) -> Matrix3<S> {
    const IDX: [usize; 3] = [0, 1, 5];
    let mut q = Matrix3::zeros();
    for (a, &i) in IDX.iter().enumerate() {
        for (b, &j) in IDX.iter().enumerate() {
            q[(a, b)] = c[(i, j)] - c[(i, 2)] * c[(2, j)] / c[(2, 2)];
        }
    }
    q
}

/// Transverse-shear stiffness of a 3-D stiffness, order `[xz, yz]` (engineering strains
/// `γ_xz, γ_yz`): `[[C55, C54], [C45, C44]]` in Voigt numbering.
pub fn transverse_shear<S: Scalar>(c: &Matrix6<S>) -> Matrix2<S> {
    Matrix2::new(c[(4, 4)], c[(4, 3)], c[(3, 4)], c[(3, 3)])
}
