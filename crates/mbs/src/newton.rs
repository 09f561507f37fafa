//! The Newton matrix of large mechanisms, `c0·I − ∂f/∂y`, kept sparse.
//!
//! The state's rates are `f = (Q(q, v), P x)`, where `x = [v̇; λ]` solves Eq. (12),
//! `A(q) x = b(q, v)`, and `P` takes its first `n_v` entries. With `R(y) = b − A x̂` the
//! residual at the solution `x̂` held fixed, `∂x/∂y = A⁻¹ R_y`: the accelerations of every body
//! depend on the state of every other through `A⁻¹`, so the dense `∂f/∂y` of a chain is full.
//! Its pieces are not: `Q_y` is block diagonal (one body's kinematic rates), `R_y` couples a body
//! with the bodies it shares a joint or a force with, `A` is [`crate::eq12`]'s sparse matrix.
//! With `z = A⁻¹ R_y δy`, the Newton system `(c0·I − ∂f/∂y) δy = r` is the sparse system
//!
//! ```text
//! [ c0·I − Q_q   −Q_v     0  ] [δq]   [r_q]
//! [ 0            c0·I    −P  ] [δv] = [r_v]
//! [ −R_q         −R_v     A  ] [z ]   [ 0 ]
//! ```
//!
//! factorised by sparse LU, its symbolic analysis kept while the pattern stays; up to
//! [`REDUCED_LIMIT`] unknowns in Eq. (12), reduced to those unknowns and factorised dense
//! instead ([`crate::reduced_newton`]).
//!
//! `R_y` and `Q_y` come from dual evaluations of the residual seeded by colour: bodies whose
//! equations share no row (no common neighbour in the graph of joints and forces) are seeded
//! together, so a chain needs three colours whatever its length, each a few chunks of a
//! body's coordinates.
//!
//! The stability limit's eigenvalues ([`StructuredJacobian::oscillatory_eigenvalues`]) are
//! those of each flexible body's block of `∂f/∂y` on its own modal coordinates and rates, with
//! Eq. (12) of the body and its neighbours alone in place of the whole mechanism's: a small
//! dense system per body instead of the eigenvalues of the whole dense Jacobian. The coupling
//! through the body's joints is in them, that between the bodies' modes is not; on a chain of
//! twelve beams the largest is within 2 % of the whole Jacobian's (tests/large_mechanisms.rs).

use std::sync::Mutex;

use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use nalgebra::{Complex, DMatrix};
use sens::{Dual, LinearSolver};

use crate::bdf::{StructuredJacobian, oscillatory_eigenvalues};
use crate::body::BodyId;
use crate::eq12::BodyMass;
use crate::joint::JointId;
use crate::kin::Kin;
use crate::model::Model;
use crate::reduced_newton::{REDUCED_LIMIT, ReducedNewton};

/// Width of the dual chunks.
const CHUNK: usize = 8;

/// Which bodies are seeded together and which rows each body's state reaches.
#[derive(Clone, Debug)]
pub(crate) struct Colouring {
    /// The state indices of each body: its `q` coordinates, then `n_q +` its `v` variables.
    columns: Vec<Vec<usize>>,
    /// Bodies seeded together.
    colours: Vec<Vec<usize>>,
    /// Per body: the bodies whose dynamic equations its state enters (itself included).
    neighbours: Vec<Vec<usize>>,
    /// Per body: the constraint rows (all rows) whose equations its state enters.
    constraint_rows: Vec<Vec<usize>>,
}

impl Colouring {
    pub(crate) fn new(model: &Model<f64>) -> Self {
        let nb = model.n_bodies();
        let nq = model.n_q();
        let columns: Vec<Vec<usize>> = model
            .body_ids()
            .map(|id| {
                let v = model.v_range(id);
                model.q_range(id).chain(v.map(|i| nq + i)).collect()
            })
            .collect();
        let mut neighbours: Vec<Vec<usize>> = (0..nb).map(|b| vec![b]).collect();
        for group in model.couplings() {
            for &a in &group {
                for &b in &group {
                    if !neighbours[a].contains(&b) {
                        neighbours[a].push(b);
                    }
                }
            }
        }
        let mut constraint_rows = vec![Vec::new(); nb];
        for (j, joint) in model.joints().iter().enumerate() {
            for body in [joint.a.body, joint.b.body].into_iter().flatten() {
                let rows = &mut constraint_rows[body.0];
                for r in model.joint_rows(JointId(j)) {
                    if !rows.contains(&r) {
                        rows.push(r);
                    }
                }
            }
        }
        // greedy distance-2 colouring: two bodies conflict when they reach a common body's
        // equations or a common joint's rows
        let reach: Vec<Vec<usize>> = neighbours
            .iter()
            .map(|n| {
                let mut r: Vec<usize> = n.iter().flat_map(|&c| neighbours[c].clone()).collect();
                r.sort_unstable();
                r.dedup();
                r
            })
            .collect();
        let mut colour = vec![usize::MAX; nb];
        let mut colours: Vec<Vec<usize>> = Vec::new();
        for b in 0..nb {
            let used: Vec<usize> = reach[b].iter().map(|&c| colour[c]).collect();
            let c = (0..).find(|c| !used.contains(c)).expect("a free colour");
            colour[b] = c;
            if c == colours.len() {
                colours.push(Vec::new());
            }
            colours[c].push(b);
        }
        Self {
            columns,
            colours,
            neighbours,
            constraint_rows,
        }
    }

