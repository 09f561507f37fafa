//! One evaluation of the optimisation problem: the deck built at a design, and the
//! objective and constrained quantities read with their exact gradients.

use super::*;

impl Problem<'_> {
    /// The `--set` arguments that write the design `x` into the deck (the optimum's deck).
    pub(super) fn sets(&self, x: &[f64]) -> Vec<String> {
        let mut sets = self.overrides.to_vec();
        for (v, &b) in self.variables.iter().zip(x) {
            sets.extend(v.overrides(b));
        }
        sets
    }

    /// An error of the evaluation at `[optimize]`.
    fn at_optimize(&self, message: String) -> CliError {
        CliError::Input(self.src.error(None, Some("optimize".into()), message))
    }

    /// The speed, the frequency and its gradient of linearised mode `mode` at operating point
    /// `point` (from 0) of `points`.
    fn operating_mode(
        &self,
        points: &[crate::commands::operating::Point],
        point: usize,
        mode: usize,
    ) -> Result<(f64, f64, Vec<f64>), CliError> {
        let p = &points[point];
        let m = p.modes.get(mode).ok_or_else(|| {
            self.at_optimize(format!(
                "operating point {} has {} modes, not {}",
                point + 1,
                p.modes.len(),
                mode + 1
            ))
        })?;
        let grad = match &p.frequency_gradients {
            Some(g) => g.row(mode).iter().copied().collect(),
            None => Vec::new(),
        };
        Ok((p.speed, m.frequency_hz(), grad))
    }

    /// Every quantity the problem reads, with its gradient, at the design `x`: the validated
    /// model moved there in memory.
    pub(super) fn evaluate(&self, x: &[f64]) -> Result<Eval, CliError> {
        let src = &self.src;
        // the run, once, when an objective of it is asked for
        let objectives = match &self.study {
            Some(study) => {
                let c = crate::commands::compute::compute(src, &study.at(src, x)?, None)?;
                c.objectives
                    .into_iter()
                    .map(|o| (o.name, (o.value, o.gradient, o.unit)))
                    .collect()
            }
            None => BTreeMap::new(),
        };
        // the operating points, once, when a quantity of theirs is asked for
        let operating = match &self.operating {
            Some((mech, def)) => Some(crate::commands::operating::operating_points(
                src,
                &mech.at(src, x)?,
                def,
            )?),
            None => None,
        };
        let mode_at = |point: usize, mode: usize| {
            self.operating_mode(operating.as_deref().expect("computed"), point, mode)
        };
        let lam = self
            .design
            .laminates_at(&self.laminates, x)
            .map_err(|(name, e)| at_design(src, format!("design variable `{name}`"), x, e))?;
        let design = self.design.at(x);
        // each flexible body's modal analysis and masses once per evaluation
        let mut bodies = BTreeMap::<&String, FlexibleQuantities>::new();
        let mut flexible = |body: &String| -> Result<FlexibleQuantities, CliError> {
            let (name, (def, span)) = self
                .bodies
                .get_key_value(body)
                .expect("constrained bodies are validated");
            if let Some(b) = bodies.get(name) {
                return Ok(b.clone());
            }
            let def = def.at(&lam).map_err(|e| {
                at_design(
                    src,
                    format!("body `{name}`"),
                    x,
                    format!("its section: {e}"),
                )
            })?;
            let b = flexible_quantities(src, name, span.clone(), &def, &design)?;
            bodies.insert(name, b.clone());
            Ok(b)
        };
        let mut read = |q: &Quantity| -> Result<(f64, Vec<f64>, &'static str), CliError> {
            Ok(match q {
                Quantity::Objective { name } => objectives[name].clone(),
                Quantity::Frequency { body, mode } => {
                    let b = flexible(body)?;
                    let n = b.frequencies.len();
                    let f = b.frequencies.get(*mode).ok_or_else(|| {
                        self.at_optimize(format!(
                            "frequency.{body}.{}: the body keeps {n} modes",
                            mode + 1
                        ))
                    })?;
                    (*f, b.d_frequencies[*mode].clone(), "Hz")
                }
                Quantity::Mass { body } if self.bodies.contains_key(body) => {
                    let b = flexible(body)?;
                    (b.mass, b.d_mass, "kg")
                }
                Quantity::ArealMass { laminate } => {
                    let def = &lam.laminates[laminate];
                    let d = crate::study::flexible::shell_design(
                        &[crate::deck::bodies::ShellLaminate::of(laminate, def)],
                        DesignRequest::Variables(&design.variables),
                    );
                    let grad = crate::commands::laminate::derivatives(&d)
                        .iter()
                        .map(|k| k.mass_per_area)
                        .collect();
                    (def.stack.stiffness().mass_per_area, grad, "kg/m^2")
                }
                Quantity::OperatingFrequency { point, mode } => {
                    let (_, f, grad) = mode_at(*point, *mode)?;
                    (f, grad, "Hz")
                }
                Quantity::OrderMargin { point, mode, order } => {
                    let (speed, f, grad) = mode_at(*point, *mode)?;
                    let line = *order as f64 * speed / (2.0 * std::f64::consts::PI);
                    (f / line - 1.0, grad.iter().map(|d| d / line).collect(), "1")
                }
                Quantity::Mass { body } => {
                    // a rigid body: its mass variable's value, or its mass in the deck
                    let mut mass = self.rigid_masses[body];
                    let grad = self
                        .variables
                        .iter()
                        .zip(x)
                        .map(|(v, &xj)| {
                            if v.target.rigid() == Some((body, None)) {
                                mass = xj;
                                1.0
                            } else {
                                0.0
                            }
                        })
                        .collect();
                    (mass, grad, "kg")
                }
            })
        };
        let n = self.variables.len();
        let gradient_of = |q: &Quantity, g: &[f64]| -> Result<(), CliError> {
            if g.len() == n {
                return Ok(());
            }
            Err(self.at_optimize(format!(
                "{} has no gradient (its response has no sensitivities, or [sensitivity] \
                 enabled = false): an optimisation needs one",
                q.label()
            )))
        };
        let (f, df, unit) = read(&self.def.objective)?;
        gradient_of(&self.def.objective, &df)?;
        let mut units = vec![unit.to_string()];
        let mut q = Vec::new();
        let mut dq = Vec::new();
        for c in &self.def.constraints {
            let (v, g, unit) = read(&c.quantity)?;
            gradient_of(&c.quantity, &g)?;
            units.push(unit.to_string());
            q.push(v);
            dq.push(g);
        }
        let ok = |x: f64| x.is_finite();
        let all_ok = ok(f)
            && df.iter().copied().all(ok)
            && q.iter().copied().all(ok)
            && dq.iter().flatten().copied().all(ok);
        if !all_ok {
            return Err(runtime("a quantity or its gradient is not finite"));
        }
        Ok(Eval {
            units,
            f,
            df,
            q,
            dq,
        })
    }

    /// The constraints as `g ≤ 0` in physical units: `(constraint, sign)` with
    /// `g = sign (q − bound)`; an equality gives both signs.
    pub(super) fn inequalities(&self) -> Vec<(usize, f64)> {
        let mut g = Vec::new();
        for (i, (bound, _)) in self.limits.iter().enumerate() {
            match bound {
                Bound::AtLeast(_) => g.push((i, -1.0)),
                Bound::AtMost(_) => g.push((i, 1.0)),
                Bound::Equals(_) | Bound::EqualsNominal => {
                    g.push((i, 1.0));
                    g.push((i, -1.0));
                }
            }
        }
        g
    }

    pub(super) fn bound_value(&self, i: usize) -> f64 {
        match self.limits[i].0 {
            Bound::AtLeast(b) | Bound::AtMost(b) | Bound::Equals(b) => b,
            Bound::EqualsNominal => unreachable!("resolved when the problem is made"),
        }
    }

    /// The largest violation of a constraint, relative to its scale.
    pub(super) fn violation(&self, e: &Eval) -> f64 {
        self.inequalities()
            .into_iter()
            .map(|(i, s)| (s * (e.q[i] - self.bound_value(i)) / self.limits[i].1).max(0.0))
            .fold(0.0, f64::max)
    }

    /// KKT stationarity of the (minimised) objective at `x` with the constraints within
    /// `FEASIBLE` of their bounds taken as active: the multipliers `λ ≥ 0` (free in sign for
    /// an equality) that best cancel the gradient on the variables not at a bound, and the
    /// largest remaining component of the Lagrangian's gradient, as the change of the
    /// objective across the variable's range relative to the objective (`|r_j| (upper_j −
    /// lower_j) / |f|`; components at a bound count only when they point out of the box): 0 at
    /// a KKT point. Multipliers are in the objective's unit per the constraint quantity's
    /// unit (`dF*/d bound`).
    pub(super) fn kkt(&self, x: &[f64], e: &Eval) -> (f64, Vec<f64>) {
        let sign = if self.def.maximize { -1.0 } else { 1.0 };
        let g: Vec<f64> = e.df.iter().map(|d| sign * d).collect();
        let n = x.len();
        let at_lower: Vec<bool> = (0..n)
            .map(|j| x[j] <= self.def.bounds[j].0 + 1e-9 * (1.0 + x[j].abs()))
            .collect();
        let at_upper: Vec<bool> = (0..n)
            .map(|j| x[j] >= self.def.bounds[j].1 - 1e-9 * (1.0 + x[j].abs()))
            .collect();
        // active constraints: (constraint, sign of g, free sign?)
        let mut active: Vec<(usize, f64, bool)> = Vec::new();
        for (i, (bound, scale)) in self.limits.iter().enumerate() {
            let r = (e.q[i] - self.bound_value(i)) / scale;
            match bound {
                Bound::AtLeast(_) if r <= FEASIBLE => active.push((i, -1.0, false)),
                Bound::AtMost(_) if r >= -FEASIBLE => active.push((i, 1.0, false)),
                Bound::Equals(_) | Bound::EqualsNominal => active.push((i, 1.0, true)),
                _ => {}
            }
        }
        let free: Vec<usize> = (0..n).filter(|&j| !at_lower[j] && !at_upper[j]).collect();
        let mut lambda = vec![0.0; self.limits.len()];
        loop {
            let m = active.len();
            if m == 0 || free.is_empty() {
                break;
            }
            // least squares over the free variables: min ‖g_F + A_F λ‖
            let a = DMatrix::from_fn(free.len(), m, |r, c| {
                let (i, s, _) = active[c];
                s * e.dq[i][free[r]]
            });
            let rhs = DVector::from_iterator(free.len(), free.iter().map(|&j| -g[j]));
            let ata = a.transpose() * &a
                + DMatrix::identity(m, m) * 1e-14 * (a.norm_squared() + f64::MIN_POSITIVE);
            let sol = ata
                .lu()
                .solve(&(a.transpose() * rhs))
                .unwrap_or_else(|| DVector::zeros(m));
            // drop the most negative multiplier of an inequality and solve again
            let worst = (0..m)
                .filter(|&c| !active[c].2 && sol[c] < 0.0)
                .min_by(|&p, &q| sol[p].total_cmp(&sol[q]));
            match worst {
                Some(c) => {
                    active.remove(c);
                }
                None => {
                    for (c, &(i, s, _)) in active.iter().enumerate() {
                        lambda[i] += s * sol[c];
                    }
                    break;
                }
            }
        }
        // residual ∇f + Σ λ_i ∇q_i (λ signed: g = s (q − b), λ_g = λ_i s)
        let r: Vec<f64> = (0..n)
            .map(|j| {
                g[j] + (0..lambda.len())
                    .map(|i| lambda[i] * e.dq[i][j])
                    .sum::<f64>()
            })
            .collect();
        let worst = (0..n)
            .map(|j| {
                let out_of_box = if at_lower[j] {
                    (-r[j]).max(0.0)
                } else if at_upper[j] {
                    r[j].max(0.0)
                } else {
                    r[j].abs()
                };
                out_of_box * (self.def.bounds[j].1 - self.def.bounds[j].0)
            })
            .fold(0.0, f64::max);
        // relative to the objective, or absolute where it is zero
        let size = if e.f != 0.0 { e.f.abs() } else { 1.0 };
        // multipliers as the sensitivity of the optimum to each bound b_i: with
        // ℒ = sign f + Σ λ_i (q_i − b_i), d(sign f*)/db_i = −λ_i
        // (+ 0.0: an inactive constraint prints 0, not −0)
        let multipliers = lambda.iter().map(|l| -sign * l + 0.0).collect();
        (worst / size.max(f64::MIN_POSITIVE), multipliers)
    }
}

