//! The mechanism's dual models for the design sensitivities, one chunk of `N` variables at a
//! time ([`DualChunks`]): the direct method integrates all chunks together, the adjoint
//! contracts them one after another, `flexsens check` builds each once.

use nalgebra::DMatrix;

use mbs::{Body, DesignModel, Model};
use sens::Dual;

use crate::deck::Source;
use crate::deck::design::DesignVariable;
use crate::error::CliError;
use crate::study::Mechanism;
use crate::study::StressInput;

/// All the dual models at once (one per chunk of `N` variables: modes, frequencies, correction
/// modes and masses with their derivatives; [`DualChunks::design_model`]) and each flexible
/// body's frequency derivatives: what the operating-point command differentiates with.
#[allow(clippy::type_complexity)]
pub(crate) fn dual_models<const N: usize>(
    src: &Source,
    mech: &Mechanism,
) -> Result<(DesignModel<N>, Vec<(String, DMatrix<f64>)>), CliError> {
    let chunks = DualChunks::<N>::new(src, mech)?;
    Ok((chunks.design_model()?, chunks.frequencies()))
}

/// The mechanism's dual models, one chunk of `N` design variables at a time: the derivatives
/// of every flexible body's modes with respect to all variables (Nelson's method, made once)
/// and what builds any chunk's `Model<Dual<N>>` from them. The direct method integrates all
/// chunks together ([`Self::design_model`]); the adjoint contracts one after another
/// ([`Self::chunk`]), so that only one is held.
pub(crate) struct DualChunks<'a, const N: usize> {
    src: &'a Source,
    mech: &'a Mechanism,
    update: fem::ModeUpdate,
    /// Per flexible part of the mechanism: `K_b`, `M_b` and the mode derivatives.
    derivatives: Vec<(Vec<fem::DesignMatrices>, fem::ModeDerivatives)>,
}

impl<'a, const N: usize> DualChunks<'a, N> {
    pub(crate) fn new(src: &'a Source, mech: &'a Mechanism) -> Result<Self, CliError> {
        Self::with(src, mech, false)
    }

    /// [`Self::new`], the updated modes' eigenvector derivatives left to the adjoint method
    /// where it can contract them (`fem::eigenvector_adjoints`: no variable splits repeated
    /// eigenvalues) when `by_adjoint`: the chunks' bodies then leave them out of their tangents
    /// and [`Self::eigenvector_gradients`] adds their part.
    pub(crate) fn with(
        src: &'a Source,
        mech: &'a Mechanism,
        by_adjoint: bool,
    ) -> Result<Self, CliError> {
        let update = if mech.design.fixed_modes {
            fem::ModeUpdate::Fixed
        } else {
            fem::ModeUpdate::Updated
        };
        let derivatives = (mech.flexible.iter())
            .map(|part| {
                let (name, span) = (part.name.as_str(), part.span.clone());
                let built = &part.built;
                let analysis = &part.analysis;
                if by_adjoint && update == fem::ModeUpdate::Updated {
                    // the eigenvalues' derivatives only, unless a variable splits a cluster
                    let fixed = fem::ModeUpdate::Fixed;
                    let (dm, mut d) =
                        built.mode_derivatives::<N>(src, name, span.clone(), analysis, fixed)?;
                    if !fem::splits_clusters(&analysis.pairs, &dm).contains(&true) {
                        d.eigenvectors_by_adjoint = true;
                        return Ok((dm, d));
                    }
                }
                built.mode_derivatives::<N>(src, name, span, analysis, update)
            })
            .collect::<Result<_, CliError>>()?;
        Ok(Self {
            src,
            mech,
            update,
            derivatives,
        })
    }

    /// Whether some body's eigenvector derivatives are left to the adjoint method
    /// ([`Self::with`]).
    pub(crate) fn eigenvectors_by_adjoint(&self) -> bool {
        (self.derivatives.iter()).any(|(_, d)| d.eigenvectors_by_adjoint)
    }

