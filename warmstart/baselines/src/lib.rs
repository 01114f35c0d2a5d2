//! # deepcontact-warmstart
//!
//! Baseline warm-start providers and the [`Registry`] that builds providers and solvers
//! from text specs such as `random:seed=3` or `copy:decimals=2`. Third-party crates add
//! their own providers with [`Registry::register_provider`].
#![warn(missing_docs)]

mod error;
pub mod registry;
pub mod spec;

pub use deepcontact_core::{CarriedWarmStart as Builtin, ZeroWarmStart as Zeros};
pub use error::WarmstartError;
pub use registry::{ProviderFactory, Registry, SolverFactory};
pub use spec::{Params, Spec, split_spec_list};
