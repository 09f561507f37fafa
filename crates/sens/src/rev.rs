//! Reverse-mode differentiation on a thread-local tape: [`Rev`] and [`Tape`].
//!
//! A [`Rev`] is a value and the index of the tape node that made it. Every operation on a
//! value that depends on an input ([`Rev::input`]) appends one node to the current thread's
//! tape with the partial derivatives of the result with respect to its (at most two)
//! arguments; operations on constants record nothing, nor do those whose result is a constant
//! (a zero partial: `x · 0`) or its argument itself (`x + 0`, `x · 1`, `x / 1`: the argument's
//! node serves) — the sums of products with zero and unit entries that rotation and
//! kinematics code is full of. A reverse sweep
//! ([`Tape::backpropagate`]) then carries adjoints from the outputs back to every node at once:
//! the gradient of one scalar with respect to all inputs costs a few evaluations, whatever
//! their number (the adjoint method of docs/design.md §3).
//!
//! The tape is a stack, so one part of it can outlive another: the inputs and the quantities
//! computed from them once (a model's data and what is cached from it) at the bottom, the
//! evaluations that use them above, rewound ([`Tape::rewind`]) after each sweep. The adjoints
//! a sweep leaves on the bottom part add up over the sweeps; one final sweep of the bottom part
//! carries their sum to the inputs.
//!
//! A function whose reverse is cheaper written by hand than swept node by node (many
//! multiply-adds with few inputs and outputs) can be recorded as one operation instead
//! ([`Rev::external`]): its outputs are nodes of their own, and the sweep calls its
//! [`ExternalReverse`] once they have their adjoints. [`Rev::dot_rows`] is one such operation:
//! the rows of a table dotted with a vector, one node per row instead of two per product.
//!
//! A `Rev` is only meaningful on the thread that made it, while the tape still holds its node
//! (not rewound below it, not cleared).

use std::cell::RefCell;
use std::fmt;
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};
use std::rc::Rc;

use num_traits::{One, Zero};

use crate::{LinearSolver, Scalar};

/// Index of no node: a constant, or a node's missing second argument.
const NONE: u32 = u32::MAX;

/// `args[1]` of a node with more than two arguments ([`Scalar::dot`], [`Scalar::sub_scaled`]):
/// they are entries `args[0]..partials[0]` of the thread's table of wide arguments.
const WIDE: u32 = u32::MAX - 1;

/// One operation: the result's partial derivatives with respect to its arguments. A missing
/// argument (an input's, a unary operation's second, a constant's) is the node itself with a
/// zero partial: the sweep adds `0 · adjoint` to an adjoint it has already passed on, so it runs
/// without a branch.
#[derive(Clone, Copy)]
struct Node {
    args: [u32; 2],
    partials: [f64; 2],
}

/// The reverse of a function recorded as one operation ([`Rev::external`]).
pub trait ExternalReverse: 'static {
    /// Add `(∂y/∂x)ᵀ ȳ` to the inputs' adjoints `x_bar` (input `p`'s by
    /// [`InputAdjoints::add`]), `y_bar` the adjoints of its outputs. Called during a sweep: it
    /// must not record on the tape.
    fn reverse(&self, y_bar: &[f64], x_bar: &mut InputAdjoints<'_>);
}

/// The adjoints of an external operation's inputs during a sweep: the tape's own, reached
/// through the inputs' nodes (no buffer of the inputs' adjoints to fill and scatter).
pub struct InputAdjoints<'a> {
    /// The tape's adjoints below the operation's outputs (where its inputs' nodes are).
    adjoints: &'a mut [f64],
    inputs: &'a [u32],
}

impl InputAdjoints<'_> {
    /// Add `a` to the adjoint of input `p` (nothing for a constant input).
    ///
    /// # Panics
    /// If `p` is not an input of the operation.
    #[inline]
    pub fn add(&mut self, p: usize, a: f64) {
        let i = self.inputs[p];
        if i != NONE {
            self.adjoints[i as usize] += a;
        }
    }
}

/// An operation recorded by [`Rev::external`]: its outputs are nodes `first..end`.
struct External {
    first: usize,
    end: usize,
    /// The inputs' nodes ([`NONE`] for a constant).
    inputs: Vec<u32>,
    op: Box<dyn ExternalReverse>,
}

/// The reverse of [`Rev::dot_rows`]: `x̄_p = Σ_i ȳ_i a_ip`, `ā_ip = ȳ_i x_p` (inputs `x`, then
/// the rows' entries).
struct DotRows {
    rows: Vec<f64>,
    lens: Vec<usize>,
    x: Vec<f64>,
}

impl ExternalReverse for DotRows {
    fn reverse(&self, y_bar: &[f64], x_bar: &mut InputAdjoints<'_>) {
        let nx = self.x.len();
        let mut x_adj = vec![0.0; nx];
        let mut start = 0;
        for (&len, &y) in self.lens.iter().zip(y_bar) {
            let row = &self.rows[start..start + len];
            for (p, (x_adj, (&a, &x))) in x_adj.iter_mut().zip(row.iter().zip(&self.x)).enumerate()
            {
                *x_adj += y * a;
                x_bar.add(nx + start + p, y * x);
            }
            start += len;
        }
        x_adj.iter().enumerate().for_each(|(p, &a)| x_bar.add(p, a));
    }
}

