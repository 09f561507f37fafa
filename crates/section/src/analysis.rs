//! The Giavotto/BECAS warping analysis: assembly, the two solves with one factorisation, the
//! compliance from the strain energy, and tangents through the same factorisation.
//!
//!
//! The formulation is documented on [`SectionAnalysis`].

use faer::Side;
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use laminate::{bond_stress_matrix, rotate_stiffness, rotate_stiffness_of};
use std::ops::Mul;

use nalgebra::{Matrix6, SMatrix};
use sens::{Dual, LinearSolver, Scalar, SparseCholesky, chunk_ranges};

use crate::element::MAX_NODES;
use crate::mesh::{Region, SectionMesh};
use crate::properties::{MassProperties, Props, SectionProperties, SectionSensitivities};
use crate::{DesignMap, SectionError};

/// Geometry of one integration point, in the scalar `G` of the node coordinates (`f64`, or
/// dual numbers whose tangents are node velocities: a ply thickness as a design variable).
#[derive(Clone, Copy, Debug)]
struct GaussPoint<G = f64> {
    /// Weight × Jacobian determinant (m²).
    w: G,
    /// Position `(x₂, x₃)`.
    x: [G; 2],
    /// Shape functions.
    n: [f64; MAX_NODES],
    /// Their derivatives `[∂/∂x₂, ∂/∂x₃]`.
    dx: [[G; 2]; MAX_NODES],
    /// The parametric directions `[∂x/∂ξ, ∂x/∂η]`.
    dx_dxi: [[G; 2]; 2],
}

const NONE: usize = usize::MAX;

/// A section whose warping system has been assembled, factorised and solved: values are
/// available at once, derivatives for any design map on request (reusing the factorisation).
///
/// # Formulation
/// The displacement of a prismatic beam is a rigid section motion plus a warping field
/// `w(x₂, x₃, x₁) = N(x₂, x₃) u(x₁)` (three components per node). With the generalised strains
/// `ψ = [ε, γ₂, γ₃, κ₁, κ₂, κ₃]` the 3-D strain (Voigt `[11, 22, 33, 23, 13, 12]`) is
///
/// `ε = Z ψ + B N u + S N u'`,
///
/// where `Z` carries the rigid-section strains (`ε₁₁ = ε + x₃κ₂ − x₂κ₃`, `γ₁₂ = γ₂ − x₃κ₁`,
/// `γ₁₃ = γ₃ + x₂κ₁`), `B` the in-plane derivatives and `S` the axial derivative of the warping.
/// Under end loads the section forces `θ = [F₁, F₂, F₃, M₁, M₂, M₃]` vary as `θ' = T θ`
/// (`M₂' = F₃`, `M₃' = −F₂`), and the central (Saint-Venant) solution is `u = X θ`, `ψ = Y θ`,
/// `u' = X₁ θ`, `ψ' = Y₁ θ` with `X₁ = X T`. Equilibrium of the section gives two linear systems
/// with the same symmetric matrix `K = ∫[BN Z]ᵀ Q [BN Z]` (Giavotto et al. 1983; Blasques 2012):
///
/// 1. `∫[BN Z]ᵀ Q (BN X₁ + Z Y₁) = [0; T]`,
/// 2. `∫[BN Z]ᵀ Q (BN X + Z Y + SN X₁) = [∫(SN)ᵀ Q (BN X₁ + Z Y₁); I]`,
///
/// and the compliance is the strain energy per unit length, `F = ∫ εᵀ Q ε` with
/// `ε = Z Y + BN X + SN X₁` per unit force. The stiffness is `F⁻¹`.
///
/// The six rigid-body modes of the warping are removed by pinning six nodal components
/// (`w₁` at three non-collinear nodes, `w₂, w₃` at one node and one more in-plane component at
/// the node farthest from it). The right-hand sides are self-equilibrated, so the reactions at
/// the pins vanish and the compliance does not depend on the choice; the pinned `K` is
/// symmetric positive definite and factorised once by sparse Cholesky (faer).
///
/// Derivatives: with `X̂₁, Ŷ₁, X̂, Ŷ` fixed, the residuals of systems 1 and 2 are evaluated with
/// dual-number ply angles and material stiffnesses (only `Q` depends on them) or dual node
/// coordinates (the Gauss points' positions, weights and shape-function gradients, and the
/// wall frames, depend on them), and their tangents pushed through the same factorisation
/// (the pattern of [`sens::solve_tangents`], batched so that the `6 N` tangent columns of a
/// system go through one multi-column solve of [`sens::LinearSolver`]); the compliance and the
/// mass integrals are then evaluated in duals.
///
/// Conditioning: the Rayleigh quotients of the load cases' solutions bound the smallest
/// eigenvalue of the diagonally scaled matrix, Gershgorin's discs its largest; a section whose
/// estimated condition number would cost its results more than 0.5 % (walls very thin for the
/// section's size) is refused with [`SectionError::IllConditioned`].
pub struct SectionAnalysis {
    model: Model,
    llt: SparseCholesky,
    /// Solutions per unit section force, node-dof-major: `x[(3·node + k)·6 + column]`.
    x1: Vec<f64>,
    y1: [f64; 36],
    x: Vec<f64>,
    y: [f64; 36],
    properties: SectionProperties,
}

/// The discretised section: geometry at the integration points and the dof numbering.
struct Model {
    mesh: SectionMesh,
    gps: Vec<GaussPoint>,
    /// Offsets of each element's integration points in `gps`.
    gp_start: Vec<usize>,
    /// Free-dof index of each nodal component `3·node + k`, or `NONE` (pinned or unused).
    dof: Vec<usize>,
    n_free: usize,
    /// Material stiffness of each region in its principal axes.
    c_bar: Vec<Matrix6<f64>>,
}

/// Analyse a section: the 6×6 stiffness and everything derived from it (see
/// [`SectionProperties`]).
pub fn analyse(mesh: &SectionMesh) -> Result<SectionProperties, SectionError> {
    Ok(SectionAnalysis::new(mesh)?.properties().clone())
}

