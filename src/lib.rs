//! mocomp: motion estimation, optical flow and motion-compensated video
//! compression.
//!
//! The normative half (pictures, bitstream, motion compensation, decoder) is
//! the `mocomp-codec` crate, re-exported as [`codec`]; everything an encoder
//! or analyst chooses lives here. See `ARCHITECTURE.md`.
//!
//! Features: `cli` (default) builds the `mocomp` command line and what only
//! it needs (clap, indicatif, the plots); `plot` alone adds the RD plots
//! ([`rd::plot`]). With `default-features = false` the library depends on
//! none of them.
//!
//! ```
//! use mocomp::codec::Frame;
//! use mocomp::metrics::FrameQuality;
//! let a = Frame::filled(32, 32, 90, 128, 128).unwrap();
//! let b = Frame::filled(32, 32, 92, 128, 128).unwrap();
//! let q = FrameQuality::measure(&a, &b);
//! assert!((q.psnr.y - 42.11).abs() < 0.01);
//! ```
#![warn(missing_docs)]

pub use mocomp_codec as codec;

pub mod analyze;
#[cfg(feature = "cli")]
pub mod cli;
pub mod encode;
pub mod features;
pub mod flow;
pub mod fuzzing;
pub mod global;
pub mod imgproc;
pub mod interpolate;
pub mod io;
pub mod me;
pub mod metrics;
pub mod raster;
pub mod rd;
pub mod segment;
mod spare_planes;
pub mod stabilize;
pub mod synth;
pub mod viz;

/// The README's code, compiled and run as a test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
