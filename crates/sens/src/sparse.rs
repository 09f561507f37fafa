//! Sparse Cholesky factorisation with a fill-reducing ordering computed on the *node* graph.
//!
//! Finite-element matrices come in blocks: every node carries the same few unknowns (three
//! warping components of a section node, six dof of a shell node), coupled all-to-all within
//! the node and with the same neighbours. The approximate minimum degree ordering of faer's
//! default path works on the matrix graph, `b²` times larger than the graph of the nodes
//! (`b` unknowns a node), and finds the blocks again by its supervariable detection. Ordering
//! the node graph instead and numbering each node's unknowns together is the same ordering in
//! effect at a fraction of the cost (about 11 % of a 20 000-element section's analysis went
//! into faer's ordering; docs/performance.md).
//!
//! Unknowns that couple with everything (a section's six generalised strains, Lagrange
//! multipliers) are given group [`LAST`]: they are numbered after all nodes, where a minimum
//! degree ordering puts dense rows anyway.

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::FaerError;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Side, get_global_parallelism};

use crate::LinearSolver;

/// The group of an unknown numbered after every node.
pub const LAST: usize = usize::MAX;

/// The fill-reducing ordering of a symmetric matrix whose unknown `i` belongs to node
/// `group[i]` (or to [`LAST`]): the approximate minimum degree ordering of the graph of the
/// nodes (two nodes are adjacent when any of their unknowns couple in `pattern`), each node's
/// unknowns numbered together in their own order, the [`LAST`] unknowns at the end.
///
/// `pattern` is either triangle, or both. Returns `(perm, perm_inv)`: `perm[k]` is the unknown
/// numbered `k`.
pub fn grouped_ordering(
    pattern: SymbolicSparseColMatRef<'_, usize>,
    group: &[usize],
) -> Result<(Vec<usize>, Vec<usize>), FaerError> {
    let n = pattern.nrows();
    assert_eq!(
        pattern.ncols(),
        n,
        "grouped_ordering: the matrix is not square"
    );
    assert_eq!(group.len(), n, "grouped_ordering: one group per unknown");
    let n_groups = group
        .iter()
        .filter(|&&g| g != LAST)
        .map(|&g| g + 1)
        .max()
        .unwrap_or(0);
    // Each node's unknowns, in their own order.
    let mut members_ptr = vec![0usize; n_groups + 1];
    for &g in group {
        if g != LAST {
            members_ptr[g + 1] += 1;
        }
    }
    for g in 0..n_groups {
        members_ptr[g + 1] += members_ptr[g];
    }
    let mut members = vec![0usize; members_ptr[n_groups]];
    let mut fill = members_ptr[..n_groups].to_vec();
    for (i, &g) in group.iter().enumerate() {
        if g != LAST {
            members[fill[g]] = i;
            fill[g] += 1;
        }
    }
    drop(fill);
    // The node graph: each node's neighbours met in its own columns, once each (marked).
    let (col_ptr, row_idx) = (pattern.col_ptr(), pattern.row_idx());
    let mut adjacent: Vec<Vec<usize>> = vec![Vec::new(); n_groups];
    let mut mark = vec![LAST; n_groups];
    for gj in 0..n_groups {
        mark[gj] = gj;
        for &j in &members[members_ptr[gj]..members_ptr[gj + 1]] {
            for &i in &row_idx[col_ptr[j]..col_ptr[j + 1]] {
                let gi = group[i];
                if gi != LAST && mark[gi] != gj {
                    mark[gi] = gj;
                    adjacent[gj].push(gi);
                }
            }
        }
    }
    // A triangle-only pattern lists a pair under one node: mirror every pair, then keep the
    // lower triangle of the union.
    let mut ptr = vec![0usize; n_groups + 1];
    for (gj, adj) in adjacent.iter().enumerate() {
        for &gi in adj {
            let c = gi.min(gj);
            ptr[c + 1] += 1;
        }
    }
    for g in 0..n_groups {
        ptr[g + 1] += ptr[g];
    }
    let mut idx = vec![0usize; ptr[n_groups]];
    let mut next = ptr[..n_groups].to_vec();
    for (gj, adj) in adjacent.iter().enumerate() {
        for &gi in adj {
            let (r, c) = (gi.max(gj), gi.min(gj));
            idx[next[c]] = r;
            next[c] += 1;
        }
    }
    drop(adjacent);
    // sort and remove the pairs listed under both nodes
    let mut write = 0;
    let mut start = 0;
    for c in 0..n_groups {
        let end = ptr[c + 1];
        idx[start..end].sort_unstable();
        let col_start = write;
        for k in start..end {
            if write == col_start || idx[write - 1] != idx[k] {
                idx[write] = idx[k];
                write += 1;
            }
        }
        start = end;
        ptr[c + 1] = write;
    }
    idx.truncate(write);
    let nnz = idx.len();
    let graph = SymbolicSparseColMatRef::new_checked(n_groups, n_groups, &ptr, None, &idx);
    let mut node_perm = vec![0usize; n_groups];
    let mut node_perm_inv = vec![0usize; n_groups];
    if n_groups > 0 {
        let mut mem = MemBuffer::try_new(amd::order_scratch::<usize>(n_groups, nnz))?;
        amd::order(
            &mut node_perm,
            &mut node_perm_inv,
            graph,
            amd::Control::default(),
            MemStack::new(&mut mem),
        )?;
    }
    // Nodes in the minimum degree order.
    let mut perm = Vec::with_capacity(n);
    for &g in &node_perm {
        perm.extend_from_slice(&members[members_ptr[g]..members_ptr[g + 1]]);
    }
    perm.extend((0..n).filter(|&i| group[i] == LAST));
    let mut perm_inv = vec![0usize; n];
    for (k, &i) in perm.iter().enumerate() {
        perm_inv[i] = k;
    }
    Ok((perm, perm_inv))
}