/// Analyse a section and differentiate every result with respect to the design variables of
/// `design`, `N` variables at a time (the result does not depend on `N`).
pub fn analyse_with_derivatives<const N: usize>(
    mesh: &SectionMesh,
    design: &DesignMap,
) -> Result<SectionSensitivities, SectionError> {
    SectionAnalysis::new(mesh)?.sensitivities::<N>(design)
}

/// The material stiffness the kernel integrates: per region in the ply axes, rotated to the
/// section axes at every integration point (dual stiffnesses, whose rotated copies would not
/// fit in memory), or already in section axes at every integration point of [`Model::gps`].
#[derive(Clone, Copy)]
enum Materials<'a, S> {
    PerRegion(&'a [Matrix6<S>]),
    PerPoint(&'a [Matrix6<S>]),
}

/// Fields of the kernel, per column (6 columns), node-dof-major.
#[derive(Clone, Copy)]
struct Fields<'a, S> {
    u: Option<&'a [S]>,
    u1: Option<&'a [S]>,
    psi: Option<&'a [S; 36]>,
}

/// The nominal solutions `X̂₁, Ŷ₁, X̂, Ŷ` in a fields' scalar.
#[derive(Clone, Copy)]
struct Hats<'a, F> {
    x1: &'a [F],
    y1: &'a [F; 36],
    x: &'a [F],
    y: &'a [F; 36],
}

/// Outputs of the kernel, all accumulated.
struct Outputs<'a, S> {
    /// `∫ (BN)ᵀ σ`, node-dof-major × 6 columns.
    b: Option<&'a mut [S]>,
    /// `∫ (SN)ᵀ σ`.
    s: Option<&'a mut [S]>,
    /// `∫ Zᵀ σ`, `z[i·6 + c]`.
    z: Option<&'a mut [S; 36]>,
    /// `∫ ε_cᵀ σ_d`, `energy[c·6 + d]`.
    energy: Option<&'a mut [S; 36]>,
}

/// Whether `x` is zero with all its tangents (a structural zero that products may skip).
fn is_zero<G: Scalar>(x: G) -> bool {
    x.value() == 0.0 && x.tangents().iter().all(|d| *d == 0.0)
}

/// `T Q Tᵀ` for a Bond matrix in the geometry's scalar and a generic stiffness.
fn congruence<S, G>(t: &Matrix6<G>, q: &Matrix6<S>) -> Matrix6<S>
where
    S: Scalar + Mul<G, Output = S>,
    G: Scalar,
{
    let mut tq = [[S::zero(); 6]; 6];
    for i in 0..6 {
        for j in 0..6 {
            let mut acc = S::zero();
            for k in 0..6 {
                if !is_zero(t[(i, k)]) {
                    acc += q[(k, j)] * t[(i, k)];
                }
            }
            tq[i][j] = acc;
        }
    }
    let mut out = Matrix6::zeros();
    for i in 0..6 {
        for j in 0..6 {
            let mut acc = S::zero();
            for k in 0..6 {
                if !is_zero(t[(j, k)]) {
                    acc += tq[i][k] * t[(j, k)];
                }
            }
            out[(i, j)] = acc;
        }
    }
    out
}

impl SectionAnalysis {
    /// Validate the mesh, assemble and factorise the warping system, solve it and compute the
    /// section properties.
    pub fn new(mesh: &SectionMesh) -> Result<Self, SectionError> {
        mesh.validate()?;
        let mesh = mesh.clone();
        let (gps, gp_start) = geometry(&mesh, &mesh.nodes);
        let (dof, n_free) = dof_map(&mesh);
        let c_bar: Vec<Matrix6<f64>> = mesh
            .regions
            .iter()
            .map(|r| r.material.stiffness())
            .collect();
        let n_tot = n_free + 6;

        let m = Model {
            mesh,
            gps,
            gp_start,
            dof,
            n_free,
            c_bar,
        };
        let q_ply: Vec<Matrix6<f64>> = m
            .mesh
            .regions
            .iter()
            .zip(&m.c_bar)
            .map(|(r, c)| rotate_stiffness(c, &Region::ply_rotation(r.ply_angle)))
            .collect();
        // the material in section axes at every integration point, rotated once for the
        // assembly and the three kernel passes below (dropped with this function)
        let q_points = m.stiffness_at_points(&q_ply);
        let (llt, mut conditioning) = m.factorise(&q_points)?;
        let nd = 3 * m.mesh.nodes.len();

        // System 1: K [X₁; Y₁] = [0; T].
        let mut rhs = vec![0.0; n_tot * 6];
        let t = force_derivative_map();
        for c in 0..6 {
            for i in 0..6 {
                rhs[c * n_tot + n_free + i] = t[i * 6 + c];
            }
        }
        let b = rhs.clone();
        llt.solve_columns(&mut rhs, 6);
        conditioning.observe(&b, &rhs);
        let (x1, y1) = m.unpack(&rhs);

        // System 2: K [X; Y] = [∫(SN)ᵀσ₁ − ∫(BN)ᵀ Q SN X₁; I − ∫Zᵀ Q SN X₁].
        let mut s1 = vec![0.0; nd * 6];
        m.kernel(
            Materials::PerPoint(&q_points),
            &m.gps,
            Fields {
                u: Some(&x1),
                u1: None,
                psi: Some(&y1),
            },
            Outputs {
                b: None,
                s: Some(&mut s1),
                z: None,
                energy: None,
            },
        );
        let mut b2 = vec![0.0; nd * 6];
        let mut z2 = [0.0; 36];
        m.kernel(
            Materials::PerPoint(&q_points),
            &m.gps,
            Fields {
                u: None,
                u1: Some(&x1),
                psi: None,
            },
            Outputs {
                b: Some(&mut b2),
                s: None,
                z: Some(&mut z2),
                energy: None,
            },
        );
        let mut rhs = vec![0.0; n_tot * 6];
        for (g, &f) in m.dof.iter().enumerate() {
            if f != NONE {
                for c in 0..6 {
                    rhs[c * n_tot + f] = s1[g * 6 + c] - b2[g * 6 + c];
                }
            }
        }
        for c in 0..6 {
            for i in 0..6 {
                let id = if i == c { 1.0 } else { 0.0 };
                rhs[c * n_tot + n_free + i] = id - z2[i * 6 + c];
            }
        }
        let b = rhs.clone();
        llt.solve_columns(&mut rhs, 6);
        conditioning.observe(&b, &rhs);
        let condition = conditioning.condition();
        if condition.is_nan() || condition * f64::EPSILON > MAX_ROUNDOFF {
            return Err(SectionError::IllConditioned {
                condition,
                thinness: m.mesh.thinness(),
            });
        }
        let (x, y) = m.unpack(&rhs);

        // Compliance: the strain energy of the central solution per unit force.
        let mut f = [0.0; 36];
        m.kernel(
            Materials::PerPoint(&q_points),
            &m.gps,
            Fields {
                u: Some(&x),
                u1: Some(&x1),
                psi: Some(&y),
            },
            Outputs {
                b: None,
                s: None,
                z: None,
                energy: Some(&mut f),
            },
        );
        let compliance = symmetric(&f);
        let mass = m.mass_properties();
        let props = Props::from_compliance(compliance).ok_or(SectionError::SingularCompliance)?;
        let properties = SectionProperties::from_props(&props, &mass, |s| s);
        Ok(SectionAnalysis {
            model: m,
            llt,
            x1,
            y1,
            x,
            y,
            properties,
        })
    }

