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
//! dynamics, only whether the basis can take the loads at all. It needs a reference condition
//! that holds the body (not free-free).

use nalgebra::{DMatrix, DVector, Vector3};

use crate::assembly::{Properties, lumped_nodal_masses};
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

/// The basis check of `analysis` for the loads `interfaces` and the frame's inertia loads.
/// `None` for a body with rigid motions free (free-free, partly free).
pub fn static_completeness(
    mesh: &Mesh,
    props: &Properties<f64>,
    analysis: &ModalAnalysis,
    interfaces: &[InterfaceLoads],
) -> Result<Option<Completeness>, FemError> {
    if analysis.n_rigid > 0 {
        return Ok(None);
    }
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
    if loads.is_empty() {
        return Ok(Some(Completeness { cases: Vec::new() }));
    }
    let f = DMatrix::from_columns(&loads);
    let llt = stiffness_factor(assembly, &analysis.k)?;
    let mut u = f.clone();
    {
        use sens::LinearSolver;
        llt.solve_columns(u.as_mut_slice(), f.ncols());
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