    /// Number of colours.
    #[cfg(test)]
    pub(crate) fn n_colours(&self) -> usize {
        self.colours.len()
    }
}

/// The entries of the sparse Newton system, their pattern and its symbolic LU, kept while the
/// entries come in the same order.
pub(crate) struct NewtonPattern {
    entries: Vec<(usize, usize)>,
    pattern: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    lu: SymbolicLu<usize>,
}

impl std::fmt::Debug for NewtonPattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NewtonPattern({} entries)", self.entries.len())
    }
}

/// `∂f/∂y` of a large mechanism as the entries of the sparse Newton system (see the module
/// documentation).
pub(crate) struct SparseNewton {
    /// `n_q`, `n_v` and the unknowns of Eq. (12).
    sizes: (usize, usize, usize),
    /// Each body's coordinates and velocity variables.
    bodies: Vec<(std::ops::Range<usize>, std::ops::Range<usize>)>,
    /// Row and column of each entry.
    idx: Vec<(usize, usize)>,
    /// Entries without the `c0` terms.
    values: Vec<f64>,
    /// Positions in `values` (and the pattern's entries) that take `c0`.
    diagonal: Vec<usize>,
    pattern: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    lu: SymbolicLu<usize>,
    oscillatory: Vec<Complex<f64>>,
}

/// The builder of a [`SparseNewton`]: entries in the order they are added.
struct Entries {
    idx: Vec<(usize, usize)>,
    val: Vec<f64>,
}

impl Entries {
    fn push(&mut self, i: usize, j: usize, x: f64) {
        self.idx.push((i, j));
        self.val.push(x);
    }

    /// A derivative entry: left out where it is zero (structurally, in the main), which keeps
    /// the pattern of a chain's kinematic rates to their few nonzero blocks.
    fn push_nonzero(&mut self, i: usize, j: usize, x: f64) {
        if x != 0.0 {
            self.push(i, j, x);
        }
    }
}

