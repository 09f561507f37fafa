//! The adjoint of a dual modal body's dependence on its eigenvectors' derivatives: what lets
//! the adjoint method contract the updated modes' derivatives without one Nelson solve per
//! design variable (docs/design.md §3, "The adjoint method").
//!
//! A dual body of [`crate::modal_body_dual`] carries, for each design variable, tangents that
//! are linear in the retained eigenvectors' derivatives `X_b`: the modes' columns
//! (`T X_b`, `T` the expansion to all dof, and the couplings' rows fitted to them), and with
//! static correction modes the shapes' derivatives (`G_b = Ψ_b − X_b A − X(X_bᵀMΨ + …)`,
//! `Φ_b = G_b C`), the modal stiffness and mass `d(BᵀKB)`, `d(BᵀMB)` of the basis
//! `B = [X, Φ]` (the eigenmodes' block of the stiffness excepted: it is `diag(λ + λ_b)`) and the
//! damping made from them. With the adjoint of every datum of the body (`bar`), the sum
//! `Σ bar · tangents` of a variable is therefore that of the body made without the
//! eigenvectors' part ([`crate::ModeDerivatives::eigenvectors_by_adjoint`]) plus `⟨Ȳ, X_b⟩`,
//! where [`eigenvector_adjoints`] gives `Ȳ` once for all variables and
//! [`crate::eigenvector_adjoint`] contracts it with one solve per mode.

use nalgebra::DMatrix;

use crate::body::{ModalAnalysis, damping_laws, floored_weights, split_clusters};
use crate::correction::times;
use crate::error::FemError;
use crate::modal::ModalBody;
use crate::sensitivity::ModeDerivatives;

/// The adjoint `Ȳ` (free dof × computed modes; zero for the modes not retained) of the
/// retained eigenvectors' derivatives in the dual bodies of `analysis` whose data have the
/// adjoints `bar` (a body of their shape, each datum its adjoint): see the module's doc.
/// `derivs` are the modes' derivatives for every design variable. Refused where a variable
/// splits repeated eigenvalues (the bodies' tangents then depend on the chunk of variables
/// they are made for).
pub fn eigenvector_adjoints(
    analysis: &ModalAnalysis,
    derivs: &ModeDerivatives,
    bar: &ModalBody<f64>,
) -> Result<DMatrix<f64>, FemError> {
    let all: Vec<usize> = (0..derivs.eigenvalues.len()).collect();
    if !split_clusters(analysis, derivs, &all)?.is_empty() {
        return Err(FemError::Derivatives(
            "a design variable splits repeated eigenvalues: the eigenvectors' derivatives \
             cannot be contracted by the adjoint"
                .into(),
        ));
    }
    let (kept, p) = (&analysis.kept, analysis.n_modes);
    let pe = kept.len();
    // the couplings' rows back to the mesh's, then to the free dof
    let n_mesh = bar.modes.nrows() - 6 * analysis.couplings.len();
    let mut modes_bar = bar.modes.rows(0, n_mesh).into_owned();
    for (c, d) in analysis.couplings.iter().enumerate() {
        let rows = bar.modes.rows(n_mesh + 6 * c, 6).into_owned();
        d.rows_adjoint(&rows, &mut modes_bar);
    }
    let free_bar = analysis.assembly.restrict_columns(&modes_bar);
    let mut y_bar = free_bar.columns(0, pe).into_owned();
    if let Some(correction) = &analysis.correction {
        let s = correction.shapes.ncols();
        let r = pe + s;
        let x = analysis.pairs.vectors.select_columns(kept);
        let mut phi_bar = free_bar.columns(pe, s).into_owned();
        // the modal stiffness's and damping's adjoints, their diagonals with them
        let square = |m: &Option<Box<DMatrix<f64>>>, diagonal: &[f64]| {
            let mut out = m
                .as_deref()
                .cloned()
                .unwrap_or_else(|| DMatrix::zeros(r, r));
            for (i, d) in diagonal.iter().enumerate() {
                out[(i, i)] += d;
            }
            out
        };
        let mut k_bar = square(&bar.stiffness_matrix, &bar.eigenvalues);
        let c_bar = square(&bar.damping_matrix, &bar.modal_damping);
        let mut m_bar = DMatrix::zeros(r, r);
        // the damping outside the eigenmodes' block: linear in K', M'
        let lambda: Vec<f64> = (kept.iter().map(|&i| analysis.pairs.values[i]))
            .chain(correction.values.iter().copied())
            .collect();
        let fit = (analysis.options.damping)
            .map(|d| d.coefficients(&analysis.pairs.values[..p]))
            .transpose()?;
        let outside = |i: usize, j: usize| i >= pe || j >= pe;
        match analysis.options.correction_damping.floor()? {
            Some(z) => {
                let laws = damping_laws(&lambda, pe, fit.unwrap_or((0.0, 0.0)), z);
                for i in 0..r {
                    for j in (0..r).filter(|&j| outside(i, j)) {
                        let (wk, wm) = floored_weights(&laws, &lambda, i, j);
                        k_bar[(i, j)] += c_bar[(i, j)] * wk;
                        m_bar[(i, j)] += c_bar[(i, j)] * wm;
                    }
                }
            }
            None => {
                if let Some((alpha, beta)) = fit {
                    for i in 0..r {
                        for j in (0..r).filter(|&j| outside(i, j)) {
                            k_bar[(i, j)] += c_bar[(i, j)] * beta;
                            m_bar[(i, j)] += c_bar[(i, j)] * alpha;
                        }
                    }
                }
            }
        }
        // the eigenmodes' block of the stiffness is theirs, not d(BᵀKB)'s
        k_bar.view_mut((0, 0), (pe, pe)).fill(0.0);
        // d(BᵀAB) = B_bᵀAB + BᵀAB_b + …: B̄_b = K B (K̄ + K̄ᵀ) + M B (M̄ + M̄ᵀ)
        let mut b = DMatrix::zeros(x.nrows(), r);
        b.columns_mut(0, pe).copy_from(&x);
        b.columns_mut(pe, s).copy_from(&correction.shapes);
        let b_bar = times(&analysis.k, &b) * (&k_bar + k_bar.transpose())
            + times(&analysis.m, &b) * (&m_bar + m_bar.transpose());
        y_bar += b_bar.columns(0, pe);
        phi_bar += b_bar.columns(pe, s);
        y_bar += correction.eigenvector_adjoint(&analysis.m, &x, &phi_bar);
    }
    let mut out = DMatrix::zeros(y_bar.nrows(), analysis.pairs.values.len());
    for (j, &i) in kept.iter().enumerate() {
        out.set_column(i, &y_bar.column(j));
    }
    Ok(out)
}
