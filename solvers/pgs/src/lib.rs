//! # deepcontact-pgs
//!
//! Box2D v2.4-style sequential impulses: a projected Gauss-Seidel velocity solver
//! ([`PgsSolver`]) with friction-then-normal row order, clamped accumulated impulses,
//! restitution bias and an optional 2-point block solver; and the non-linear
//! Gauss-Seidel position pass ([`PgsPositionSolver`]).
//!
//! Solver stages, in order: **prepare** (copy the problem into solver-friendly rows,
//! buffers reused) → **warm start** (apply the start impulses) → **solve** (iterate until
//! the stop rule holds) → **store impulses** (write them back, natural-map residual).
//! [`PgsSolver::solve_again`] runs the last three on the prepared rows of the island solved
//! last, from another start or with its rows' effective masses scaled (a provider's repeated
//! sweeps of one island), to the bits of a fresh solve; [`PgsSolver::solve_stages`] solves an
//! island in stages with the rows' effective masses scaled by each stage's factors (an
//! over-relaxation schedule), to the bits of one solve per stage on scaled copies.
//!
//! **Threads.** An island of [`PgsSettings::parallel_min_points`] points or more (default
//! 2048) is swept in the domain plan ([`PgsSettings::domains`], default 16;
//! [`PgsSettings::threads`], `pgs:threads=N`): its movable bodies cut into bands of a
//! breadth-first walk of their contacts, each band's manifolds swept as an island of its own,
//! the even bands side by side on threads, then the odd ones (a band's manifolds move bodies of
//! that band and of its neighbours only). With `domains = 0` it is swept colour by colour in
//! fixed chunks instead. The position pass sweeps such islands in the same kind of domains
//! ([`PgsPositionSettings::domains`], [`PgsPositionSettings::threads`]). Every part's measures
//! are folded in a fixed order, so the result is bit-identical for any thread count. The
//! position pass of a smaller island of 256 points or more is shared in problem order
//! (`position::ordered`): each thread corrects the points of a slab of bodies, and a body two
//! threads move waits for the corrections that come before in that order, so the result is
//! the one-thread loop's bits. Other islands run on the calling thread; given all of a step's
//! islands at once
//! ([`VelocitySolver::solve_many`](deepcontact_core::VelocitySolver::solve_many), as the world
//! does), islands of up to 32 points are packed into the lanes of shared batches, up to eight
//! islands a sweep, each with its own stop rule and to the bits of its own solve.
//!
//! **Instruction set.** The velocity sweep loop is compiled twice, for the x86-64 baseline and
//! for AVX2 + FMA, and the solver picks one at run time (`pulp::Arch`, detected when the solver
//! is made). With AVX2 a [`LANES`]-wide batch field is one 256-bit register and the batches
//! run through a kernel written in its intrinsics, two batches of a colour side by side (their
//! dependent chains overlap); elsewhere the portable loop runs, one batch at a time. The
//! arithmetic is the same operations in the same order, so the results are bit-identical
//! either way.
//!
//! **Precision.** The sweep runs in `f64` by default; [`Precision::F32`]
//! ([`PgsSettings::precision`], `pgs:precision=f32`) runs its iterations in `f32`, eight
//! single-point manifolds to an AVX2 register, on the calling thread.
//!
//! The solver most users want: pass [`PgsSolver`] and [`PgsPositionSolver`] to `World::step`, or
//! solve a hand-built `ContactProblem` with [`PgsSolver`] alone.
//!
//! Guides, with code that CI compiles and runs: [embed the solver in your
//! engine](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/embed.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

mod position;
mod registry;
mod threads;
mod velocity;

pub use position::{PgsPositionSettings, PgsPositionSolver};
pub use registry::{MAX_THREADS, register};
pub use threads::partition::{DOMAIN_POINTS, MAX_DOMAINS};
pub use velocity::{LANES, Ordering, OverRelaxation, PgsSettings, PgsSolver, Precision, Stage};

/// Errors of this crate (wrapped into [`deepcontact_core::CoreError`] at the trait boundary).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PgsError {
    /// The problem failed validation.
    #[error("invalid problem: {0}")]
    InvalidProblem(#[from] deepcontact_core::CoreError),
    /// The iteration produced a non-finite impulse (the input was too extreme).
    #[error("non-finite impulse at point {point} in iteration {iteration}")]
    Diverged {
        /// Point index.
        point: usize,
        /// Iteration (1-based).
        iteration: u32,
    },
    /// [`PgsSolver::solve_again`] was asked for an island other than the one its plan was
    /// built for (or before any solve).
    #[error("solve_again: the solver's plan is not of this island; solve it first")]
    NotPlanned,
    /// An over-relaxation schedule that is not one ([`OverRelaxation::new`]).
    #[error("over-relaxation schedule: {0}")]
    OverRelaxation(String),
    /// A stage of [`PgsSolver::solve_stages`] whose mass factors are not one finite, positive
    /// factor per contact point.
    #[error("stage {stage}: {reason}")]
    StageScale {
        /// The stage (0-based).
        stage: usize,
        /// What is wrong with its factors.
        reason: String,
    },
}

impl From<PgsError> for deepcontact_core::CoreError {
    fn from(e: PgsError) -> Self {
        match e {
            PgsError::InvalidProblem(e) => e,
            other => deepcontact_core::CoreError::Solver {
                solver: "pgs".into(),
                reason: other.to_string(),
            },
        }
    }
}
