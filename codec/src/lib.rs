//! `mocomp-codec`: the normative half of mocomp.
//!
//! Everything a decoder must do bit-exactly lives here, and nothing about how
//! an encoder searches: picture types, the bitstream syntax and its range
//! coder, transforms and dequantisation, intra prediction, motion
//! compensation (block, OBMC, the dense grid warp) and the decoder;
//! `FORMAT.md` beside this crate specifies the stream. It depends on no other
//! crate of the workspace. See `ARCHITECTURE.md` at the repository root.
#![warn(missing_docs)]

pub mod bits;
pub mod consts;
pub mod cpu;
pub mod deblock;
pub mod decoder;
pub mod dsp;
pub mod entropy;
pub mod interp;
pub mod intra;
pub mod intra4x4;
pub mod intra8x8;
pub mod modes;
pub mod mv;
pub mod mvpred;
pub mod obmc;
pub mod partition;
pub mod picture;
pub mod recon;
pub mod residual;
pub mod syntax;
pub mod transform;
pub mod transform8x8;
pub mod warp;
pub mod weight;

pub use picture::{Frame, PictureError, Plane, MAX_DIMENSION};
