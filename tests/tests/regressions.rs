//! Regression tests of the bugs found by fuzzing and property testing (one test per bug,
//! named after it). The harness is the fuzzers' own (`fuzz/src/lib.rs`).

#[path = "../../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod harness;
