//! Two-node 3-D Timoshenko beam with a fully coupled 6×6 section stiffness (paper §3.3, Eq. 23).
//!
//! Formulation: the *exact* (flexibility-based) stiffness of a uniform beam segment. Under end
//! loads the section forces are linear along the element, so the flexibility of node 2 relative
//! to a clamped node 1 is `F = ∫₀ᴸ T(s)ᵀ C⁻¹ T(s) ds` (exact with two Gauss points), `K₂₂ = F⁻¹`,
//! and the 12×12 stiffness follows from rigid-body equilibrium, `K = Hᵀ K₂₂ H`. It holds every
//! coupling of the section stiffness (extension–shear–twist–bending) and is free of shear
//! locking by construction. The interior displacement field used for the consistent mass is the
//! exact static field of the same segment (the "interdependent interpolation" of Timoshenko
//! beams, here computed for any coupled section), integrated exactly with four Gauss points.
//!
//! Section convention (shared with `section`): beam axis x₁ from node 1 to node 2; generalised
//! strains `[ε₁₁, γ₁₂, γ₁₃, κ₁, κ₂, κ₃]` with `γ₁₂ = u₂' − θ₃`, `γ₁₃ = u₃' + θ₂`, `κᵢ = θᵢ'`;
//! forces `[F₁, F₂, F₃, M₁, M₂, M₃]`; all referred to the element's node line.

use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3};
use sens::Scalar;

use crate::small::{gauss01, invert, skew};

/// Cross-section properties of a beam, per unit length, in the section axes (x₂, x₃).
#[derive(Clone, Debug, PartialEq)]
pub struct BeamSection<S: Scalar> {
    /// 6×6 stiffness, forces `[F₁,F₂,F₃,M₁,M₂,M₃] = C [ε₁₁,γ₁₂,γ₁₃,κ₁,κ₂,κ₃]`, symmetric
    /// positive definite (N, N·m, N·m²).
    pub stiffness: Matrix6<S>,
    /// Mass per unit length `m = ∫ρ dA` (kg/m).
    pub mass_per_length: S,
    /// Mass centre `(x₂, x₃)` relative to the reference line (m).
    pub mass_centre: [S; 2],
    /// Second mass moments per unit length about the mass centre,
    /// `[∫ρ x̃₃² dA, ∫ρ x̃₂² dA, ∫ρ x̃₂x̃₃ dA]` with `x̃ = x − x_c` (kg·m): the inertia about x₂ and
    /// x₃ and the product; the polar inertia about x₁ is the sum of the first two.
    pub inertia: [S; 3],
}

impl<S: Scalar> BeamSection<S> {
    /// The same section converted to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> BeamSection<Q> {
        BeamSection {
            stiffness: self.stiffness.map(f),
            mass_per_length: f(self.mass_per_length),
            mass_centre: self.mass_centre.map(f),
            inertia: self.inertia.map(f),
        }
    }

    /// An uncoupled section from its diagonal stiffnesses `[EA, GA₂, GA₃, GJ, EI₂, EI₃]` (shear
    /// correction included) and a mass centre on the reference line.
    pub fn diagonal(stiffness: [S; 6], mass_per_length: S, inertia22: S, inertia33: S) -> Self {
        let mut c = Matrix6::zeros();
        for k in 0..6 {
            c[(k, k)] = stiffness[k];
        }
        Self {
            stiffness: c,
            mass_per_length,
            mass_centre: [S::zero(); 2],
            inertia: [inertia22, inertia33, S::zero()],
        }
    }

    /// The 6×6 sectional mass matrix for the reference-line velocities `[u̇; θ̇]` (local axes):
    /// `[[m I, −m[c×]], [m[c×], m[c×]ᵀ[c×] + J_c]]`.
    pub fn mass_matrix(&self) -> Matrix6<S> {
        let m = self.mass_per_length;
        let c = skew([S::zero(), self.mass_centre[0], self.mass_centre[1]]);
        let [i22, i33, i23] = self.inertia;
        let z = S::zero();
        let jc = Matrix3::new(i22 + i33, z, z, z, i22, -i23, z, -i23, i33);
        let mut out = Matrix6::zeros();
        let mi = Matrix3::identity() * m;
        let mc = c * m;
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&mi);
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-mc));
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&mc);
        out.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(c.transpose() * mc + jc));
        out
    }

    /// The rotary inertia per unit length about the reference line, `m[c×]ᵀ[c×] + J_c`.
    pub fn rotary_inertia(&self) -> Matrix3<S> {
        self.mass_matrix().fixed_view::<3, 3>(3, 3).into_owned()
    }
}

