//! # deepcontact-graph
//!
//! A learned warm start that builds on what builtin knows: a small message-passing network
//! over the contact graph reads, per point, the carried impulse and the point's geometry and
//! velocities, and predicts the *correction* to the carried impulse (residual learning). It
//! runs as a plain Rust forward pass (no ONNX runtime): one pass per island, buffers reused.
//!
//! - [`model`]: the architecture ([`FEATURES`], message passing over contact–body edges)
//!   and the forward pass, mirroring `ContactGraph` in `models/train/graph.py`.
//! - [`card`]: model cards (SHA-256, architecture, training seeds and loss).
//! - [`GraphWarmStart`]: the provider ([`point_inputs`]: its per-point model inputs);
//!   [`register`] adds `graph` (the shipped model, `models/graph.safetensors`, built into the
//!   crate) and `graph:path=...` to a registry.
//!
//! ```
//! let mut registry = deepcontact_core::Registry::empty();
//! deepcontact_graph::register(&mut registry);
//! let provider = registry.build_provider("graph").unwrap();
//! assert_eq!(provider.name(), "graph");
//! ```
//!
//! A provider to compare against or to retrain (`models/train/graph.py`).
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md),
//! [reproduce the thesis and run the
//! suite](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/reproduce.md).
#![warn(missing_docs)]

pub mod card;
mod error;
pub mod model;
mod provider;
mod registry;

pub use error::GraphError;
pub use model::{Architecture, ContactGraphModel, FEATURES, PointInput, Scratch};
pub use provider::{GraphWarmStart, point_inputs};
pub use registry::register;
