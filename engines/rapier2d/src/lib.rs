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
//!
//! ```
//! use deepcontact_rapier2d::{RapierWorld, WarmStartHooks};
//! use rapier2d::prelude::*;
//!
//! let registry = deepcontact_experiments::full_registry(); // without tract: no CNNs
//! let hooks = WarmStartHooks::new(registry.build_provider("sor")?);
//! // Your own world: every collider asks for the hook.
//! let mut world = RapierWorld::new();
//! let ground = world.bodies.insert(RigidBodyBuilder::fixed());
//! let collider = ColliderBuilder::cuboid(5.0, 0.5).active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
//! world.colliders.insert_with_parent(collider, ground, &mut world.bodies);
//! // ... or a deepcontact scene:
//! let mut world = RapierWorld::from_scene(&registry.build_scene("pyramid:base=4", 0)?)?;
//! for _ in 0..60 {
//!     // begin_step, PhysicsPipeline::step with the hooks, finish_step (observe, counts):
//!     let stats = world.step(&hooks)?;
//!     assert_eq!(stats.fallbacks, 0);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod error;
pub mod hooks;
pub mod island;
pub mod units;
pub mod world;

pub use error::AdapterError;
pub use hooks::{Grouping, HookSettings, OnFailure, PointKey, StepStats, WarmStartHooks};
pub use world::{RapierWorld, StepMeasures};

/// `docs/guide/rapier2d.md`: its Rust code compiles and runs as this crate's doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../docs/guide/rapier2d.md")]
pub struct GuideRapier2d;
