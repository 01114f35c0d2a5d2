//! # deepcontact-onnx
//!
//! CNN warm-start providers: each step, the world is spread onto grids (particles → grid),
//! an ONNX model predicts impulse grids, and those are read back at the contact points
//! (grid → particles). Shipped models: [`PRESSURE`], [`PEAK`] and the residual
//! [`PRESSURE_RESIDUAL`] (in `models/`, with model
//! cards); any other model with a card loads through `onnx:path=...`.
//!
//! Backends (see [`backend`]): tract (pure Rust, default) or ONNX Runtime (`load-dynamic`).
//!
//! ```no_run
//! let mut registry = deepcontact_core::Registry::empty();
//! deepcontact_pgs::register(&mut registry);
//! deepcontact_warmstart::register(&mut registry);
//! deepcontact_onnx::register(&mut registry);
//! let provider = registry.build_provider("pressure").unwrap();
//! assert_eq!(provider.name(), "pressure");
//! ```
//!
//! Needs an ONNX backend (tract by default, pure Rust; ONNX Runtime with `load-dynamic`) and the
//! world view, so it runs in deepcontact worlds only.
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md),
//! [reproduce the thesis and run the
//! suite](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/reproduce.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

#[cfg(not(any(feature = "tract", feature = "load-dynamic")))]
compile_error!(
    "deepcontact-onnx needs a backend: enable the `tract` (default) or the `load-dynamic` feature"
);

pub mod backend;
pub mod card;
mod error;
pub mod features;
pub mod model;
pub mod provider;
mod registry;

pub use backend::Backend;
pub use card::{LayoutExpectation, ModelCard, TensorCard, sha256_hex};
pub use error::OnnxError;
pub use features::{GridFeatures, GridLayout};
pub use model::{ModelSource, OnnxModel};
pub use provider::{
    CnnWarmStart, PEAK, PRESSURE, PRESSURE_RESIDUAL, ProviderOptions, ShippedModel,
};
pub use registry::register;
