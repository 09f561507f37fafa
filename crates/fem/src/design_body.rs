//! Design-dependent flexible bodies: from a body's modal analysis and the properties its design
//! variables give, the dual modal bodies that `mbs::DesignModel` takes, one per chunk of `N`
//! variables, with every derivative the reduced body carries (eigenvalues, mode shapes for
//! updated modes, modal damping, static correction modes, lumped masses and inertias).
//!
//! This is the library path of the chain laminate or section design → modes →
//! `Model<Dual<N>>`: the command line builds its bodies with it, and
//! `crates/mbs/examples/flexible_slider_crank.rs` shows it on a slider-crank built in Rust.

use nalgebra::{DMatrix, Vector3};
use sens::{Dual, chunk_ranges, seed_chunk};

use crate::assembly::{Properties, lumped_nodal_masses};
use crate::body::{ModalAnalysis, ModeUpdate, analysis_derivatives, modal_body_dual};
use crate::error::FemError;
use crate::mesh::Mesh;
use crate::modal::ModalBody;
use crate::sensitivity::{DesignMatrices, ModeDerivatives};

/// A body's dual modal bodies for all its design variables ([`design_bodies`]).
#[derive(Clone, Debug)]
pub struct DesignBodies<const N: usize> {
    /// One body per chunk of `N` variables, in order (`sens::chunk_ranges`): its tangents are
    /// the derivatives with respect to that chunk's variables.
    pub chunks: Vec<ModalBody<Dual<N>>>,
    /// The element properties of each chunk's seeded design (what its second-order field,
    /// [`crate::second_order_field`], needs besides the body).
    pub properties: Vec<Properties<Dual<N>>>,
    /// The derivatives of the analysis's modes for every variable.
    pub derivatives: ModeDerivatives,
    /// `K_b`, `M_b` of every variable on the analysis's dof.
    pub matrices: Vec<DesignMatrices>,
}

impl<const N: usize> DesignBodies<N> {
    /// `∂f/∂b` of the retained eigenmodes ([`ModeDerivatives::frequency_derivatives`]).
    pub fn frequency_derivatives(&self, analysis: &ModalAnalysis) -> DMatrix<f64> {
        self.derivatives.frequency_derivatives(analysis)
    }
}

impl ModeDerivatives {
    /// `∂f/∂b` of `analysis`'s retained eigenmodes (Hz per unit of each variable; rows: the
    /// modes of [`ModalAnalysis::kept`], columns: the variables).
    pub fn frequency_derivatives(&self, analysis: &ModalAnalysis) -> DMatrix<f64> {
        let kept = &analysis.kept;
        let mut df = DMatrix::zeros(kept.len(), self.eigenvalues.len());
        for (j, dl) in self.eigenvalues.iter().enumerate() {
            for (k, &i) in kept.iter().enumerate() {
                let (l, d) = (analysis.pairs.values[i], dl[i]);
                // f = √λ / 2π ⇒ df = dλ / (4π √λ)
                df[(k, j)] = d / (4.0 * std::f64::consts::PI * l.max(0.0).sqrt());
            }
        }
        df
    }
}

/// The dual modal bodies of `analysis` (of `mesh`, with the nominal `properties`) for the
/// design variables at `b`: `props(b)` gives the element properties of a dual design vector
/// (one code path for the values and their derivatives). Mode derivatives by Nelson's method
/// ([`analysis_derivatives`], repeated eigenvalues handled), fixed- or updated-mode; each
/// chunk's body from [`modal_body_dual`], with the mesh nodes' lumped masses and inertias
/// evaluated on that chunk's seeded design (a density or a thickness moves them).
pub fn design_bodies<const N: usize, F>(
    mesh: &Mesh,
    properties: &Properties<f64>,
    analysis: &ModalAnalysis,
    b: &[f64],
    mut props: F,
    update: ModeUpdate,
) -> Result<DesignBodies<N>, FemError>
where
    F: FnMut(&[Dual<N>]) -> Properties<Dual<N>>,
{
    let (matrices, derivatives) =
        analysis_derivatives::<N, _>(mesh, analysis, b, &mut props, update)?;
    let mut chunks = Vec::new();
    let mut seeded_properties = Vec::new();
    for range in chunk_ranges(b.len(), N) {
        let chunk = (matrices.as_slice(), &derivatives, range.start);
        let (body, seeded) =
            design_body_chunk(mesh, properties, analysis, b, chunk, &mut props, update)?;
        chunks.push(body);
        seeded_properties.push(seeded);
    }
    Ok(DesignBodies {
        chunks,
        properties: seeded_properties,
        derivatives,
        matrices,
    })
}

/// One chunk's dual modal body of [`design_bodies`], from the derivatives of all variables
/// ([`analysis_derivatives`]) `(matrices, derivatives)` and the chunk's first variable: its
/// tangents are the derivatives with respect to the `N` variables from there, its lumped
/// masses and inertias evaluated on the chunk's seeded design; with the element properties of
/// that design. A caller that needs one chunk at a time (an adjoint contraction) builds them
/// so instead of keeping all.
pub fn design_body_chunk<const N: usize, F>(
    mesh: &Mesh,
    properties: &Properties<f64>,
    analysis: &ModalAnalysis,
    b: &[f64],
    (matrices, derivatives, start): (&[DesignMatrices], &ModeDerivatives, usize),
    mut props: F,
    update: ModeUpdate,
) -> Result<(ModalBody<Dual<N>>, Properties<Dual<N>>), FemError>
where
    F: FnMut(&[Dual<N>]) -> Properties<Dual<N>>,
{
    let mut body = modal_body_dual::<N>(
        mesh,
        properties,
        analysis,
        matrices,
        derivatives,
        start,
        update,
    )?;
    let seeded = props(&seed_chunk::<N>(b, start));
    let (m, mu) = lumped_nodal_masses(mesh, &seeded, &analysis.options.element)?;
    // the mesh's nodes; the couplings' nodes after them carry no mass
    for (k, (m, mu)) in m.into_iter().zip(mu).enumerate() {
        body.node_masses[k] = m;
        body.node_inertias[k] = Vector3::new(mu[0], mu[1], mu[2]);
    }
    Ok((body, seeded))
}