impl SparseNewton {
    /// `∂f/∂y` at `(t, q, v)` with the mass matrix `mass` and the constraint kinematics `kin`
    /// there, and the solution `x_hat` of Eq. (12) on the rows `rows`.
    pub(crate) fn new(
        model: &Model<f64>,
        colouring: &Colouring,
        t: f64,
        (q, v): (&[f64], &[f64]),
        (mass, kin): (&BodyMass<f64>, &[Kin<f64>]),
        (rows, x_hat): (&[usize], &[f64]),
        cache: &Mutex<Option<NewtonPattern>>,
    ) -> Option<Self> {
        let (nq, nv) = (model.n_q(), model.n_v());
        let n_y = nq + nv;
        let mut position = vec![usize::MAX; model.n_constraints()];
        for (p, &r) in rows.iter().enumerate() {
            position[r] = p;
        }
        let mut e = Entries {
            idx: Vec::new(),
            val: Vec::new(),
        };
        // c0 on the diagonal of the q and v rows, −P in the v rows
        let diagonal: Vec<usize> = (0..n_y)
            .map(|i| {
                e.push(i, i, 0.0);
                e.val.len() - 1
            })
            .collect();
        for i in 0..nv {
            e.push(nq + i, n_y + i, -1.0);
        }
        let mut elastic = ElasticColumns::new(model);
        let y: Vec<f64> = q.iter().chain(v).copied().collect();
        for colour in &colouring.colours {
            let width = colour
                .iter()
                .map(|&b| colouring.columns[b].len())
                .max()
                .unwrap_or(0);
            for start in (0..width).step_by(CHUNK) {
                let mut yd: Vec<Dual<CHUNK>> = y.iter().map(|&x| Dual::constant(x)).collect();
                for &b in colour {
                    for (k, &c) in colouring.columns[b]
                        .iter()
                        .skip(start)
                        .take(CHUNK)
                        .enumerate()
                    {
                        yd[c] = Dual::variable(y[c], k);
                    }
                }
                let (qd, vd) = yd.split_at(nq);
                let res = model.residual(t, qd, vd, rows, x_hat);
                let mut qdot = vec![Dual::<CHUNK>::constant(0.0); nq];
                model.kinematic_rates(qd, vd, &mut qdot);
                for &b in colour {
                    let cols = colouring.columns[b].iter().skip(start).take(CHUNK);
                    for (k, &c) in cols.enumerate() {
                        for i in model.q_range(BodyId(b)) {
                            e.push_nonzero(i, c, -qdot[i].d[k]);
                        }
                        for &nb in &colouring.neighbours[b] {
                            for i in model.v_range(BodyId(nb)) {
                                e.push_nonzero(n_y + i, c, -res[i].d[k]);
                                elastic.record(c, i, res[i].d[k]);
                            }
                        }
                        for &r in &colouring.constraint_rows[b] {
                            if position[r] != usize::MAX {
                                let p = nv + position[r];
                                e.push_nonzero(n_y + p, c, -res[p].d[k]);
                                elastic.record(c, p, res[p].d[k]);
                            }
                        }
                    }
                }
            }
        }
        // A: the mass blocks and the kept rows of J, both sides
        for (o, block) in mass.blocks() {
            for j in 0..block.ncols() {
                for i in 0..block.nrows() {
                    e.push(n_y + o + i, n_y + o + j, block[(i, j)]);
                }
            }
        }
        for (p, &r) in rows.iter().enumerate() {
            for (c, &x) in kin[r].jac.iter() {
                e.push(n_y + nv + p, n_y + c, x);
                e.push(n_y + c, n_y + nv + p, x);
            }
        }
        let size = n_y + nv + rows.len();
        let (pattern, argsort, lu) = symbolic(size, &e.idx, cache)?;
        Some(Self {
            sizes: (nq, nv, nv + rows.len()),
            bodies: model
                .body_ids()
                .map(|id| (model.q_range(id), model.v_range(id)))
                .collect(),
            idx: e.idx,
            values: e.val,
            diagonal,
            pattern,
            argsort,
            lu,
            oscillatory: elastic.oscillatory(&Local {
                model,
                colouring,
                mass,
                kin,
                rows,
                position: &position,
            }),
        })
    }
}

/// The pattern and symbolic LU of the `size × size` matrix with entries at `idx`, from
/// `cache` when it holds the same entries.
fn symbolic(
    size: usize,
    idx: &[(usize, usize)],
    cache: &Mutex<Option<NewtonPattern>>,
) -> Option<(
    SymbolicSparseColMat<usize>,
    Argsort<usize>,
    SymbolicLu<usize>,
)> {
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    if cache.as_ref().is_none_or(|p| p.entries != idx) {
        let pairs: Vec<Pair<usize, usize>> = idx.iter().map(|&(i, j)| Pair::new(i, j)).collect();
        let (pattern, argsort) =
            SymbolicSparseColMat::try_new_from_indices(size, size, &pairs).ok()?;
        let lu = SymbolicLu::try_new(pattern.as_ref()).ok()?;
        *cache = Some(NewtonPattern {
            entries: idx.to_vec(),
            pattern,
            argsort,
            lu,
        });
    }
    let p = cache.as_ref()?;
    Some((p.pattern.clone(), p.argsort.clone(), p.lu.clone()))
}

impl StructuredJacobian for SparseNewton {
    fn factor(&self, c0: f64) -> Option<Box<dyn LinearSolver>> {
        if self.sizes.2 <= REDUCED_LIMIT
            && let Some(r) =
                ReducedNewton::new(self.sizes, &self.bodies, (&self.idx, &self.values), c0)
        {
            return Some(Box::new(r));
        }
        let mut values = self.values.clone();
        for &d in &self.diagonal {
            values[d] += c0;
        }
        let a =
            SparseColMat::new_from_argsort(self.pattern.clone(), &self.argsort, &values).ok()?;
        let lu = Lu::try_new_with_symbolic(self.lu.clone(), a.as_ref()).ok()?;
        Some(Box::new(NewtonLu {
            lu,
            n_y: self.sizes.0 + self.sizes.1,
        }))
    }

    fn oscillatory_eigenvalues(&self) -> Vec<Complex<f64>> {
        self.oscillatory.clone()
    }
}