    /// The section properties.
    pub fn properties(&self) -> &SectionProperties {
        &self.properties
    }

    /// The mesh analysed.
    pub fn mesh(&self) -> &SectionMesh {
        &self.model.mesh
    }

    /// Number of equations of the warping system (free warping components plus the six
    /// generalised strains).
    pub fn equation_count(&self) -> usize {
        self.model.n_free + 6
    }

    /// The warping displacements `[w₁, w₂, w₃]` at each node for the generalised strains
    /// `strains` (order `[ε, γ₂, γ₃, κ₁, κ₂, κ₃]`), i.e. for the section forces
    /// `θ = K strains` of the central solution. Defined up to the rigid modes removed by the
    /// pins (see the formulation above). Under shear forces the warping also changes along
    /// the beam, at the rate `X₁ θ`.
    pub fn warping(&self, strains: [f64; 6]) -> Vec<[f64; 3]> {
        let theta = self.properties.stiffness * nalgebra::Vector6::from(strains);
        (0..self.model.mesh.nodes.len())
            .map(|n| {
                let mut w = [0.0; 3];
                for (k, wk) in w.iter_mut().enumerate() {
                    *wk = (0..6).map(|c| self.x[(3 * n + k) * 6 + c] * theta[c]).sum();
                }
                w
            })
            .collect()
    }

    /// Values and derivatives of every result with respect to the design variables of
    /// `design`, evaluated `N` variables at a time through the stored factorisation.
    pub fn sensitivities<const N: usize>(
        &self,
        design: &DesignMap,
    ) -> Result<SectionSensitivities, SectionError> {
        assert!(N > 0, "Dual<0> carries no tangents");
        design.validate(&self.model.mesh)?;
        let m = design.variables.len();
        let integrals = self.model.region_mass_integrals(&self.model.gps);
        let mut derivatives = vec![SectionProperties::default(); m];
        for range in chunk_ranges(m, N) {
            // Dual ply angles and material stiffnesses: tangent k of region r is dθ_r/db and
            // dC̄_r/db of variable start + k.
            let mut angles: Vec<Dual<N>> = self
                .model
                .mesh
                .regions
                .iter()
                .map(|r| Dual::constant(r.ply_angle))
                .collect();
            let mut c_bar: Vec<Matrix6<Dual<N>>> = self
                .model
                .c_bar
                .iter()
                .map(|c| c.map(Dual::constant))
                .collect();
            let mut density: Vec<Dual<N>> = self
                .model
                .mesh
                .regions
                .iter()
                .map(|r| Dual::constant(r.material.density()))
                .collect();
            for (k, v) in range.clone().enumerate() {
                for &(r, factor) in &design.variables[v].links {
                    angles[r].d[k] += factor;
                }
                for (r, dc) in &design.variables[v].materials {
                    for (x, d) in c_bar[*r].iter_mut().zip(dc.iter()) {
                        x.d[k] += d;
                    }
                }
                for &(r, drho) in &design.variables[v].densities {
                    density[r].d[k] += drho;
                }
            }
            let moves_nodes = range.clone().any(|v| !design.variables[v].nodes.is_empty());
            let (mass, compliance) = if moves_nodes {
                // Node coordinates carry their velocities dX/db: the geometry, the mass
                // integrals and the (lifted) fields are dual.
                let mut nodes: Vec<[Dual<N>; 2]> = self
                    .model
                    .mesh
                    .nodes
                    .iter()
                    .map(|p| p.map(Dual::constant))
                    .collect();
                for (k, v) in range.clone().enumerate() {
                    for &(n, dx) in &design.variables[v].nodes {
                        nodes[n][0].d[k] += dx[0];
                        nodes[n][1].d[k] += dx[1];
                    }
                }
                let (gps, _) = geometry(&self.model.mesh, &nodes);
                let integrals = self.model.region_mass_integrals(&gps);
                let lift = |x: &[f64]| x.iter().map(|&v| Dual::constant(v)).collect::<Vec<_>>();
                let lift36 = |y: &[f64; 36]| y.map(Dual::constant);
                let hats = Hats {
                    x1: &lift(&self.x1),
                    y1: &lift36(&self.y1),
                    x: &lift(&self.x),
                    y: &lift36(&self.y),
                };
                (
                    MassProperties::scaled_sum(&integrals, &density),
                    self.compliance_dual(&angles, &c_bar, &gps, hats),
                )
            } else {
                let hats = Hats {
                    x1: &self.x1,
                    y1: &self.y1,
                    x: &self.x,
                    y: &self.y,
                };
                (
                    MassProperties::scaled_sum(&integrals, &density),
                    self.compliance_dual(&angles, &c_bar, &self.model.gps, hats),
                )
            };
            let props =
                Props::from_compliance(compliance).ok_or(SectionError::SingularCompliance)?;
            for (k, v) in range.enumerate() {
                derivatives[v] = SectionProperties::from_props(&props, &mass, |s| s.d[k]);
            }
        }
        Ok(SectionSensitivities {
            properties: self.properties.clone(),
            variables: design.variables.iter().map(|v| v.name.clone()).collect(),
            derivatives,
        })
    }

