//! # deepcontact-grid
//!
//! Particles ↔ grid transfer for the thesis's CNN warm starts (section 5 of *Deep
//! Contact*), and the `grid` oracle.
//!
//! * [`GridSpec`] — a regular grid (thesis: 61 × 61 nodes at 0.25 m over `[0, 15]²`).
//! * [`Kernel`] — poly6 (default), spiky and cut-off Gaussian smoothing kernels,
//!   normalised in 2D, support radius `h`.
//! * [`Transfer`] — particles → grid (Algorithm 1, weights normalised per particle),
//!   grid → particles (Algorithm 2, weights normalised per node; or bilinear), and the
//!   fused round trip; neighbours by exact lookup on the regular grid (default) or kiddo
//!   k-d trees ([`NeighbourSearch`]). Buffers are reused across calls.
//! * [`GridLayout`] — the one description of the grids (spec, kernel, `h`, channel
//!   names and order, wall mass), serialised as JSON for the data generator, the ONNX
//!   providers and the Python training.
//! * [`GridEncoder`] — a world → the 6 input channels `[mass, vx, vy, omega, nx, ny]`
//!   (walls marked with mass 100); impulses ↔ the 2 output channels
//!   `[normal_impulse, tangent_impulse]`.
//! * [`GridFiltered`] and [`register`] — the `grid` warm start: `copy` (or any
//!   provider) → grid → contact points.
//! * [`RoundTrip`] — the thesis's Table 1 measurement.
//!
//! ```
//! use deepcontact_core::Vector;
//! use deepcontact_grid::{GridLayout, GridEncoder};
//!
//! // A CNN provider's inner loop, minus the model:
//! let layout = GridLayout::thesis();
//! let mut encoder = GridEncoder::new(layout.clone()).unwrap();
//! let points = [Vector::new(4.0, 0.5), Vector::new(4.5, 1.2)];
//! let impulses = [deepcontact_core::Impulse::new(2.0, 0.1), deepcontact_core::Impulse::new(1.0, -0.2)];
//! let mut output = vec![0.0; layout.output_len()];
//! encoder.encode_labels(&points, &impulses, &mut output).unwrap(); // stands in for the model
//! let mut back = [deepcontact_core::Impulse::ZERO; 2];
//! encoder.decode(&output, &points, &mut back).unwrap();
//! assert!((back[0].normal + back[1].normal - 3.0).abs() < 1e-9); // nothing gained or lost
//! ```
//!
//! Used by the CNN providers and the `grid` oracle; use it directly to move data between contacts
//! and grids.
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md),
//! [reproduce the thesis and run the
//! suite](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/reproduce.md).
#![warn(missing_docs)]

mod encode;
mod error;
mod kernel;
mod layout;
mod provider;
mod roundtrip;
mod spec;
mod transfer;
pub mod walls;

pub use encode::{EncodeStats, GridEncoder};
pub use error::GridError;
pub use kernel::Kernel;
pub use layout::{
    CH_MASS, CH_NORMAL, CH_NX, CH_NY, CH_OMEGA, CH_TANGENT, CH_VX, CH_VY, GridLayout,
    INPUT_CHANNELS, OUTPUT_CHANNELS, TensorOrder,
};
pub use provider::{GridFilterConfig, GridFiltered, register};
pub use roundtrip::{RoundTrip, RoundTripSums, TABLE1_VALUES, THESIS_TABLE1};
pub use spec::GridSpec;
pub use transfer::{G2pMethod, NeighbourSearch, Transfer, TransferStats};