/// The sparse LU of the Newton system, solving for `δy` alone.
struct NewtonLu {
    lu: Lu<usize, f64>,
    n_y: usize,
}

impl LinearSolver for NewtonLu {
    fn dim(&self) -> usize {
        self.n_y
    }

    fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
        let (n, big) = (self.n_y, self.lu.dim());
        assert_eq!(rhs.len(), n * ncols, "right-hand side has the wrong size");
        let mut b = vec![0.0; big * ncols];
        for k in 0..ncols {
            b[k * big..k * big + n].copy_from_slice(&rhs[k * n..(k + 1) * n]);
        }
        self.lu.solve_columns(&mut b, ncols);
        for k in 0..ncols {
            rhs[k * n..(k + 1) * n].copy_from_slice(&b[k * big..k * big + n]);
        }
    }
}

/// The columns of `R_y` along every flexible body's modal coordinates and rates, gathered while
/// the residual's tangents are read, for the stability limit's eigenvalues: each body's block of
/// `∂f/∂y` on its own `(w, ẇ)`, `[[0, I], [P A⁻¹ R_w, P A⁻¹ R_ẇ]]` on its elastic rows, with
/// `A` the Eq. (12) of the body and its neighbours alone (their masses, the joints among them):
/// a small dense system per body, so that the cost stays linear in the number of bodies.
struct ElasticColumns {
    /// The body and the column (of its `2 n_modes`: `w`, then `ẇ`) of each state index.
    column: Vec<Option<(usize, usize)>>,
    bodies: Vec<ElasticBody>,
}

/// A flexible body's columns of `R_y` along its modal coordinates and rates.
struct ElasticBody {
    body: usize,
    modes: usize,
    /// Per column, the residual rows (`v` index, or `n_v +` the kept row's position) with
    /// their tangents.
    columns: Vec<Vec<(usize, f64)>>,
}

/// What the local systems of [`ElasticColumns::oscillatory`] are made of.
struct Local<'a> {
    model: &'a Model<f64>,
    colouring: &'a Colouring,
    mass: &'a BodyMass<f64>,
    kin: &'a [Kin<f64>],
    rows: &'a [usize],
    /// The position of each constraint row among the kept `rows` (`usize::MAX`: not kept).
    position: &'a [usize],
}

impl ElasticColumns {
    fn new(model: &Model<f64>) -> Self {
        let nq = model.n_q();
        let mut column = vec![None; nq + model.n_v()];
        let mut bodies = Vec::new();
        for (b, id) in model.body_ids().enumerate() {
            let (qr, vr) = (model.q_range(id), model.v_range(id));
            let modes = vr.len() - 6;
            if modes == 0 {
                continue;
            }
            let slot = bodies.len();
            bodies.push(ElasticBody {
                body: b,
                modes,
                columns: vec![Vec::new(); 2 * modes],
            });
            for k in 0..modes {
                column[qr.start + 7 + k] = Some((slot, k));
                column[nq + vr.start + 6 + k] = Some((slot, modes + k));
            }
        }
        Self { column, bodies }
    }

    /// The tangent `x` of residual row `row` along state index `c`.
    fn record(&mut self, c: usize, row: usize, x: f64) {
        if let Some((slot, j)) = self.column[c]
            && x != 0.0
        {
            self.bodies[slot].columns[j].push((row, x));
        }
    }