    /// The compliance with dual ply angles, material stiffnesses and (with `G` dual) node
    /// coordinates: tangents of both solves through the factorisation. `hats` are the nominal
    /// solutions in the fields' scalar `F` (`f64`, or dual constants when the geometry is
    /// dual).
    fn compliance_dual<const N: usize, F, G>(
        &self,
        angles: &[Dual<N>],
        c_bar: &[Matrix6<Dual<N>>],
        gps: &[GaussPoint<G>],
        hats: Hats<'_, F>,
    ) -> Matrix6<Dual<N>>
    where
        Dual<N>: Mul<F, Output = Dual<N>> + Mul<G, Output = Dual<N>>,
        F: Scalar + Mul<G, Output = F>,
        G: Scalar,
    {
        let q_ply: Vec<Matrix6<Dual<N>>> = angles
            .iter()
            .zip(c_bar)
            .map(|(&a, c)| rotate_stiffness_of(c, &Region::ply_rotation(a)))
            .collect();
        let nd = 3 * self.model.mesh.nodes.len();
        let zero = Dual::<N>::constant(0.0);
        let t = force_derivative_map();

        // System 1 residual: [0; T] − K(b) [X̂₁; Ŷ₁] (f64 fields, dual stiffness).
        let (x1, y1) = {
            let mut b = vec![zero; nd * 6];
            let mut z = [zero; 36];
            self.model.kernel(
                Materials::PerRegion(&q_ply),
                gps,
                Fields {
                    u: Some(hats.x1),
                    u1: None,
                    psi: Some(hats.y1),
                },
                Outputs {
                    b: Some(&mut b),
                    s: None,
                    z: Some(&mut z),
                    energy: None,
                },
            );
            self.tangent_solve(
                &self.x1,
                &self.y1,
                |g, col| -b[g * 6 + col],
                |i, col| Dual::constant(t[i * 6 + col]) - z[i * 6 + col],
            )
        };

        // System 2 residual: [∫(SN)ᵀσ₁; I] − ∫[BN Z]ᵀ Q (BN X̂ + Z Ŷ + SN X₁), with X₁, Y₁ dual.
        let (x, y) = {
            let mut s1 = vec![zero; nd * 6];
            self.model.kernel(
                Materials::PerRegion(&q_ply),
                gps,
                Fields {
                    u: Some(&x1),
                    u1: None,
                    psi: Some(&y1),
                },
                Outputs {
                    b: None,
                    s: Some(&mut s1),
                    z: None,
                    energy: None,
                },
            );
            let mut b = vec![zero; nd * 6];
            let mut z = [zero; 36];
            self.model.kernel(
                Materials::PerRegion(&q_ply),
                gps,
                Fields {
                    u: Some(hats.x),
                    u1: None,
                    psi: Some(hats.y),
                },
                Outputs {
                    b: Some(&mut b),
                    s: None,
                    z: Some(&mut z),
                    energy: None,
                },
            );
            self.model.kernel(
                Materials::PerRegion(&q_ply),
                gps,
                Fields {
                    u: None,
                    u1: Some(&x1),
                    psi: None,
                },
                Outputs {
                    b: Some(&mut b),
                    s: None,
                    z: Some(&mut z),
                    energy: None,
                },
            );
            self.tangent_solve(
                &self.x,
                &self.y,
                |g, col| s1[g * 6 + col] - b[g * 6 + col],
                |i, col| Dual::constant(if i == col { 1.0 } else { 0.0 }) - z[i * 6 + col],
            )
        };

        let mut f = [Dual::<N>::constant(0.0); 36];
        self.model.kernel(
            Materials::PerRegion(&q_ply),
            gps,
            Fields {
                u: Some(&x),
                u1: Some(&x1),
                psi: Some(&y),
            },
            Outputs {
                b: None,
                s: None,
                z: None,
                energy: Some(&mut f),
            },
        );
        symmetric(&f)
    }

