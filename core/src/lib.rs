//! # deepcontact-core
//!
//! The foundation of deepcontact: rigid bodies and shapes (through parry2d), a
//! Box2D-style world that steps them, contact ids with impulse persistence,
//! islands, the solver-facing [`ContactProblem`], and the two plug-in traits
//! the project is built around:
//!
//! * [`WarmStart`] — supplies the first iterate of the velocity solver;
//! * [`VelocitySolver`] (and [`PositionSolver`]) — solve a contact problem.
//!
//! One step of a [`World`] runs the [`Stage`]s in the order of [`Stage::ORDER`].
//!
//! All public math uses [`nalgebra`] with [`Real`] = `f64`; parry2d's glam
//! types are confined to the [`math`] module.
//!
//! Use it directly to write a provider (implement [`WarmStart`]), to solve contact problems your
//! engine builds ([`ContactProblem`]), or to build and step a [`World`] in code.
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md), [embed
//! the solver in your
//! engine](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/embed.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

pub mod body;
pub mod broad_phase;
pub mod contact;
pub mod error;
pub mod island;
pub mod math;
pub mod narrow_phase;
pub mod problem;
pub mod registry;
pub mod report;
pub mod rng;
pub mod scene;
pub mod scene_file;
pub mod shape;
mod shared_collide;
pub mod solver;
pub mod threads;
pub mod warm_start;
pub mod world;

pub use body::{Body, BodyDesc, BodyHandle, BodyKind, Material};
pub use contact::{ContactId, Impulse};
pub use error::CoreError;
pub use math::{Pose, Real, Vector, Velocity};
pub use problem::{ContactPoint, ContactProblem, PointDesc, ProblemBody};
pub use registry::{ProviderInfo, Registry, Spec, SpecError};
pub use report::{SolveReport, StepReport};
pub use shape::ShapeDesc;
pub use solver::{
    CircleContact, IslandSolve, PassCost, PositionReport, PositionSettings, PositionSolver,
    ResidualNorm, SolverSettings, VelocitySolver,
};
pub use warm_start::{
    CarriedWarmStart, GuardPolicy, Observation, WarmStart, WarmStartContext, WarmStartError,
    ZeroWarmStart, check_output, project_start,
};
pub use world::{MAX_BUDGET, Stage, World, WorldSettings};