thread_local! {
    static TAPE: RefCell<Vec<Node>> = const { RefCell::new(Vec::new()) };
    /// The arguments and partials of the nodes with more than two, in the order of the nodes.
    static WIDE_ARGS: RefCell<Vec<(u32, f64)>> = const { RefCell::new(Vec::new()) };
    /// The external operations on the tape, in the order of their outputs.
    static EXTERNAL: RefCell<Vec<External>> = const { RefCell::new(Vec::new()) };
}

#[inline]
fn push(args: [u32; 2], partials: [f64; 2]) -> u32 {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        let index = t.len();
        // 2³² nodes would take 96 GiB: memory runs out first
        debug_assert!(index < NONE as usize, "the reverse-mode tape is full");
        let args = args.map(|a| if a == NONE { index as u32 } else { a });
        t.push(Node { args, partials });
        index as u32
    })
}

/// The arguments of a node being recorded by [`wide_node`].
struct WideArgs<'a>(&'a mut Vec<(u32, f64)>);

impl WideArgs<'_> {
    /// An argument with its partial; nothing for a constant or a zero partial.
    #[inline]
    fn arg(&mut self, index: u32, partial: f64) {
        if index != NONE && partial != 0.0 {
            self.0.push((index, partial));
        }
    }
}

/// The node of a result whose arguments `add` gives: [`NONE`] for none, a node of the usual
/// kind for two at most, a wide node for more.
#[inline]
fn wide_node(add: impl FnOnce(&mut WideArgs)) -> u32 {
    WIDE_ARGS.with(|w| {
        let mut w = w.borrow_mut();
        let start = w.len();
        add(&mut WideArgs(&mut w));
        match w.len() - start {
            0 => NONE,
            1 | 2 => {
                let first = w[start];
                let second = w.get(start + 1).copied().unwrap_or((NONE, 0.0));
                w.truncate(start);
                push([first.0, second.0], [first.1, second.1])
            }
            _ => push_wide(start, w.len()),
        }
    })
}

/// A node whose arguments are the wide arguments `start..end`.
fn push_wide(start: usize, end: usize) -> u32 {
    TAPE.with(|t| {
        let mut t = t.borrow_mut();
        let index = t.len();
        debug_assert!(index < WIDE as usize, "the reverse-mode tape is full");
        let start = u32::try_from(start).expect("fewer than 2³² wide arguments");
        t.push(Node {
            args: [start, WIDE],
            partials: [end as f64, 0.0],
        });
        index as u32
    })
}

/// The current thread's tape (a namespace: the tape itself is thread-local).
pub struct Tape;

impl Tape {
    /// The number of nodes on the tape: a mark to [`Tape::rewind`] to.
    pub fn len() -> usize {
        TAPE.with(|t| t.borrow().len())
    }

    /// Whether the tape is empty.
    pub fn is_empty() -> bool {
        Self::len() == 0
    }

    /// Drop the nodes above `mark`; every `Rev` made after it becomes invalid.
    pub fn rewind(mark: usize) {
        TAPE.with(|t| {
            let mut t = t.borrow_mut();
            // the wide arguments of the nodes dropped: from the first wide node's on
            if let Some(node) = t
                .get(mark..)
                .and_then(|n| n.iter().find(|n| n.args[1] == WIDE))
            {
                WIDE_ARGS.with(|w| w.borrow_mut().truncate(node.args[0] as usize));
            }
            t.truncate(mark);
        });
        EXTERNAL.with(|e| {
            let mut e = e.borrow_mut();
            let keep = e.partition_point(|x| x.end <= mark);
            e.truncate(keep);
        });
    }

    /// Drop every node.
    pub fn clear() {
        Self::rewind(0);
    }

    /// The reverse sweep over nodes `down_to..` (from the top down): each node's adjoint,
    /// times its partial derivatives, is added to its arguments' adjoints, which may lie
    /// below `down_to` (they are accumulated there, not swept further). `adjoints` is indexed
    /// by node and extended with zeros to the tape's length; seed it with [`Rev::seed`].
    /// An external operation is reversed when the sweep has passed its outputs; one whose
    /// outputs straddle `down_to` is an error.
    pub fn backpropagate(adjoints: &mut Vec<f64>, down_to: usize) {
        Self::sweep::<false>(adjoints, down_to);
    }

    /// [`Tape::backpropagate`] that leaves the adjoints of the nodes `down_to..` zero once it
    /// has passed them (what is below `down_to` accumulates as there): `adjoints` is ready for
    /// the next seeding of the part above `down_to` without being refilled.
    pub fn backpropagate_clearing(adjoints: &mut Vec<f64>, down_to: usize) {
        Self::sweep::<true>(adjoints, down_to);
    }