    /// Push the residual tangents of one system through the factorisation: returns the dual
    /// solution in node-dof-major layout. `res_u(g, col)` is the residual of nodal component
    /// `g`, `res_psi(i, col)` that of generalised strain `i`.
    ///
    /// This is [`sens::solve_tangents`] for the six load columns at once: the `6 N` tangent
    /// right-hand sides go through one multi-column triangular solve (much faster than six
    /// separate ones on a large factor).
    fn tangent_solve<const N: usize>(
        &self,
        x_hat: &[f64],
        y_hat: &[f64; 36],
        res_u: impl Fn(usize, usize) -> Dual<N>,
        res_psi: impl Fn(usize, usize) -> Dual<N>,
    ) -> (Vec<Dual<N>>, [Dual<N>; 36]) {
        let n_free = self.model.n_free;
        let n_tot = n_free + 6;
        let nd = 3 * self.model.mesh.nodes.len();
        // Column `col·N + k` holds tangent k of load column col.
        let mut rhs = vec![0.0; n_tot * 6 * N];
        for col in 0..6 {
            for (g, &f) in self.model.dof.iter().enumerate() {
                if f != NONE {
                    let r = res_u(g, col);
                    for k in 0..N {
                        rhs[(col * N + k) * n_tot + f] = r.d[k];
                    }
                }
            }
            for i in 0..6 {
                let r = res_psi(i, col);
                for k in 0..N {
                    rhs[(col * N + k) * n_tot + n_free + i] = r.d[k];
                }
            }
        }
        self.llt.solve_columns(&mut rhs, 6 * N);
        let dual = |row: usize, col: usize, value: f64| {
            let mut d = [0.0; N];
            for (k, dk) in d.iter_mut().enumerate() {
                *dk = rhs[(col * N + k) * n_tot + row];
            }
            Dual::new(value, d)
        };
        let mut x = vec![Dual::<N>::constant(0.0); nd * 6];
        let mut y = [Dual::<N>::constant(0.0); 36];
        for col in 0..6 {
            for (g, &f) in self.model.dof.iter().enumerate() {
                if f != NONE {
                    x[g * 6 + col] = dual(f, col, x_hat[g * 6 + col]);
                }
            }
            for i in 0..6 {
                y[i * 6 + col] = dual(n_free + i, col, y_hat[i * 6 + col]);
            }
        }
        (x, y)
    }
}

impl Model {
    /// Split a column-major solution (`n_free + 6` rows × 6) into node-dof-major warping and
    /// the 6×6 generalised-strain block.
    fn unpack(&self, sol: &[f64]) -> (Vec<f64>, [f64; 36]) {
        let n_tot = self.n_free + 6;
        let mut x = vec![0.0; self.dof.len() * 6];
        for (g, &f) in self.dof.iter().enumerate() {
            if f != NONE {
                for c in 0..6 {
                    x[g * 6 + c] = sol[c * n_tot + f];
                }
            }
        }
        let mut y = [0.0; 36];
        for i in 0..6 {
            for c in 0..6 {
                y[i * 6 + c] = sol[c * n_tot + self.n_free + i];
            }
        }
        (x, y)
    }

    /// The material stiffness in section axes at integration point `gp` of an element of
    /// region `r`: `T_wall Q_ply T_wallᵀ`.
    fn stiffness_at<S, G>(
        &self,
        region: usize,
        gp: &GaussPoint<G>,
        q_ply: &Matrix6<S>,
    ) -> Matrix6<S>
    where
        S: Scalar + Mul<G, Output = S>,
        G: Scalar,
    {
        let r = self.mesh.regions[region].frame.rotation_at(gp.x, gp.dx_dxi);
        congruence(&bond_stress_matrix(&r), q_ply)
    }

    /// [`Model::stiffness_at`] at every integration point of [`Model::gps`], in their order.
    fn stiffness_at_points(&self, q_ply: &[Matrix6<f64>]) -> Vec<Matrix6<f64>> {
        let mut out = Vec::with_capacity(self.gps.len());
        for (e, el) in self.mesh.elements.iter().enumerate() {
            for gp in &self.gps[self.gp_start[e]..self.gp_start[e + 1]] {
                out.push(self.stiffness_at(el.region, gp, &q_ply[el.region]));
            }
        }
        out
    }

