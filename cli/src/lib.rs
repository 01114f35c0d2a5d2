//! Library side of the `deepcontact` command-line tool: each subcommand is a module with
//! its arguments and a `run` function, so tests can drive them without a process.
#![warn(missing_docs)]

pub mod common;
pub mod compare;
pub mod generate;
pub mod grid_roundtrip;
pub mod plots;
pub mod render;
pub mod simulate;
pub mod soak;
