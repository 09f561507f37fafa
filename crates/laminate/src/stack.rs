//! Ply stacks and their plate stiffness (Eqs. 20–21, 49–50).

use nalgebra::{Matrix2, Matrix3, Matrix6};
use sens::Scalar;

use crate::rotation::{
    plane_stress, rotate_stiffness, rotate_stiffness_of, rotated_stiffness_angle_derivative,
    rotation_about_normal, transverse_shear,
};
use crate::{LaminateError, OrthotropicMaterial};

/// The usual shear correction factor of first-order shear deformation theory.
pub const DEFAULT_SHEAR_CORRECTION: f64 = 5.0 / 6.0;

/// One ply: a material, a thickness (m) and a fibre angle (radians, about the laminate normal,
/// from the reference x axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ply<S: Scalar> {
    pub material: OrthotropicMaterial,
    pub thickness: S,
    pub angle: S,
}

impl<S: Scalar> Ply<S> {
    /// The ply's 3-D stiffness in laminate axes, `C = T(θ) C̄ T(θ)ᵀ` (Pa).
    pub fn stiffness(&self) -> Matrix6<S> {
        rotate_stiffness(
            &self.material.stiffness(),
            &rotation_about_normal(self.angle),
        )
    }
}

/// Where the reference surface (z = 0 of A, B, D) lies.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum ReferenceSurface {
    /// The mid-plane of the stack.
    #[default]
    MidPlane,
    /// The bottom face (first ply's lower face).
    Bottom,
    /// The top face (last ply's upper face).
    Top,
    /// A surface this far above the mid-plane (m).
    Offset(f64),
}

/// Plies stacked from bottom (first) to top (last) along the laminate normal z.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyStack<S: Scalar> {
    plies: Vec<Ply<S>>,
    reference: ReferenceSurface,
    shear_correction: f64,
}

/// The plate stiffness and inertia of a ply stack about its reference surface.
///
/// `[N; M] = [A B; B D] [ε⁰; κ]` with in-plane order `[xx, yy, xy]` (engineering shear
/// `γ_xy`, twisting curvature `2κ_xy`), and `[Q_x; Q_y] = A_s [γ_xz; γ_yz]`.
#[derive(Clone, Debug, PartialEq)]
pub struct LaminateStiffness<S: Scalar> {
    /// Extensional stiffness `A` (N/m).
    pub a: Matrix3<S>,
    /// Extension–bending coupling `B` (N).
    pub b: Matrix3<S>,
    /// Bending stiffness `D` (N·m).
    pub d: Matrix3<S>,
    /// Transverse shear stiffness `A_s`, order `[xz, yz]`, correction factor included (N/m).
    pub shear: Matrix2<S>,
    /// Mass per unit area `I0 = ∫ρ dz` (kg/m²).
    pub mass_per_area: S,
    /// First mass moment `I1 = ∫ρ z dz` about the reference surface (kg/m).
    pub first_moment: S,
    /// Rotary inertia per unit area `I2 = ∫ρ z² dz` about the reference surface (kg).
    pub rotary_inertia: S,
    /// Total thickness (m).
    pub thickness: S,
}

impl<S: Scalar> LaminateStiffness<S> {
    /// The same stiffness and inertia converted to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> LaminateStiffness<Q> {
        LaminateStiffness {
            a: self.a.map(f),
            b: self.b.map(f),
            d: self.d.map(f),
            shear: self.shear.map(f),
            mass_per_area: f(self.mass_per_area),
            first_moment: f(self.first_moment),
            rotary_inertia: f(self.rotary_inertia),
            thickness: f(self.thickness),
        }
    }

    /// The 6×6 matrix `[A B; B D]`.
    pub fn abd(&self) -> Matrix6<S> {
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.a);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&self.b);
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&self.b);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.d);
        m
    }

    /// The values only.
    pub fn values(&self) -> LaminateStiffness<f64> {
        let v = |x: &S| x.value();
        LaminateStiffness {
            a: self.a.map(|x| x.value()),
            b: self.b.map(|x| x.value()),
            d: self.d.map(|x| x.value()),
            shear: self.shear.map(|x| x.value()),
            mass_per_area: v(&self.mass_per_area),
            first_moment: v(&self.first_moment),
            rotary_inertia: v(&self.rotary_inertia),
            thickness: v(&self.thickness),
        }
    }

    /// Tangent component `k` of every entry (the derivative with respect to design variable `k`
    /// of the chunk).
    pub fn tangent(&self, k: usize) -> LaminateStiffness<f64> {
        let t = |x: &S| x.tangent(k);
        LaminateStiffness {
            a: self.a.map(|x| x.tangent(k)),
            b: self.b.map(|x| x.tangent(k)),
            d: self.d.map(|x| x.tangent(k)),
            shear: self.shear.map(|x| x.tangent(k)),
            mass_per_area: t(&self.mass_per_area),
            first_moment: t(&self.first_moment),
            rotary_inertia: t(&self.rotary_inertia),
            thickness: t(&self.thickness),
        }
    }
}