    /// The sparsity pattern (lower triangle, sorted CSC) of the warping matrix: nodal
    /// components couple when their nodes share an element; every warping component couples
    /// with the six generalised strains.
    fn pattern(&self) -> (Vec<usize>, Vec<usize>) {
        let nn = self.mesh.nodes.len();
        let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nn];
        for el in &self.mesh.elements {
            for &a in &el.nodes {
                adj[a].extend_from_slice(&el.nodes);
            }
        }
        for v in &mut adj {
            v.sort_unstable();
            v.dedup();
        }
        // Free dofs are numbered node by node in increasing node order, so the rows below come
        // out sorted.
        let mut owner = vec![0; self.n_free];
        for (g, &f) in self.dof.iter().enumerate() {
            if f != NONE {
                owner[f] = g;
            }
        }
        let mut col_ptr = Vec::with_capacity(self.n_free + 7);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for (j, &g) in owner.iter().enumerate() {
            for &nb in &adj[g / 3] {
                for k in 0..3 {
                    let i = self.dof[3 * nb + k];
                    if i != NONE && i >= j {
                        row_idx.push(i);
                    }
                }
            }
            row_idx.extend(self.n_free..self.n_free + 6);
            col_ptr.push(row_idx.len());
        }
        for j in 0..6 {
            row_idx.extend(self.n_free + j..self.n_free + 6);
            col_ptr.push(row_idx.len());
        }
        (col_ptr, row_idx)
    }

    /// Assemble the lower triangle of `K = ∫[BN Z]ᵀ Q [BN Z]` (pinned components removed)
    /// and factorise it; with what the solves need to estimate its conditioning.
    fn factorise(
        &self,
        q_points: &[Matrix6<f64>],
    ) -> Result<(SparseCholesky, Conditioning), SectionError> {
        let n_tot = self.n_free + 6;
        let (col_ptr, row_idx, values) = self.assemble(q_points);
        let k = SparseColMat::new(
            SymbolicSparseColMat::new_checked(n_tot, n_tot, col_ptr, None, row_idx),
            values,
        );
        // The fill-reducing ordering of the node graph (the strains last).
        let mut group = vec![sens::sparse::LAST; n_tot];
        for (g, &f) in self.dof.iter().enumerate() {
            if f != NONE {
                group[f] = g / 3;
            }
        }
        let symbolic = SparseCholesky::symbolic(k.symbolic(), Side::Lower, &group)
            .map_err(|e| SectionError::Factorisation(format!("{e:?}")))?;
        // The materials are positive definite and the mesh valid, so K is: a failed
        // factorisation is round-off.
        let ill = |condition: f64| SectionError::IllConditioned {
            condition,
            thinness: self.mesh.thinness(),
        };
        let llt = SparseCholesky::new(symbolic, k.as_ref(), Side::Lower)
            .map_err(|_| ill(f64::INFINITY))?;
        Ok((llt, Conditioning::of(&k)))
    }

    /// The lower triangle of `K = ∫[BN Z]ᵀ Q [BN Z]` (pinned components removed), sorted CSC:
    /// `(col_ptr, row_idx, values)`; `q_points` the material at the integration points.
    fn assemble(&self, q_points: &[Matrix6<f64>]) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
        let (col_ptr, row_idx) = self.pattern();
        let mut values = vec![0.0; row_idx.len()];
        let mut add = |r: usize, c: usize, v: f64| {
            let col = &row_idx[col_ptr[c]..col_ptr[c + 1]];
            let k = col
                .binary_search(&r)
                .expect("entry in the assembled pattern");
            values[col_ptr[c] + k] += v;
        };
        let mut a_block = [[0.0; 6]; 6];
        const M: usize = 3 * MAX_NODES + 6;
        for (e, el) in self.mesh.elements.iter().enumerate() {
            let nn = el.kind.node_count();
            let m = 3 * nn + 6;
            let mut ke = [[0.0; M]; M];
            for (k, gp) in self.gps[self.gp_start[e]..self.gp_start[e + 1]]
                .iter()
                .enumerate()
            {
                let q = q_points[self.gp_start[e] + k];
                // G = [B₁ … B_nn Z] (6 × m).
                let mut g = [[0.0; M]; 6];
                for a in 0..nn {
                    let [d2, d3] = gp.dx[a];
                    let c = 3 * a;
                    g[1][c + 1] = d2;
                    g[2][c + 2] = d3;
                    g[3][c + 1] = d3;
                    g[3][c + 2] = d2;
                    g[4][c] = d3;
                    g[5][c] = d2;
                }
                let [x2, x3] = gp.x;
                let z = 3 * nn;
                g[0][z] = 1.0;
                g[0][z + 4] = x3;
                g[0][z + 5] = -x2;
                g[4][z + 2] = 1.0;
                g[4][z + 3] = x2;
                g[5][z + 1] = 1.0;
                g[5][z + 3] = -x3;
                // QG (6 × m), then Gᵀ(QG), lower triangle.
                let mut qg = [[0.0; M]; 6];
                for i in 0..6 {
                    for k in 0..6 {
                        let qik = q[(i, k)] * gp.w;
                        if qik != 0.0 {
                            for j in 0..m {
                                qg[i][j] += qik * g[k][j];
                            }
                        }
                    }
                }
                for i in 0..m {
                    for k in 0..6 {
                        let gki = g[k][i];
                        if gki != 0.0 {
                            for j in 0..=i {
                                ke[i][j] += gki * qg[k][j];
                            }
                        }
                    }
                }
            }
            let global = |i: usize| -> usize {
                if i < 3 * nn {
                    self.dof[3 * el.nodes[i / 3] + i % 3]
                } else {
                    self.n_free + i - 3 * nn
                }
            };
            for i in 0..m {
                let gi = global(i);
                if gi == NONE {
                    continue;
                }
                for j in 0..=i {
                    let gj = global(j);
                    if gj == NONE {
                        continue;
                    }
                    if i >= 3 * nn && j >= 3 * nn {
                        a_block[i - 3 * nn][j - 3 * nn] += ke[i][j];
                        continue;
                    }
                    let (r, c) = if gi >= gj { (gi, gj) } else { (gj, gi) };
                    add(r, c, ke[i][j]);
                }
            }
        }
        for i in 0..6 {
            for j in 0..=i {
                add(self.n_free + i, self.n_free + j, a_block[i][j]);
            }
        }
        (col_ptr, row_idx, values)
    }

    /// The section kernel: at every integration point, the strain
    /// `ε_c = Z ψ_c + BN u_c + SN u1_c` of each of the 6 columns, the stress `σ_c = Q ε_c`, and
    /// the requested projections of `σ`.
    ///
    /// The fields may be plain `f64` while the stiffness carries tangents (`S = Dual`,
    /// `F = f64`): then only the stiffness is differentiated, at half the cost. The geometry
    /// `gps` is [`Model::gps`] (`G = f64`) or, when nodes move with a design variable, its
    /// dual counterpart (then the fields are dual too).
    fn kernel<S, F, G>(
        &self,
        materials: Materials<'_, S>,
        gps: &[GaussPoint<G>],
        f: Fields<'_, F>,
        mut out: Outputs<'_, S>,
    ) where
        S: Scalar + Mul<F, Output = S> + Mul<G, Output = S>,
        F: Scalar + Mul<G, Output = F>,
        G: Scalar,
    {
        for (e, el) in self.mesh.elements.iter().enumerate() {
            let nn = el.kind.node_count();
            for (k, gp) in gps[self.gp_start[e]..self.gp_start[e + 1]]
                .iter()
                .enumerate()
            {
                let q = match materials {
                    Materials::PerRegion(q_ply) => {
                        self.stiffness_at(el.region, gp, &q_ply[el.region])
                    }
                    Materials::PerPoint(q) => q[self.gp_start[e] + k],
                };
                let [x2, x3] = gp.x;
                let mut eps = [[F::zero(); 6]; 6];
                for (c, ec) in eps.iter_mut().enumerate() {
                    if let Some(psi) = f.psi {
                        let p = |i: usize| psi[i * 6 + c];
                        ec[0] += p(0) + p(4) * x3 - p(5) * x2;
                        ec[4] += p(2) + p(3) * x2;
                        ec[5] += p(1) - p(3) * x3;
                    }
                    if let Some(u) = f.u {
                        for a in 0..nn {
                            let g = 3 * el.nodes[a];
                            let [d2, d3] = gp.dx[a];
                            let (u0, u1, u2) =
                                (u[g * 6 + c], u[(g + 1) * 6 + c], u[(g + 2) * 6 + c]);
                            ec[1] += u1 * d2;
                            ec[2] += u2 * d3;
                            ec[3] += u1 * d3 + u2 * d2;
                            ec[4] += u0 * d3;
                            ec[5] += u0 * d2;
                        }
                    }
                    if let Some(u1) = f.u1 {
                        for a in 0..nn {
                            let g = 3 * el.nodes[a];
                            let na = gp.n[a];
                            ec[0] += u1[g * 6 + c] * na;
                            ec[5] += u1[(g + 1) * 6 + c] * na;
                            ec[4] += u1[(g + 2) * 6 + c] * na;
                        }
                    }
                }
                let mut sig = [[S::zero(); 6]; 6];
                for c in 0..6 {
                    for i in 0..6 {
                        let mut acc = S::zero();
                        for k in 0..6 {
                            acc += q[(i, k)] * eps[c][k];
                        }
                        sig[c][i] = acc * gp.w;
                    }
                }
                if let Some(b) = out.b.as_deref_mut() {
                    for a in 0..nn {
                        let g = 3 * el.nodes[a];
                        let [d2, d3] = gp.dx[a];
                        for (c, s) in sig.iter().enumerate() {
                            b[g * 6 + c] += s[5] * d2 + s[4] * d3;
                            b[(g + 1) * 6 + c] += s[1] * d2 + s[3] * d3;
                            b[(g + 2) * 6 + c] += s[2] * d3 + s[3] * d2;
                        }
                    }
                }
                if let Some(sn) = out.s.as_deref_mut() {
                    for a in 0..nn {
                        let g = 3 * el.nodes[a];
                        let na = gp.n[a];
                        for (c, s) in sig.iter().enumerate() {
                            sn[g * 6 + c] += s[0] * na;
                            sn[(g + 1) * 6 + c] += s[5] * na;
                            sn[(g + 2) * 6 + c] += s[4] * na;
                        }
                    }
                }
                if let Some(z) = out.z.as_deref_mut() {
                    for (c, s) in sig.iter().enumerate() {
                        z[c] += s[0];
                        z[6 + c] += s[5];
                        z[12 + c] += s[4];
                        z[18 + c] += s[4] * x2 - s[5] * x3;
                        z[24 + c] += s[0] * x3;
                        z[30 + c] -= s[0] * x2;
                    }
                }
                if let Some(en) = out.energy.as_deref_mut() {
                    for c in 0..6 {
                        for d in 0..6 {
                            let mut acc = S::zero();
                            for i in 0..6 {
                                acc += sig[d][i] * eps[c][i];
                            }
                            en[c * 6 + d] += acc;
                        }
                    }
                }
            }
        }
    }

    /// Unit-density integrals `∫1, ∫x₂, …` of each region (`m…` with ρ = 1) over the
    /// geometry `gps`.
    fn region_mass_integrals<G: Scalar>(&self, gps: &[GaussPoint<G>]) -> Vec<MassProperties<G>> {
        let mut out = vec![MassProperties::default(); self.mesh.regions.len()];
        for (e, el) in self.mesh.elements.iter().enumerate() {
            let mp = &mut out[el.region];
            for gp in &gps[self.gp_start[e]..self.gp_start[e + 1]] {
                let [x2, x3] = gp.x;
                mp.area += gp.w;
                mp.m += gp.w;
                mp.m2 += gp.w * x2;
                mp.m3 += gp.w * x3;
                mp.m22 += gp.w * x2 * x2;
                mp.m33 += gp.w * x3 * x3;
                mp.m23 += gp.w * x2 * x3;
            }
        }
        out
    }

    /// The mass integrals with the regions' densities.
    fn mass_properties(&self) -> MassProperties {
        let rho: Vec<f64> = self
            .mesh
            .regions
            .iter()
            .map(|r| r.material.density())
            .collect();
        MassProperties::scaled_sum(&self.region_mass_integrals(&self.gps), &rho)
    }
}

