//! The sparse Newton system of [`crate::newton`] reduced to the unknowns of Eq. (12).
//!
//! The system is `[[T, U], [L, A]] [δy; z] = [r; 0]` with
//! `T = [[c0·I − Q_q, −Q_v], [0, c0·I]]`, `U = [0; −P]` and `L = −R_y`. A body's kinematic
//! rates depend on its own state alone, so `T` is block diagonal by bodies, and eliminating
//! `δy` leaves a system of the order of Eq. (12):
//!
//! ```text
//! S z = −L y',   y' = T⁻¹ r,   S = A − L T⁻¹ U = A + L [W P; P] / c0,
//! δy = y' + [W P z; P z] / c0,   W_b = (c0·I − Q_q,b)⁻¹ Q_v,b
//! ```
//!
//! with `y'_v = r_v / c0` and `y'_q,b = (c0·I − Q_q,b)⁻¹ r_q,b + W_b y'_v,b`. `S` differs from
//! Eq. (12)'s matrix `A` in the columns of the accelerations, along the couplings that `R_y`
//! has (a body with its neighbours), and is factorised dense: for a mechanism of a few bodies
//! with many modes (the spatial four-bar: 90 unknowns in Eq. (12), 237 in the Newton system)
//! a factorisation takes a quarter of the instructions of the whole system's sparse LU, and a
//! solve two thirds.

use std::ops::Range;

use nalgebra::DMatrix;
use sens::{DenseLu, LinearSolver};

/// Up to this many unknowns in Eq. (12) the reduced system is factorised dense. The spatial
/// four-bar (90) takes 11 % fewer instructions than with the whole system's sparse LU; a chain
/// of eight beams with four modes each (120) showed no difference beyond the timings' scatter.
pub(crate) const REDUCED_LIMIT: usize = 100;

/// A body's block of `T`: its coordinates and velocity variables, the LU of
/// `c0·I − Q_q,b` and `W_b` (row-major).
struct BodyBlock {
    q: Range<usize>,
    v: Range<usize>,
    t: DenseLu,
    w: Vec<f64>,
}

impl BodyBlock {
    /// Row `a` of `W_b`.
    fn w_row(&self, a: usize) -> &[f64] {
        let n = self.v.len();
        &self.w[a * n..(a + 1) * n]
    }

    /// `y += scale · W_b x`.
    fn add_product(&self, y: &mut [f64], x: &[f64], scale: f64) {
        for (a, yi) in y.iter_mut().enumerate() {
            *yi += scale * self.w_row(a).iter().zip(x).map(|(w, x)| w * x).sum::<f64>();
        }
    }
}

/// The Newton matrix `c0·I − ∂f/∂y` of a structured Jacobian, factorised through the reduced
/// system (see the module documentation).
pub(crate) struct ReducedNewton {
    nq: usize,
    nv: usize,
    c0: f64,
    bodies: Vec<BodyBlock>,
    /// The entries of `L` by state columns: `lower[start[c]..start[c + 1]]` holds column `c`'s
    /// Eq. (12) rows and values.
    start: Vec<usize>,
    lower: Vec<(usize, f64)>,
    s: DenseLu,
}