/// `--set` arguments that give every mesh file of the deck (`section.*.file`, `body.*.file`)
/// as an absolute path, so that the optimum deck, written elsewhere, reads the same meshes.
pub(super) fn absolute_file_keys(path: &Path, raw: &deck::RawDeck) -> Vec<String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let absolute = |f: &str| {
        let p = dir.join(f);
        std::fs::canonicalize(&p).unwrap_or(p).display().to_string()
    };
    let quote = |s: String| toml::Value::String(s).to_string();
    let mut sets = Vec::new();
    for (name, s) in &raw.section {
        if let Some(f) = &s.get_ref().file {
            sets.push(format!(
                "section.{name}.file={}",
                quote(absolute(f.get_ref()))
            ));
        }
    }
    for (name, b) in &raw.body {
        if let Some(f) = &b.get_ref().file {
            sets.push(format!("body.{name}.file={}", quote(absolute(f.get_ref()))));
        }
    }
    sets
}

/// A flexible body's frequencies and mass with their gradients (per design variable).
#[derive(Clone)]
pub(super) struct FlexibleQuantities {
    frequencies: Vec<f64>,
    /// `[mode][variable]`, Hz per unit of the variable.
    d_frequencies: Vec<Vec<f64>>,
    mass: f64,
    d_mass: Vec<f64>,
}