impl<S: Scalar> PlyStack<S> {
    /// The same stack with its plies' thicknesses and angles converted to another scalar.
    pub fn map<Q: Scalar>(&self, f: &impl Fn(S) -> Q) -> PlyStack<Q> {
        PlyStack {
            plies: (self.plies.iter())
                .map(|p| Ply {
                    material: p.material,
                    thickness: f(p.thickness),
                    angle: f(p.angle),
                })
                .collect(),
            reference: self.reference,
            shear_correction: self.shear_correction,
        }
    }

    /// A validated stack with the default reference surface (mid-plane) and shear correction 5/6.
    pub fn new(plies: Vec<Ply<S>>) -> Result<Self, LaminateError> {
        Self::with_options(plies, ReferenceSurface::MidPlane, DEFAULT_SHEAR_CORRECTION)
    }

    /// A validated stack with the given reference surface and shear correction factor.
    pub fn with_options(
        plies: Vec<Ply<S>>,
        reference: ReferenceSurface,
        shear_correction: f64,
    ) -> Result<Self, LaminateError> {
        if plies.is_empty() {
            return Err(LaminateError::Empty);
        }
        for (k, p) in plies.iter().enumerate() {
            let t = p.thickness.value();
            if !(t.is_finite() && t > 0.0) {
                return Err(LaminateError::PlyThickness { ply: k, value: t });
            }
            if !p.angle.value().is_finite() {
                return Err(LaminateError::PlyAngle {
                    ply: k,
                    value: p.angle.value(),
                });
            }
        }
        if !(shear_correction > 0.0 && shear_correction <= 1.0) {
            return Err(LaminateError::ShearCorrection {
                value: shear_correction,
            });
        }
        if let ReferenceSurface::Offset(e) = reference
            && !e.is_finite()
        {
            return Err(LaminateError::ReferenceOffset { value: e });
        }
        Ok(Self {
            plies,
            reference,
            shear_correction,
        })
    }

    /// The plies, bottom first.
    pub fn plies(&self) -> &[Ply<S>] {
        &self.plies
    }
    /// The reference surface.
    pub fn reference(&self) -> ReferenceSurface {
        self.reference
    }
    /// The shear correction factor.
    pub fn shear_correction(&self) -> f64 {
        self.shear_correction
    }

    /// Total thickness (m).
    pub fn thickness(&self) -> S {
        self.plies.iter().map(|p| p.thickness).sum()
    }

    /// The ply interface coordinates `z_0 < z_1 < … < z_n` measured from the reference surface.
    pub fn interfaces(&self) -> Vec<S> {
        let h = self.thickness();
        let bottom = match self.reference {
            ReferenceSurface::MidPlane => -(h * 0.5),
            ReferenceSurface::Bottom => S::zero(),
            ReferenceSurface::Top => -h,
            ReferenceSurface::Offset(e) => -(h * 0.5) - e,
        };
        let mut z = Vec::with_capacity(self.plies.len() + 1);
        z.push(bottom);
        let mut acc = bottom;
        for p in &self.plies {
            acc += p.thickness;
            z.push(acc);
        }
        z
    }

    /// A, B, D, transverse shear, mass and rotary inertia (Eqs. 20–21).
    pub fn stiffness(&self) -> LaminateStiffness<S> {
        let c_bar: Vec<Matrix6<S>> = self
            .plies
            .iter()
            .map(|p| p.material.stiffness().map(S::from_f64))
            .collect();
        let density: Vec<S> = self
            .plies
            .iter()
            .map(|p| S::from_f64(p.material.density()))
            .collect();
        self.stiffness_with_materials(&c_bar, &density)
    }