/// The factor `P A Pᵀ = L Lᵀ` of a symmetric positive definite sparse matrix (faer's
/// supernodal factorisation, whatever the size: faer's flop ratio picks the simplicial one
/// for the paper decks' small sections, 1 700 unknowns, which made the beam deck's model
/// build with derivatives 45 ms instead of 35 ms), ordered by
/// [`grouped_ordering`]. Its symbolic part can be shared by matrices of the same pattern.
#[derive(Clone, Debug)]
pub struct SparseCholesky {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

/// A matrix that is not numerically positive definite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotPositiveDefinite;

impl std::fmt::Display for NotPositiveDefinite {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("the matrix is not numerically positive definite")
    }
}

impl std::error::Error for NotPositiveDefinite {}

impl SparseCholesky {
    /// The symbolic factorisation of the pattern `pattern` (the triangle `side` of a symmetric
    /// matrix) with the node groups `group` of [`grouped_ordering`].
    pub fn symbolic(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        side: Side,
        group: &[usize],
    ) -> Result<Arc<SymbolicCholesky<usize>>, FaerError> {
        let (perm, perm_inv) = grouped_ordering(pattern, group)?;
        let ordering = PermRef::new_checked(&perm, &perm_inv, perm.len());
        factorize_symbolic_cholesky(
            pattern,
            side,
            SymmetricOrdering::Custom(ordering),
            supernodal(),
        )
        .map(Arc::new)
    }

    /// The symbolic factorisation of the pattern `pattern` (the triangle `side`) in the order
    /// of its unknowns: for a matrix assembled in the order of [`grouped_ordering`] already,
    /// which spares the numeric factorisation a permuted copy of the matrix.
    pub fn symbolic_in_order(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        side: Side,
    ) -> Result<Arc<SymbolicCholesky<usize>>, FaerError> {
        // without a permutation faer reads the pattern as given, and its analysis wants the
        // upper triangle
        let upper = match side {
            Side::Upper => None,
            Side::Lower => Some(pattern.transpose().to_col_major()?),
        };
        let pattern = upper.as_ref().map_or(pattern, |u| u.as_ref());
        factorize_symbolic_cholesky(
            pattern,
            Side::Upper,
            SymmetricOrdering::Identity,
            supernodal(),
        )
        .map(Arc::new)
    }

    /// The numeric factorisation of `a` (the triangle `side`, of the pattern `symbolic` was
    /// made for).
    pub fn new(
        symbolic: Arc<SymbolicCholesky<usize>>,
        a: SparseColMatRef<'_, usize, f64>,
        side: Side,
    ) -> Result<Self, NotPositiveDefinite> {
        let mut values = vec![0.0; symbolic.len_val()];
        let par = get_global_parallelism();
        let mut mem =
            MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut values,
                a,
                side,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|_| NotPositiveDefinite)?;
        Ok(Self { symbolic, values })
    }

    /// The symbolic factorisation, to factorise another matrix of the same pattern.
    pub fn symbolic_part(&self) -> &Arc<SymbolicCholesky<usize>> {
        &self.symbolic
    }

    /// Number of stored entries of `L`.
    pub fn factor_len(&self) -> usize {
        self.values.len()
    }
}

/// faer's symbolic parameters with the supernodal factorisation at every size (see
/// [`SparseCholesky`]).
fn supernodal() -> faer::sparse::linalg::cholesky::CholeskySymbolicParams<'static> {
    faer::sparse::linalg::cholesky::CholeskySymbolicParams {
        supernodal_flop_ratio_threshold:
            faer::sparse::linalg::SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    }
}

impl LinearSolver for SparseCholesky {
    fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    fn solve_columns(&self, rhs: &mut [f64], ncols: usize) {
        let n = self.dim();
        assert_eq!(rhs.len(), n * ncols, "right-hand side has the wrong size");
        if n == 0 || ncols == 0 {
            return;
        }
        let par = get_global_parallelism();
        let mut mem = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(ncols, par));
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, ncols),
            par,
            MemStack::new(&mut mem),
        );
    }
}
