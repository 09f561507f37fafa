//! `SparseCholesky` and its node-graph ordering: the ordering is a permutation that keeps each
//! node's unknowns together and puts the `LAST` ones at the end; it fills the factor no more
//! than faer's own minimum degree ordering of the whole matrix graph; the factor solves its
//! system to round-off, also for a matrix numbered in the ordering beforehand; an indefinite
//! matrix is refused.

use faer::Side;
use faer::sparse::linalg::cholesky::{SymmetricOrdering, factorize_symbolic_cholesky};
use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};
use sens::sparse::{LAST, grouped_ordering};
use sens::{LinearSolver, NotPositiveDefinite, SparseCholesky};

/// A block matrix of an `nx × ny` grid of nodes with `b` unknowns each, coupled with the eight
/// neighbours (a bilinear finite-element pattern), plus `extra` unknowns coupled with every
/// other unknown. Symmetric, strictly diagonally dominant (so positive definite) with
/// deterministic pseudo-random entries. Unknowns are numbered node by node, the nodes in a
/// scrambled order (so that the natural order is a poor one), the extra unknowns in between.
/// Returns the lower triangle, the full matrix and the group of each unknown.
struct Grid {
    lower: SparseColMat<usize, f64>,
    full: SparseColMat<usize, f64>,
    group: Vec<usize>,
}

fn grid(nx: usize, ny: usize, b: usize, extra: usize) -> Grid {
    let nodes = nx * ny;
    // scrambled node numbering
    let order: Vec<usize> = (0..nodes).map(|k| (k * 7919) % nodes).collect();
    let mut group = Vec::new();
    let mut first = vec![0; nodes];
    for (k, &node) in order.iter().enumerate() {
        if k == nodes / 2 {
            group.extend(std::iter::repeat_n(LAST, extra));
        }
        first[node] = group.len();
        group.extend(std::iter::repeat_n(node, b));
    }
    let n = group.len();
    let extra_at: Vec<usize> = (0..n).filter(|&i| group[i] == LAST).collect();
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut rand = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut off: Vec<(usize, usize, f64)> = Vec::new();
    for x in 0..nx {
        for y in 0..ny {
            let a = x * ny + y;
            for dx in -1i64..=1 {
                for dy in -1i64..=1 {
                    let (xb, yb) = (x as i64 + dx, y as i64 + dy);
                    if xb < 0 || yb < 0 || xb >= nx as i64 || yb >= ny as i64 {
                        continue;
                    }
                    let nb = xb as usize * ny + yb as usize;
                    if nb < a {
                        continue;
                    }
                    for i in 0..b {
                        for j in 0..b {
                            let (r, c) = (first[a] + i, first[nb] + j);
                            if r != c && (nb != a || r > c) {
                                off.push((r.max(c), r.min(c), rand()));
                            }
                        }
                    }
                }
            }
        }
    }
    for &e in &extra_at {
        for i in 0..n {
            if i != e && (group[i] != LAST || i > e) {
                off.push((i.max(e), i.min(e), 0.1 * rand()));
            }
        }
    }
    let mut row_sum = vec![0.0; n];
    for &(r, c, v) in &off {
        row_sum[r] += v.abs();
        row_sum[c] += v.abs();
    }
    let mut lower: Vec<Triplet<usize, usize, f64>> =
        off.iter().map(|&(r, c, v)| Triplet::new(r, c, v)).collect();
    lower.extend((0..n).map(|i| Triplet::new(i, i, row_sum[i] + 1.0)));
    let mut full = lower.clone();
    full.extend(off.iter().map(|&(r, c, v)| Triplet::new(c, r, v)));
    Grid {
        lower: SparseColMat::try_new_from_triplets(n, n, &lower).expect("lower"),
        full: SparseColMat::try_new_from_triplets(n, n, &full).expect("full"),
        group,
    }
}

#[test]
fn the_ordering_keeps_nodes_together_and_the_last_unknowns_last() {
    let g = grid(12, 9, 3, 4);
    let n = g.group.len();
    let (perm, perm_inv) = grouped_ordering(g.lower.symbolic(), &g.group).expect("ordering");
    let mut seen = vec![false; n];
    for (k, &i) in perm.iter().enumerate() {
        assert!(!seen[i], "unknown {i} numbered twice");
        seen[i] = true;
        assert_eq!(perm_inv[i], k);
    }
    assert!(seen.iter().all(|&s| s));
    // the four extra unknowns last, in their own order
    let last: Vec<usize> = (0..n).filter(|&i| g.group[i] == LAST).collect();
    assert_eq!(&perm[n - 4..], &last[..]);
    // each node's three unknowns consecutive and ascending
    for chunk in perm[..n - 4].chunks(3) {
        assert!(chunk.iter().all(|&i| g.group[i] == g.group[chunk[0]]));
        assert!(chunk.windows(2).all(|w| w[1] == w[0] + 1));
    }
    // the lower triangle and the full pattern describe the same graph
    let from_full = grouped_ordering(g.full.symbolic(), &g.group).expect("ordering");
    assert_eq!(from_full.0, perm);
}

/// The factor of the node ordering is no larger than 1.1 × that of faer's minimum degree
/// ordering of the whole matrix, and far smaller than that of the scrambled natural order.
#[test]
fn the_node_ordering_fills_as_little_as_a_minimum_degree_ordering_of_the_matrix() {
    let g = grid(40, 30, 3, 6);
    let grouped = SparseCholesky::symbolic(g.lower.symbolic(), Side::Lower, &g.group)
        .expect("symbolic")
        .len_val();
    let amd = factorize_symbolic_cholesky(
        g.lower.symbolic(),
        Side::Lower,
        Default::default(),
        Default::default(),
    )
    .expect("symbolic")
    .len_val();
    let identity: Vec<usize> = (0..g.group.len()).collect();
    let natural = factorize_symbolic_cholesky(
        g.lower.symbolic(),
        Side::Lower,
        SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(
            &identity,
            &identity,
            identity.len(),
        )),
        Default::default(),
    )
    .expect("symbolic")
    .len_val();
    assert!(
        (grouped as f64) < 1.1 * amd as f64,
        "node ordering fills {grouped}, the matrix's minimum degree ordering {amd}"
    );
    assert!(
        (grouped as f64) < 0.25 * natural as f64,
        "node ordering {grouped}, natural {natural}"
    );
}