impl ReducedNewton {
    /// Factorise the Newton system whose entries (without the `c0` terms, duplicates summed)
    /// are `values` at `idx`, laid out as [`crate::newton`] builds it: `n_q` coordinates, `n_v`
    /// velocity variables, `nz` unknowns of Eq. (12), the bodies' coordinates and velocity
    /// variables at `bodies`. `None` if an entry falls outside that layout or a factor is
    /// singular.
    pub(crate) fn new(
        (nq, nv, nz): (usize, usize, usize),
        bodies: &[(Range<usize>, Range<usize>)],
        (idx, values): (&[(usize, usize)], &[f64]),
        c0: f64,
    ) -> Option<Self> {
        let ny = nq + nv;
        let mut owner = vec![usize::MAX; nq];
        for (b, (qr, _)) in bodies.iter().enumerate() {
            owner[qr.clone()].fill(b);
        }
        let mut tq: Vec<DMatrix<f64>> = bodies
            .iter()
            .map(|(qr, _)| DMatrix::from_diagonal_element(qr.len(), qr.len(), c0))
            .collect();
        let mut qv: Vec<DMatrix<f64>> = bodies
            .iter()
            .map(|(qr, vr)| DMatrix::zeros(qr.len(), vr.len()))
            .collect();
        let mut s = vec![0.0; nz * nz];
        let mut lower = Vec::new();
        for (&(i, j), &x) in idx.iter().zip(values) {
            if i < nq {
                let (qr, vr) = bodies.get(owner[i])?;
                if qr.contains(&j) {
                    tq[owner[i]][(i - qr.start, j - qr.start)] += x;
                } else if j >= nq && vr.contains(&(j - nq)) {
                    // the entry is −Q_v
                    qv[owner[i]][(i - qr.start, j - nq - vr.start)] -= x;
                } else if x != 0.0 {
                    return None;
                }
            } else if i < ny {
                // c0·I and −P: the layout's own
            } else if j < ny {
                lower.push((i - ny, j, x));
            } else {
                s[(i - ny) * nz + (j - ny)] += x;
            }
        }
        let mut blocks = Vec::with_capacity(bodies.len());
        for ((qr, vr), (t, mut w)) in bodies.iter().zip(tq.iter().zip(qv)) {
            let t = DenseLu::new(t);
            if !t.is_invertible() || !t.solve_matrix(&mut w) {
                return None;
            }
            blocks.push(BodyBlock {
                q: qr.clone(),
                v: vr.clone(),
                t,
                w: w.transpose().as_slice().to_vec(),
            });
        }
        // S = A + L [W P; P] / c0
        for &(row, col, x) in &lower {
            let out = &mut s[row * nz..(row + 1) * nz];
            if col < nq {
                let b = &blocks[owner[col]];
                let w = b.w_row(col - b.q.start);
                for (o, wk) in out[b.v.clone()].iter_mut().zip(w) {
                    *o += x * wk / c0;
                }
            } else {
                out[col - nq] += x / c0;
            }
        }
        let s = DenseLu::from_row_major(nz, s);
        if !s.is_invertible() {
            return None;
        }
        let mut start = vec![0; ny + 1];
        for &(_, col, _) in &lower {
            start[col + 1] += 1;
        }
        for c in 0..ny {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut by_column = vec![(0, 0.0); lower.len()];
        for &(row, col, x) in &lower {
            by_column[next[col]] = (row, x);
            next[col] += 1;
        }
        Some(Self {
            nq,
            nv,
            c0,
            bodies: blocks,
            start,
            lower: by_column,
            s,
        })
    }

    /// Replace `r` (length `n_q + n_v`) by `δy`; `z` holds Eq. (12)'s unknowns.
    fn solve(&self, r: &mut [f64], z: &mut [f64]) {
        let (rq, rv) = r.split_at_mut(self.nq);
        rv.iter_mut().for_each(|x| *x /= self.c0);
        for b in &self.bodies {
            let yq = &mut rq[b.q.clone()];
            b.t.solve_in_place(yq);
            b.add_product(yq, &rv[b.v.clone()], 1.0);
        }
        z.fill(0.0);
        for (c, &y) in rq.iter().chain(rv.iter()).enumerate() {
            if y != 0.0 {
                for &(row, x) in &self.lower[self.start[c]..self.start[c + 1]] {
                    z[row] -= x * y;
                }
            }
        }
        self.s.solve_in_place(z);
        for (y, zk) in rv.iter_mut().zip(&z[..self.nv]) {
            *y += zk / self.c0;
        }
        for b in &self.bodies {
            b.add_product(&mut rq[b.q.clone()], &z[b.v.clone()], 1.0 / self.c0);
        }
    }
}

impl LinearSolver for ReducedNewton {
    fn dim(&self) -> usize {
        self.nq + self.nv
    }

    fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
        let n = self.dim();
        assert_eq!(rhs.len(), n * ncols, "right-hand side has the wrong size");
        let mut z = vec![0.0; self.s.dim()];
        for col in rhs.chunks_mut(n.max(1)).take(ncols) {
            self.solve(col, &mut z);
        }
    }
}