impl BeamSection<f64> {
    /// The beam section of a cross-section analysis: its 6×6 stiffness and mass properties about
    /// the section origin, which becomes the beam's reference line (the conventions of `section`
    /// and of this element are the same).
    pub fn from_section(p: &section::SectionProperties) -> Self {
        Self {
            stiffness: p.stiffness,
            mass_per_length: p.mass_per_length,
            mass_centre: p.mass_centre,
            inertia: p.mass_inertia,
        }
    }
}

impl<S: Scalar> BeamSection<S> {
    /// The beam section of a cross-section analysis with its derivatives with respect to the
    /// section's design variables, pushed through the chain rule: `b[v]` is design variable `v`
    /// of `s` as a scalar whose tangents are its derivatives with respect to the caller's
    /// variables, so tangent `k` of every entry is `Σ_v ∂entry/∂b_v · ∂b_v/∂(variable k)`.
    ///
    /// # Panics
    /// If `b` does not have one entry per design variable of `s` (a programming error).
    pub fn from_sensitivities(s: &section::SectionSensitivities, b: &[S]) -> Self {
        assert_eq!(
            b.len(),
            s.derivatives.len(),
            "one scalar per design variable of the section"
        );
        let chain = |value: f64, d: &dyn Fn(&section::SectionProperties) -> f64| {
            let mut t = vec![0.0; S::TANGENTS];
            for (dv, bv) in s.derivatives.iter().zip(b) {
                let g = d(dv);
                if g != 0.0 {
                    for (k, tk) in t.iter_mut().enumerate() {
                        *tk += g * bv.tangent(k);
                    }
                }
            }
            S::from_parts(value, &t)
        };
        let p = &s.properties;
        Self {
            stiffness: Matrix6::from_fn(|i, j| {
                chain(p.stiffness[(i, j)], &|q| q.stiffness[(i, j)])
            }),
            mass_per_length: chain(p.mass_per_length, &|q| q.mass_per_length),
            mass_centre: [
                chain(p.mass_centre[0], &|q| q.mass_centre[0]),
                chain(p.mass_centre[1], &|q| q.mass_centre[1]),
            ],
            inertia: [
                chain(p.mass_inertia[0], &|q| q.mass_inertia[0]),
                chain(p.mass_inertia[1], &|q| q.mass_inertia[1]),
                chain(p.mass_inertia[2], &|q| q.mass_inertia[2]),
            ],
        }
    }
}

/// The element frame: rows are the local axes `e₁` (node 1 → node 2), `e₂`, `e₃` in global
/// coordinates; `e₂` is the part of `orientation` normal to `e₁`.
pub fn beam_frame(
    p1: &Vector3<f64>,
    p2: &Vector3<f64>,
    orientation: &Vector3<f64>,
) -> (f64, Matrix3<f64>) {
    let d = p2 - p1;
    let l = d.norm();
    let e1 = d / l;
    let mut v = orientation - e1 * orientation.dot(&e1);
    if v.norm() < 1e-9 * orientation.norm().max(1.0) {
        // orientation parallel to the axis: pick any normal
        let a = if e1.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        v = a - e1 * a.dot(&e1);
    }
    let e2 = v.normalize();
    let e3 = e1.cross(&e2);
    (
        l,
        Matrix3::from_rows(&[e1.transpose(), e2.transpose(), e3.transpose()]),
    )
}

type M12<S> = SMatrix<S, 12, 12>;
type M6x12<S> = SMatrix<S, 6, 12>;

/// `T_x(s)`: section forces at `s` from a generalised load at station `x` (for `s ≤ x`).
fn transfer<S: Scalar>(arm: f64) -> Matrix6<S> {
    let mut t = Matrix6::identity();
    // M += arm · e₁ × F : M₂ −= arm F₃, M₃ += arm F₂
    t[(4, 2)] = S::from_f64(-arm);
    t[(5, 1)] = S::from_f64(arm);
    t
}

