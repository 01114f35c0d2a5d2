//! # deepcontact-warmstart
//!
//! Baseline warm-start providers and the [`Registry`] that builds providers and solvers
//! from text specs such as `random:seed=3` or `copy:decimals=2`. Third-party crates add
//! their own providers with [`Registry::register_provider`].
//!
//! | name | provider | what it writes |
//! |------|----------|----------------|
//! | `none` | [`Zeros`] | zeros (a cold start) |
//! | `builtin` | [`Builtin`] | last step's impulses, matched by contact id |
//! | `random` | [`RandomWarmStart`] | normal U(0, 5), tangent U(−2, 2), seeded |
//! | `bad` | [`ConstantWarmStart`] | (50, 50) everywhere |
//! | `copy` | [`OracleWarmStart`] | this step's problem solved first, to 1e-6 |
//! | `copy2`, `copy0` | [`Rounded`]`<`[`OracleWarmStart`]`>` | `copy` rounded to 2 / 0 decimals |
//!
//! [`Rounded`] wraps any provider, so "how much precision does a prediction need" can be
//! asked of every provider, not just the oracle.
#![warn(missing_docs)]

mod constant;
mod error;
mod oracle;
mod random;
pub mod registry;
mod rounded;
pub mod spec;

pub use constant::ConstantWarmStart;
pub use deepcontact_core::{CarriedWarmStart as Builtin, ZeroWarmStart as Zeros};
pub use error::WarmstartError;
pub use oracle::{OracleConfig, OracleWarmStart};
pub use random::{RandomConfig, RandomWarmStart};
pub use registry::{ProviderFactory, Registry, SolverFactory};
pub use rounded::Rounded;
pub use spec::{Params, Spec, split_spec_list};
