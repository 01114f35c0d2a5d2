//! # deepcontact-lcp
//!
//! Contact solvers that assemble the island's frictional problem explicitly, with
//! [faer](https://docs.rs/faer) for the linear algebra:
//!
//! * [`Delassus`] — `W = J M⁻¹ Jᵀ` and `q = J v_free − bias` (relative velocity `Wλ + q`),
//!   dense for small islands and sparse (compressed columns) for large ones
//!   ([`AssemblyMode`], [`DEFAULT_DENSE_THRESHOLD`]); buffers are reused between solves.
//! * [`PsorSolver`] (`"psor"`) — projected Gauss-Seidel / SOR with relaxation ω on `W`.
//!   With ω = 1 it visits the rows in deepcontact-pgs's order and reaches the same
//!   impulses as `PgsSolver` with its block solver off: a cross-check of both.
//! * [`NewtonSolver`] (`"newton"`) — semismooth Newton on the natural map
//!   `λ − proj(λ − m (Wλ + q))` with the friction bounds `±μλn` coupled into the
//!   generalised Jacobian, a sparse LU on 2×2 point blocks (static pivots, fill-reducing
//!   order and update lists worked out once per solve) with a growing regularisation for
//!   redundant contacts, and a projected Armijo line search that falls back to one PGS
//!   sweep; it starts from the warm start like every solver here.
//! * [`PgsRescueSolver`] (`"pgs-rescue"`) — deepcontact-pgs's PGS on every island, and
//!   semismooth Newton (from PGS's impulses or from zeros) on the islands PGS leaves at its
//!   cap with a natural residual above 5 × the stop tolerance — on the piles, mostly the
//!   ~1 % of problems on which PGS cycles from every start; Newton's result is kept only
//!   when its natural residual is lower. Islands PGS settles keep its bits.
//! * [`solve_exact`] — enumeration of contact states for a few points, the oracle of the
//!   tests, and [`violation`], a checker of the complementarity conditions.
//! * [`NewtonWork`], [`PsorWork`] — what a Newton or PSOR solve weighs in PGS passes, counted
//!   from the island's structure, for pass budgets
//!   ([`deepcontact_core::VelocitySolver::pass_cost`]).
//!
//! `psor` and `newton` implement [`deepcontact_core::VelocitySolver`] and report per iteration
//! `max |Δλ|` and `sqrt(Σ Δλ²)`, the natural-map residual (in impulse units, as PGS), the
//! iteration count and the wall time, so the stop rule of
//! [`deepcontact_core::SolverSettings`] and every figure work unchanged. Errors are
//! [`LcpError`], converted to [`deepcontact_core::CoreError`] at the trait boundary.
//!
//! For comparisons and oracles: the assembled solvers converge where PGS stalls, at a higher cost
//! per iteration.
//!
//! Guides, with code that CI compiles and runs: [embed the solver in your
//! engine](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/embed.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

mod assembly;
mod block_lu;
mod error;
mod exact;
mod newton;
mod point_graph;
mod psor;
mod registry;
mod rescue;
mod weight;

pub use assembly::{AssemblyMode, DEFAULT_DENSE_THRESHOLD, Delassus, MAX_DENSE_ROWS};
pub use error::LcpError;
pub use exact::{
    ContactState, EXACT_MAX_POINTS, EXACT_REGULARIZATION, ExactSolution, Violation, solve_exact,
    violation,
};
pub use newton::{NewtonSettings, NewtonSolver, NewtonStats, RETRY_REGULARIZATION};
pub use psor::{PsorSettings, PsorSolver};
pub use registry::register;
pub use rescue::{
    PgsRescueSolver, RescueSettings, RescueStart, RescueStats, RescueTrigger, stalled,
};
pub use weight::{NewtonWork, PsorWork};
