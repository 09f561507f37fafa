//! How completely a body's reduced basis represents the loads a mechanism puts on it: the
//! static compliance under each load case that the basis misses.
//!
//! For a load `f` on the free dof, the exact static response is `u = K⁻¹f` and its compliance
//! `c = fᵀu`; the basis `B` gives the Ritz response `u_r = B (BᵀKB)⁻¹ Bᵀf`, the `K`-orthogonal
//! projection of `u` on the basis, with compliance `c_r = fᵀu_r ≤ c`. `c − c_r` is the energy
//! of what the basis misses (`‖u − u_r‖²_K`). The load cases are unit forces and moments at the
//! body's interfaces (nodes and couplings where joints and forces act) and the inertia loads of
//! unit accelerations of the body frame (three translations, three angular accelerations at
//! the frame origin), moments and angular accelerations scaled by the body's size `L` so that
//! every case is a load of about one newton. Each case's missed compliance is reported as a
//! share of the largest compliance of all cases, so that a case the body hardly deforms under
//! (an axial load on a slender rod) cannot dominate.
//!
//! The check is static: it says nothing of how well the retained eigenmodes resolve the body's
//! dynamics, only whether the basis can take the loads at all. On a body whose reference
//! condition leaves rigid motions free (free-free, partly free) a load is first relieved of its
//! rigid-body part (inertia relief, `f̃ = f − M R Rᵀ f` with the mass-normalised rigid modes
//! `R`), which its elastic modes cannot carry and its frame does; `u` is then the elastic
//! response, `M`-orthogonal to `R`, found with springs at a statically determinate set of dof
//! (no force reaches them under a self-equilibrated load).

use nalgebra::{DMatrix, DVector, Vector3};

use crate::assembly::{Properties, ReducedDof, lumped_nodal_masses};
use crate::body::ModalAnalysis;
use crate::correction::stiffness_factor;
use crate::error::FemError;
use crate::mesh::{Mesh, NodeId};

/// The loads a mechanism puts on the body at one interface: forces and moments along the
/// given directions (mesh axes; any length, normalised here) at a mesh node
/// (`target < n_nodes`) or at coupling `target − n_nodes`.
#[derive(Clone, Debug, PartialEq)]
pub struct InterfaceLoads {
    pub target: NodeId,
    pub forces: Vec<Vector3<f64>>,
    pub moments: Vec<Vector3<f64>>,
}

/// The missed compliance of one load case.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadCase {
    /// What the load is, e.g. `node 50 force [0.000, 0.000, 1.000]`, `coupling 1 moment
    /// [1.000, 0.000, 0.000]` (the direction in mesh axes), `inertia x`, `inertia about z`.
    pub name: String,
    /// Missed compliance `c − c_r` as a share of the largest compliance of all cases.
    pub missed: f64,
    /// `c_r / c`: the share of this case's own compliance the basis captures.
    pub captured: f64,
}

/// The basis check of one body.
#[derive(Clone, Debug, PartialEq)]
pub struct Completeness {
    pub cases: Vec<LoadCase>,
}

impl Completeness {
    /// The case with the largest missed share.
    pub fn worst(&self) -> Option<&LoadCase> {
        self.cases
            .iter()
            .max_by(|a, b| a.missed.total_cmp(&b.missed))
    }
}

