//! DSP tables, as x264's `x264_pixel_function_t` and dav1d's DSP
//! contexts: each area's kernels in one struct of function pointers, one
//! table per CPU level, the table of the level in force chosen by
//! [`PerLevel::get`] (the level is [`crate::cpu`]'s: detected once,
//! lowered by `MOCOMP_CPU`). Callers hold the table they got and call
//! through it; nothing outside the table builders asks the CPU level.
//!
//! Every entry of a SIMD table has a scalar twin in the scalar table that
//! gives the same bits; `tests/checkasm.rs` holds each entry equal to its
//! twin at every level on random and worst-case inputs, and each table has
//! a criterion bench per entry (`benches/dsp.rs`).
//!
//! The kernels here read and write plain slices (no picture geometry, no
//! borders): the code around them (`interp`, `recon`, ...) finds the
//! samples and calls the table.
//!
//! Tables of this crate: [`mc`] (motion compensation), [`itx`] (transform
//! and quantisation), [`ipred`] (intra prediction), [`lf`] (deblocking).
//! The `mocomp` crate builds its own the same way (pixel distortions and
//! half-pel planes, the macroblock coder, metrics, image filters, flow,
//! feature matching).

pub mod ipred;
pub mod itx;
pub mod lf;
pub mod mc;
#[cfg(target_arch = "x86_64")]
pub mod x86;

use crate::cpu::{self, CpuLevel};

/// One table per CPU level, lowest first.
#[derive(Debug)]
pub struct PerLevel<T: 'static>(pub [T; 3]);

impl<T> PerLevel<T> {
    /// The table of the level in force.
    #[inline]
    pub fn get(&'static self) -> &'static T {
        &self.0[cpu::level() as usize]
    }

    /// The table of `level`, or of the highest level this CPU runs when
    /// `level` is above it (a table is never handed out for instructions
    /// the CPU lacks).
    pub fn at(&'static self, level: CpuLevel) -> &'static T {
        &self.0[level.min(CpuLevel::detected()) as usize]
    }
}

/// Kernels compiled for an instruction set from the same safe source as
/// the scalar ones (for what the compiler vectorises well on its own):
/// each `fn name(args) -> ret => body;` becomes a safe `name` that calls
/// `body` compiled with `feature` enabled. Written inside a private module
/// of a table builder, so that only the tables of levels that have the
/// feature can reach the functions.
#[macro_export]
macro_rules! compiled_for {
    ($feature:literal: $(fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? => $body:expr;)*) => {
        $(
            #[doc = concat!("`", stringify!($body), "` compiled with ", $feature, ".")]
            #[allow(clippy::too_many_arguments)]
            pub(super) fn $name($($arg: $ty),*) $(-> $ret)? {
                #[target_feature(enable = $feature)]
                #[allow(clippy::too_many_arguments)]
                unsafe fn wide($($arg: $ty),*) $(-> $ret)? {
                    let body = $body;
                    // (Some bodies are `unsafe fn`s whose contract is
                    // this feature.)
                    #[allow(unused_unsafe)]
                    unsafe {
                        body($($arg),*)
                    }
                }
                // SAFETY: this function is placed only in the tables of
                // levels that have the feature, and `PerLevel` hands out
                // a table only for a level the CPU runs.
                unsafe { wide($($arg),*) }
            }
        )*
    };
}
