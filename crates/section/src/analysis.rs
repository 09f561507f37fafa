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

mod moving;

/// The strain and stress at one integration point of a section ([`SectionAnalysis::stresses`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SectionPoint {
    pub element: usize,
    pub region: usize,
    /// `(x₂, x₃)` (m).
    pub position: [f64; 2],
    /// Strain and stress in section axes, Voigt `[11, 22, 33, 23, 13, 12]` with 1 along the
    /// beam (engineering shear; Pa).
    pub strain: [f64; 6],
    pub stress: [f64; 6],
    /// The same in the region's material axes (1 along the fibres).
    pub material_strain: [f64; 6],
    pub material_stress: [f64; 6],
}

/// The derivative of a point's stress along one design variable
/// ([`SectionAnalysis::stress_derivatives`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StressDerivative {
    /// `dσ/db` in section axes (Voigt `[11, 22, 33, 23, 13, 12]`).
    pub stress: [f64; 6],
    /// `dσ/db` in the region's material axes.
    pub material_stress: [f64; 6],
}

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
/// Derivatives: of the properties, only the compliance (and, through the densities and the
/// geometry, the mass integrals) is differentiated; every other property follows from it in
/// dual numbers. The recovered stresses' derivatives take the central solutions' tangents
/// through the factorisation ([`SectionAnalysis::stress_derivatives`]).
/// - Ply angles and material stiffnesses (only `Q` depends on them): by the adjoints of the
///   two systems (`SectionAnalysis::compliance_derivatives`), two six-column solves through
///   the same factorisation and one pass over the integration points of the regions the
///   variables change, whatever their number (the moments of each region, contracted with
///   each variable's `Q'`; a region with one or two such variables, when nodes move too, is
///   contracted in the pass of the moving variables below instead, from its strains there).
/// - Node coordinates (a ply thickness: the Gauss points' positions, weights and
///   shape-function gradients, and the wall frames, depend on them): by the same adjoints
///   (`SectionAnalysis::compliance_adjoint_dual`), the Lagrangian of both systems
///   differentiated through the points' geometry (their velocities and velocity gradients,
///   the frames' rates of turn) over the elements that move, the fields and adjoints held,
///   `N` variables a pass; no dual right-hand side goes through the factorisation. The direct
///   form (the residuals of systems 1 and 2 evaluated with dual coordinates and their `6 N`
///   tangent columns pushed through the factorisation, the pattern
///   of [`sens::solve_tangents`]; `SectionAnalysis::compliance_dual`) is the tests' oracle.
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
    /// The material in section axes at every integration point of [`Model::gps`] (rotated
    /// once: for the assembly, the analysis's kernel passes and the adjoint derivatives').
    q_points: Vec<Matrix6<f64>>,
    /// `∫[BN Z]ᵀ Q ε` of the central solution's strains, node-dof-major and `6 × 6`: the
    /// right-hand side of the first adjoint of the derivatives
    /// ([`SectionAnalysis::for_derivatives`]).
    stress_projection: Option<(Vec<f64>, [f64; 36])>,
    properties: SectionProperties,
    /// The adjoints of the compliance derivatives, solved at the first derivative asked for
    /// and shared by every chunk of variables after it.
    adjoints: std::sync::OnceLock<ComplianceAdjoints>,
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

