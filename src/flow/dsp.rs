//! The flow kernels, one table per CPU level ([`crate::codec::dsp`]): the
//! DIS patch search over a pyramid level, its densification and the
//! variational refinement; and the search's AVX2 residual of an 8x8 patch
//! ([`x86::dis_residual8`]), which the AVX2 build of the search calls.
//! Their AVX2 builds are the scalar source compiled for AVX2, without FMA,
//! so that every sum rounds as in the scalar build: the same bits (held by
//! `tests/checkasm.rs` and the golden flows).

use ndarray::Array2;

use super::dis::densify::densify_body;
use super::dis::search::{search_level_body, LevelSearch, Padded, SparseFlow};
use super::refine::{band_body, Band, BandFn};
use crate::codec::dsp::PerLevel;

/// The DIS search of one pyramid level: `(input, patch side)`.
pub(crate) type DisSearchFn = fn(&LevelSearch, usize) -> SparseFlow;

/// DIS densification of a band of rows of one level: `(i1, padded i2,
/// patch vectors, first row, u, v)` (`u`, `v` the band's rows).
pub(crate) type DensifyFn = fn(&Array2<f32>, &Padded, &SparseFlow, usize, &mut [f32], &mut [f32]);

/// The flow kernels of one CPU level.
#[derive(Clone, Copy)]
pub(crate) struct FlowDsp {
    /// DIS patch search over a level.
    pub dis_search_level: DisSearchFn,
    /// DIS densification of a level.
    pub densify: DensifyFn,
    /// A band of the variational refinement's work.
    pub refine_band: BandFn,
}

const SCALAR: FlowDsp = FlowDsp {
    dis_search_level: |input, patch| search_level_body::<false>(input, patch),
    densify: densify_body,
    refine_band: band_body,
};

/// The tables, lowest level first.
pub(crate) static FLOW: PerLevel<FlowDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    FlowDsp {
        dis_search_level: avx2::dis_search_level,
        densify: avx2::densify,
        refine_band: avx2::refine_band,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub(crate) fn flow() -> &'static FlowDsp {
    FLOW.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use ndarray::Array2;

    use super::{Band, LevelSearch, Padded, SparseFlow};
    crate::codec::compiled_for! { "avx2":
        fn dis_search_level(input: &LevelSearch, patch: usize) -> SparseFlow => super::search_level_body::<true>;
        fn densify(a1: &Array2<f32>, a2: &Padded, s: &SparseFlow, first: usize, u: &mut [f32], v: &mut [f32])
            => super::densify_body;
        fn refine_band(band: Band<'_>) => super::band_body;
    }
}

/// DIS's residual over an 8x8 patch with AVX2: the same operations in the
/// same order as the search's scalar `Template::residual` loop, a row
/// of the patch one register (the loop as LLVM vectorises it shuffles one
/// load into the next instead), so the same bits.
#[cfg(target_arch = "x86_64")]
pub(crate) mod x86 {
    use std::arch::x86_64::*;

    /// `(sum d, sum d^2, sum d gx, sum d gy)` of `d` the bilinear sample of
    /// the picture `data` (rows of `s`) at `base` with `weights`,
    /// minus `i0` (8x8, row-major, as `gx` and `gy`); each sum over the rows
    /// per column, then over the columns in order, as the scalar loop.
    ///
    /// # Safety
    /// The CPU must run AVX2.
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn dis_residual8(
        data: &[f32],
        s: usize,
        base: usize,
        [w00, w01, w10, w11]: [f32; 4],
        [i0, gx, gy]: [&[f32]; 3],
    ) -> [f32; 4] {
        // Every load below reads data[base + r s ..= base + r s + 8] for r
        // in 0..=8, and 8 samples from 8 r of the template's rows: checked
        // once here.
        assert!(
            base + 8 * s + 9 <= data.len(),
            "dis_residual8: patch outside the picture"
        );
        assert!(
            i0.len() == 64 && gx.len() == 64 && gy.len() == 64,
            "dis_residual8: not an 8x8 template"
        );
        let p = data.as_ptr().add(base);
        let (a, b, c, d) = (
            _mm256_set1_ps(w00),
            _mm256_set1_ps(w01),
            _mm256_set1_ps(w10),
            _mm256_set1_ps(w11),
        );
        let (mut sd, mut sd2, mut sdx, mut sdy) = (
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
        );
        for r in 0..8 {
            let (top, bot) = (p.add(r * s), p.add((r + 1) * s));
            let mut e = _mm256_add_ps(
                _mm256_mul_ps(a, _mm256_loadu_ps(top)),
                _mm256_mul_ps(b, _mm256_loadu_ps(top.add(1))),
            );
            e = _mm256_add_ps(e, _mm256_mul_ps(c, _mm256_loadu_ps(bot)));
            e = _mm256_add_ps(e, _mm256_mul_ps(d, _mm256_loadu_ps(bot.add(1))));
            e = _mm256_sub_ps(e, _mm256_loadu_ps(i0.as_ptr().add(8 * r)));
            sd = _mm256_add_ps(sd, e);
            sd2 = _mm256_add_ps(sd2, _mm256_mul_ps(e, e));
            sdx = _mm256_add_ps(sdx, _mm256_mul_ps(e, _mm256_loadu_ps(gx.as_ptr().add(8 * r))));
            sdy = _mm256_add_ps(sdy, _mm256_mul_ps(e, _mm256_loadu_ps(gy.as_ptr().add(8 * r))));
        }
        [sd, sd2, sdx, sdy].map(|v| sum_lanes_in_order(v))
    }

    /// The eight lanes of `v` added first to last, as the scalar loop adds
    /// its columns. Written out rather than `iter().sum()`: some builds (the
    /// Python extension's) left that a call, four per residual.
    #[inline(always)]
    unsafe fn sum_lanes_in_order(v: __m256) -> f32 {
        let mut l = [0f32; 8];
        _mm256_storeu_ps(l.as_mut_ptr(), v);
        let mut total = l[0];
        for x in &l[1..] {
            total += x;
        }
        total
    }
}