/// The largest estimated condition number ([`Conditioning`]) times the machine epsilon that is
/// accepted. The flatwise stiffness of a thin strip carries an error of 1–25 % of it
/// (measured on `w × h` strips meshed [16, 2], [64, 2] and [16, 4]: 2.6e-5 at h/w = 1e-3,
/// estimate 2.8e12; 1.5e-3 at 5e-4, 8.1e13; 1.5 % at 3e-4, 4.1e14), so an accepted result is
/// within 0.5 %; the limit falls near h/w = 5e-4 (`crates/section/tests/thin_strips.rs`).
const MAX_ROUNDOFF: f64 = 2e-2;

/// What the solves say of the conditioning of `S = D^{-1/2} K D^{-1/2}` (`D` the diagonal of
/// `K`): its largest eigenvalue bounded by Gershgorin's discs, its smallest by the Rayleigh
/// quotients `xᵀKx / xᵀDx = xᵀb / xᵀDx` of the solutions `x` of the load cases `K x = b`.
/// The loads of a thin section excite its soft modes (a strip's flatwise bending is resisted
/// by the anticlastic in-plane bending of its wall), so the quotient of that solution is near
/// the smallest eigenvalue; a soft mode no load excites does not move the results.
struct Conditioning {
    diag: Vec<f64>,
    largest: f64,
    smallest: f64,
}

impl Conditioning {
    fn of(k: &SparseColMat<usize, f64>) -> Self {
        let n = k.nrows();
        let (col_ptr, row_idx, values) = (k.symbolic().col_ptr(), k.symbolic().row_idx(), k.val());
        let mut diag = vec![0.0; n];
        for c in 0..n {
            for p in col_ptr[c]..col_ptr[c + 1] {
                if row_idx[p] == c {
                    diag[c] = values[p];
                }
            }
        }
        let scale: Vec<f64> = diag.iter().map(|d| 1.0 / d.sqrt()).collect();
        let mut sums = vec![0.0; n];
        for c in 0..n {
            for p in col_ptr[c]..col_ptr[c + 1] {
                let r = row_idx[p];
                let v = values[p].abs() * scale[r] * scale[c];
                sums[r] += v;
                if r != c {
                    sums[c] += v;
                }
            }
        }
        Conditioning {
            diag,
            largest: sums.iter().fold(0.0f64, |a, &x| a.max(x)),
            smallest: f64::INFINITY,
        }
    }