    /// The oscillatory eigenvalues of every body's elastic block of `∂f/∂y` with its
    /// neighbours (see [`ElasticColumns`]).
    fn oscillatory(&self, l: &Local<'_>) -> Vec<Complex<f64>> {
        let nv = l.model.n_v();
        let mut local = vec![usize::MAX; nv];
        let mut out = Vec::new();
        for e in &self.bodies {
            let (b, m) = (e.body, e.modes);
            let bodies = &l.colouring.neighbours[b];
            let mut nl = 0;
            for &nb in bodies {
                for i in l.model.v_range(BodyId(nb)) {
                    local[i] = nl;
                    nl += 1;
                }
            }
            // the kept rows among these bodies alone
            let mut kept: Vec<usize> = Vec::new();
            for &nb in bodies {
                for &r in &l.colouring.constraint_rows[nb] {
                    let p = l.position[r];
                    if p != usize::MAX
                        && !kept.contains(&p)
                        && l.kin[r].jac.iter().all(|(c, _)| local[c] != usize::MAX)
                    {
                        kept.push(p);
                    }
                }
            }
            let size = nl + kept.len();
            let mut a = DMatrix::zeros(size, size);
            for &nb in bodies {
                let vr = l.model.v_range(BodyId(nb));
                for i in vr.clone() {
                    for j in vr.clone() {
                        a[(local[i], local[j])] = l.mass[(i, j)];
                    }
                }
            }
            for (k, &p) in kept.iter().enumerate() {
                for (c, &x) in l.kin[l.rows[p]].jac.iter() {
                    a[(nl + k, local[c])] = x;
                    a[(local[c], nl + k)] = x;
                }
            }
            let mut rhs = DMatrix::zeros(size, 2 * m);
            for (j, col) in e.columns.iter().enumerate() {
                for &(row, x) in col {
                    let i = if row < nv {
                        local[row]
                    } else {
                        kept.iter()
                            .position(|&p| p == row - nv)
                            .map_or(usize::MAX, |k| nl + k)
                    };
                    if i != usize::MAX {
                        rhs[(i, j)] = x;
                    }
                }
            }
            let e0 = local[l.model.v_range(BodyId(b)).start + 6];
            for &nb in bodies {
                for i in l.model.v_range(BodyId(nb)) {
                    local[i] = usize::MAX;
                }
            }
            let Some(x) = a.lu().solve(&rhs) else {
                continue;
            };
            let mut jb = DMatrix::zeros(2 * m, 2 * m);
            jb.view_mut((0, m), (m, m)).fill_with_identity();
            jb.view_mut((m, 0), (m, 2 * m))
                .copy_from(&x.view((e0, 0), (m, 2 * m)));
            out.extend(oscillatory_eigenvalues(&jb));
        }
        out
    }
}

/// The symbolic parts a [`MultibodySystem`](crate::MultibodySystem) keeps for its sparse Newton
/// matrices.
#[derive(Debug, Default)]
pub(crate) struct NewtonCache {
    pub(crate) colouring: std::sync::OnceLock<Colouring>,
    pub(crate) pattern: Mutex<Option<NewtonPattern>>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Joint, JointKind, Marker, RigidBody};
    use nalgebra::{Matrix3, Vector3};

    /// `n` rigid links pinned end to end, the first to the ground, and a spring between the
    /// first and the last.
    fn chain(n: usize, spring: bool) -> Model<f64> {
        let mut model = Model::new();
        let mut prev: Option<BodyId> = None;
        let mut first = None;
        for i in 0..n {
            let b = model
                .add_rigid_body(RigidBody::new(
                    format!("link {i}"),
                    1.0,
                    Matrix3::identity(),
                ))
                .unwrap();
            first.get_or_insert(b);
            let a = match prev {
                None => Marker::ground(Vector3::zeros()),
                Some(p) => Marker::on(p, Vector3::new(0.5, 0.0, 0.0)),
            };
            let pin = Marker::on(b, Vector3::new(-0.5, 0.0, 0.0));
            model
                .add_joint(Joint::new(format!("pin {i}"), JointKind::Revolute, a, pin))
                .unwrap();
            prev = Some(b);
        }
        if spring {
            model
                .add_force(crate::Force::SpringDamper {
                    a: Marker::on(first.unwrap(), Vector3::zeros()),
                    b: Marker::on(prev.unwrap(), Vector3::zeros()),
                    stiffness: 1.0,
                    damping: 0.0,
                    free_length: 1.0,
                })
                .unwrap();
        }
        model
    }

    /// No two bodies of a colour reach a common body's equations or a common joint's rows.
    fn assert_proper(c: &Colouring) {
        for colour in &c.colours {
            for (i, &a) in colour.iter().enumerate() {
                for &b in &colour[i + 1..] {
                    let shared = c.neighbours[a].iter().any(|x| c.neighbours[b].contains(x))
                        || c.constraint_rows[a]
                            .iter()
                            .any(|r| c.constraint_rows[b].contains(r));
                    assert!(!shared, "bodies {a} and {b} share equations but one colour");
                }
            }
        }
    }

    #[test]
    fn a_chain_needs_three_colours_whatever_its_length() {
        for n in [3, 10, 41] {
            let c = Colouring::new(&chain(n, false));
            assert_eq!(c.n_colours(), 3, "{n} links");
            assert_proper(&c);
            assert_eq!(c.colours.iter().map(Vec::len).sum::<usize>(), n);
        }
    }

    #[test]
    fn a_force_between_two_bodies_couples_them_like_a_joint() {
        let c = Colouring::new(&chain(10, true));
        assert!(c.neighbours[0].contains(&9) && c.neighbours[9].contains(&0));
        assert_proper(&c);
    }
}
