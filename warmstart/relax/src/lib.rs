//! # deepcontact-relax
//!
//! A learned warm start built on `sor` (deepcontact-warmstart's over-relaxed sweeps from the
//! carried impulses): instead of one factor ω for every contact, a small policy picks each
//! contact's ω_i from six features of the point and its island ([`FEATURES`]: how vertical
//! the contact is, how much load it carried, whether it is new, whether it touches a wall,
//! how large its island is). The policy is a logistic map with six weights
//! ([`RelaxationPolicy`]), fitted on the simulator itself: an evolution strategy over the
//! weights that minimises the sweeps a step needs, the provider's and the world's PGS's
//! together, on training seeds 0–99, selected on 100–109 (`models/train/relax.py`). Its own
//! cost is six multiply-adds and one exponential per point.
//!
//! Under a fixed budget of passes the per-point factors give way to a learned schedule: one
//! factor for each equal share of the provider's sweeps, fitted per budget
//! ([`shipped_schedules`], `models/train/schedule.py`); islands that relaxation hardly reaches
//! (towers of boxes, whose points lie in two-point manifolds solved as blocks) get
//! Anderson-mixed single sweeps instead ([`LEARNED_MIX_BELOW`]).
//!
//! The same schedules can run inside the world's solve instead of before it: the solver
//! `learned-pgs` ([`ScheduledPgs`]) sweeps a budget's first passes by its schedule, with no
//! second solve of the island to pay for.
//!
//! [`register`] adds `learned-sor` (the shipped policy, `models/learned-sor.json`, and the
//! shipped schedules, `models/learned-schedule.json`, built in; `path=` and `schedules=` read
//! others).
//!
//! ```
//! let mut registry = deepcontact_core::Registry::empty();
//! deepcontact_relax::register(&mut registry);
//! let provider = registry.build_provider("learned-sor").unwrap();
//! assert_eq!(provider.name(), "learned-sor");
//! ```
//!
//! A provider to compare against or to refit (`models/train/relax.py`).
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md),
//! [reproduce the thesis and run the
//! suite](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/reproduce.md).
#![warn(missing_docs)]

mod error;
mod policy;
mod registry;
mod schedule;
mod solver;

pub use error::RelaxError;
pub use policy::{FEATURES, FORMAT, PolicyFile, RelaxationPolicy};
pub use registry::{LEARNED_BUDGET_OMEGA, LEARNED_MIX_BELOW, LEARNED_PAIRS, learned_sor, register};
pub use schedule::{
    SCHEDULE_FORMAT, ScheduleFile, schedules_from_file, schedules_from_json, shipped_schedules,
};
pub use solver::ScheduledPgs;