    /// [`Self::stiffness`] with each ply's material stiffness `C̄` (material axes) and density
    /// given, e.g. duals whose tangents are derivatives with respect to material constants.
    pub fn stiffness_with_materials(
        &self,
        c_bar: &[Matrix6<S>],
        density: &[S],
    ) -> LaminateStiffness<S> {
        assert_eq!(c_bar.len(), self.plies.len(), "one stiffness per ply");
        assert_eq!(density.len(), self.plies.len(), "one density per ply");
        let z = self.interfaces();
        let mut out = LaminateStiffness {
            a: Matrix3::zeros(),
            b: Matrix3::zeros(),
            d: Matrix3::zeros(),
            shear: Matrix2::zeros(),
            mass_per_area: S::zero(),
            first_moment: S::zero(),
            rotary_inertia: S::zero(),
            thickness: self.thickness(),
        };
        for (k, ply) in self.plies.iter().enumerate() {
            let (z0, z1) = (z[k], z[k + 1]);
            // H_n = (z1^n − z0^n) / n, Eq. (21)
            let h1 = z1 - z0;
            let h2 = (z1 * z1 - z0 * z0) * 0.5;
            let h3 = (z1 * z1 * z1 - z0 * z0 * z0) * (1.0 / 3.0);
            let c = rotate_stiffness_of(&c_bar[k], &rotation_about_normal(ply.angle));
            let q = plane_stress(&c);
            out.a += q * h1;
            out.b += q * h2;
            out.d += q * h3;
            out.shear += transverse_shear(&c) * (h1 * self.shear_correction);
            let rho = density[k];
            out.mass_per_area += h1 * rho;
            out.first_moment += h2 * rho;
            out.rotary_inertia += h3 * rho;
        }
        out
    }

    /// The same stack with every ply's angle (radians) and thickness (m) replaced, e.g. by dual
    /// numbers seeded with design variables.
    pub fn with_plies<T: Scalar>(
        &self,
        angles: &[T],
        thicknesses: &[T],
    ) -> Result<PlyStack<T>, LaminateError> {
        assert_eq!(angles.len(), self.plies.len(), "one angle per ply");
        assert_eq!(thicknesses.len(), self.plies.len(), "one thickness per ply");
        let plies = self
            .plies
            .iter()
            .zip(angles.iter().zip(thicknesses))
            .map(|(p, (&angle, &thickness))| Ply {
                material: p.material,
                thickness,
                angle,
            })
            .collect();
        PlyStack::with_options(plies, self.reference, self.shear_correction)
    }

    /// The same stack with every ply's angle replaced (radians), e.g. by dual numbers seeded with
    /// design variables; thicknesses are carried over as constants of the new scalar type.
    pub fn with_angles<T: Scalar>(&self, angles: &[T]) -> Result<PlyStack<T>, LaminateError> {
        assert_eq!(angles.len(), self.plies.len(), "one angle per ply");
        let plies = self
            .plies
            .iter()
            .zip(angles)
            .map(|(p, &angle)| Ply {
                material: p.material,
                thickness: T::from_f64(p.thickness.value()),
                angle,
            })
            .collect();
        PlyStack::with_options(plies, self.reference, self.shear_correction)
    }
}

impl PlyStack<f64> {
    /// Closed-form derivative of A, B, D and the transverse shear with respect to a common change
    /// of the angles of the plies `plies` (Eqs. 49–50), independent of the dual-number path.
    /// Mass terms do not depend on angles and are zero.
    pub fn angle_derivative(&self, plies: &[usize]) -> LaminateStiffness<f64> {
        let z = self.interfaces();
        let mut out = LaminateStiffness {
            a: Matrix3::zeros(),
            b: Matrix3::zeros(),
            d: Matrix3::zeros(),
            shear: Matrix2::zeros(),
            mass_per_area: 0.0,
            first_moment: 0.0,
            rotary_inertia: 0.0,
            thickness: 0.0,
        };
        for &k in plies {
            let ply = &self.plies[k];
            let (z0, z1) = (z[k], z[k + 1]);
            let c = ply.stiffness();
            let dc = rotated_stiffness_angle_derivative(&ply.material.stiffness(), ply.angle);
            // d/dθ of Q_ij = C_ij − C_i3 C_3j / C_33
            const IDX: [usize; 3] = [0, 1, 5];
            let mut dq = Matrix3::zeros();
            for (a, &i) in IDX.iter().enumerate() {
                for (b, &j) in IDX.iter().enumerate() {
                    dq[(a, b)] = dc[(i, j)]
                        - (dc[(i, 2)] * c[(2, j)] + c[(i, 2)] * dc[(2, j)]) / c[(2, 2)]
                        + c[(i, 2)] * c[(2, j)] * dc[(2, 2)] / (c[(2, 2)] * c[(2, 2)]);
                }
            }
            out.a += dq * (z1 - z0);
            out.b += dq * ((z1 * z1 - z0 * z0) / 2.0);
            out.d += dq * ((z1.powi(3) - z0.powi(3)) / 3.0);
            out.shear += transverse_shear(&dc) * ((z1 - z0) * self.shear_correction);
        }
        out
    }
}