    fn sweep<const CLEAR: bool>(adjoints: &mut Vec<f64>, down_to: usize) {
        TAPE.with(|t| {
            EXTERNAL.with(|e| {
                let (t, e) = (t.borrow(), e.borrow());
                WIDE_ARGS.with(|w| {
                    let wide = w.borrow();
                    let t = (&t[..], &wide[..]);
                    if adjoints.len() < t.0.len() {
                        adjoints.resize(t.0.len(), 0.0);
                    }
                    let mut top = t.0.len();
                    for op in e.iter().rev().take_while(|op| op.end > down_to) {
                        assert!(
                            op.first >= down_to,
                            "a sweep that splits an external operation"
                        );
                        sweep_nodes::<CLEAR>(t, adjoints, op.end..top);
                        // the inputs' nodes are below the outputs'
                        let (below, above) = adjoints.split_at_mut(op.first);
                        let y_bar = &mut above[..op.end - op.first];
                        let mut x_bar = InputAdjoints {
                            adjoints: below,
                            inputs: &op.inputs,
                        };
                        op.op.reverse(y_bar, &mut x_bar);
                        if CLEAR {
                            y_bar.fill(0.0);
                        }
                        top = op.first;
                    }
                    sweep_nodes::<CLEAR>(t, adjoints, down_to..top);
                })
            })
        });
    }
}

/// The reverse sweep over the nodes of `range`, from the top down, each node's adjoint left
/// zero after it when `CLEAR`.
#[inline]
fn sweep_nodes<const CLEAR: bool>(
    (t, wide): (&[Node], &[(u32, f64)]),
    adjoints: &mut [f64],
    range: std::ops::Range<usize>,
) {
    for i in range.rev() {
        // (a zero adjoint adds zeros: cheaper than a branch on it)
        let a = adjoints[i];
        let node = &t[i];
        if node.args[1] == WIDE {
            let args = &wide[node.args[0] as usize..node.partials[0] as usize];
            for &(j, p) in args {
                adjoints[j as usize] += a * p;
            }
        } else {
            adjoints[node.args[0] as usize] += a * node.partials[0];
            adjoints[node.args[1] as usize] += a * node.partials[1];
        }
        if CLEAR {
            // after the node's own missing arguments have added to it
            adjoints[i] = 0.0;
        }
    }
}

/// A value on the reverse-mode tape of the current thread (see the module documentation).
///
/// Equality and ordering compare the value only, as for [`crate::Dual`]. Where a derivative is
/// infinite (`sqrt`, `asin`, `acos`, `ln`, `powi`, `powf` at their singular points) the
/// recorded partial is zero: the result [`crate::Dual`] gives for an argument whose tangent is
/// zero, the case such points arise in (the root of a squared norm that vanishes).
#[derive(Clone, Copy)]
pub struct Rev {
    value: f64,
    index: u32,
}

impl Rev {
    /// A constant: it records nothing and has no adjoint.
    #[inline]
    pub const fn constant(value: f64) -> Self {
        Self { value, index: NONE }
    }

    /// A new independent input: a node of its own.
    pub fn input(value: f64) -> Self {
        Self {
            value,
            index: push([NONE, NONE], [0.0, 0.0]),
        }
    }

    /// Values `outputs` of a function of `inputs` computed elsewhere, recorded as one
    /// operation whose reverse is `op` (called by [`Tape::backpropagate`] with the outputs'
    /// adjoints): one node per output, and no node for the function's own operations. With
    /// every input a constant the outputs are constants.
    pub fn external(inputs: &[Rev], outputs: &[f64], op: impl ExternalReverse) -> Vec<Rev> {
        if inputs.iter().all(|x| x.is_constant()) {
            return outputs.iter().map(|&y| Self::constant(y)).collect();
        }
        let first = Tape::len();
        debug_assert!(
            (inputs.iter()).all(|x| x.index == NONE || (x.index as usize) < first),
            "an external operation's inputs are on the tape before it"
        );
        let out: Vec<Rev> = outputs.iter().map(|&y| Self::input(y)).collect();
        EXTERNAL.with(|e| {
            e.borrow_mut().push(External {
                first,
                end: first + outputs.len(),
                inputs: inputs.iter().map(|x| x.index).collect(),
                op: Box::new(op),
            })
        });
        out
    }

    /// `y_i = Σ_p a_ip x_p` for the rows `a_i` of `rows`, laid end to end (row `i` is the next
    /// `lens[i]` entries, dotted with `x[..lens[i]]`), recorded as one operation: one node per
    /// row instead of two per product. The values are those of the products summed in order
    /// from zero, as the same dot products recorded operation by operation give.
    ///
    /// # Panics
    /// If the lengths do not add up to the entries, or a row is longer than `x`.
    pub fn dot_rows(rows: &[Rev], lens: &[usize], x: &[Rev]) -> Vec<Rev> {
        assert_eq!(
            lens.iter().sum::<usize>(),
            rows.len(),
            "the rows' lengths add up to their entries"
        );
        assert!(
            lens.iter().all(|&len| len <= x.len()),
            "a row no longer than the vector"
        );
        let op = DotRows {
            rows: rows.iter().map(|a| a.value).collect(),
            lens: lens.to_vec(),
            x: x.iter().map(|a| a.value).collect(),
        };
        let mut values = Vec::with_capacity(lens.len());
        let mut start = 0;
        for &len in lens {
            let row = &op.rows[start..start + len];
            values.push(row.iter().zip(&op.x).fold(0.0, |acc, (a, b)| acc + a * b));
            start += len;
        }
        let inputs: Vec<Rev> = x.iter().chain(rows).copied().collect();
        Self::external(&inputs, &values, op)
    }

    /// The tape node of this value (`None` for a constant).
    pub fn node(self) -> Option<usize> {
        (self.index != NONE).then_some(self.index as usize)
    }