    /// Take in the solutions `x` of `K x = b` (columns of `diag.len()` rows).
    fn observe(&mut self, b: &[f64], x: &[f64]) {
        let n = self.diag.len();
        for (bc, xc) in b.chunks(n).zip(x.chunks(n)) {
            let work: f64 = bc.iter().zip(xc).map(|(b, x)| b * x).sum();
            let norm: f64 = self.diag.iter().zip(xc).map(|(d, x)| d * x * x).sum();
            if norm > 0.0 {
                let q = work / norm;
                self.smallest = self.smallest.min(if q > 0.0 { q } else { 0.0 });
            }
        }
    }

    /// The estimate of the condition number (infinite when a quotient was not positive).
    fn condition(&self) -> f64 {
        self.largest / self.smallest
    }
}

/// `θ' = T θ` for a beam without distributed load: `M₂' = F₃`, `M₃' = −F₂`; `t[i·6 + j]`.
fn force_derivative_map() -> [f64; 36] {
    let mut t = [0.0; 36];
    t[4 * 6 + 2] = 1.0;
    t[5 * 6 + 1] = -1.0;
    t
}

/// `(A + Aᵀ)/2` as a matrix (removes round-off asymmetry).
fn symmetric<S: Scalar>(a: &[S; 36]) -> Matrix6<S> {
    SMatrix::from_fn(|i, j| (a[i * 6 + j] + a[j * 6 + i]) * 0.5)
}

/// Integration-point geometry of every element (the mesh has been validated), with the node
/// coordinates `nodes` in the scalar `G` (the mesh's own, or dual ones that move with design
/// variables).
fn geometry<G: Scalar>(mesh: &SectionMesh, nodes: &[[G; 2]]) -> (Vec<GaussPoint<G>>, Vec<usize>) {
    let mut gps = Vec::new();
    let mut start = Vec::with_capacity(mesh.elements.len() + 1);
    let mut n = [0.0; MAX_NODES];
    let mut dn = [[0.0; 2]; MAX_NODES];
    let z = G::zero();
    for el in &mesh.elements {
        start.push(gps.len());
        let nn = el.kind.node_count();
        for &(xi, eta, w) in el.kind.rule() {
            el.kind.shape(xi, eta, &mut n, &mut dn);
            // J[i][k] = ∂x_i/∂ξ_k
            let mut j = [[z; 2]; 2];
            for (&node, d) in el.nodes.iter().zip(&dn[..nn]) {
                let x = nodes[node];
                for i in 0..2 {
                    for k in 0..2 {
                        j[i][k] += x[i] * d[k];
                    }
                }
            }
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            // ∂ξ/∂x = J⁻¹.
            let inv = [
                [j[1][1] / det, -j[0][1] / det],
                [-j[1][0] / det, j[0][0] / det],
            ];
            let mut gp = GaussPoint {
                w: det * w,
                x: [z; 2],
                n: [0.0; MAX_NODES],
                dx: [[z; 2]; MAX_NODES],
                dx_dxi: [[j[0][0], j[1][0]], [j[0][1], j[1][1]]],
            };
            for a in 0..nn {
                let x = nodes[el.nodes[a]];
                gp.n[a] = n[a];
                gp.x[0] += x[0] * n[a];
                gp.x[1] += x[1] * n[a];
                for i in 0..2 {
                    gp.dx[a][i] = inv[0][i] * dn[a][0] + inv[1][i] * dn[a][1];
                }
            }
            gps.push(gp);
        }
    }
    start.push(gps.len());
    (gps, start)
}

/// Free-dof numbering with six pinned components that remove the rigid modes of the warping.
fn dof_map(mesh: &SectionMesh) -> (Vec<usize>, usize) {
    let nn = mesh.nodes.len();
    let mut used = vec![false; nn];
    for el in &mesh.elements {
        for &n in &el.nodes {
            used[n] = true;
        }
    }
    let used_nodes: Vec<usize> = (0..nn).filter(|&i| used[i]).collect();
    let p = |i: usize| mesh.nodes[i];
    let a = used_nodes[0];
    let dist2 = |i: usize, j: usize| (p(i)[0] - p(j)[0]).powi(2) + (p(i)[1] - p(j)[1]).powi(2);
    let b = *used_nodes
        .iter()
        .max_by(|&&i, &&j| dist2(a, i).total_cmp(&dist2(a, j)))
        .expect("validated mesh has nodes");
    let area = |i: usize| {
        let (u, v) = (
            [p(b)[0] - p(a)[0], p(b)[1] - p(a)[1]],
            [p(i)[0] - p(a)[0], p(i)[1] - p(a)[1]],
        );
        (u[0] * v[1] - u[1] * v[0]).abs()
    };
    let c = *used_nodes
        .iter()
        .max_by(|&&i, &&j| area(i).total_cmp(&area(j)))
        .expect("validated mesh has nodes");
    let mut pinned = vec![false; 3 * nn];
    for n in [a, b, c] {
        pinned[3 * n] = true;
    }
    pinned[3 * a + 1] = true;
    pinned[3 * a + 2] = true;
    if (p(b)[0] - p(a)[0]).abs() >= (p(b)[1] - p(a)[1]).abs() {
        pinned[3 * b + 2] = true;
    } else {
        pinned[3 * b + 1] = true;
    }
    let mut dof = vec![NONE; 3 * nn];
    let mut n_free = 0;
    for &n in &used_nodes {
        for k in 0..3 {
            if !pinned[3 * n + k] {
                dof[3 * n + k] = n_free;
                n_free += 1;
            }
        }
    }
    (dof, n_free)
}