/// The strain and stress (section axes) and the stress in the material axes at integration
/// point `gp` of an element of `nodes` in `region` (its ply angle `angle`, its material in
/// section axes there `q`) under `forces`, of the central solution `fields`:
/// `ε = (Z Y + BN X + SN X₁) θ`, `σ = Q ε`, turned by the wall frame and the ply angle.
fn point_stress<F, G>(
    (nodes, gp, fields): (&[usize], &GaussPoint<G>, Fields<'_, F>),
    region: &Region,
    angle: F,
    q: &Matrix6<F>,
    forces: [F; 6],
) -> [[F; 6]; 3]
where
    F: Scalar + Mul<G, Output = F> + From<G>,
    G: Scalar,
{
    let eps = strains(nodes, gp, fields);
    let strain: [F; 6] =
        std::array::from_fn(|i| (0..6).fold(F::zero(), |acc, c| acc + eps[c][i] * forces[c]));
    let stress: [F; 6] =
        std::array::from_fn(|i| (0..6).fold(F::zero(), |acc, j| acc + q[(i, j)] * strain[j]));
    // material axes in section axes: the wall frame's, turned by the ply angle
    let r = region.frame.rotation_at(gp.x, gp.dx_dxi).map(F::from) * Region::ply_rotation(angle);
    let to_material = bond_stress_matrix(&r.transpose());
    let material: [F; 6] = std::array::from_fn(|i| {
        (0..6).fold(F::zero(), |acc, j| acc + to_material[(i, j)] * stress[j])
    });
    [strain, stress, material]
}

/// Each region's material in section axes, `T(θ) C̄ T(θ)ᵀ`, of dual angles and stiffnesses.
fn ply_stiffnesses<const N: usize>(
    angles: &[Dual<N>],
    c_bar: &[Matrix6<Dual<N>>],
) -> Vec<Matrix6<Dual<N>>> {
    (angles.iter().zip(c_bar))
        .map(|(&a, c)| rotate_stiffness_of(c, &Region::ply_rotation(a)))
        .collect()
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
    SectionAnalysis::for_derivatives(mesh)?.sensitivities::<N>(design)
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

/// The fields of the compliance's Lagrangian ([`SectionAnalysis::compliance_derivatives`]):
/// the solutions `X, Y, X₁, Y₁` and the adjoints `λ`, `μ`, in the scalar `F`.
#[derive(Clone, Copy)]
struct LagrangeFields<'a, F> {
    eps: Fields<'a, F>,
    e1: Fields<'a, F>,
    lambda: Fields<'a, F>,
    s_lambda: Fields<'a, F>,
    mu: Fields<'a, F>,
}

impl<'a, F: Scalar> LagrangeFields<'a, F> {
    /// From `(X, X₁, Y, Y₁)` and the adjoints `(λ_X, λ_Y, μ_X, μ_Y)`.
    fn new(
        (x, x1, y, y1): (&'a [F], &'a [F], &'a [F; 36], &'a [F; 36]),
        (lx, ly, mx, my): (&'a [F], &'a [F; 36], &'a [F], &'a [F; 36]),
    ) -> Self {
        let field = |u, u1, psi| Fields { u, u1, psi };
        Self {
            eps: field(Some(x), Some(x1), Some(y)),
            e1: field(Some(x1), None, Some(y1)),
            lambda: field(Some(lx), None, Some(ly)),
            s_lambda: field(None, Some(lx), None),
            mu: field(Some(mx), None, Some(my)),
        }
    }

    /// `[ε, α, e₁, β]` of the six columns at `gp` (of an element with nodes `nodes`) written
    /// into `out`, with `ε = [BN Z] u + SN X₁`, `α = ε/2 − [BN Z] λ`, `e₁ = [BN Z] u₁`,
    /// `β = SN λ_X − [BN Z] μ`, in the scalar `O` of the fields' products with the geometry's
    /// (the fields', or dual numbers for plain fields at dual integration points). Written in
    /// place, so that no array (kilobytes in dual numbers) is copied at each integration point.
    #[inline(always)]
    fn at_into<G, O>(&self, nodes: &[usize], gp: &GaussPoint<G>, out: &mut [[[O; 6]; 6]; 4])
    where
        F: Mul<G, Output = O>,
        G: Scalar,
        O: Scalar + From<F>,
    {
        let [eps, alpha, e1, beta] = out;
        strains_into(nodes, gp, self.eps, eps);
        strains_into(nodes, gp, self.e1, e1);
        strains_into(nodes, gp, self.lambda, alpha);
        strains_into(nodes, gp, self.s_lambda, beta);
        let half = O::from_f64(0.5);
        for (a, e) in alpha.iter_mut().zip(eps.iter()) {
            for (a, &e) in a.iter_mut().zip(e) {
                *a = half * e - *a;
            }
        }
        let mut mu = [[O::zero(); 6]; 6];
        strains_into(nodes, gp, self.mu, &mut mu);
        for (b, m) in beta.iter_mut().zip(&mu) {
            for (b, &m) in b.iter_mut().zip(m) {
                *b -= m;
            }
        }
    }
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

/// The strains `[BN Z] u + SN u₁` (`u` the warping with `psi` the generalised strains, `u₁`
/// the warping rate) of the six columns of the fields `f` at the integration point `gp` of an
/// element with nodes `nodes`: `eps[column][component]`.
#[inline(always)]
fn strains<F, G, O>(nodes: &[usize], gp: &GaussPoint<G>, f: Fields<'_, F>) -> [[O; 6]; 6]
where
    F: Copy + Mul<G, Output = O>,
    G: Scalar,
    O: Scalar + From<F>,
{
    let mut out = [[O::zero(); 6]; 6];
    strains_into(nodes, gp, f, &mut out);
    out
}

/// [`strains`] written into `out`.
#[inline(always)]
fn strains_into<F, G, O>(
    nodes: &[usize],
    gp: &GaussPoint<G>,
    f: Fields<'_, F>,
    out: &mut [[O; 6]; 6],
) where
    F: Copy + Mul<G, Output = O>,
    G: Scalar,
    O: Scalar + From<F>,
{
    let [x2, x3] = gp.x;
    // component-major while accumulating (the six columns of a nodal component are
    // contiguous in the fields), column-major on return
    let mut e = [[O::zero(); 6]; 6];
    if let Some(psi) = f.psi {
        for c in 0..6 {
            let p = |i: usize| psi[i * 6 + c];
            e[0][c] += O::from(p(0)) + p(4) * x3 - p(5) * x2;
            e[4][c] += O::from(p(2)) + p(3) * x2;
            e[5][c] += O::from(p(1)) - p(3) * x3;
        }
    }
    if let Some(u) = f.u {
        for (a, &node) in nodes.iter().enumerate() {
            let g = 3 * node;
            let [d2, d3] = gp.dx[a];
            let (u0, u1, u2) = (
                &u[g * 6..g * 6 + 6],
                &u[(g + 1) * 6..(g + 1) * 6 + 6],
                &u[(g + 2) * 6..(g + 2) * 6 + 6],
            );
            for c in 0..6 {
                e[1][c] += u1[c] * d2;
                e[2][c] += u2[c] * d3;
                e[3][c] += u1[c] * d3 + u2[c] * d2;
                e[4][c] += u0[c] * d3;
                e[5][c] += u0[c] * d2;
            }
        }
    }
    if let Some(u1) = f.u1 {
        for (a, &node) in nodes.iter().enumerate() {
            let g = 3 * node;
            let na = gp.n[a];
            for c in 0..6 {
                e[0][c] += O::from(u1[g * 6 + c]) * na;
                e[5][c] += O::from(u1[(g + 1) * 6 + c]) * na;
                e[4][c] += O::from(u1[(g + 2) * 6 + c]) * na;
            }
        }
    }
    for (c, out) in out.iter_mut().enumerate() {
        for (k, out) in out.iter_mut().enumerate() {
            *out = e[k][c];
        }
    }
}

impl SectionAnalysis {
    /// Validate the mesh, assemble and factorise the warping system, solve it and compute the
    /// section properties.
    pub fn new(mesh: &SectionMesh) -> Result<Self, SectionError> {
        Self::analyse(mesh, false)
    }

    /// [`SectionAnalysis::new`] for a section whose compliance derivatives will be asked for
    /// ([`SectionAnalysis::sensitivities`]): the last pass over the integration points also
    /// projects the stresses for the derivatives' first adjoint (a few percent of the
    /// analysis, where the derivatives would take a pass of their own). The results are the
    /// same to the last bit.
    pub fn for_derivatives(mesh: &SectionMesh) -> Result<Self, SectionError> {
        Self::analyse(mesh, true)
    }

    /// [`SectionAnalysis::new`], with the stresses' projection when `project`.
    fn analyse(mesh: &SectionMesh, project: bool) -> Result<Self, SectionError> {
        mesh.validate()?;
        let mesh = mesh.clone();
        let (gps, gp_start) = geometry(&mesh, &mesh.nodes, true);
        let (dof, n_free) = dof_map(&mesh)?;
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
        // assembly, the three kernel passes below and the derivatives
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
        let (b2, z2) = m.b_and_z(
            Materials::PerPoint(&q_points),
            &m.gps,
            Fields {
                u: None,
                u1: Some(&x1),
                psi: None,
            },
        );
        for (s, b) in s1.iter_mut().zip(&b2) {
            *s -= b;
        }
        let mut psi2 = [0.0; 36];
        for i in 0..6 {
            for c in 0..6 {
                psi2[i * 6 + c] = if i == c { 1.0 } else { 0.0 } - z2[i * 6 + c];
            }
        }
        let mut rhs = m.pack(&s1, &psi2);
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

        // Compliance: the strain energy of the central solution per unit force; the same
        // pass may project its stresses for the derivatives' first adjoint (`∫[BN Z]ᵀ Q ε`,
        // `SectionAnalysis::solve_adjoints`), which would otherwise take a pass of its own.
        let mut f = [0.0; 36];
        let mut stress_projection = project.then(|| (vec![0.0; nd * 6], [0.0; 36]));
        let (projection_b, projection_z) = match stress_projection.as_mut() {
            Some((b, z)) => (Some(&mut b[..]), Some(z)),
            None => (None, None),
        };
        m.kernel(
            Materials::PerPoint(&q_points),
            &m.gps,
            Fields {
                u: Some(&x),
                u1: Some(&x1),
                psi: Some(&y),
            },
            Outputs {
                b: projection_b,
                s: None,
                z: projection_z,
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
            q_points,
            stress_projection,
            properties,
            adjoints: std::sync::OnceLock::new(),
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

    /// The 3-D strain and stress at every integration point under the section forces
    /// `forces = [F₁, F₂, F₃, M₁, M₂, M₃]` (N, N·m; `F₁` axial, `M₁` torsion) of the central
    /// solution: `ε = (Z Y + BN X + SN X₁) θ` and `σ = Q ε`, the warping of the shear forces
    /// along the beam included (BECAS's recovery), in section axes and in each region's
    /// material axes.
    pub fn stresses(&self, forces: [f64; 6]) -> Vec<SectionPoint> {
        let m = &self.model;
        let mut out = Vec::with_capacity(m.gps.len());
        let mut k = 0;
        let fields = Fields {
            u: Some(&self.x[..]),
            u1: Some(&self.x1[..]),
            psi: Some(&self.y),
        };
        for (e, el) in m.mesh.elements.iter().enumerate() {
            let nn = el.kind.node_count();
            let region = &m.mesh.regions[el.region];
            for gp in &m.gps[m.gp_start[e]..m.gp_start[e + 1]] {
                let [strain, stress, material_stress] = point_stress(
                    (&el.nodes[..nn], gp, fields),
                    region,
                    region.ply_angle,
                    &self.q_points[k],
                    forces,
                );
                let compliance = region.material.compliance();
                let material_strain: [f64; 6] = std::array::from_fn(|i| {
                    (0..6)
                        .map(|j| compliance[(i, j)] * material_stress[j])
                        .sum()
                });
                out.push(SectionPoint {
                    element: e,
                    region: el.region,
                    position: gp.x,
                    strain,
                    stress,
                    material_strain,
                    material_stress,
                });
                k += 1;
            }
        }
        out
    }

    /// The derivatives of the stresses of [`SectionAnalysis::stresses`] under the fixed
    /// section forces `forces` with respect to each variable of `design`, `N` at a time: per
    /// variable, per integration point (in the order of `stresses`; a point that a thickness
    /// moves is followed), `dσ/db` in section and in material axes. The central solutions'
    /// tangents go through the stored factorisation (the residuals of both warping systems in
    /// dual numbers, as `SectionAnalysis::compliance_dual`), the materials', angles' and
    /// geometry's through the recovery itself.
    pub fn stress_derivatives<const N: usize>(
        &self,
        forces: [f64; 6],
        design: &DesignMap,
    ) -> Result<Vec<Vec<StressDerivative>>, SectionError> {
        let cases = self.load_case_derivatives::<N>(&[forces], design)?;
        Ok(cases
            .into_iter()
            .map(|mut per_case| per_case.remove(0))
            .collect())
    }

    /// The derivatives of each integration point's material-axis stress per unit section
    /// force: per variable of `design`, per point (in the order of
    /// [`SectionAnalysis::stresses`]), `[k][i]` the derivative of stress component `i` under
    /// the unit force `k` (`[F₁, F₂, F₃, M₁, M₂, M₃]`). The stresses are linear in the forces,
    /// so these and the values of the six unit load cases give the derivative of the stress
    /// under any forces, and of forces that depend on the design themselves. One pass of the
    /// central solutions' tangents per chunk of `N` variables serves the six cases.
    pub fn unit_stress_derivatives<const N: usize>(
        &self,
        design: &DesignMap,
    ) -> Result<Vec<Vec<[[f64; 6]; 6]>>, SectionError> {
        let unit: [[f64; 6]; 6] =
            std::array::from_fn(|k| std::array::from_fn(|i| f64::from(i == k)));
        let cases = self.load_case_derivatives::<N>(&unit, design)?;
        Ok(cases
            .into_iter()
            .map(|per_case| {
                let points = per_case[0].len();
                (0..points)
                    .map(|p| std::array::from_fn(|k| per_case[k][p].material_stress))
                    .collect()
            })
            .collect())
    }

    /// The stress derivatives under each of the section forces `cases`: per variable, per
    /// case, per integration point.
    #[allow(clippy::type_complexity)]
    fn load_case_derivatives<const N: usize>(
        &self,
        cases: &[[f64; 6]],
        design: &DesignMap,
    ) -> Result<Vec<Vec<Vec<StressDerivative>>>, SectionError> {
        assert!(N > 0, "Dual<0> carries no tangents");
        design.validate(&self.model.mesh)?;
        let mut out = vec![Vec::new(); design.variables.len()];
        for range in chunk_ranges(design.variables.len(), N) {
            let vars: Vec<usize> = range.clone().collect();
            let (angles, c_bar, nodes) = self.seeded::<N>(design, &vars);
            let q_ply = ply_stiffnesses(&angles, &c_bar);
            // the central solutions' tangents once (at the moved Gauss points when a thickness
            // moves nodes), then each case's recovery
            let moved = nodes.map(|nodes| geometry(&self.model.mesh, &nodes, true).0);
            let fields = match &moved {
                Some(gps) => {
                    let lift = |x: &[f64]| x.iter().map(|&v| Dual::constant(v)).collect::<Vec<_>>();
                    let (x1, x) = (lift(&self.x1), lift(&self.x));
                    let (y1, y) = (self.y1.map(Dual::constant), self.y.map(Dual::constant));
                    let hats = Hats {
                        x1: &x1,
                        y1: &y1,
                        x: &x,
                        y: &y,
                    };
                    self.fields_dual(&q_ply, gps, hats)
                }
                None => {
                    let hats = Hats {
                        x1: &self.x1,
                        y1: &self.y1,
                        x: &self.x,
                        y: &self.y,
                    };
                    self.fields_dual(&q_ply, &self.model.gps, hats)
                }
            };
            let per_case: Vec<Vec<[[Dual<N>; 6]; 2]>> = (cases.iter())
                .map(|forces| {
                    let forces = forces.map(Dual::<N>::constant);
                    match &moved {
                        Some(gps) => self.dual_stresses(&q_ply, &angles, gps, &fields, forces),
                        None => {
                            self.dual_stresses(&q_ply, &angles, &self.model.gps, &fields, forces)
                        }
                    }
                })
                .collect();
            for (k, v) in range.enumerate() {
                out[v] = (per_case.iter())
                    .map(|points| {
                        (points.iter())
                            .map(|[stress, material]| StressDerivative {
                                stress: stress.map(|x| x.d[k]),
                                material_stress: material.map(|x| x.d[k]),
                            })
                            .collect()
                    })
                    .collect();
            }
        }
        Ok(out)
    }

    /// The stresses (section axes, material axes) at every integration point `gps` under
    /// `forces`, with the dual central solutions `fields`, materials `q_ply` and angles.
    #[allow(clippy::type_complexity)]
    fn dual_stresses<const N: usize, G>(
        &self,
        q_ply: &[Matrix6<Dual<N>>],
        angles: &[Dual<N>],
        gps: &[GaussPoint<G>],
        (x1, _, x, y): &(Vec<Dual<N>>, [Dual<N>; 36], Vec<Dual<N>>, [Dual<N>; 36]),
        forces: [Dual<N>; 6],
    ) -> Vec<[[Dual<N>; 6]; 2]>
    where
        Dual<N>: Mul<G, Output = Dual<N>> + From<G>,
        G: Scalar,
    {
        let m = &self.model;
        let fields = Fields {
            u: Some(&x[..]),
            u1: Some(&x1[..]),
            psi: Some(y),
        };
        let mut out = Vec::with_capacity(gps.len());
        for (e, el) in m.mesh.elements.iter().enumerate() {
            let nodes = &el.nodes[..el.kind.node_count()];
            let region = &m.mesh.regions[el.region];
            for gp in &gps[m.gp_start[e]..m.gp_start[e + 1]] {
                let q = m.stiffness_at(el.region, gp, &q_ply[el.region]);
                let [_, stress, material] =
                    point_stress((nodes, gp, fields), region, angles[el.region], &q, forces);
                out.push([stress, material]);
            }
        }
        out
    }

    /// Values and derivatives of every result with respect to the design variables of
    /// `design`, evaluated `N` variables at a time through the stored factorisation.
    pub fn sensitivities<const N: usize>(
        &self,
        design: &DesignMap,
    ) -> Result<SectionSensitivities, SectionError> {
        self.sensitivities_by::<N>(design, true)
    }

    /// [`SectionAnalysis::sensitivities`], the compliance derivatives by the adjoints
    /// (`adjoint`: of all the variables that leave the nodes in place at once, and with dual
    /// geometry for those that move nodes, `N` at a time; a variable that moves nothing of the
    /// section costs nothing) or by dual numbers through the solves (the oracle of the tests).
    fn sensitivities_by<const N: usize>(
        &self,
        design: &DesignMap,
        adjoint: bool,
    ) -> Result<SectionSensitivities, SectionError> {
        assert!(N > 0, "Dual<0> carries no tangents");
        design.validate(&self.model.mesh)?;
        let m = design.variables.len();
        let integrals = self.model.region_mass_integrals(&self.model.gps);
        // A variable that moves nothing of this section (another segment's ply, say) has zero
        // derivatives and costs nothing. With the adjoints, the compliance derivatives of all
        // the variables that leave the nodes in place come at once; those that move nodes take
        // the adjoints with dual geometry, gathered in chunks of their own (each chunk is one
        // dual pass over the section). Without them (the tests' oracle), every variable in
        // chunks in order, through the solves.
        let var = |v: usize| &design.variables[v];
        let (fixed_geometry, moving): (Vec<usize>, Vec<usize>) = if adjoint {
            (0..m)
                .filter(|&v| !var(v).is_empty())
                .partition(|&v| var(v).nodes.is_empty())
        } else {
            (Vec::new(), (0..m).collect())
        };
        // The ply stiffnesses' tangents of the variables that leave the nodes in place, by
        // region: a region with a few of them rides along the first moving chunk's pass when
        // there is one (its strains are there, and a contraction a variable at each point is
        // then cheaper than the moments); the others take the moments.
        let mut q_tangents = self.ply_stiffness_tangents(design, &fixed_geometry);
        let mut carried = vec![Vec::new(); q_tangents.len()];
        if !moving.is_empty() {
            for (t, c) in q_tangents.iter_mut().zip(&mut carried) {
                if t.len() <= CARRIED_AT_MOST {
                    std::mem::swap(t, c);
                }
            }
        }
        let mut d_fixed = self.compliance_derivatives(&q_tangents, fixed_geometry.len());
        let mut derivatives = vec![SectionProperties::default(); m];
        let mut store = |vars: &[usize], mass: MassProperties<Dual<N>>, compliance| {
            let props =
                Props::from_compliance(compliance).ok_or(SectionError::SingularCompliance)?;
            for (k, &v) in vars.iter().enumerate() {
                derivatives[v] = SectionProperties::from_props(&props, &mass, |s| s.d[k]);
            }
            Ok::<(), SectionError>(())
        };
        for (i, vars) in moving.chunks(N).enumerate() {
            let density = self.chunk_densities::<N>(design, vars);
            let carried = (i == 0).then_some(Carried {
                tangents: &carried,
                out: &mut d_fixed,
            });
            let (mass, compliance) = self.mass_and_compliance_dual(
                design,
                vars,
                (&density, &integrals),
                adjoint,
                carried,
            );
            store(vars, mass, compliance)?;
        }
        for (vars, d) in fixed_geometry.chunks(N).zip(d_fixed.chunks(N)) {
            let density = self.chunk_densities::<N>(design, vars);
            let mut f = self.properties.compliance.map(Dual::<N>::constant);
            for (k, d) in d.iter().enumerate() {
                for (x, dx) in f.iter_mut().zip(d.iter()) {
                    x.d[k] = *dx;
                }
            }
            store(vars, MassProperties::scaled_sum(&integrals, &density), f)?;
        }
        Ok(SectionSensitivities {
            properties: self.properties.clone(),
            variables: design.variables.iter().map(|v| v.name.clone()).collect(),
            derivatives,
        })
    }

    /// The regions' densities as dual numbers whose tangent `k` is `dρ_region/db` of variable
    /// `vars[k]` of `design`.
    fn chunk_densities<const N: usize>(&self, design: &DesignMap, vars: &[usize]) -> Vec<Dual<N>> {
        let mut density: Vec<Dual<N>> = (self.model.mesh.regions.iter())
            .map(|r| Dual::constant(r.material.density()))
            .collect();
        for (k, &v) in vars.iter().enumerate() {
            for &(r, drho) in &design.variables[v].densities {
                density[r].d[k] += drho;
            }
        }
        density
    }

    /// The mass properties and the compliance of the variables `vars` as dual numbers, the
    /// geometry dual when a variable moves nodes: the compliance's tangents by the adjoints
    /// with the dual geometry ([`SectionAnalysis::compliance_adjoint_dual`], `adjoint` and a
    /// variable that moves nodes) or through the solves
    /// ([`SectionAnalysis::compliance_dual`]); `density` the regions' dual densities,
    /// `integrals` their unit-density integrals in the nominal geometry; `carried` other
    /// variables' tangents the adjoints' pass takes along.
    fn mass_and_compliance_dual<const N: usize>(
        &self,
        design: &DesignMap,
        vars: &[usize],
        (density, integrals): (&[Dual<N>], &[MassProperties]),
        adjoint: bool,
        carried: Option<Carried<'_>>,
    ) -> (MassProperties<Dual<N>>, Matrix6<Dual<N>>) {
        let (angles, c_bar, nodes) = self.seeded(design, vars);
        if let Some(nodes) = nodes {
            // Node coordinates carry their velocities dX/db: the geometry, the mass
            // integrals and the (lifted) fields are dual.
            let (gps, _) = geometry(&self.model.mesh, &nodes, !adjoint);
            let integrals = self.model.region_mass_integrals(&gps);
            if adjoint {
                return (
                    MassProperties::scaled_sum(&integrals, density),
                    self.compliance_adjoint_dual((&angles, &c_bar), &gps, &nodes, carried),
                );
            }
            let lift = |x: &[f64]| x.iter().map(|&v| Dual::constant(v)).collect::<Vec<_>>();
            let lift36 = |y: &[f64; 36]| y.map(Dual::constant);
            let hats = Hats {
                x1: &lift(&self.x1),
                y1: &lift36(&self.y1),
                x: &lift(&self.x),
                y: &lift36(&self.y),
            };
            (
                MassProperties::scaled_sum(&integrals, density),
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
                MassProperties::scaled_sum(integrals, density),
                self.compliance_dual(&angles, &c_bar, &self.model.gps, hats),
            )
        }
    }

    /// The regions' ply angles and material stiffnesses, and when a variable moves nodes the
    /// node coordinates, as dual numbers whose tangent `k` is the derivative along variable
    /// `vars[k]` of `design`.
    #[allow(clippy::type_complexity)]
    fn seeded<const N: usize>(
        &self,
        design: &DesignMap,
        vars: &[usize],
    ) -> (
        Vec<Dual<N>>,
        Vec<Matrix6<Dual<N>>>,
        Option<Vec<[Dual<N>; 2]>>,
    ) {
        let m = &self.model;
        let mut angles: Vec<Dual<N>> = (m.mesh.regions.iter())
            .map(|r| Dual::constant(r.ply_angle))
            .collect();
        let mut c_bar: Vec<Matrix6<Dual<N>>> =
            m.c_bar.iter().map(|c| c.map(Dual::constant)).collect();
        for (k, &v) in vars.iter().enumerate() {
            for &(r, factor) in &design.variables[v].links {
                angles[r].d[k] += factor;
            }
            for (r, dc) in &design.variables[v].materials {
                for (x, d) in c_bar[*r].iter_mut().zip(dc.iter()) {
                    x.d[k] += d;
                }
            }
        }
        if vars.iter().all(|&v| design.variables[v].nodes.is_empty()) {
            return (angles, c_bar, None);
        }
        let mut nodes: Vec<[Dual<N>; 2]> =
            m.mesh.nodes.iter().map(|p| p.map(Dual::constant)).collect();
        for (k, &v) in vars.iter().enumerate() {
            for &(n, dx) in &design.variables[v].nodes {
                nodes[n][0].d[k] += dx[0];
                nodes[n][1].d[k] += dx[1];
            }
        }
        (angles, c_bar, Some(nodes))
    }

    /// The compliance with dual ply angles, material stiffnesses and dual node coordinates by
    /// the adjoints of [`SectionAnalysis::compliance_derivatives`]. Its derivation holds for
    /// any dependence of the section's bilinear forms on the variables: with the `f64` fields
    /// `u`, `u₁` and adjoints `λ`, `μ` held, the compliance's derivative is that of the
    /// Lagrangian `Σ ∫ ε_cᵀ Q α_d + e₁_cᵀ Q β_d + (c ↔ d)` (`α = ε/2 − [BN Z] λ`,
    /// `β = SN λ_X − [BN Z] μ`; the right-hand sides `[0; T]` and `[0; I]` do not depend on
    /// the geometry). Moving nodes change the weights, the positions in `Z`, the gradients in
    /// `B` and the wall frame in `Q` at the integration points `gps` (dual), so one pass over
    /// them gives every tangent, with the strains' tangents from the points' velocity
    /// gradients (`moving`): no dual fields through the solves.
    ///
    /// `carried`: the tangents `Q'_ply` of variables that leave the nodes in place, contracted
    /// with the same points' plain strains (`dF += ∫ ε_cᵀ Q' α_d + e₁_cᵀ Q' β_d + (c ↔ d)`,
    /// [`SectionAnalysis::compliance_derivatives`]) and added to their slots.
    fn compliance_adjoint_dual<const N: usize>(
        &self,
        (angles, c_bar): (&[Dual<N>], &[Matrix6<Dual<N>>]),
        gps: &[GaussPoint<Dual<N>>],
        nodes: &[[Dual<N>; 2]],
        carried: Option<Carried<'_>>,
    ) -> Matrix6<Dual<N>> {
        let m = &self.model;
        // an element whose nodes stay and whose material is held adds no tangent
        let moves = |x: &Dual<N>| x.d.iter().any(|&t| t != 0.0);
        let node_moves: Vec<bool> = nodes.iter().map(|p| p.iter().any(moves)).collect();
        let q_ply = ply_stiffnesses(angles, c_bar);
        let ComplianceAdjoints { lx, ly, mx, my } = self.compliance_adjoints();
        let fields = LagrangeFields::new((&self.x, &self.x1, &self.y, &self.y1), (lx, ly, mx, my));
        let region_moves: Vec<bool> = q_ply.iter().map(|q| q.iter().any(moves)).collect();
        let generator = moving::frame_generator();
        let (neg_mx, neg_my): (Vec<f64>, _) = (mx.iter().map(|m| -m).collect(), my.map(|m| -m));
        let beta_fields = Fields {
            u: Some(&neg_mx),
            u1: Some(lx),
            psi: Some(&neg_my),
        };
        let no_tangents = vec![Vec::new(); m.mesh.regions.len()];
        let (carried_tangents, mut carried_out) = match carried {
            Some(Carried { tangents, out }) => (tangents, Some(out)),
            None => (&no_tangents[..], None),
        };
        // ∫ ε_cᵀ Q' α_d + e₁_cᵀ Q' β_d of each carried slot
        let mut raw = vec![Matrix6::<f64>::zeros(); carried_out.as_ref().map_or(0, |o| o.len())];
        let zero = Dual::<N>::constant(0.0);
        // the Lagrangian's integral with its tangents
        let mut l = [[zero; 6]; 6];
        let mut strains = [[[zero; 6]; 6]; 4];
        for (e, el) in m.mesh.elements.iter().enumerate() {
            let nodes = &el.nodes[..el.kind.node_count()];
            let carries = &carried_tangents[el.region];
            if !region_moves[el.region]
                && carries.is_empty()
                && !nodes.iter().any(|&n| node_moves[n])
            {
                continue;
            }
            let frame = &m.mesh.regions[el.region].frame;
            for p in m.gp_start[e]..m.gp_start[e + 1] {
                let (gp, moved) = (&m.gps[p], &gps[p]);
                let tangents = moving::PointTangents::of(moved);
                fields.moving_at_into((nodes, gp, &tangents), beta_fields, &mut strains);
                let q = &self.q_points[p];
                let mut acc = [[zero; 6]; 6];
                moving::contract_strains(q, &strains, &mut acc);
                // Q̇_k of the chunk's angles and materials (T Q̇_ply Tᵀ) and of a turning frame
                // (φ̇_k (Γ Q + Q Γᵀ))
                let mut add_tangent = |form: &Matrix6<f64>, k: usize, rate: f64| {
                    for (acc, form) in acc.iter_mut().zip(form.row_iter()) {
                        for (acc, p) in acc.iter_mut().zip(form.iter()) {
                            acc.d[k] += rate * p;
                        }
                    }
                };
                if region_moves[el.region] {
                    let q_moved = m.stiffness_at(el.region, gp, &q_ply[el.region]);
                    for k in 0..N {
                        let form = moving::strain_form(&q_moved.map(|x| x.d[k]), &strains);
                        add_tangent(&form, k, 1.0);
                    }
                }
                if let Some(rates) = moving::frame_rates(frame.tangent_at(moved.x, moved.dx_dxi)) {
                    let gq = generator * q;
                    let form = moving::strain_form(&(gq + gq.transpose()), &strains);
                    for (k, &rate) in rates.iter().enumerate() {
                        add_tangent(&form, k, rate);
                    }
                }
                if !carries.is_empty() {
                    let r = frame.rotation_at(gp.x, gp.dx_dxi);
                    for (slot, dq) in carries {
                        let q_dot = rotate_stiffness_of(dq, &r);
                        raw[*slot] += moving::strain_form(&q_dot, &strains) * gp.w;
                    }
                }
                for (l, acc) in l.iter_mut().zip(&acc) {
                    for (l, &a) in l.iter_mut().zip(acc) {
                        *l += moved.w * a;
                    }
                }
            }
        }
        if let Some(out) = carried_out.as_mut() {
            for (out, raw) in out.iter_mut().zip(&raw) {
                *out += raw + raw.transpose();
            }
        }
        let f = &self.properties.compliance;
        Matrix6::from_fn(|c, d| {
            let t = std::array::from_fn(|k| l[c][d].d[k] + l[d][c].d[k]);
            Dual::new(f[(c, d)], t)
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
        let q_ply = ply_stiffnesses(angles, c_bar);
        let (x1, _, x, y) = self.fields_dual(&q_ply, gps, hats);
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

    /// The central solutions `X₁, Y₁, X, Y` with the dual materials in section axes `q_ply`
    /// (per region) and (with `G` dual) node coordinates: their tangents by both systems'
    /// residuals through the factorisation ([`SectionAnalysis::compliance_dual`]).
    #[allow(clippy::type_complexity)]
    fn fields_dual<const N: usize, F, G>(
        &self,
        q_ply: &[Matrix6<Dual<N>>],
        gps: &[GaussPoint<G>],
        hats: Hats<'_, F>,
    ) -> (Vec<Dual<N>>, [Dual<N>; 36], Vec<Dual<N>>, [Dual<N>; 36])
    where
        Dual<N>: Mul<F, Output = Dual<N>> + Mul<G, Output = Dual<N>>,
        F: Scalar + Mul<G, Output = F>,
        G: Scalar,
    {
        let q_ply = q_ply.to_vec();
        let nd = 3 * self.model.mesh.nodes.len();
        let zero = Dual::<N>::constant(0.0);
        let t = force_derivative_map();

        // System 1 residual: [0; T] − K(b) [X̂₁; Ŷ₁] (f64 fields, dual stiffness).
        let (x1, y1) = {
            let (b, z) = self.model.b_and_z(
                Materials::PerRegion(&q_ply),
                gps,
                Fields {
                    u: Some(hats.x1),
                    u1: None,
                    psi: Some(hats.y1),
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
        (x1, y1, x, y)
    }

    /// `dF/db` of variables that leave the nodes in place by the adjoints of the
    /// two warping systems: two six-column solves and one pass over the integration points,
    /// whatever the number of variables.
    ///
    /// With `u = [X; Y]`, `u₁ = [X₁; Y₁]`, `K u₁ = [0; T]` and `K u = e + C u₁`
    /// (`C u₁ = ∫(SN)ᵀ Q [BN Z] u₁ − ∫[BN Z]ᵀ Q SN X₁`, the right-hand side of system 2), the
    /// compliance is the energy `F_cd = ∫ ε_cᵀ Q ε_d` of `ε = [BN Z] u + SN X₁`. Only `Q`
    /// depends on the variables, and
    ///
    /// `dF_cd = ∫ ε_cᵀ Q' ε_d + du_cᵀ w_d + du₁_cᵀ p_d + du_dᵀ w_c + du₁_dᵀ p_c`, with
    /// `w_d = ∫[BN Z]ᵀ Q ε_d`, `p_d = ∫(SN)ᵀ Q ε_d`, `K du = C' u₁ + C du₁ − K' u` and
    /// `K du₁ = −K' u₁`. The adjoints `λ = K⁻¹ w` and `μ = K⁻¹ (Cᵀ λ + p)` turn it into
    ///
    /// `dF_cd = ∫ α_dᵀ Q' ε_c + β_dᵀ Q' e₁_c + (c ↔ d)`, where `α = ε/2 − [BN Z] λ`,
    /// `β = SN λ_X − [BN Z] μ` and `e₁ = [BN Z] u₁`,
    ///
    /// and `Q' = T Q'_ply Tᵀ` at a point, so each region's integral is the contraction of
    /// its `Q'_ply` with the moments `Σ w (Tᵀ ε_c)(Tᵀ α_d)ᵀ + (Tᵀ e₁_c)(Tᵀ β_d)ᵀ`, accumulated
    /// once for all variables. The direct method ([`SectionAnalysis::compliance_dual`]) needs
    /// `12 N` tangent solves and dual fields instead; both are checked against each other in
    /// this module's tests.
    ///
    /// `q_tangents` are the variables' `Q'_ply` by region
    /// ([`SectionAnalysis::ply_stiffness_tangents`]: `[region] → [(slot, Q'_ply)]`) and
    /// `slots` their number.
    fn compliance_derivatives(
        &self,
        q_tangents: &[Vec<(usize, Matrix6<f64>)>],
        slots: usize,
    ) -> Vec<Matrix6<f64>> {
        let m = &self.model;
        let mut out = vec![Matrix6::zeros(); slots];
        if q_tangents.iter().all(Vec::is_empty) {
            return out;
        }
        let adjoints = self.compliance_adjoints();

        // The moments of each region that a variable changes, contracted with its Q'_ply.
        let mut elements_of: Vec<Vec<usize>> = vec![Vec::new(); m.mesh.regions.len()];
        for (e, el) in m.mesh.elements.iter().enumerate() {
            if !q_tangents[el.region].is_empty() {
                elements_of[el.region].push(e);
            }
        }
        for (r, tangents) in q_tangents.iter().enumerate() {
            if tangents.is_empty() {
                continue;
            }
            let moments = self.region_moments(r, &elements_of[r], adjoints);
            contract_moments(&moments, tangents, &mut out);
        }
        out
    }

    /// `Q'_ply` of each variable of `vars` in each region it changes:
    /// `[region] → [(slot in vars, Q'_ply)]` (Pa per unit of the variable).
    fn ply_stiffness_tangents(
        &self,
        design: &DesignMap,
        vars: &[usize],
    ) -> Vec<Vec<(usize, Matrix6<f64>)>> {
        let m = &self.model;
        let regions = &m.mesh.regions;
        let mut q_tangents: Vec<Vec<(usize, Matrix6<f64>)>> = vec![Vec::new(); regions.len()];
        for (slot, &v) in vars.iter().enumerate() {
            let var = &design.variables[v];
            debug_assert!(var.nodes.is_empty(), "a variable that moves nodes");
            let mut d_angle = vec![0.0; regions.len()];
            let mut d_c: Vec<Option<Matrix6<f64>>> = vec![None; regions.len()];
            for &(r, factor) in &var.links {
                d_angle[r] += factor;
            }
            for (r, dc) in &var.materials {
                *d_c[*r].get_or_insert_with(Matrix6::zeros) += dc;
            }
            for (r, region) in regions.iter().enumerate() {
                if d_angle[r] == 0.0 && d_c[r].is_none() {
                    continue;
                }
                let dc = d_c[r].unwrap_or_else(Matrix6::zeros);
                let c = m.c_bar[r].zip_map(&dc, |c, d| Dual::<1>::new(c, [d]));
                let angle = Dual::<1>::new(region.ply_angle, [d_angle[r]]);
                let q = rotate_stiffness_of(&c, &Region::ply_rotation(angle));
                q_tangents[r].push((slot, q.map(|x| x.d[0])));
            }
        }
        q_tangents
    }

    /// The adjoints `λ = K⁻¹ ∫[BN Z]ᵀ Q ε` and `μ = K⁻¹ (Cᵀ λ + p)` of
    /// [`SectionAnalysis::compliance_derivatives`], solved once.
    fn compliance_adjoints(&self) -> &ComplianceAdjoints {
        self.adjoints.get_or_init(|| self.solve_adjoints())
    }

    /// [`SectionAnalysis::compliance_adjoints`]: two six-column solves.
    fn solve_adjoints(&self) -> ComplianceAdjoints {
        let m = &self.model;
        let q = Materials::PerPoint(&self.q_points);
        let solve = |u: &[f64], psi: &[f64; 36]| {
            let mut rhs = m.pack(u, psi);
            self.llt.solve_columns(&mut rhs, 6);
            m.unpack(&rhs)
        };
        // λ = K⁻¹ ∫[BN Z]ᵀ Q ε
        let (lx, ly) = match &self.stress_projection {
            Some((b, z)) => solve(b, z),
            None => {
                let (b, z) = m.b_and_z(
                    q,
                    &m.gps,
                    Fields {
                        u: Some(&self.x),
                        u1: Some(&self.x1),
                        psi: Some(&self.y),
                    },
                );
                solve(&b, &z)
            }
        };
        // μ = K⁻¹ (Cᵀ λ + p): Cᵀ λ = ∫[BN Z]ᵀ Q SN λ_X − ∫(SN)ᵀ Q [BN Z] λ (on the X₁ rows),
        // p = ∫(SN)ᵀ Q ε (on the X₁ rows)
        let (mx, my) = {
            let (mut b, z) = m.b_and_z(
                q,
                &m.gps,
                Fields {
                    u: None,
                    u1: Some(&lx),
                    psi: None,
                },
            );
            let x_minus: Vec<f64> = self.x.iter().zip(&lx).map(|(a, b)| a - b).collect();
            let y_minus: [f64; 36] = std::array::from_fn(|i| self.y[i] - ly[i]);
            m.kernel(
                q,
                &m.gps,
                Fields {
                    u: Some(&x_minus),
                    u1: Some(&self.x1),
                    psi: Some(&y_minus),
                },
                Outputs {
                    b: None,
                    s: Some(&mut b),
                    z: None,
                    energy: None,
                },
            );
            solve(&b, &z)
        };
        ComplianceAdjoints { lx, ly, mx, my }
    }

    /// The moments `Σ w (Tᵀ ε_c)(Tᵀ α_d)ᵀ + (Tᵀ e₁_c)(Tᵀ β_d)ᵀ` of region `r` over the
    /// integration points of its elements `elements`: `moments[c][d][i·6 + j]`.
    fn region_moments(
        &self,
        r: usize,
        elements: &[usize],
        adjoints: &ComplianceAdjoints,
    ) -> [[[f64; 36]; 6]; 6] {
        let m = &self.model;
        let ComplianceAdjoints { lx, ly, mx, my } = adjoints;
        let fields = LagrangeFields::new((&self.x, &self.x1, &self.y, &self.y1), (lx, ly, mx, my));
        let mut moments = [[[0.0; 36]; 6]; 6];
        let mut strains = [[[0.0; 6]; 6]; 4];
        for &e in elements {
            let el = &m.mesh.elements[e];
            let nodes = &el.nodes[..el.kind.node_count()];
            for gp in &m.gps[m.gp_start[e]..m.gp_start[e + 1]] {
                let t = bond_stress_matrix(&m.mesh.regions[r].frame.rotation_at(gp.x, gp.dx_dxi));
                fields.at_into(nodes, gp, &mut strains);
                let [eps, alpha, e1, beta] = &strains;
                // Tᵀ a, in the ply axes
                let ply = |a: [f64; 6]| -> [f64; 6] {
                    std::array::from_fn(|j| (0..6).map(|i| t[(i, j)] * a[i]).sum())
                };
                let mut p_eps = [[0.0; 6]; 6];
                let mut p_alpha = [[0.0; 6]; 6];
                let mut p_e1 = [[0.0; 6]; 6];
                let mut p_beta = [[0.0; 6]; 6];
                for c in 0..6 {
                    p_eps[c] = ply(eps[c]);
                    p_alpha[c] = ply(alpha[c]);
                    p_e1[c] = ply(e1[c]);
                    p_beta[c] = ply(beta[c]);
                }
                for c in 0..6 {
                    for d in 0..6 {
                        let acc = &mut moments[c][d];
                        for i in 0..6 {
                            let (a, b) = (gp.w * p_eps[c][i], gp.w * p_e1[c][i]);
                            for j in 0..6 {
                                acc[i * 6 + j] += a * p_alpha[d][j] + b * p_beta[d][j];
                            }
                        }
                    }
                }
            }
        }
        moments
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

/// The most tangents of variables that leave the nodes in place a region may have to ride
/// along a pass over a moving section ([`Carried`]): each costs a congruence and a contraction
/// at each point (about 1 300 products), the moments about 3 500 whatever their number.
const CARRIED_AT_MOST: usize = 2;

/// The ply stiffnesses' tangents of variables that leave the nodes in place, taken along by
/// the pass over the points of a section whose nodes move
/// ([`SectionAnalysis::compliance_adjoint_dual`]).
struct Carried<'a> {
    /// `[region] → [(slot, Q'_ply)]`.
    tangents: &'a [Vec<(usize, Matrix6<f64>)>],
    /// The compliance derivatives of the slots, added to.
    out: &'a mut [Matrix6<f64>],
}

/// The adjoint solutions of [`SectionAnalysis::compliance_derivatives`], node-dof-major per
/// unit section force.
struct ComplianceAdjoints {
    /// Warping part of `λ = K⁻¹ ∫[BN Z]ᵀ Q ε`.
    lx: Vec<f64>,
    /// Generalised-strain part of `λ`.
    ly: [f64; 36],
    /// Warping part of `μ = K⁻¹ (Cᵀ λ + p)`.
    mx: Vec<f64>,
    /// Generalised-strain part of `μ`.
    my: [f64; 36],
}

/// Add to `out[slot]` the contraction `dF_cd = Σ_ij Q'_ij (moments[c][d] + moments[d][c])_ij`
/// of a region's moments with the `Q'_ply` of each variable that changes it.
fn contract_moments(
    moments: &[[[f64; 36]; 6]; 6],
    tangents: &[(usize, Matrix6<f64>)],
    out: &mut [Matrix6<f64>],
) {
    for (slot, dq) in tangents {
        let df = &mut out[*slot];
        for c in 0..6 {
            for d in 0..6 {
                let mut acc = 0.0;
                for i in 0..6 {
                    for j in 0..6 {
                        acc += dq[(i, j)] * (moments[c][d][i * 6 + j] + moments[d][c][i * 6 + j]);
                    }
                }
                df[(c, d)] += acc;
            }
        }
    }
}

impl Model {
    /// Gather a node-dof-major warping part `u` (`3·nodes × 6`) and a 6×6 generalised-strain
    /// part `psi` into a column-major right-hand side (`n_free + 6` rows × 6), the pinned
    /// components dropped: the inverse of [`Model::unpack`].
    fn pack(&self, u: &[f64], psi: &[f64; 36]) -> Vec<f64> {
        let n_tot = self.n_free + 6;
        let mut out = vec![0.0; n_tot * 6];
        for (g, &f) in self.dof.iter().enumerate() {
            if f != NONE {
                for c in 0..6 {
                    out[c * n_tot + f] = u[g * 6 + c];
                }
            }
        }
        for i in 0..6 {
            for c in 0..6 {
                out[c * n_tot + self.n_free + i] = psi[i * 6 + c];
            }
        }
        out
    }

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
        // A node's free components have consecutive numbers (`dof_map`): listing the neighbours
        // by their first number makes the rows below come out sorted.
        let first = self.first_dofs();
        let mut adj = node_neighbours(&self.mesh);
        for v in &mut adj {
            v.sort_by_key(|&n| first[n]);
        }
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

    /// The number of each node's first free component (`NONE` for a node without one); its
    /// free components follow it consecutively (`dof_map`).
    fn first_dofs(&self) -> Vec<usize> {
        (0..self.mesh.nodes.len())
            .map(|n| (0..3).map(|k| self.dof[3 * n + k]).min().unwrap_or(NONE))
            .collect()
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
        // The unknowns are numbered in the fill-reducing order of the node graph (`dof_map`),
        // the strains last: no permuted copy of the matrix.
        let symbolic = SparseCholesky::symbolic_in_order(k.symbolic(), Side::Lower)
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
        // The position of row `r` in column `c` (`r ≥ c`), by a binary search.
        let search = |r: usize, c: usize| -> usize {
            let col = &row_idx[col_ptr[c]..col_ptr[c + 1]];
            col_ptr[c]
                + col
                    .binary_search(&r)
                    .expect("entry in the assembled pattern")
        };
        // A node's free components have consecutive numbers from `first[node]` (`dof_map`), and
        // the rows of a column come sorted: column `c` of node B holds B's components from `c`
        // on, then each neighbour's block whole, then the six strains. So one search per pair
        // of an element's nodes places the whole block of the pair.
        let first = self.first_dofs();
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
            // offset[a][b]: where the block of node a starts in the first column of node b
            // (for a after b), relative to that column's start
            let mut offset = [[0usize; MAX_NODES]; MAX_NODES];
            for (a, &na) in el.nodes[..nn].iter().enumerate() {
                for (b, &nb) in el.nodes[..nn].iter().enumerate() {
                    if first[na] != NONE && first[nb] != NONE && first[na] > first[nb] {
                        offset[a][b] = search(first[na], first[nb]) - col_ptr[first[nb]];
                    }
                }
            }
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
                    let position = if i >= 3 * nn {
                        // a strain row: the last six of the warping column
                        col_ptr[gj + 1] - 6 + (i - 3 * nn)
                    } else {
                        let ((r, a), (c, b)) = if gi >= gj {
                            ((gi, i / 3), (gj, j / 3))
                        } else {
                            ((gj, j / 3), (gi, i / 3))
                        };
                        let (na, nb) = (el.nodes[a], el.nodes[b]);
                        if na == nb {
                            col_ptr[c] + (r - c)
                        } else {
                            col_ptr[c] + offset[a][b] - (c - first[nb]) + (r - first[na])
                        }
                    };
                    debug_assert_eq!(position, search(gi.max(gj), gi.min(gj)), "scatter position");
                    values[position] += ke[i][j];
                }
            }
        }
        for i in 0..6 {
            for j in 0..=i {
                let position = search(self.n_free + i, self.n_free + j);
                values[position] += a_block[i][j];
            }
        }
        (col_ptr, row_idx, values)
    }

    /// [`Model::kernel`]'s projections `(∫(BN)ᵀσ, ∫Zᵀσ)` of the stress of the fields `f`.
    fn b_and_z<S, F, G>(
        &self,
        materials: Materials<'_, S>,
        gps: &[GaussPoint<G>],
        f: Fields<'_, F>,
    ) -> (Vec<S>, [S; 36])
    where
        S: Scalar + Mul<F, Output = S> + Mul<G, Output = S>,
        F: Scalar + Mul<G, Output = F>,
        G: Scalar,
    {
        let mut b = vec![S::zero(); 3 * self.mesh.nodes.len() * 6];
        let mut z = [S::zero(); 36];
        self.kernel(
            materials,
            gps,
            f,
            Outputs {
                b: Some(&mut b),
                s: None,
                z: Some(&mut z),
                energy: None,
            },
        );
        (b, z)
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
                let eps = strains(&el.nodes[..nn], gp, f);
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
/// variables); the shape functions' gradients `dx` only when `gradients` (zero otherwise: the
/// adjoints' pass over a moving section takes the points' velocity gradients from `dx_dxi`).
fn geometry<G: Scalar>(
    mesh: &SectionMesh,
    nodes: &[[G; 2]],
    gradients: bool,
) -> (Vec<GaussPoint<G>>, Vec<usize>) {
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
                if gradients {
                    for i in 0..2 {
                        gp.dx[a][i] = inv[0][i] * dn[a][0] + inv[1][i] * dn[a][1];
                    }
                }
            }
            gps.push(gp);
        }
    }
    start.push(gps.len());
    (gps, start)
}

/// The nodes that share an element with each node (itself included), sorted.
fn node_neighbours(mesh: &SectionMesh) -> Vec<Vec<usize>> {
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); mesh.nodes.len()];
    for el in &mesh.elements {
        for &a in &el.nodes {
            adj[a].extend_from_slice(&el.nodes);
        }
    }
    for v in &mut adj {
        v.sort_unstable();
        v.dedup();
    }
    adj
}

/// Free-dof numbering with six pinned components that remove the rigid modes of the warping:
/// node by node in the fill-reducing order of the graph of the nodes with a free component
/// ([`sens::sparse::grouped_ordering`]), so that the warping matrix is assembled in the order
/// its factor eliminates (`SparseCholesky::symbolic_in_order`; the six strains follow).
fn dof_map(mesh: &SectionMesh) -> Result<(Vec<usize>, usize), SectionError> {
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
    // the nodes with a free component, in the fill-reducing order of their graph
    let has_free = |n: usize| (0..3).any(|k| !pinned[3 * n + k]);
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for (a, list) in node_neighbours(mesh).iter().enumerate() {
        if has_free(a) {
            row_idx.extend(list.iter().filter(|&&b| has_free(b)));
        }
        col_ptr.push(row_idx.len());
    }
    let graph = SymbolicSparseColMat::new_checked(nn, nn, col_ptr, None, row_idx);
    let identity: Vec<usize> = (0..nn).collect();
    let (order, _) = sens::sparse::grouped_ordering(graph.as_ref(), &identity)
        .map_err(|e| SectionError::Factorisation(format!("{e:?}")))?;
    let mut dof = vec![NONE; 3 * nn];
    let mut n_free = 0;
    for &n in &order {
        if !used[n] {
            continue;
        }
        for k in 0..3 {
            if !pinned[3 * n + k] {
                dof[3 * n + k] = n_free;
                n_free += 1;
            }
        }
    }
    Ok((dof, n_free))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{BoxWalls, GeneratedSection, PlySpec};
    use laminate::OrthotropicMaterial;

    const DEG: f64 = std::f64::consts::PI / 180.0;

    fn composite() -> OrthotropicMaterial {
        OrthotropicMaterial::new(
            [128e9, 10.1e9, 10.1e9],
            [5.36e9, 5.36e9, 5.36e9],
            [0.23, 0.23, 0.23],
            1586.0,
        )
        .unwrap()
    }

    /// Every derivative of the adjoint path against the direct (dual) path, each entry scaled
    /// by its natural size; returns the largest difference.
    fn adjoint_against_direct<const N: usize>(mesh: &SectionMesh, design: &DesignMap) -> f64 {
        let a = SectionAnalysis::new(mesh).unwrap();
        let adjoint = a.sensitivities_by::<N>(design, true).unwrap();
        let direct = a.sensitivities_by::<N>(design, false).unwrap();
        let p = a.properties();
        let mut worst: f64 = 0.0;
        for (x, y) in adjoint.derivatives.iter().zip(&direct.derivatives) {
            for i in 0..6 {
                for j in 0..6 {
                    let s = (p.stiffness[(i, i)] * p.stiffness[(j, j)]).sqrt();
                    worst = worst.max((x.stiffness[(i, j)] - y.stiffness[(i, j)]).abs() / s);
                    let s = (p.compliance[(i, i)] * p.compliance[(j, j)]).sqrt();
                    worst = worst.max((x.compliance[(i, j)] - y.compliance[(i, j)]).abs() / s);
                }
            }
            for k in 0..2 {
                // centres on the scale of the section (1 cm)
                worst = worst.max((x.shear_centre[k] - y.shear_centre[k]).abs() / 0.01);
                worst = worst.max((x.tension_centre[k] - y.tension_centre[k]).abs() / 0.01);
            }
            assert_eq!(x.mass_per_length, y.mass_per_length);
        }
        worst
    }

    /// The adjoint compliance derivatives are those of the direct method to round-off, for
    /// ply angles (alone and combined), a material constant, a density and a ply thickness
    /// (the adjoints with dual geometry, with the other variables of its chunk) on an
    /// off-centre tube and on an unsymmetric box; and a derivative is not zero (the
    /// comparison means something).
    #[test]
    fn adjoint_compliance_derivatives_equal_the_direct_ones() {
        let ply = |n: &str, a: f64, t: f64| PlySpec::new(n, composite(), a * DEG, t, 1);
        let generated = GeneratedSection::Tube {
            inner_radius: 0.01,
            plies: vec![
                ply("p0", 30.0, 5e-4),
                ply("p1", -45.0, 5e-4),
                ply("p2", 60.0, 5e-4),
            ],
            circumferential: 24,
        };
        let mesh = generated.mesh().unwrap().translated([0.002, 0.001]);
        let velocities = generated
            .node_velocities(|p| f64::from(u8::from(p.name == "p1")))
            .unwrap();
        let d_e1 =
            composite().stiffness_derivative(&[1e9, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0]);
        let mut design = DesignMap::new()
            .with_named_variable(&mesh, "inner", &[("p0", 1.0)])
            .unwrap()
            .with_named_variable(&mesh, "balanced", &[("p1", 1.0), ("p2", -1.0)])
            .unwrap()
            .with_material_variable("E1", vec![(1, d_e1)])
            .with_geometry_variable("t1", &velocities)
            .with_named_variable(&mesh, "double", &[("p2", 2.0)])
            .unwrap();
        design.variables.push(crate::DesignVariable {
            name: "rho0".into(),
            links: Vec::new(),
            materials: Vec::new(),
            densities: vec![(0, 1.0)],
            nodes: Vec::new(),
        });
        let worst = adjoint_against_direct::<1>(&mesh, &design);
        assert!(worst < 1e-10, "tube, one variable a chunk: {worst:e}");
        let worst = adjoint_against_direct::<2>(&mesh, &design);
        assert!(worst < 1e-10, "tube, two variables a chunk: {worst:e}");

        // Every node moving its own way (the elements distorted, the points' radial frames
        // and the frames along the elements' directions turning), with an angle in the chunk.
        let shake: Vec<[f64; 2]> = (0..mesh.nodes.len())
            .map(|n| {
                let n = n as f64;
                [0.01 * (1.3 * n).sin(), 0.01 * (2.1 * n + 0.4).cos()]
            })
            .collect();
        let mut shaken = DesignMap::new().with_geometry_variable("shake", &shake);
        shaken.variables[0].links.push((2, 1.0));
        let shaken = shaken.with_geometry_variable("t1", &velocities);
        let worst = adjoint_against_direct::<2>(&mesh, &shaken);
        assert!(worst < 1e-10, "tube, nodes shaken: {worst:e}");
        let mut along = mesh.clone();
        for (r, region) in along.regions.iter_mut().enumerate() {
            region.frame = crate::mesh::WallFrame::AlongElement(if r == 1 {
                crate::mesh::ElementDirection::Eta
            } else {
                crate::mesh::ElementDirection::Xi
            });
        }
        let worst = adjoint_against_direct::<2>(&along, &shaken);
        assert!(
            worst < 1e-10,
            "tube with frames along its elements, shaken: {worst:e}"
        );

        let walls = BoxWalls {
            top: vec![ply("a", 30.0, 0.001), ply("b", -10.0, 0.0005)],
            bottom: vec![ply("a", 60.0, 0.0008)],
            left: vec![ply("a", 0.0, 0.001), ply("b", 45.0, 0.001)],
            right: vec![ply("a", -20.0, 0.0006)],
        };
        let mesh = crate::thin_walled_box(0.03, 0.02, &walls, 6, 4).unwrap();
        let design = DesignMap::each_region(&mesh);
        let worst = adjoint_against_direct::<4>(&mesh, &design);
        assert!(worst < 1e-10, "box: {worst:e}");
        // the analysis for derivatives gives the same derivatives to the last bit
        let projected = SectionAnalysis::for_derivatives(&mesh).unwrap();
        assert_eq!(
            projected.sensitivities::<4>(&design).unwrap(),
            SectionAnalysis::new(&mesh)
                .unwrap()
                .sensitivities::<4>(&design)
                .unwrap()
        );
        let a = SectionAnalysis::new(&mesh).unwrap();
        let s = a.sensitivities::<4>(&design).unwrap();
        let p = a.properties();
        assert!(
            s.derivatives[0].stiffness[(0, 0)].abs() > 1e-3 * p.stiffness[(0, 0)],
            "{}",
            s.derivatives[0].stiffness[(0, 0)]
        );
    }
}
