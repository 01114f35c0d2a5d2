//! # deepcontact-rapier2d
//!
//! Any deepcontact [`WarmStart`](deepcontact_core::WarmStart) provider driving rapier2d's
//! contact warm starts, through rapier's `PhysicsHooks::modify_solver_contacts`.
//!
//! * [`WarmStartHooks`]: the hooks (one deepcontact problem per rapier manifold, the
//!   provider's start written into the solver contacts, the solved impulses read back for
//!   `observe`, rapier's carried impulses as the provider's `carried`);
//! * [`units`]: rapier's per-substep impulses ↔ deepcontact's per-step ones, and the signs;
//! * [`RapierWorld`]: a rapier world built from a deepcontact scene, stepped natively or
//!   through the hooks, with deepcontact's step measures.
//!
//! **Version pin.** rapier2d 0.31–0.34 only: 0.35 removed `SolverContact::warmstart_impulse`
//! and `warmstart_tangent_impulse`, so a hook can no longer set a warm start. Only the first
//! substep's start is the provider's: the later substeps of a step start from their
//! predecessor, as in native rapier.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod error;
pub mod hooks;
pub mod units;
pub mod world;

pub use error::AdapterError;
pub use hooks::{HookSettings, OnFailure, PointKey, StepStats, WarmStartHooks};
pub use world::{RapierWorld, StepMeasures};