/// The basis check of `analysis` for the loads `interfaces` and the frame's inertia loads
/// (relieved of their rigid-body part on a body with free rigid motions); always `Some`.
pub fn static_completeness(
    mesh: &Mesh,
    props: &Properties<f64>,
    analysis: &ModalAnalysis,
    interfaces: &[InterfaceLoads],
) -> Result<Option<Completeness>, FemError> {
    let assembly = &analysis.assembly;
    let n = mesh.nodes.len();
    let (lo, hi) = mesh.bounding_box();
    let size = (hi - lo).norm().max(f64::MIN_POSITIVE);
    let mut names = Vec::new();
    let mut loads = Vec::new();
    for i in interfaces {
        // the node's (or coupling's) six unit loads on the free dof (`None`: fixed)
        let unit = |d: usize| -> Option<DVector<f64>> {
            if i.target < n {
                assembly.unit_load(6 * i.target + d)
            } else {
                let c = analysis.couplings.get(i.target - n)?;
                Some(assembly.restrict(c.load(d, n).as_slice()))
            }
        };
        if i.target >= n + analysis.couplings.len() {
            return Err(FemError::BasisCheck(format!(
                "basis check at node {}: the mesh has {n} nodes and {} couplings",
                i.target,
                analysis.couplings.len()
            )));
        }
        let place = if i.target < n {
            format!("node {}", i.target)
        } else {
            format!("coupling {}", i.target - n)
        };
        for (what, dirs, first, scale) in [
            ("force", &i.forces, 0, 1.0),
            ("moment", &i.moments, 3, size),
        ] {
            for dir in dirs {
                let dir = dir.normalize();
                let mut f = DVector::zeros(assembly.n_free());
                for a in 0..3 {
                    if let Some(col) = unit(first + a) {
                        f += col * (dir[a] * scale);
                    }
                }
                if f.amax() > 0.0 {
                    names.push(format!(
                        "{place} {what} [{:.3}, {:.3}, {:.3}]",
                        dir.x, dir.y, dir.z
                    ));
                    loads.push(f);
                }
            }
        }
    }
    // inertia loads M a of unit accelerations: translations, then angular accelerations
    // α = e_i / L about the frame origin (a = α × r)
    let (masses, inertias) = lumped_nodal_masses(mesh, props, &analysis.options.element)?;
    for kind in 0..6 {
        let mut full = DVector::zeros(6 * n);
        for k in 0..n {
            let (a, alpha) = if kind < 3 {
                (Vector3::ith(kind, 1.0), Vector3::zeros())
            } else {
                let alpha = Vector3::ith(kind - 3, 1.0 / size);
                (alpha.cross(&(mesh.nodes[k] - analysis.origin)), alpha)
            };
            for d in 0..3 {
                full[6 * k + d] = masses[k] * a[d];
                full[6 * k + 3 + d] = inertias[k][d] * alpha[d];
            }
        }
        let f = assembly.restrict(full.as_slice());
        if f.amax() > 0.0 {
            let axis = ["x", "y", "z"][kind % 3];
            names.push(if kind < 3 {
                format!("inertia {axis}")
            } else {
                format!("inertia about {axis}")
            });
            loads.push(f);
        }
    }
    let relief = relief(mesh, analysis)?;
    if let Some(r) = &relief {
        // a load the frame carries whole (an acceleration along a free motion) is no case
        let mut kept = Vec::new();
        for (name, f) in names.drain(..).zip(loads.drain(..)) {
            let relieved = r.relieve(&f);
            if relieved.norm() > 1e-9 * f.norm() {
                kept.push((name, relieved));
            }
        }
        (names, loads) = kept.into_iter().unzip();
    }
    if loads.is_empty() {
        return Ok(Some(Completeness { cases: Vec::new() }));
    }
    let f = DMatrix::from_columns(&loads);
    let mut u = f.clone();
    {
        use sens::LinearSolver;
        match &relief {
            Some(r) => {
                r.factor.solve_columns(u.as_mut_slice(), f.ncols());
                for mut c in u.column_iter_mut() {
                    let elastic = r.relieve_displacement(&c.clone_owned());
                    c.copy_from(&elastic);
                }
            }
            None => {
                let llt = stiffness_factor(assembly, &analysis.k)?;
                llt.solve_columns(u.as_mut_slice(), f.ncols());
            }
        }
    }
    let b = analysis.free_shapes();
    let kr = crate::eigen::project(&analysis.k, &b, &b);
    let kr = (&kr + kr.transpose()) * 0.5;
    let bf = b.transpose() * &f;
    // the basis is K-orthogonal with positive Ritz values: a Cholesky factor exists
    let ur = kr
        .cholesky()
        .ok_or_else(|| FemError::BasisCheck("basis check: the modal stiffness is singular".into()))?
        .solve(&bf);
    let exact: Vec<f64> = (0..f.ncols())
        .map(|c| f.column(c).dot(&u.column(c)))
        .collect();
    let reduced: Vec<f64> = (0..f.ncols())
        .map(|c| bf.column(c).dot(&ur.column(c)))
        .collect();
    let largest = exact.iter().fold(0.0f64, |a, &c| a.max(c));
    let cases = names
        .into_iter()
        .zip(exact.iter().zip(&reduced))
        .map(|(name, (&c, &cr))| LoadCase {
            name,
            missed: ((c - cr) / largest).max(0.0),
            captured: if c > 0.0 { (cr / c).min(1.0) } else { 1.0 },
        })
        .collect();
    Ok(Some(Completeness { cases }))
}

