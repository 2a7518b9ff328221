//! The integration tests, one module per file of this folder, in one test
//! binary: 23 binaries each linked the whole library and monomorphised
//! its generics again (CI's test build from a clean clone, here: 508 s as
//! 23 binaries, 390 s as one). Run one file's tests with
//! `cargo test --test integration NAME::` (for example
//! `cargo test --test integration metrics::`).

mod analyze;
mod checkasm;
mod cli;
mod common;
mod dis;
mod encode;
mod features;
mod flo;
mod flow;
mod fuzzing;
mod global;
mod golden;
mod golden_motion;
mod image;
mod interpolate;
mod kernels;
mod me;
mod metrics;
mod quality_cli;
mod segment;
mod stabilize;
mod synth;
mod tvl1;
mod y4m;