    /// Whether this value is a constant (depends on no input).
    pub fn is_constant(self) -> bool {
        self.index == NONE
    }

    /// Add `w` to this value's adjoint (nothing for a constant).
    pub fn seed(self, adjoints: &mut Vec<f64>, w: f64) {
        if let Some(i) = self.node() {
            if adjoints.len() <= i {
                adjoints.resize(i + 1, 0.0);
            }
            adjoints[i] += w;
        }
    }

    /// This value's adjoint after a sweep (0 for a constant).
    pub fn adjoint(self, adjoints: &[f64]) -> f64 {
        self.node()
            .and_then(|i| adjoints.get(i).copied())
            .unwrap_or(0.0)
    }

    /// A unary result `f` with derivative `df`.
    #[inline]
    fn unary(self, f: f64, df: f64) -> Self {
        if self.index == NONE || df == 0.0 {
            return Self::constant(f);
        }
        if df == 1.0 && f.to_bits() == self.value.to_bits() {
            // the argument itself (`x + 0`, `x · 1`): its node serves
            return self;
        }
        Self {
            value: f,
            index: push([self.index, NONE], [df, 0.0]),
        }
    }

    /// As [`Rev::unary`] with a derivative that may be infinite at the point (taken as zero).
    #[inline]
    fn unary_singular(self, f: f64, df: f64) -> Self {
        self.unary(f, if df.is_finite() { df } else { 0.0 })
    }

    /// A binary result `f` with partials `da`, `db`.
    #[inline]
    fn binary(a: Self, b: Self, f: f64, da: f64, db: f64) -> Self {
        match (a.index == NONE, b.index == NONE) {
            (true, true) => Self::constant(f),
            (false, true) => a.unary(f, da),
            (true, false) => b.unary(f, db),
            (false, false) => Self {
                value: f,
                index: push([a.index, b.index], [da, db]),
            },
        }
    }
}

impl Default for Rev {
    fn default() -> Self {
        Self::constant(0.0)
    }
}

impl fmt::Debug for Rev {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.node() {
            Some(i) => write!(f, "Rev({:?} @{i})", self.value),
            None => write!(f, "Rev({:?})", self.value),
        }
    }
}

impl fmt::Display for Rev {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.value, f)
    }
}

impl PartialEq for Rev {
    fn eq(&self, other: &Self) -> bool {
        self.value == other.value
    }
}

impl PartialOrd for Rev {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        self.value.partial_cmp(&other.value)
    }
}

impl From<f64> for Rev {
    fn from(v: f64) -> Self {
        Self::constant(v)
    }
}

macro_rules! binary_ops {
    ($tr:ident, $method:ident, $tra:ident, $method_a:ident, |$a:ident, $b:ident| $body:expr) => {
        impl $tr for Rev {
            type Output = Rev;
            #[inline]
            fn $method(self, rhs: Rev) -> Rev {
                let ($a, $b) = (self, rhs);
                $body
            }
        }
        impl $tr<f64> for Rev {
            type Output = Rev;
            #[inline]
            fn $method(self, rhs: f64) -> Rev {
                self.$method(Rev::constant(rhs))
            }
        }
        impl $tr<Rev> for f64 {
            type Output = Rev;
            #[inline]
            fn $method(self, rhs: Rev) -> Rev {
                Rev::constant(self).$method(rhs)
            }
        }
        impl $tra for Rev {
            #[inline]
            fn $method_a(&mut self, rhs: Rev) {
                *self = (*self).$method(rhs);
            }
        }
        impl $tra<f64> for Rev {
            #[inline]
            fn $method_a(&mut self, rhs: f64) {
                *self = (*self).$method(rhs);
            }
        }
    };
}

binary_ops!(Add, add, AddAssign, add_assign, |a, b| Rev::binary(
    a,
    b,
    a.value + b.value,
    1.0,
    1.0
));
binary_ops!(Sub, sub, SubAssign, sub_assign, |a, b| Rev::binary(
    a,
    b,
    a.value - b.value,
    1.0,
    -1.0
));
binary_ops!(Mul, mul, MulAssign, mul_assign, |a, b| Rev::binary(
    a,
    b,
    a.value * b.value,
    b.value,
    a.value
));
binary_ops!(Div, div, DivAssign, div_assign, |a, b| {
    let inv = 1.0 / b.value;
    let f = a.value / b.value;
    Rev::binary(a, b, f, inv, -f * inv)
});

impl Neg for Rev {
    type Output = Rev;
    #[inline]
    fn neg(self) -> Rev {
        self.unary(-self.value, -1.0)
    }
}

impl Sum for Rev {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::constant(0.0), |a, b| a + b)
    }
}

impl<'a> Sum<&'a Rev> for Rev {
    fn sum<I: Iterator<Item = &'a Self>>(iter: I) -> Self {
        iter.fold(Self::constant(0.0), |a, &b| a + b)
    }
}

impl Zero for Rev {
    fn zero() -> Self {
        Self::constant(0.0)
    }
    /// The constant zero (a zero value that depends on an input is not).
    fn is_zero(&self) -> bool {
        self.value == 0.0 && self.index == NONE
    }
}

impl One for Rev {
    fn one() -> Self {
        Self::constant(1.0)
    }
}