/// Rigid transport of node 1's motion to station `x`: `[u; θ](x) = Rig(x) q₁`.
fn rigid<S: Scalar>(x: f64) -> Matrix6<S> {
    let mut r = Matrix6::identity();
    // u = u₁ − x [e₁×] θ₁ : u₂ += x θ₃, u₃ −= x θ₂
    r[(1, 5)] = S::from_f64(x);
    r[(2, 4)] = S::from_f64(-x);
    r
}

/// `D(x) = ∫₀ˣ T_x(s)ᵀ S T_L(s) ds` (exact: quadratic integrand, two Gauss points).
fn deformation<S: Scalar>(compliance: &Matrix6<S>, x: f64, l: f64) -> Matrix6<S> {
    let mut d = Matrix6::zeros();
    if x <= 0.0 {
        return d;
    }
    for &(g, w) in gauss01(2) {
        let s = g * x;
        d += transfer::<S>(x - s).transpose()
            * compliance
            * transfer::<S>(l - s)
            * S::from_f64(w * x);
    }
    d
}

/// Local-frame element matrices of a uniform segment of length `l`.
pub struct BeamLocal<S: Scalar> {
    /// 12×12 stiffness, dofs `[u₁, θ₁, u₂, θ₂]` in the local frame.
    pub stiffness: M12<S>,
    /// 12×12 consistent mass.
    pub mass: M12<S>,
}

/// Why a beam element could not be formed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BeamError {
    #[error("beam element {element}: the section stiffness is singular")]
    SingularSection { element: usize },
    #[error("beam element {element}: zero length")]
    ZeroLength { element: usize },
    #[error(
        "beam element {element}: the planar analysis needs the plane's normal along one of the \
         element's section axes (the beam must lie in the plane, its orientation vector in the \
         plane or along the normal)"
    )]
    NotInPlane { element: usize },
}

/// A segment's compliance and the end load at node 2 per local dof, `K₂₂ H` (`H = [−Rig(L),
/// I]`: node 2's motion relative to node 1's rigidly transported, `K₂₂` the stiffness of node 2
/// with node 1 clamped).
struct Clamped<S: Scalar> {
    compliance: Matrix6<S>,
    h: M6x12<S>,
    k22h: M6x12<S>,
}

fn clamped<S: Scalar>(
    section: &BeamSection<S>,
    l: f64,
    element: usize,
) -> Result<Clamped<S>, BeamError> {
    if !(l > 0.0) {
        return Err(BeamError::ZeroLength { element });
    }
    let compliance = invert(&section.stiffness).ok_or(BeamError::SingularSection { element })?;
    // flexibility of node 2 with node 1 clamped
    let f = deformation(&compliance, l, l);
    let fs = (f + f.transpose()) * S::from_f64(0.5);
    let k22 = invert(&fs).ok_or(BeamError::SingularSection { element })?;
    let mut h = M6x12::<S>::zeros();
    let rig_l = rigid::<S>(l);
    h.fixed_view_mut::<6, 6>(0, 0).copy_from(&(-rig_l));
    h.fixed_view_mut::<6, 6>(0, 6)
        .copy_from(&Matrix6::identity());
    Ok(Clamped {
        compliance,
        h,
        k22h: k22 * h,
    })
}

/// The section forces `[F₁, F₂, F₃, M₁, M₂, M₃]` at the stations `x` (m from node 1) of a beam
/// segment of length `l`, each per local dof `[u₁, θ₁, u₂, θ₂]` (6 × 12): the end load at node
/// 2, `K₂₂ H u`, carried to the station, `T(L − x)`. Under end loads these are the segment's
/// exact section forces (the forces constant along it, the moments linear).
pub fn beam_station_forces<S: Scalar>(
    section: &BeamSection<S>,
    l: f64,
    element: usize,
    x: &[f64],
) -> Result<Vec<M6x12<S>>, BeamError> {
    let Clamped { k22h, .. } = clamped(section, l, element)?;
    Ok(x.iter().map(|&x| transfer::<S>(l - x) * k22h).collect())
}

