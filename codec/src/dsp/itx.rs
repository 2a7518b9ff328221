//! The inverse transform kernels (normative: FORMAT.md section 10): a
//! block of levels dequantised, inverse transformed and added to its
//! prediction with clipping, for the 4x4 and the 8x8 transforms. The AVX2
//! builds are the scalar source compiled for AVX2 (integer arithmetic: the
//! same samples).

use super::PerLevel;
use crate::consts::MB;
use crate::transform::{dequantize, inverse_4x4, Block4};
use crate::transform8x8::{dequantize_8x8, inverse_8x8, Block8};

/// A 4x4 block added to its prediction: `(levels, qp, out, stride, (x,
/// y))`, the block at sample (x, y) of `out` (rows of `stride`).
pub type Add4x4Fn = fn(&Block4, u8, &mut [u8], usize, (usize, usize));

/// An 8x8 block added to a macroblock's luma prediction: `(levels, qp,
/// out, (x, y))`.
pub type Add8x8Fn = fn(&Block8, u8, &mut [u8; 256], (usize, usize));

/// The inverse transform kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct ItxDsp {
    /// Dequantise, inverse 4x4 transform, add.
    pub add_4x4: Add4x4Fn,
    /// Dequantise, inverse 8x8 transform, add.
    pub add_8x8: Add8x8Fn,
}

const SCALAR: ItxDsp = ItxDsp { add_4x4, add_8x8 };

/// The tables, lowest level first.
pub static ITX: PerLevel<ItxDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    ItxDsp {
        add_4x4: avx2::add_4x4,
        add_8x8: avx2::add_8x8,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn itx() -> &'static ItxDsp {
    ITX.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use crate::transform::Block4;
    use crate::transform8x8::Block8;
    crate::compiled_for! { "avx2":
        fn add_4x4(levels: &Block4, qp: u8, out: &mut [u8], stride: usize, at: (usize, usize)) => super::add_4x4;
        fn add_8x8(levels: &Block8, qp: u8, out: &mut [u8; 256], at: (usize, usize)) => super::add_8x8;
    }
}

/// Adds one 4x4 block of levels, dequantised at `qp`, to the prediction
/// held in `out` (a `stride`-wide block) at (bx, by), clipping; a block
/// without levels leaves it as it is.
#[inline(always)]
fn add_4x4(levels: &Block4, qp: u8, out: &mut [u8], stride: usize, (bx, by): (usize, usize)) {
    if levels.as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let mut c = *levels;
    dequantize(&mut c, qp);
    let residual = inverse_4x4(&c);
    for (r, res) in residual.iter().enumerate() {
        let i = (by + r) * stride + bx;
        for (o, &d) in out[i..i + 4].iter_mut().zip(res) {
            *o = (i32::from(*o) + d).clamp(0, 255) as u8;
        }
    }
}

/// Adds one 8x8 block of levels, dequantised at `qp`, to the macroblock's
/// luma prediction `out` at sample (x, y), clipping.
#[inline(always)]
fn add_8x8(levels: &Block8, qp: u8, out: &mut [u8; 256], (x, y): (usize, usize)) {
    if levels.as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let mut c = *levels;
    dequantize_8x8(&mut c, qp);
    for (r, res) in inverse_8x8(&c).iter().enumerate() {
        let i = (y + r) * MB + x;
        for (o, &d) in out[i..i + 8].iter_mut().zip(res) {
            *o = (i32::from(*o) + d).clamp(0, 255) as u8;
        }
    }
}
