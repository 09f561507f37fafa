//! The rigid-body motions a body's constraints leave free: found from the constraints alone
//! (no eigenvalue solve), named for messages, and counted for the reference conditions that
//! discard them ([`crate::ReferenceCondition::FreeFree`],
//! [`crate::ReferenceCondition::PartlyFree`]).

use std::fmt;

use nalgebra::{Matrix6, SVector, Vector3};

use crate::assembly::Constraints;
use crate::mesh::Mesh;

/// A rigid motion of the whole body: every point `x` moves by `t + θ × (x − o)` and turns by
/// `θ`, about the frame origin `o` (mesh coordinates).
#[derive(Clone, Debug, PartialEq)]
pub struct RigidMotion {
    pub translation: Vector3<f64>,
    pub rotation: Vector3<f64>,
    pub origin: Vector3<f64>,
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// `x`, `y` or `z` for a unit vector along a global axis, else its components.
fn direction(v: &Vector3<f64>) -> String {
    let u = v / v.norm();
    let i = u.iamax();
    if (1.0 - u[i].abs()) < 1e-9 {
        AXES[i].to_string()
    } else {
        format!("({:.3}, {:.3}, {:.3})", u.x, u.y, u.z)
    }
}

impl fmt::Display for RigidMotion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let th = self.rotation.norm();
        if th == 0.0 {
            return write!(f, "translation along {}", direction(&self.translation));
        }
        // the point of the rotation axis nearest the origin (a screw's pitch is not shown)
        let p = self.origin + self.rotation.cross(&self.translation) / (th * th);
        let scale = p.amax().max(self.origin.amax());
        let [x, y, z] = [p.x, p.y, p.z].map(|c| round(c, scale));
        write!(
            f,
            "rotation about {} through ({x}, {y}, {z}) m",
            direction(&self.rotation)
        )
    }
}

/// A coordinate for a message: six significant digits, zero below 1e-9 of `scale`.
fn round(x: f64, scale: f64) -> f64 {
    if x.abs() <= 1e-9 * scale {
        return 0.0;
    }
    format!("{x:.5e}").parse::<f64>().unwrap_or(x)
}

/// The rigid motions of `mesh` that the fixed dof of `constraints` leave free, about `origin`:
/// a basis of them in reduced row echelon form over `(t_x, t_y, t_z, θ_x, θ_y, θ_z)`, so that
/// motions along the global axes come out as such (a strip held in `u_z` along its end lines
/// gives the translations along x and y and the rotation about z). Rigid ties do not constrain
/// rigid motions; empty when the constraints hold every rigid motion.
pub fn free_rigid_motions(
    mesh: &Mesh,
    constraints: &Constraints,
    origin: &Vector3<f64>,
) -> Vec<RigidMotion> {
    // rotations are scaled by the body's size so that the six columns are alike
    let (lo, hi) = mesh.bounding_box();
    let size = if mesh.nodes.is_empty() {
        1.0
    } else {
        (hi - lo).norm()
    };
    let size = if size > 0.0 { size } else { 1.0 };
    let mut gram = Matrix6::<f64>::zeros();
    for g in constraints.fixed() {
        let (node, d) = (g / 6, g % 6);
        let Some(x) = mesh.nodes.get(node) else {
            continue;
        };
        let mut row = SVector::<f64, 6>::zeros();
        if d < 3 {
            // u_d = t_d + e_d · (θ × r) = t_d + θ · (r × e_d)
            row[d] = 1.0;
            let r = (x - origin) / size;
            let c = r.cross(&Vector3::ith(d, 1.0));
            row.fixed_rows_mut::<3>(3).copy_from(&c);
        } else {
            row[d] = 1.0;
        }
        gram += row * row.transpose();
    }
    let eig = gram.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
    let null: Vec<SVector<f64, 6>> = (0..6)
        .filter(|&i| eig.eigenvalues[i] <= 1e-10 * top)
        .map(|i| eig.eigenvectors.column(i).into_owned())
        .collect();
    echelon(null)
        .into_iter()
        .map(|v| RigidMotion {
            translation: v.fixed_rows::<3>(0).into_owned(),
            rotation: v.fixed_rows::<3>(3).into_owned() / size,
            origin: *origin,
        })
        .collect()
}

/// The reduced row echelon form of the rows `rows` (pivots in column order, entries below
/// 1e-9 cleared).
fn echelon(mut rows: Vec<SVector<f64, 6>>) -> Vec<SVector<f64, 6>> {
    let mut done = 0;
    for col in 0..6 {
        let Some(best) =
            (done..rows.len()).max_by(|&a, &b| rows[a][col].abs().total_cmp(&rows[b][col].abs()))
        else {
            break;
        };
        if rows[best][col].abs() < 1e-8 {
            continue;
        }
        rows.swap(done, best);
        let pivot = rows[done] / rows[done][col];
        rows[done] = pivot;
        for (i, r) in rows.iter_mut().enumerate() {
            if i != done {
                *r -= pivot * r[col];
            }
        }
        done += 1;
    }
    for r in &mut rows {
        r.apply(|x| {
            if x.abs() < 1e-9 {
                *x = 0.0
            }
        });
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::dof;

    /// A 2 × 1 grid of nodes in the x–y plane (no elements are needed for the count).
    fn grid() -> Mesh {
        let mut m = Mesh::default();
        for y in [0.0, 0.1] {
            for x in [0.0, 0.5, 1.0] {
                m.nodes.push(Vector3::new(x, y, 0.0));
            }
        }
        m
    }

    #[test]
    fn nothing_fixed_leaves_six_motions_on_the_axes() {
        let got = free_rigid_motions(&grid(), &Constraints::new(), &Vector3::zeros());
        let names: Vec<String> = got.iter().map(|m| m.to_string()).collect();
        assert_eq!(
            names,
            [
                "translation along x",
                "translation along y",
                "translation along z",
                "rotation about x through (0, 0, 0) m",
                "rotation about y through (0, 0, 0) m",
                "rotation about z through (0, 0, 0) m",
            ]
        );
    }

    #[test]
    fn deflection_held_on_two_end_lines_leaves_the_in_plane_motions() {
        let mesh = grid();
        let mut c = Constraints::new();
        c.fix_nodes(&[0, 3, 2, 5], &[dof::UZ]);
        let o = Vector3::new(0.5, 0.05, 0.0);
        let got = free_rigid_motions(&mesh, &c, &o);
        let names: Vec<String> = got.iter().map(|m| m.to_string()).collect();
        assert_eq!(
            names,
            [
                "translation along x",
                "translation along y",
                "rotation about z through (0.5, 0.05, 0) m"
            ]
        );
        // each free motion moves no fixed dof
        for m in &got {
            for &n in &[0, 3, 2, 5] {
                let u = m.translation + m.rotation.cross(&(mesh.nodes[n] - o));
                assert!(u.z.abs() < 1e-12, "{m}: {u}");
            }
        }
    }

    #[test]
    fn a_single_line_leaves_the_rotation_about_it() {
        let mesh = grid();
        let mut c = Constraints::new();
        // the line x = 0 held in all three translations: the body can turn about it
        c.fix_nodes(&[0, 3], &dof::TRANSLATIONS);
        let got = free_rigid_motions(&mesh, &c, &Vector3::new(0.5, 0.05, 0.0));
        assert_eq!(got.len(), 1);
        assert_eq!(
            got[0].to_string(),
            "rotation about y through (0, 0.05, 0) m"
        );
        c.fix(1, dof::UZ);
        assert!(free_rigid_motions(&mesh, &c, &Vector3::zeros()).is_empty());
    }
}