/// Stiffness and consistent mass of a beam segment of length `l` in its local frame.
pub fn beam_local<S: Scalar>(
    section: &BeamSection<S>,
    l: f64,
    element: usize,
) -> Result<BeamLocal<S>, BeamError> {
    let Clamped {
        compliance,
        h,
        k22h,
    } = clamped(section, l, element)?;
    let stiffness = h.transpose() * k22h;
    // consistent mass with the exact static displacement field
    let ms = section.mass_matrix();
    let mut mass = M12::<S>::zeros();
    for &(g, w) in gauss01(4) {
        let x = g * l;
        let mut n = deformation(&compliance, x, l) * k22h;
        let rx = rigid::<S>(x);
        for i in 0..6 {
            for j in 0..6 {
                n[(i, j)] += rx[(i, j)];
            }
        }
        mass += n.transpose() * ms * n * S::from_f64(w * l);
    }
    let stiffness = (stiffness + stiffness.transpose()) * S::from_f64(0.5);
    let mass = (mass + mass.transpose()) * S::from_f64(0.5);
    Ok(BeamLocal { stiffness, mass })
}

/// The section of a beam element in a planar analysis about global `axis` (the plane's
/// normal), with the transverse shear strain out of the plane released: that strain is
/// condensed out of the stiffness with its shear force zero, `C ← C − C[:,s] C[s,:] / C[s,s]`,
/// and kept only on the diagonal, so the in-plane strains no longer couple to it.
///
/// Why: a planar analysis fixes the out-of-plane translation and rotations at every node. On a
/// section whose transverse shear couples to bending in the other plane (an angle-ply tube:
/// `γ₁₃`–`κ₃` and `γ₁₂`–`κ₂`) that would hold the out-of-plane shear at zero everywhere and
/// stiffen in-plane bending up to the uncoupled `EI` (twice the classical value of a [15°]
/// tube), by an amount that grows as the mesh is refined. In the real beam that shear is
/// relieved locally by the section rotation `θ` at a cost of order `EI / (GA L²)` (about 1e-3
/// for the paper's rod) even when the ends are held out of the plane, so its force is zero to
/// that order. Twist and out-of-plane curvature stay fixed: their relief needs end rotations
/// that the joints of a planar mechanism hold.
///
/// `lam` is the element frame ([`beam_frame`]); the normal must be the element's `e₂` or `e₃`
/// axis (a beam along the normal, or skew to it, has no out-of-plane shear of its own).
pub fn release_shear<S: Scalar>(
    section: &BeamSection<S>,
    lam: &Matrix3<f64>,
    axis: usize,
    element: usize,
) -> Result<BeamSection<S>, BeamError> {
    let along = |k: usize| (lam[(k, axis)].abs() - 1.0).abs() <= 1e-9;
    let s = if along(1) {
        1
    } else if along(2) {
        2
    } else {
        return Err(BeamError::NotInPlane { element });
    };
    let c = &section.stiffness;
    let css = c[(s, s)];
    if !(css.value() > 0.0) {
        return Err(BeamError::SingularSection { element });
    }
    let mut out = section.clone();
    for i in 0..6 {
        for j in 0..6 {
            out.stiffness[(i, j)] = if i == s || j == s {
                if i == j { css } else { S::zero() }
            } else {
                c[(i, j)] - c[(i, s)] * c[(s, j)] / css
            };
        }
    }
    Ok(out)
}

/// Rotate a 12×12 local matrix to global axes: `Tᵀ A T` with `T = diag(Λ, Λ, Λ, Λ)`.
pub fn to_global<S: Scalar, const D: usize>(
    a: &SMatrix<S, D, D>,
    lambda: &Matrix3<f64>,
) -> SMatrix<S, D, D> {
    let lam = lambda.map(S::from_f64);
    let nb = D / 3;
    let mut out = SMatrix::<S, D, D>::zeros();
    for bi in 0..nb {
        for bj in 0..nb {
            let blk: Matrix3<S> = a.fixed_view::<3, 3>(3 * bi, 3 * bj).into_owned();
            let g = lam.transpose() * blk * lam;
            out.fixed_view_mut::<3, 3>(3 * bi, 3 * bj).copy_from(&g);
        }
    }
    out
}