    /// Per objective, the part of its gradient that the eigenvector derivatives left to the
    /// adjoint method make ([`Self::with`]), from the adjoints `data` of the model's data (per
    /// objective, in `Model::map`'s order: `mbs::AdjointSweep::data_adjoints`) of the swept
    /// model `swept` (a chunk's values).
    pub(crate) fn eigenvector_gradients(
        &self,
        swept: &Model<f64>,
        data: &[Vec<f64>],
    ) -> Result<Vec<Vec<f64>>, CliError> {
        let m = self.mech.design.variables.len();
        let mut out = vec![vec![0.0; m]; data.len()];
        for (part, (matrices, derivatives)) in self.mech.flexible.iter().zip(&self.derivatives) {
            if !derivatives.eigenvectors_by_adjoint {
                continue;
            }
            let bars =
                super::eigenvector_adjoint::modal_body_adjoints(self.src, swept, part, data)?;
            let an = &part.analysis;
            for (g, bar) in out.iter_mut().zip(&bars) {
                let fem_error = |e| {
                    crate::study::flexible::fem_error(self.src, &part.name, part.span.clone(), e)
                };
                let y_bar = fem::eigenvector_adjoints(an, derivatives, bar).map_err(fem_error)?;
                let part_g =
                    fem::eigenvector_adjoint(&an.k, &an.m, &an.pairs, matrices, &y_bar, None)
                        .map_err(fem_error)?;
                g.iter_mut().zip(part_g).for_each(|(g, p)| *g += p);
            }
        }
        Ok(out)
    }

    /// The variables' chunks (`sens::chunk_ranges`).
    pub(crate) fn ranges(&self) -> Vec<std::ops::Range<usize>> {
        sens::chunk_ranges(self.mech.design.variables.len(), N).collect()
    }

    /// Per flexible body: `df_k/db_j` (rows: the retained modes).
    pub(crate) fn frequencies(&self) -> Vec<(String, DMatrix<f64>)> {
        (self.mech.flexible.iter().zip(&self.derivatives))
            .map(|(part, (_, d))| (part.name.clone(), d.frequency_derivatives(&part.analysis)))
            .collect()
    }

    /// The model whose tangents are the derivatives with respect to the variables of `range`
    /// (one of [`Self::ranges`]).
    pub(crate) fn chunk(&self, range: &std::ops::Range<usize>) -> Result<Model<Dual<N>>, CliError> {
        let (src, mech) = (self.src, self.mech);
        let mut model = mech.model.map(Dual::<N>::constant);
        for (part, (matrices, derivatives)) in mech.flexible.iter().zip(&self.derivatives) {
            let built = &part.built;
            let at = (matrices.as_slice(), derivatives, range.start);
            let named = (part.name.as_str(), part.span.clone());
            let (body, props) =
                built.design_body_chunk::<N>(src, named, &part.analysis, at, self.update)?;
            // the laminates of the chunk's seeded design, as its properties were made
            let seeded = sens::seed_chunk::<N>(built.design.values(), range.start);
            let stresses = StressInput::of((src, &part.name), &part.def, built, || {
                built.design.stress_parts(&seeded)
            })?;
            let body = crate::study::flexible_model_body(
                &part.name,
                &built.mesh,
                &props,
                &part.analysis,
                body,
                (part.stiffening, stresses),
            )
            .map_err(|e| {
                crate::study::flexible::fem_error(src, &part.name, part.span.clone(), e)
            })?;
            *model.body_mut(part.id) = Body::Flexible(body);
        }
        // rigid bodies' masses and inertias and actuators' gains, seeded in the chunk of their
        // variable
        for (k, j) in range.clone().enumerate() {
            let v = &mech.design.variables[j];
            let mut d = [0.0; N];
            d[k] = 1.0;
            crate::study::set_parameter(&mut model, mech, &v.target, Dual::new(v.value, d));
        }
        Ok(model)
    }

    /// All chunks together, with the variables' error scales.
    pub(crate) fn design_model(&self) -> Result<DesignModel<N>, CliError> {
        let chunks = (self.ranges().iter())
            .map(|range| self.chunk(range))
            .collect::<Result<Vec<_>, _>>()?;
        let scales = self.mech.design.variables.iter().map(error_scale);
        DesignModel::new(chunks, self.mech.design.variables.len())
            .and_then(|d| d.with_variable_scales(scales.collect()))
            .map_err(|e| CliError::computation(self.src, e))
    }

    /// Every chunk built once and dropped (what `flexsens check` needs: the refusals of a
    /// run with sensitivities).
    pub(crate) fn check_all(&self) -> Result<(), CliError> {
        self.ranges()
            .iter()
            .try_for_each(|range| self.chunk(range).map(drop))
    }
}

/// A variable's scale in the sensitivities' error weights
/// (`mbs::DesignModel::with_variable_scales`): its derivatives are weighted as the responses'
/// change under a change of one degree of an angle (whose nominal value has no size: 0° is a
/// lay-up like any other), and of the nominal magnitude of any other variable (a thickness, a
/// modulus, a mass; one unit if it is zero).
fn error_scale(v: &DesignVariable) -> f64 {
    if v.unit == "deg" || !(v.value.is_finite() && v.value != 0.0) {
        1.0
    } else {
        v.value.abs()
    }
}
