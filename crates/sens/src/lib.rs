//! `sens` — the bottom layer of flexsens: exact first-order derivatives (and the mixed
//! second-order ones the eigenvalues of a linearisation need).
//!
//! It owns
//! - the [`Scalar`] trait, the one numeric generic of the project, implemented for `f64`
//!   (plain analysis) and for [`Dual<N>`] (a value plus `N` tangent components, hand-written
//!   forward-mode automatic differentiation), and for [`HyperDual`] (two tangents and their
//!   mixed second-order part: the design derivative of a directional derivative), and for
//!   [`Rev`] (a value on a thread-local [`Tape`]: reverse mode, the gradient of one scalar with
//!   respect to every input in one sweep; a function with its reverse written by hand recorded
//!   as one operation, [`ExternalReverse`], such as the rows of a table dotted with a vector,
//!   [`Rev::dot_rows`]);
//! - seeding of design variables and the evaluation of a function of many design variables in
//!   chunks of a compile-time width `N` ([`seed`], [`jacobian`]);
//! - pushing tangents through a linear solve whose matrix was factorised once in `f64`
//!   ([`solve`]): docs/design.md §1, the pattern of the paper's Eq. (40);
//! - [`DenseLu`], the small dense LU those solves use in the multibody step, and
//!   [`SparseCholesky`], the sparse factorisation of finite-element matrices, ordered on their
//!   node graph ([`sparse`]).
//!
//! It knows nothing about laminates, finite elements, multibody systems or decks.

mod dual;
mod hyper;
mod lu;
mod rev;
mod scalar;
pub mod seed;
pub mod solve;
pub mod sparse;

pub use dual::Dual;
pub use hyper::HyperDual;
pub use lu::DenseLu;
pub use rev::{ExternalReverse, InputAdjoints, Rev, Tape};
pub use scalar::Scalar;
pub use seed::{Jacobian, chunk_ranges, gradient, jacobian, seed_chunk};
pub use solve::{LinearSolver, solve_tangents};
pub use sparse::{NotPositiveDefinite, SparseCholesky};
