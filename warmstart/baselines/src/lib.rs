//! # deepcontact-warmstart
//!
//! Baseline warm-start providers, registered by [`register`] in a
//! [`deepcontact_core::Registry`] that builds them from text specs such as `random:seed=3`
//! or `copy:decimals=2`.
//!
//! | name | provider | what it writes |
//! |------|----------|----------------|
//! | `none` | [`ZeroWarmStart`](deepcontact_core::ZeroWarmStart) | zeros (a cold start) |
//! | `builtin` | [`CarriedWarmStart`](deepcontact_core::CarriedWarmStart) | last step's impulses, matched by contact id |
//! | `random` | [`RandomWarmStart`] | normal U(0, 5), tangent U(−2, 2), seeded |
//! | `bad` | [`ConstantWarmStart`] | (50, 50) everywhere |
//! | `copy` | [`OracleWarmStart`] | this step's problem solved first, to 1e-6 |
//! | `tail` | [`TailWarmStart`] | carried impulses plus the extrapolated rest of last step's solve |
//! | `extrapolate` | [`ExtrapolatedWarmStart`] | λ_t + α (λ_t − λ_{t−1}) by contact id |
//! | `krylov` | [`KrylovWarmStart`] | carried impulses plus a few conjugate-gradient steps on their active set |
//! | `shock` | [`ShockWarmStart`] | normal loads propagated top-down, blended with the carried impulses |
//! | `best` | [`BestOfWarmStart`] | the candidate start with the smallest one-sweep residual |
//! | `sor` | [`RelaxedWarmStart`] | carried impulses refined by over-relaxed Gauss-Seidel sweeps |
//! | `presolve` | [`PresolveWarmStart`] | carried impulses refined by a few iterations of another solver (`newton`) |
//! | `copy2`, `copy0` | [`Rounded`]`<`[`OracleWarmStart`]`>` | `copy` rounded to 2 / 0 decimals |
//!
//! [`Rounded`] wraps any provider, so "how much precision does a prediction need" can be
//! asked of every provider, not just the oracle.
//!
//! The providers every comparison measures against; their sources are short examples of the
//! [`deepcontact_core::WarmStart`] trait.
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

mod anderson;
mod best;
mod by_contact;
mod coarse;
mod constant;
mod extrapolate;
mod inner;
mod krylov;
mod oracle;
mod presolve;
mod random;
mod registry;
mod relaxed;
mod rounded;
mod rows;
mod schedule;
mod shock;
mod spd;
mod tail;

pub use anderson::{AndersonConfig, AndersonWarmStart};
pub use best::BestOfWarmStart;
pub use coarse::{CoarseConfig, CoarseWarmStart};
pub use constant::ConstantWarmStart;
pub use extrapolate::ExtrapolatedWarmStart;
pub use krylov::{KrylovConfig, KrylovWarmStart};
pub use oracle::{OracleConfig, OracleOrder, OracleWarmStart};
pub use presolve::{PresolveConfig, PresolveWarmStart};
pub use random::{RandomConfig, RandomWarmStart};
pub use registry::register;
pub use relaxed::{MIX_MIN_PASSES, Relaxation, RelaxedConfig, RelaxedWarmStart};
pub use rounded::Rounded;
pub use schedule::{BudgetSchedules, Schedule};
pub use shock::ShockWarmStart;
pub use tail::{TailConfig, TailWarmStart};