/// The retained modes' frequencies (Nelson's eigenvalue derivatives, updated modes) and the
/// mass (lumped masses in dual numbers) of flexible body `name` (deck table `span`), defined
/// by `def` at the design `design`.
pub(super) fn flexible_quantities(
    src: &Source,
    name: &str,
    span: Range<usize>,
    def: &BodyDef,
    design: &DesignDef,
) -> Result<FlexibleQuantities, CliError> {
    let mut built = build(src, name, def, DesignRequest::Variables(&design.variables))?;
    let (analysis, _) =
        crate::study::flexible::analyse(src, name, span.clone(), def, &mut built, false)?;
    let d = built.eigenvalue_derivatives::<CHUNK>(src, name, span.clone(), &analysis)?;
    let m = design.variables.len();
    let mut frequencies = Vec::new();
    let mut d_frequencies = Vec::new();
    for &i in &analysis.kept {
        let l = analysis.pairs.values[i];
        frequencies.push(l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI));
        d_frequencies.push(
            (0..m)
                .map(|v| d.eigenvalues[v][i] / (4.0 * std::f64::consts::PI * l.max(0.0).sqrt()))
                .collect(),
        );
    }
    let mut mass = 0.0;
    let mut d_mass = vec![0.0; m];
    for range in sens::chunk_ranges(m, CHUNK) {
        let seeded = sens::seed_chunk::<CHUNK>(built.design.values(), range.start);
        let props = built.design.properties(&seeded).map_err(|e| {
            runtime(format!(
                "{}: body `{name}`: its section: {e}",
                src.file.display()
            ))
        })?;
        let (masses, _) = fem::lumped_nodal_masses(&built.mesh, &props, &analysis.options.element)
            .map_err(|e| fem_error(src, name, span.clone(), e))?;
        let total = masses
            .iter()
            .fold(Dual::<CHUNK>::constant(0.0), |s, &x| s + x);
        mass = total.v;
        for (k, v) in range.enumerate() {
            d_mass[v] = total.d[k];
        }
    }
    Ok(FlexibleQuantities {
        frequencies,
        d_frequencies,
        mass,
        d_mass,
    })
}