#[test]
fn the_factor_solves_its_system() {
    let g = grid(15, 11, 6, 3);
    let n = g.group.len();
    let symbolic =
        SparseCholesky::symbolic(g.lower.symbolic(), Side::Lower, &g.group).expect("symbolic");
    let len = symbolic.len_val();
    let llt = SparseCholesky::new(symbolic, g.lower.as_ref(), Side::Lower).expect("SPD");
    assert_eq!(llt.dim(), n);
    assert_eq!(llt.factor_len(), len);
    // two right-hand sides at once
    let x: Vec<f64> = (0..2 * n)
        .map(|i| ((i * 37) % 101) as f64 / 50.0 - 1.0)
        .collect();
    let mut rhs = vec![0.0; 2 * n];
    let (cp, ri, v) = (
        g.full.symbolic().col_ptr(),
        g.full.symbolic().row_idx(),
        g.full.val(),
    );
    for c in 0..2 {
        for j in 0..n {
            for p in cp[j]..cp[j + 1] {
                rhs[c * n + ri[p]] += v[p] * x[c * n + j];
            }
        }
    }
    let ax = rhs.clone();
    llt.solve_columns(&mut rhs, 2);
    let err = rhs
        .iter()
        .zip(&x)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-12, "solution error {err:e}");
    // the symbolic part serves another matrix of the pattern: 2A solves to x/2
    let doubled = SparseColMat::new(
        g.lower.symbolic().to_owned().expect("pattern"),
        g.lower.val().iter().map(|v| 2.0 * v).collect(),
    );
    let llt2 = SparseCholesky::new(llt.symbolic_part().clone(), doubled.as_ref(), Side::Lower)
        .expect("SPD");
    let mut b: Vec<f64> = ax[..n].to_vec();
    llt2.solve_columns(&mut b, 1);
    let err = b
        .iter()
        .zip(&x[..n])
        .map(|(a, b)| (2.0 * a - b).abs() / 2.0)
        .fold(0.0, f64::max);
    assert!(err < 1e-12, "solution error {err:e}");
}

/// A matrix numbered in the node ordering already, factorised without a permutation
/// (`symbolic_in_order`, from either triangle): the same fill as the ordered factorisation of
/// the original numbering, and solutions to round-off.
#[test]
fn a_matrix_in_the_ordering_factorises_without_a_permutation() {
    let g = grid(12, 9, 3, 2);
    let n = g.group.len();
    let ordered =
        SparseCholesky::symbolic(g.lower.symbolic(), Side::Lower, &g.group).expect("symbolic");
    let (_, perm_inv) = grouped_ordering(g.lower.symbolic(), &g.group).expect("ordering");
    // P A Pᵀ: unknown i becomes perm_inv[i]
    let (cp, ri, v) = (
        g.full.symbolic().col_ptr(),
        g.full.symbolic().row_idx(),
        g.full.val(),
    );
    let mut lower = Vec::new();
    let mut upper = Vec::new();
    for j in 0..n {
        for p in cp[j]..cp[j + 1] {
            let (r, c) = (perm_inv[ri[p]], perm_inv[j]);
            if r >= c {
                lower.push(Triplet::new(r, c, v[p]));
            }
            if r <= c {
                upper.push(Triplet::new(r, c, v[p]));
            }
        }
    }
    let x: Vec<f64> = (0..n)
        .map(|i| ((i * 53) % 97) as f64 / 48.0 - 1.0)
        .collect();
    for (side, triplets) in [(Side::Lower, lower), (Side::Upper, upper)] {
        let a = SparseColMat::try_new_from_triplets(n, n, &triplets).expect("matrix");
        let symbolic = SparseCholesky::symbolic_in_order(a.symbolic(), side).expect("symbolic");
        assert_eq!(symbolic.len_val(), ordered.len_val(), "{side:?}: fill");
        let llt = SparseCholesky::new(symbolic, a.as_ref(), side).expect("SPD");
        // b = (P A Pᵀ) x from the full matrix
        let mut b = vec![0.0; n];
        for j in 0..n {
            for p in cp[j]..cp[j + 1] {
                b[perm_inv[ri[p]]] += v[p] * x[perm_inv[j]];
            }
        }
        llt.solve_columns(&mut b, 1);
        let err = b
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12, "{side:?}: solution error {err:e}");
    }
}

#[test]
fn an_indefinite_matrix_is_refused() {
    let g = grid(5, 4, 2, 1);
    let symbolic =
        SparseCholesky::symbolic(g.lower.symbolic(), Side::Lower, &g.group).expect("symbolic");
    let negated = SparseColMat::new(
        g.lower.symbolic().to_owned().expect("pattern"),
        g.lower.val().iter().map(|v| -v).collect(),
    );
    assert_eq!(
        SparseCholesky::new(symbolic, negated.as_ref(), Side::Lower).err(),
        Some(NotPositiveDefinite)
    );
    // nothing to order: no unknowns
    let empty = SymbolicSparseColMat::<usize>::new_checked(0, 0, vec![0], None, vec![]);
    let (perm, _) = grouped_ordering(empty.as_ref(), &[]).expect("empty ordering");
    assert!(perm.is_empty());
}
