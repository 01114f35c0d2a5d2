//! # deepcontact-experiments
//!
//! The experiment library behind the `deepcontact` command: everything `compare`,
//! `simulate`, `generate`, `grid-roundtrip` and `soak` do, callable from your own code with
//! your own providers.
//!
//! * [`compare`] — the thesis's warm-start comparison: a parallel runner whose results do not
//!   depend on the thread count, summary statistics, `steps.csv` / `curves.csv` /
//!   `summary.{csv,md,json}` and the figures;
//! * [`simulate`] — one scene with one provider, a report per step;
//! * [`soak`] — long runs checked every step;
//! * [`roundtrip`] — the thesis's Table 1 (particles → grid → particles);
//! * `generate` (feature `onnx`) — training data, one safetensors file per seed;
//! * [`seeds`] — the one seed-list grammar; [`atomic`] — files written all or nothing;
//! * [`plots`], [`render`] — figures and world pictures with plotters;
//! * [`full_registry`] — every provider and solver of this build, to add your own to.
//!
//! Your provider in the full comparison, tables and figures included:
//!
//! ```no_run
//! use deepcontact_core::{Impulse, ProviderInfo, WarmStart, WarmStartContext, WarmStartError};
//! use deepcontact_experiments::{compare, full_registry};
//!
//! struct Half;
//! impl WarmStart for Half {
//!     fn name(&self) -> &str { "half" }
//!     fn warm_start(&mut self, ctx: &WarmStartContext<'_>, out: &mut [Impulse]) -> Result<(), WarmStartError> {
//!         for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) { *o = Impulse::new(0.5 * c.normal, 0.5 * c.tangent); }
//!         Ok(())
//!     }
//! }
//!
//! let mut registry = full_registry();
//! registry.register_provider("half", ProviderInfo::new("half the carried impulse"), |_, _| Ok(Box::new(Half)));
//! let config = compare::Config::with_warm_starts("none,builtin,half").unwrap();
//! let results = compare::run_experiment_with(&config, &registry).unwrap();
//! compare::write_outputs(&results, "results".as_ref(), true).unwrap();
//! ```
//!
//! Use it to measure your own provider or scene with the same runner, statistics and figures as the
//! `deepcontact` command (`default-features = false` leaves out the CNNs and tract).
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md), [embed
//! the solver in your
//! engine](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/embed.md), [reproduce
//! the thesis and run the
//! suite](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/reproduce.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

pub mod atomic;
pub mod compare;
mod error;
#[cfg(feature = "onnx")]
pub mod generate;
pub mod limits;
pub mod plots;
pub mod preset;
pub mod record;
mod registry;
pub mod render;
pub mod roundtrip;
pub mod seeds;
pub mod simulate;
pub mod soak;
pub mod suite;

pub use error::ExperimentError;
pub use registry::{full_registry, scene_for};

/// Serialises `rows` as CSV (a header line from the field names, then one line per row) with
/// the `csv` crate; `None` fields are empty.
pub fn csv_bytes<T: serde::Serialize>(
    rows: impl IntoIterator<Item = T>,
) -> Result<Vec<u8>, ExperimentError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for row in rows {
        w.serialize(row)
            .map_err(|e| ExperimentError::Invalid(format!("csv: {e}")))?;
    }
    w.into_inner()
        .map_err(|e| ExperimentError::Invalid(format!("csv: {e}")))
}

/// `requested` worker threads, or one per core for 0.
pub fn threads(requested: usize) -> usize {
    if requested == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        requested
    }
}

/// A rayon pool of `threads` workers (an error, not a panic, when the OS refuses them).
pub fn pool(threads: usize) -> Result<rayon::ThreadPool, ExperimentError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| ExperimentError::Invalid(format!("cannot start {threads} threads: {e}")))
}