/// The inertia relief of a body whose reference condition leaves rigid motions free: its rigid
/// modes on the free dof, mass-normalised, and the Cholesky factor of its stiffness with
/// springs at a statically determinate set of dof.
struct Relief {
    r: DMatrix<f64>,
    /// `M R`, made once.
    mr: DMatrix<f64>,
    factor: sens::SparseCholesky,
}

impl Relief {
    /// `f − M R Rᵀ f`: the load without its rigid-body part.
    fn relieve(&self, f: &DVector<f64>) -> DVector<f64> {
        f - &self.mr * (self.r.transpose() * f)
    }

    /// `u − R (M R)ᵀ u = u − R Rᵀ M u` (`M` symmetric): the displacement without its
    /// rigid-body part.
    fn relieve_displacement(&self, u: &DVector<f64>) -> DVector<f64> {
        u - &self.r * (self.mr.transpose() * u)
    }
}

/// The [`Relief`] of `analysis`, `None` when its constraints hold every rigid motion.
fn relief(mesh: &Mesh, analysis: &ModalAnalysis) -> Result<Option<Relief>, FemError> {
    if analysis.n_rigid == 0 {
        return Ok(None);
    }
    let assembly = &analysis.assembly;
    let motions = crate::rigid::free_rigid_motions(mesh, &analysis.constraints, &analysis.origin);
    let nf = assembly.n_free();
    let mut r = DMatrix::zeros(nf, motions.len());
    for (j, mo) in motions.iter().enumerate() {
        let at = |p: &Vector3<f64>, c: usize| {
            if c < 3 {
                (mo.translation + mo.rotation.cross(&(p - mo.origin)))[c]
            } else {
                mo.rotation[c - 3]
            }
        };
        for (i, d) in assembly.dofs().iter().enumerate() {
            r[(i, j)] = match *d {
                ReducedDof::Node(g) => at(&mesh.nodes[g / 6], g % 6),
                ReducedDof::Tie {
                    tie, coordinate, ..
                } => at(&analysis.constraints.ties()[tie].point, coordinate),
            };
        }
    }
    let bad = |what: &str| FemError::BasisCheck(format!("basis check: {what}"));
    // mass-normalised: R L⁻ᵀ with Rᵀ M R = L Lᵀ
    let g = crate::eigen::project(&analysis.m, &r, &r);
    let l = g
        .cholesky()
        .ok_or_else(|| bad("the rigid motions have no mass"))?
        .l();
    let rt = l
        .solve_lower_triangular(&r.transpose())
        .ok_or_else(|| bad("the rigid motions have no mass"))?;
    let r = rt.transpose();
    // a statically determinate set of dof: complete pivoting on R's columns
    let mut a = r.clone();
    let mut used = vec![false; a.ncols()];
    let mut held = Vec::new();
    for _ in 0..a.ncols() {
        let (mut best, mut at) = (0.0f64, (0, 0));
        for j in (0..a.ncols()).filter(|&j| !used[j]) {
            for d in 0..nf {
                if a[(d, j)].abs() > best {
                    (best, at) = (a[(d, j)].abs(), (d, j));
                }
            }
        }
        let (d, j) = at;
        used[j] = true;
        held.push(d);
        let pivot = a.column(j).clone_owned();
        for c in (0..a.ncols()).filter(|&c| !used[c]) {
            let f = a[(d, c)] / pivot[d];
            a.column_mut(c).axpy(-f, &pivot, 1.0);
        }
    }
    // springs as stiff as the stiffness's mean diagonal at those dof
    let k = &analysis.k;
    let (cp, ri) = (k.symbolic().col_ptr(), k.symbolic().row_idx());
    let diagonal = |d: usize| (cp[d]..cp[d + 1]).find(|&p| ri[p] == d);
    let mut values = k.val().to_vec();
    let kappa = (0..nf)
        .filter_map(|d| diagonal(d).map(|p| values[p].abs()))
        .sum::<f64>()
        / nf.max(1) as f64;
    for &d in &held {
        let p = diagonal(d).ok_or_else(|| bad("a dof without a diagonal entry"))?;
        values[p] += kappa;
    }
    let held_k = assembly.matrix(values);
    let factor = crate::correction::factor_held(assembly, &held_k, || {
        bad("the stiffness held at its rigid motions is not positive definite (a mechanism)")
    })?;
    let mut mr = DMatrix::zeros(nf, r.ncols());
    crate::eigen::spmv_columns(&analysis.m, r.as_slice(), mr.as_mut_slice(), r.ncols());
    Ok(Some(Relief { r, mr, factor }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::dof;
    use crate::body::{ModalOptions, ReferenceCondition, Support, modal_analysis};
    use laminate::{OrthotropicMaterial, Ply, PlyStack};

    /// An aluminium strip `l × b × h` in the x–y plane, `nx × ny` cells, held only in its
    /// deflection along its end lines (its in-plane motion free).
    fn partly_free_strip(
        l: f64,
        b: f64,
        h: f64,
        nx: usize,
        ny: usize,
    ) -> (Mesh, Properties<f64>, ModalAnalysis) {
        let mesh = Mesh::rectangle(l, b, nx, ny, 0).unwrap();
        let al = OrthotropicMaterial::isotropic(70e9, 0.3, 2700.0).unwrap();
        let stack = PlyStack::new(vec![Ply {
            material: al,
            thickness: h,
            angle: 0.0,
        }])
        .unwrap();
        let props = Properties {
            sections: vec![],
            laminates: vec![stack.stiffness()],
        };
        let mut o = ModalOptions::new(4);
        o.reference = ReferenceCondition::PartlyFree;
        o.supports = [0, nx]
            .map(|i| Support {
                nodes: (0..=ny).map(|j| (nx + 1) * j + i).collect(),
                dofs: vec![dof::UZ],
            })
            .to_vec();
        let an = modal_analysis(&mesh, &props, &o).unwrap();
        (mesh, props, an)
    }

    /// The compliance `fᵀu` of equal and opposite axial forces `F` spread over the end lines
    /// of a partly free strip (self-equilibrated: relief leaves them as they are), the
    /// largest momentum of `u` along the free motions relative to `|u|`, and the relieved
    /// norm of a uniform pull along x (a load along a free motion) relative to its norm.
    fn axial_pull(nx: usize, ny: usize) -> (f64, f64, f64) {
        let (l, b, h) = (0.5, 0.04, 0.004);
        let (mesh, _, an) = partly_free_strip(l, b, h, nx, ny);
        let relief = relief(&mesh, &an).unwrap().expect("in-plane motions free");
        assert_eq!(relief.r.ncols(), 3);
        let force = 100.0;
        let mut full = vec![0.0; 6 * mesh.nodes.len()];
        for j in 0..=ny {
            // consistent loads of a uniform traction on linear edges: half at the corners
            let w = if j == 0 || j == ny { 0.5 } else { 1.0 } / ny as f64;
            full[6 * ((nx + 1) * j)] -= force * w;
            full[6 * ((nx + 1) * j + nx)] += force * w;
        }
        let f = an.assembly.restrict(&full);
        let relieved = relief.relieve(&f);
        assert!((&relieved - &f).norm() <= 1e-12 * f.norm());
        let mut u = relieved.clone();
        {
            use sens::LinearSolver;
            relief.factor.solve_columns(u.as_mut_slice(), 1);
        }
        let u = relief.relieve_displacement(&u);
        let exact = force * force * l / (70e9 * b * h);
        let mut mu = vec![0.0; u.len()];
        crate::eigen::spmv(&an.m, u.as_slice(), &mut mu);
        let momentum = (relief.r.transpose() * DVector::from_vec(mu)).norm() / u.norm();
        let mut along = vec![0.0; 6 * mesh.nodes.len()];
        (0..mesh.nodes.len()).for_each(|k| along[6 * k] = 1.0);
        let mut m_along = vec![0.0; an.assembly.n_free()];
        crate::eigen::spmv(&an.m, an.assembly.restrict(&along).as_slice(), &mut m_along);
        let m_along = DVector::from_vec(m_along);
        let left = relief.relieve(&m_along).norm() / m_along.norm();
        (relieved.dot(&u) / exact - 1.0, momentum, left)
    }

    /// Relieved loads on a partly free strip: an axial pull's compliance converges to the
    /// bar's `F² L / (E b h)` (measured 1.5e-3 and 4.3e-4 at 20 × 4 and 40 × 8 cells), its
    /// elastic response carries no momentum along the free motions, and a load along a free
    /// motion is carried by the frame whole.
    #[test]
    fn a_relieved_axial_pull_converges_to_the_bars_compliance() {
        let (coarse, m1, l1) = axial_pull(20, 4);
        let (fine, m2, l2) = axial_pull(40, 8);
        assert!(
            fine.abs() < 1e-3 && fine.abs() < 0.4 * coarse.abs(),
            "{coarse:e} then {fine:e}"
        );
        assert!(
            m1.max(m2) < 1e-12 && l1.max(l2) < 1e-9,
            "{m1:e} {m2:e} {l1:e} {l2:e}"
        );
    }
}
