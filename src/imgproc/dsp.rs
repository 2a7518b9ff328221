//! The image filters' kernels, one table per CPU level
//! ([`crate::codec::dsp`]): the horizontal and vertical passes of a
//! separable filter over a band of rows, the binomial pyramid's halving
//! and the linear upsampling of a coarse field. The AVX2 builds are the scalar
//! source compiled for AVX2, without FMA, so that every output adds its
//! terms in the same order and rounds the same way: the same bits.

use ndarray::{Array2, ArrayView2};

use super::pyramid::{
    downsample_binomial_body, downsample_binomial_u8_body, upsample_levels_body, upsample_levels_pair_body,
};
use crate::codec::dsp::PerLevel;

/// The horizontal pass over a band of whole rows: `(src, w, kernel, out)`,
/// `src` and `out` holding the same rows of width `w`, edges repeated.
pub type RowsFn = fn(&[f32], usize, &[f32], &mut [f32]);

/// The vertical pass: `(src, h, w, y0, kernel, out)`, output rows `y0..`
/// (as many as `out` holds) of the `h x w` picture `src`, edges repeated.
pub type ColsFn = fn(&[f32], usize, usize, usize, &[f32], &mut [f32]);

/// The binomial halving: `(src, scratch, out)`, as
/// [`super::pyramid::downsample_binomial_into`].
pub type HalveFn = fn(ArrayView2<'_, f32>, &mut Vec<f32>, &mut Array2<f32>);

/// The binomial halving of 8-bit samples, as
/// [`super::pyramid::downsample_binomial_u8_into`].
pub type HalveU8Fn = fn(ArrayView2<'_, u8>, &mut Vec<f32>, &mut Array2<f32>);

/// Linear upsampling by levels: `(src, (h, w), levels, scale, out)`, the
/// `h x w` field written over `out`, as
/// [`super::pyramid::upsample_levels_into`].
pub type UpsampleFn = fn(&Array2<f32>, (usize, usize), usize, f32, &mut [f32]);

/// Both components of a field upsampled into (u, v) pairs: `(u, v, (h, w),
/// levels, scale, y0, out)`, output rows `y0..` (as many as `out` holds),
/// as [`super::pyramid::upsample_levels_interleaved`].
pub type UpsamplePairFn = fn(&Array2<f32>, &Array2<f32>, (usize, usize), usize, f32, usize, &mut [f32]);

/// The image filters' kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct ImgprocDsp {
    /// Horizontal separable pass.
    pub filter_rows: RowsFn,
    /// Vertical separable pass.
    pub filter_cols: ColsFn,
    /// A pyramid level from the one below, binomial filter.
    pub downsample_binomial: HalveFn,
    /// The same from 8-bit samples.
    pub downsample_binomial_u8: HalveU8Fn,
    /// A coarse field brought levels finer.
    pub upsample_levels: UpsampleFn,
    /// Both components of a coarse field brought levels finer, interleaved.
    pub upsample_levels_pair: UpsamplePairFn,
}

const SCALAR: ImgprocDsp = ImgprocDsp {
    filter_rows: rows_band,
    filter_cols: cols_band,
    downsample_binomial: downsample_binomial_body,
    downsample_binomial_u8: downsample_binomial_u8_body,
    upsample_levels: upsample_levels_body,
    upsample_levels_pair: upsample_levels_pair_body,
};

/// The tables, lowest level first.
pub static IMGPROC: PerLevel<ImgprocDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    ImgprocDsp {
        filter_rows: avx2::rows_band,
        filter_cols: avx2::cols_band,
        downsample_binomial: avx2::downsample_binomial,
        downsample_binomial_u8: avx2::downsample_binomial_u8,
        upsample_levels: avx2::upsample_levels,
        upsample_levels_pair: avx2::upsample_levels_pair,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn imgproc() -> &'static ImgprocDsp {
    IMGPROC.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use ndarray::{Array2, ArrayView2};

    crate::codec::compiled_for! { "avx2":
        fn downsample_binomial(src: ArrayView2<'_, f32>, tmp: &mut Vec<f32>, out: &mut Array2<f32>)
            => super::downsample_binomial_body;
        fn downsample_binomial_u8(src: ArrayView2<'_, u8>, tmp: &mut Vec<f32>, out: &mut Array2<f32>)
            => super::downsample_binomial_u8_body;
        fn upsample_levels(src: &Array2<f32>, size: (usize, usize), levels: usize, scale: f32, out: &mut [f32])
            => super::upsample_levels_body;
        fn upsample_levels_pair(
            u: &Array2<f32>, v: &Array2<f32>, size: (usize, usize), levels: usize, scale: f32, y0: usize,
            out: &mut [f32]
        ) => super::upsample_levels_pair_body;
        fn rows_band(src: &[f32], w: usize, kernel: &[f32], out: &mut [f32]) => super::rows_band;
        fn cols_band(src: &[f32], h: usize, w: usize, y0: usize, kernel: &[f32], out: &mut [f32]) => super::cols_band;
    }
}

/// Outputs accumulated together in registers by the filters.
const CHUNK: usize = 16;

/// `dst[x] = sum_k kernel[k] * src[x + k]` for `dst.len()` outputs (`src` is
/// `kernel.len() - 1` longer): [`combine_rows`] over the shifted copies
/// `src[k..]`, so both passes share one accumulation loop.
#[inline(always)]
fn correlate_row(src: &[f32], kernel: &[f32], dst: &mut [f32]) {
    let n = dst.len();
    let shifted: Vec<&[f32]> = (0..kernel.len()).map(|k| &src[k..k + n]).collect();
    combine_rows(&shifted, kernel, dst);
}

/// `dst[x] = sum_k kernel[k] * rows[k][x]`, chunk by chunk: all taps of a
/// chunk of outputs accumulate in registers before one store. Each output
/// adds its terms in tap order, so every instruction set gives the same bits.
#[inline(always)]
fn combine_rows(rows: &[&[f32]], kernel: &[f32], dst: &mut [f32]) {
    let n = dst.len();
    let mut x = 0;
    while x + CHUNK <= n {
        let mut acc = [0f32; CHUNK];
        for (row, &kv) in rows.iter().zip(kernel) {
            let s = &row[x..x + CHUNK];
            for i in 0..CHUNK {
                acc[i] += kv * s[i];
            }
        }
        dst[x..x + CHUNK].copy_from_slice(&acc);
        x += CHUNK;
    }
    for (i, d) in dst[x..].iter_mut().enumerate() {
        *d = rows
            .iter()
            .zip(kernel)
            .map(|(row, &kv)| kv * row[x + i])
            .fold(0.0, |a, b| a + b);
    }
}

/// The horizontal pass over a band of whole rows (`src` and `out` hold the
/// same rows), one padded copy of each row at a time.
#[inline(always)]
fn rows_band(src: &[f32], w: usize, kernel: &[f32], out: &mut [f32]) {
    let r = kernel.len() / 2;
    let mut padded = vec![0f32; w + 2 * r];
    for (row, dst) in src.chunks_exact(w).zip(out.chunks_exact_mut(w)) {
        padded[..r].fill(row[0]);
        padded[r..r + w].copy_from_slice(row);
        padded[r + w..].fill(row[w - 1]);
        correlate_row(&padded, kernel, dst);
    }
}

/// The vertical pass for output rows `y0..` (as many as `out` holds) of
/// the `h x w` picture `src`.
#[inline(always)]
fn cols_band(src: &[f32], h: usize, w: usize, y0: usize, kernel: &[f32], out: &mut [f32]) {
    let r = kernel.len() as isize / 2;
    let mut rows: Vec<&[f32]> = Vec::with_capacity(kernel.len());
    for (k, dst) in out.chunks_exact_mut(w).enumerate() {
        let y = y0 + k;
        rows.clear();
        for t in 0..kernel.len() as isize {
            let sy = (y as isize + t - r).clamp(0, h as isize - 1) as usize;
            rows.push(&src[sy * w..(sy + 1) * w]);
        }
        combine_rows(&rows, kernel, dst);
    }
}