impl Scalar for Rev {
    const TANGENTS: usize = 0;
    /// One node with an argument for each factor (constants left out), the value summed as
    /// `f64` sums it.
    fn dot(a: &[Self], b: &[Self]) -> Self {
        assert_eq!(a.len(), b.len(), "dot of two slices of one length");
        let mut value = 0.0;
        let index = wide_node(|args| {
            for (k, (x, y)) in a.iter().zip(b).enumerate() {
                let p = x.value * y.value;
                value = if k == 0 { p } else { value + p };
                args.arg(x.index, y.value);
                args.arg(y.index, x.value);
            }
        });
        Self { value, index }
    }

    /// One node with an argument for `init` and each `a_j` (constants left out), the value
    /// as `f64` computes it.
    fn sub_scaled(init: Self, a: &[Self], x: &[f64]) -> Self {
        assert_eq!(a.len(), x.len(), "sub_scaled of two slices of one length");
        let mut value = init.value;
        let index = wide_node(|args| {
            args.arg(init.index, 1.0);
            for (a, &x) in a.iter().zip(x) {
                value -= a.value * x;
                args.arg(a.index, -x);
            }
        });
        Self { value, index }
    }
    const PLAIN: bool = false;

    #[inline]
    fn from_f64(x: f64) -> Self {
        Self::constant(x)
    }
    fn is_constant(&self) -> bool {
        self.index == NONE
    }
    /// One operation on the tape whose reverse is `ḡ += A⁻¹ x̄` (`A` symmetric).
    fn symmetric_solution(
        g: &[Self],
        x_values: Vec<f64>,
        ncols: usize,
        solver: &Rc<dyn LinearSolver>,
    ) -> Vec<Self> {
        crate::scalar::check_solution_sizes(g.len(), x_values.len(), solver.dim(), ncols);
        /// The reverse of `x = A⁻¹ g` for a symmetric `A`.
        struct SymmetricSolve(Rc<dyn LinearSolver>, usize);
        impl ExternalReverse for SymmetricSolve {
            fn reverse(&self, y_bar: &[f64], x_bar: &mut InputAdjoints<'_>) {
                let mut r = y_bar.to_vec();
                self.0.solve_columns(&mut r, self.1);
                r.iter().enumerate().for_each(|(p, &r)| x_bar.add(p, r));
            }
        }
        Self::external(g, &x_values, SymmetricSolve(Rc::clone(solver), ncols))
    }
    /// # Panics
    /// Always: a taped value has no tangents to be built from (its derivatives would be lost);
    /// code that assembles results from precomputed tangents does not support `Rev`.
    fn from_parts(_value: f64, _tangents: &[f64]) -> Self {
        panic!("Rev cannot be built from precomputed tangents: its derivatives would be lost")
    }
    #[inline]
    fn value(self) -> f64 {
        self.value
    }
    #[inline]
    fn tangents(&self) -> &[f64] {
        &[]
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.value.sqrt();
        self.unary_singular(s, 0.5 / s)
    }
    #[inline]
    fn sin(self) -> Self {
        let (s, c) = self.value.sin_cos();
        self.unary(s, c)
    }
    #[inline]
    fn cos(self) -> Self {
        let (s, c) = self.value.sin_cos();
        self.unary(c, -s)
    }
    #[inline]
    fn tan(self) -> Self {
        let t = self.value.tan();
        self.unary(t, 1.0 + t * t)
    }
    #[inline]
    fn asin(self) -> Self {
        let v = self.value;
        self.unary_singular(v.asin(), 1.0 / (1.0 - v * v).sqrt())
    }
    #[inline]
    fn acos(self) -> Self {
        let v = self.value;
        self.unary_singular(v.acos(), -1.0 / (1.0 - v * v).sqrt())
    }
    #[inline]
    fn atan(self) -> Self {
        let v = self.value;
        self.unary(v.atan(), 1.0 / (1.0 + v * v))
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy − y dx) / (x² + y²)
        let (y, r2) = (self.value, x.value * x.value + self.value * self.value);
        let (dy, dx) = if r2 > 0.0 {
            (x.value / r2, -y / r2)
        } else {
            (0.0, 0.0)
        };
        Self::binary(self, x, y.atan2(x.value), dy, dx)
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.value.exp();
        self.unary(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.unary_singular(self.value.ln(), 1.0 / self.value)
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        match n {
            0 => Self::constant(1.0),
            1 => self,
            _ => self.unary_singular(self.value.powi(n), f64::from(n) * self.value.powi(n - 1)),
        }
    }
    #[inline]
    fn powf(self, p: Self) -> Self {
        let f = self.value.powf(p.value);
        if p.index == NONE {
            // constant exponent: valid for a negative base with an integral exponent too
            if p.value == 0.0 {
                return Self::constant(1.0);
            }
            return self.unary_singular(f, p.value * self.value.powf(p.value - 1.0));
        }
        // d(a^p) = a^p (ln a dp + p/a da)
        let da = p.value * f / self.value;
        let dp = f * self.value.ln();
        let finite = |d: f64| if d.is_finite() { d } else { 0.0 };
        Self::binary(self, p, f, finite(da), finite(dp))
    }
    #[inline]
    fn abs(self) -> Self {
        if self.value < 0.0 { -self } else { self }
    }
    #[inline]
    fn hypot(self, other: Self) -> Self {
        let h = self.value.hypot(other.value);
        let (da, db) = if h > 0.0 {
            (self.value / h, other.value / h)
        } else {
            (0.0, 0.0)
        };
        Self::binary(self, other, h, da, db)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Dual;

    /// The gradient of `f` at `x` by one reverse sweep.
    fn reverse_gradient(f: impl Fn(&[Rev]) -> Rev, x: &[f64]) -> (f64, Vec<f64>) {
        let mark = Tape::len();
        let inputs: Vec<Rev> = x.iter().map(|&v| Rev::input(v)).collect();
        let y = f(&inputs);
        let mut adj = Vec::new();
        y.seed(&mut adj, 1.0);
        Tape::backpropagate(&mut adj, mark);
        let g = inputs.iter().map(|r| r.adjoint(&adj)).collect();
        Tape::rewind(mark);
        (y.value(), g)
    }

    /// A function of three variables through every operation of [`Scalar`].
    fn every_operation<S: Scalar>(x: &[S]) -> S {
        let (a, b, c) = (x[0], x[1], x[2]);
        let mut s = a * b - c / a + (a + 2.0) * (b - 0.5) / 3.0;
        s += a.sqrt() * b.sin() + c.cos() * a.tan() + (b * 0.5).asin() - (c * 0.3).acos();
        s -= a.atan() * b.atan2(c) + (a * 0.1).exp() * b.ln() + a.powi(3) - b.powf(c);
        s *= S::from_f64(1.5);
        s /= c.hypot(a) + 1.0;
        s += -c.abs() + a.powf(S::from_f64(2.5)) + (c * a).max(b).min(a);
        let sum: S = x.iter().copied().sum();
        s + sum * 0.25 - S::from_f64(1.0) / (a + 0.1)
    }

    /// `(x₀ x₁, x₀ + x₁²)` with its reverse written by hand.
    struct ProductAndSquare([f64; 2]);

    impl ExternalReverse for ProductAndSquare {
        fn reverse(&self, y_bar: &[f64], x_bar: &mut InputAdjoints<'_>) {
            let [a, b] = self.0;
            x_bar.add(0, y_bar[0] * b + y_bar[1]);
            x_bar.add(1, y_bar[0] * a + y_bar[1] * 2.0 * b);
        }
    }

    fn product_and_square<S: Scalar>(x: &[S]) -> [S; 2] {
        [x[0] * x[1], x[0] + x[1] * x[1]]
    }

    #[test]
    fn an_external_operation_is_reversed_as_its_nodes_would_be() {
        // f = sin(y₀) y₁ + x₂ y₀ with y the pair of x₀ + x₂ and 3 x₁, each way
        let f = |x: &[Rev], external: bool| {
            let args = [x[0] + x[2], x[1] * 3.0];
            let y = if external {
                let a = args.map(|a| a.value());
                let y = Rev::external(&args, &product_and_square(&a), ProductAndSquare(a));
                [y[0], y[1]]
            } else {
                product_and_square(&args)
            };
            y[0].sin() * y[1] + x[2] * y[0]
        };
        let x = [0.4, -1.1, 0.7];
        let (v0, g0) = reverse_gradient(|x| f(x, false), &x);
        let before = Tape::len();
        let (v1, g1) = reverse_gradient(|x| f(x, true), &x);
        assert_eq!(Tape::len(), before, "rewound");
        assert_eq!(v0, v1);
        for k in 0..3 {
            assert!(
                (g0[k] - g1[k]).abs() <= 1e-14 * g0[k].abs().max(1.0),
                "{g0:?} vs {g1:?}"
            );
        }
        // nothing of the operation is left after a rewind: a later sweep is the plain one
        assert!(EXTERNAL.with(|e| e.borrow().is_empty()));
        // constant inputs give constants and record nothing
        let y = Rev::external(&[Rev::constant(1.0)], &[2.0], ProductAndSquare([0.0; 2]));
        assert!(y[0].is_constant() && Tape::len() == before);
    }

    /// Swept twice with different seeds, clearing as it goes, an evaluation over data gives
    /// the data the adjoints two plain sweeps give (summed), and leaves zero above them: the
    /// second sweep reads no adjoint the first left (nodes, an external operation's outputs).
    #[test]
    fn a_clearing_sweep_leaves_zeros_above_and_the_same_adjoints_below() {
        let data: Vec<Rev> = [0.4, 0.2, 0.7].iter().map(|&v| Rev::input(v)).collect();
        let top = Tape::len();
        let x = Rev::input(0.3);
        let args = [data[0] * x + data[2], data[1] * 3.0];
        let a = args.map(|a| a.value());
        let y = Rev::external(&args, &product_and_square(&a), ProductAndSquare(a));
        let z = every_operation(&[y[0] + 0.5, y[1] * x + 0.3, data[2] + 0.5]);
        let outputs = [y[0] * z, y[1] - z];
        let seeds = [[1.0, -2.0], [0.5, 3.0]];
        let sweep = |adj: &mut Vec<f64>, seed: &[f64; 2], clear: bool| {
            for (o, &w) in outputs.iter().zip(seed) {
                o.seed(adj, w);
            }
            if clear {
                Tape::backpropagate_clearing(adj, top + 1);
                let x_bar = std::mem::take(&mut adj[top]);
                (adj.len(), x_bar)
            } else {
                Tape::backpropagate(adj, top);
                let x_bar = x.adjoint(adj);
                adj.truncate(top);
                (adj.len(), x_bar)
            }
        };
        let (mut plain, mut clearing) = (vec![0.0; top], vec![0.0; top]);
        for seed in &seeds {
            let (_, x0) = sweep(&mut plain, seed, false);
            let (len, x1) = sweep(&mut clearing, seed, true);
            assert!(len > top + 1, "the clearing sweep keeps the length");
            assert!(clearing[top..].iter().all(|&a| a == 0.0), "zero above");
            assert!((x0 - x1).abs() <= 1e-14 * x0.abs(), "{x0} vs {x1}");
        }
        for (a, b) in plain.iter().zip(&clearing) {
            assert!(
                (a - b).abs() <= 1e-14 * a.abs().max(1e-300),
                "{plain:?} vs {clearing:?}"
            );
        }
        assert!(data.iter().all(|d| d.adjoint(&plain) != 0.0));
        Tape::rewind(top - 3);
    }

    #[test]
    fn rows_dotted_as_one_operation_reverse_as_their_products_do() {
        // rows of lengths 3, 0, 2, 3 (an input repeated, a constant among the entries) dotted
        // with the first entries of x, then a nonlinear function of the results
        let lens = [3, 0, 2, 3];
        let f = |v: &[Rev], one_op: bool| {
            let (x, a) = v.split_at(3);
            let rows = [a[0], a[1], a[2], a[3], x[0], a[4], Rev::constant(0.7), a[0]];
            let y = if one_op {
                Rev::dot_rows(&rows, &lens, x)
            } else {
                let mut start = 0;
                (lens.iter())
                    .map(|&len| {
                        let row = &rows[start..start + len];
                        start += len;
                        row.iter()
                            .zip(x)
                            .fold(Rev::constant(0.0), |acc, (&r, &xp)| acc + r * xp)
                    })
                    .collect()
            };
            (y[0] * y[2]).sin() + y[3] * y[3] + y[1] * x[1]
        };
        let v = [0.3, -1.2, 0.8, 1.1, 0.4, -0.6, 2.0, 0.9];
        let (v0, g0) = reverse_gradient(|v| f(v, false), &v);
        let (v1, g1) = reverse_gradient(|v| f(v, true), &v);
        assert_eq!(v0, v1, "the same values");
        let plain = |v: &[f64]| {
            let rows = [v[3], v[4], v[5], v[6], v[0], v[7], 0.7, v[3]];
            let dot = |r: &[f64]| r.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
            let y = [dot(&rows[0..3]), 0.0, dot(&rows[3..5]), dot(&rows[5..8])];
            (y[0] * y[2]).sin() + y[3] * y[3]
        };
        for k in 0..v.len() {
            assert!((g0[k] - g1[k]).abs() <= 1e-14 * g0[k].abs().max(1.0), "{k}");
            let h = 1e-6;
            let (mut p, mut m) = (v, v);
            p[k] += h;
            m[k] -= h;
            let fd = (plain(&p) - plain(&m)) / (2.0 * h);
            assert!(
                (g1[k] - fd).abs() <= 1e-8 * fd.abs().max(1.0),
                "{k}: {} vs {fd}",
                g1[k]
            );
        }
        // one node per row, none for the products
        let mark = Tape::len();
        let x: Vec<Rev> = (0..3).map(|k| Rev::input(k as f64)).collect();
        let inputs = Tape::len();
        let y = Rev::dot_rows(&[x[0], x[1], x[2], x[0]], &[3, 1], &x);
        assert_eq!(
            (Tape::len() - inputs, y[0].value(), y[1].value()),
            (2, 5.0, 0.0)
        );
        Tape::rewind(mark);
    }

    #[test]
    fn the_gradient_of_every_operation_equals_forward_mode() {
        for x in [[0.7, 1.3, 0.4], [1.9, 0.6, -1.2], [0.2, 1.7, 2.5]] {
            let (value, g) = reverse_gradient(every_operation::<Rev>, &x);
            let duals: Vec<Dual<3>> = (0..3).map(|k| Dual::variable(x[k], k)).collect();
            let d = every_operation(&duals);
            assert_eq!(value, d.v);
            for k in 0..3 {
                let err = (g[k] - d.d[k]).abs();
                assert!(
                    err <= 1e-13 * d.d[k].abs().max(1.0),
                    "{k}: {} vs {}",
                    g[k],
                    d.d[k]
                );
            }
            // and against central differences, independently of the dual type
            for k in 0..3 {
                let h = 1e-6;
                let (mut xp, mut xm) = (x, x);
                xp[k] += h;
                xm[k] -= h;
                let fd = (every_operation::<f64>(&xp) - every_operation::<f64>(&xm)) / (2.0 * h);
                assert!(
                    (g[k] - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                    "{k}: {} vs {fd}",
                    g[k]
                );
            }
        }
        assert!(Tape::is_empty());
    }

    #[test]
    fn constants_record_nothing_and_a_sweep_stops_at_its_mark() {
        let mark = Tape::len();
        let c = Rev::constant(2.0) * 3.0 + Rev::from_f64(1.0).sin();
        assert!(c.is_constant());
        assert_eq!(Tape::len(), mark);
        // the bottom part: an input and a quantity computed from it once
        let x = Rev::input(1.5);
        let x2 = x * x;
        let bottom = Tape::len();
        let mut adj = Vec::new();
        // two evaluations above it, each swept down to the bottom and rewound
        for w in [1.0, 2.0] {
            let y = x2 * w + x;
            y.seed(&mut adj, 1.0);
            Tape::backpropagate(&mut adj, bottom);
            adj.truncate(bottom);
            Tape::rewind(bottom);
        }
        // the bottom's adjoints add up: d/dx of (x² + x) + (2x² + x) = 6x + 2
        assert_eq!(
            x.adjoint(&adj),
            2.0,
            "only the direct uses reached the input yet"
        );
        Tape::backpropagate(&mut adj, mark);
        assert_eq!(x.adjoint(&adj), 6.0 * 1.5 + 2.0);
        Tape::rewind(mark);
    }

    #[test]
    fn dot_and_sub_scaled_are_one_node_reversed_as_their_products_are() {
        let x = [1.5, -0.7, 2.0, 0.3, 0.9];
        let c = Rev::constant(4.0);
        let written = |v: &[Rev]| v[1] * v[2] + c * v[3] + v[2] * v[4] + v[3] * c;
        let (value, gradient) = reverse_gradient(written, &x);
        let mark = Tape::len();
        let v: Vec<Rev> = x.iter().map(|&x| Rev::input(x)).collect();
        let wide_mark = WIDE_ARGS.with(|w| w.borrow().len());
        let nodes = Tape::len();
        let y = Rev::dot(&[v[1], c, v[2], v[3]], &[v[2], v[3], v[4], c]);
        let z = Rev::sub_scaled(v[0], &[v[1], v[2], v[3]], &[0.5, -2.0, 3.0]);
        assert_eq!(Tape::len(), nodes + 2, "one node each");
        assert_eq!(y.value, value, "summed as written out");
        assert_eq!(z.value, 1.5 - -0.7 * 0.5 - 2.0 * -2.0 - 0.3 * 3.0);
        let mut adj = Vec::new();
        y.seed(&mut adj, 1.0);
        z.seed(&mut adj, 10.0);
        Tape::backpropagate(&mut adj, mark);
        let expected = [
            10.0,
            gradient[1] - 5.0,
            gradient[2] + 20.0,
            gradient[3] - 30.0,
        ];
        for (xi, g) in v.iter().zip(expected.iter().chain(&gradient[4..])) {
            assert!((xi.adjoint(&adj) - g).abs() <= 1e-14 * g.abs().max(1.0));
        }
        // two arguments at most make a node of the usual kind; constants record nothing
        let narrow = Rev::dot(&[v[1], c], &[c, c]);
        assert_eq!(narrow.value, -0.7 * 4.0 + 16.0);
        assert_eq!(Tape::len(), nodes + 3);
        assert!(Rev::dot(&[c], &[c]).is_constant() && Rev::dot(&[], &[]).value == 0.0);
        // a rewind drops the wide nodes' arguments with them
        Tape::rewind(mark);
        assert_eq!(WIDE_ARGS.with(|w| w.borrow().len()), wide_mark);
        // the other types compute the same operations in the same order
        assert_eq!(
            f64::dot(&[-0.7, 4.0, 2.0, 0.3], &[2.0, 0.3, 0.9, 4.0]),
            value
        );
        let plain = f64::sub_scaled(1.5, &[-0.7, 2.0, 0.3], &[0.5, -2.0, 3.0]);
        assert_eq!(plain, z.value);
    }

    #[test]
    fn identities_and_zero_partials_record_nothing_and_keep_the_gradient() {
        let mark = Tape::len();
        let x = Rev::input(1.5);
        let after_input = Tape::len();
        let same = [x + 0.0, x - 0.0, x * 1.0, x / 1.0, Rev::from_f64(0.0) + x];
        assert_eq!(Tape::len(), after_input, "no node for an identity");
        assert!(same.iter().all(|y| y.node() == x.node() && y.value == 1.5));
        let zero = x * 0.0;
        assert!(zero.is_constant() && zero.value == 0.0);
        // −0 + 0 is +0: the value is the operation's, the node the argument's
        let nz = Rev::input(-0.0);
        assert!((nz + 0.0).value.is_sign_positive() && (nz + 0.0).node() != nz.node());
        // d/dx of (x + 0)·1·x + 0·x + x·2 = 2x + 2
        let y = (x + 0.0) * 1.0 * x + x * 0.0 + x * 2.0;
        let mut adj = Vec::new();
        y.seed(&mut adj, 1.0);
        Tape::backpropagate(&mut adj, mark);
        assert_eq!(x.adjoint(&adj), 2.0 * 1.5 + 2.0);
        Tape::rewind(mark);
    }

    #[test]
    fn a_singular_point_gives_the_zero_tangent_result_of_dual() {
        let mark = Tape::len();
        let x = Rev::input(0.0);
        let r = (x * x).sqrt();
        let mut adj = Vec::new();
        r.seed(&mut adj, 1.0);
        Tape::backpropagate(&mut adj, mark);
        assert_eq!(x.adjoint(&adj), 0.0);
        Tape::rewind(mark);
    }

    #[test]
    #[should_panic(expected = "precomputed tangents")]
    fn building_from_parts_is_refused() {
        let _ = Rev::from_parts(1.0, &[]);
    }
}
