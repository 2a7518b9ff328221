//! The pixel kernels of motion search, one table per CPU level
//! ([`crate::codec::dsp`]): block distortions (SAD, SATD, the paired 4x4
//! SATD of the intra search, the capped 16x16 SATD of the block search)
//! and the half-pel planes with the copies and averages that rank sub-pel
//! candidates on them. The scalar kernels here are the reference the
//! others must equal (`tests/checkasm.rs`).
//!
//! On x86-64 the SAD kernels use `psadbw`: SSE2 for rows of 8 and 16
//! samples, AVX2 for rows of 16 two at a time and rows of 32; other widths
//! use the scalar kernel.
//!
//! Measured, for 16x16: one call at a time (`cargo bench --bench me --
//! cost_16x16`, latency) SSE2 is a little faster (25 against 22 Gelem/s),
//! but in the search, where calls overlap, the AVX2 kernel wins (`mocomp me
//! --method esa --range 16 --threads 1` on pan_cif: 7.4-8.0 against
//! 8.2-9.3 ms per pass, 5 runs each, alternated), so AVX2 keeps it. For
//! 32x32 AVX2 is 1.8 times SSE2 in both.

use std::cell::RefCell;

use crate::codec::dsp::PerLevel;
use crate::codec::Plane;

mod intra;
pub use intra::{intra_satd_x3_16x16, satd_4x4_quad, IntraSatdX3Fn, QuadFn};

thread_local! {
    /// The horizontal pass the half-pel planes are filled from, reused.
    static HPASS: RefCell<Vec<i16>> = const { RefCell::new(Vec::new()) };
}

/// Signature of a block cost kernel: `(a, a_stride, b, b_stride, w, h)`.
pub type CostFn = fn(&[u8], usize, &[u8], usize, usize, usize) -> u32;

/// Signature of the paired 4x4 SATD: two 4x4 tiles side by side in 8x4
/// blocks (rows of 8 bytes), each tile's SATD (halved, rounded up, as
/// [`satd`] of that tile alone).
pub type PairFn = fn(&[u8; 32], &[u8; 32]) -> [u32; 2];

/// Signature of the capped 16x16 SATD: `(a, a_stride, b, b_stride, cap)`,
/// the SATD of the two 16x16 blocks or, when the SATD of their top 16x8
/// halves already exceeds `cap`, that one: a search's positions that
/// cannot beat its best stop half way (SATD only grows with rows).
pub type CappedFn = fn(&[u8], usize, &[u8], usize, u32) -> u32;

/// Signature of the half-pel planes: `(reference, band)` writes the
/// horizontal, vertical and diagonal half-pel phases of `reference` over
/// the band's region, with the codec's filter and rounding
/// ([`fill_halfpel`] makes the bands of whole planes; the search's
/// patches are bands of their own).
pub type HalfpelFn = fn(&Plane, HalfpelBand<'_>);

/// Signature of a half-pel patch for a 16x16 block's sub-pel steps:
/// `(reference, origin, out)` writes the three phases over the
/// [`PATCH18_ROWS`] x [`PATCH18_STRIDE`] samples from picture position
/// `origin` into `out` (each phase [`PATCH18_ROWS`] rows of
/// [`PATCH18_STRIDE`], one after the other; the first 18 columns are the
/// patch, the rest what the vector width computes anyway). The
/// reference's border must hold 3 samples before the rectangle and 4
/// after it.
pub type PatchFn = fn(&Plane, (isize, isize), &mut [u8]);

/// A 16x16 block's patch rows: the block and one sample each way.
pub const PATCH18_ROWS: usize = 18;

/// A 16x16 block's patch columns as computed: the 18 it needs, rounded
/// up to the vector width.
pub const PATCH18_STRIDE: usize = 32;

/// One phase of a 16x16 block's patch.
pub const PATCH18_PHASE: usize = PATCH18_ROWS * PATCH18_STRIDE;

/// A region of the three half-pel phases and where it is written.
pub struct HalfpelBand<'a> {
    /// The picture coordinates of the region's first sample (its phases
    /// are those at (x + 1/2, y), (x, y + 1/2) and (x + 1/2, y + 1/2));
    /// the filter reads 3 samples before and 4 after it, which the
    /// reference's border must hold.
    pub origin: (isize, isize),
    /// The region's rows.
    pub rows: usize,
    /// The region's columns.
    pub span: usize,
    /// The horizontal, vertical and diagonal phases, each from the
    /// region's first row.
    pub out: [&'a mut [u8]; 3],
    /// The column of each output row where the region's samples start.
    pub out_x: usize,
    /// Of the outputs' rows.
    pub stride: usize,
}

/// The half-pel planes of `reference` by `kernel` into `planes` (three,
/// its size and padding), over the picture and `margin` pixels around it,
/// in `bands` bands of rows on the current rayon pool's threads (each
/// band filters the 7 rows its vertical taps share with the next again;
/// the planes are the same for any number of bands).
///
/// Only the picture and the [`REACH`] samples around it are filtered:
/// beyond them every tap reads the same edge sample of the padded
/// reference, so each plane repeats its outermost filtered row and column
/// out to the margin (at a copy's cost instead of a filter's: 11 % of
/// the area filtered before at 720p with a margin of 32, 28 % at CIF).
pub fn fill_halfpel(kernel: HalfpelFn, reference: &Plane, margin: usize, planes: &mut [Plane], bands: usize) {
    use rayon::prelude::*;
    let (rows, cols) = filtered_region(reference, margin);
    let per_band = rows.len().div_ceil(bands.clamp(1, rows.len().max(1)));
    let m = margin as isize;
    // The bands are cut from the planes: their stride, not the reference's.
    let ([a, b, c], stride) = three_planes(planes);
    let first_row = rows.start as isize - m;
    let len = per_band * stride;
    let start = |p: &mut Plane| p.index(-m, first_row);
    let (sa, sb, sc) = (start(a), start(b), start(c));
    let jobs: Vec<HalfpelBand<'_>> = a.data_mut()[sa..]
        .chunks_mut(len)
        .zip(b.data_mut()[sb..].chunks_mut(len))
        .zip(c.data_mut()[sc..].chunks_mut(len))
        .enumerate()
        .take(rows.len().div_ceil(per_band.max(1)))
        .map(|(i, ((a, b), c))| {
            let first = rows.start + i * per_band;
            HalfpelBand {
                origin: (cols.start as isize - m, first as isize - m),
                rows: (first + per_band).min(rows.end) - first,
                span: cols.len(),
                out: [a, b, c],
                out_x: cols.start,
                stride,
            }
        })
        .collect();
    if jobs.len() == 1 {
        jobs.into_iter().for_each(|band| kernel(reference, band));
    } else {
        jobs.into_par_iter().for_each(|band| kernel(reference, band));
    }
    for plane in [a, b, c] {
        repeat_edges(plane, margin, (&rows, &cols), rows.clone());
    }
}

/// [`fill_halfpel`]'s rows `rows` of the planes alone (counted from the
/// margin's first row: `0..height + 2 * margin`), on the calling thread:
/// the same samples as the whole planes' when runs of rows come from the
/// top, for a reference that arrives a band at a time. Row `r` reads the
/// reference's rows to `r - margin + REACH` (and its borders there); the
/// rows beyond the last one filtered, copies of it, are written with it.
pub fn fill_halfpel_rows(
    kernel: HalfpelFn,
    reference: &Plane,
    margin: usize,
    planes: &mut [Plane],
    rows: std::ops::Range<usize>,
) {
    let (all, cols) = filtered_region(reference, margin);
    let band = rows.start.max(all.start)..rows.end.min(all.end);
    let m = margin as isize;
    // A run of the margin's rows alone writes nothing: those above the
    // first filtered row come with it, those below the last with that.
    if band.is_empty() {
        return;
    }
    let ([a, b, c], stride) = three_planes(planes);
    let first_row = band.start as isize - m;
    let len = band.len() * stride;
    let at = |p: &mut Plane| p.index(-m, first_row);
    let (sa, sb, sc) = (at(a), at(b), at(c));
    let job = HalfpelBand {
        origin: (cols.start as isize - m, first_row),
        rows: band.len(),
        span: cols.len(),
        out: [
            &mut a.data_mut()[sa..sa + len],
            &mut b.data_mut()[sb..sb + len],
            &mut c.data_mut()[sc..sc + len],
        ],
        out_x: cols.start,
        stride,
    };
    kernel(reference, job);
    for plane in [a, b, c] {
        repeat_edges(plane, margin, (&all, &cols), band.clone());
    }
}

/// The rows and columns of `reference`'s half-pel planes that the filter
/// computes (from the margin's first): the picture and [`REACH`] around
/// it, within `margin`.
fn filtered_region(reference: &Plane, margin: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    let filtered =
        |len: usize| margin.saturating_sub(REACH)..(margin + len + REACH - 1).min(len + 2 * margin);
    (filtered(reference.height()), filtered(reference.width()))
}

/// The three half-pel planes and their stride (one for all).
fn three_planes(planes: &mut [Plane]) -> ([&mut Plane; 3], usize) {
    let [a, b, c] = planes else {
        panic!("three half-pel planes");
    };
    let stride = a.stride();
    assert!(
        b.stride() == stride && c.stride() == stride,
        "half-pel planes of one size"
    );
    ([a, b, c], stride)
}

/// How far from the picture the half-pel filter reads a sample that is
/// not the edge's: 4 samples before (the 8 taps of the phase at x - 4 + 1/2
/// read x - 7 .. x, all the edge sample at x = 0) and 3 after.
pub const REACH: usize = 4;

/// Repeats the filtered `rows` x `cols` of a half-pel plane (counted from
/// the margin's first) out to `margin` around the picture, as far as the
/// filtered rows `band` go: their ends, the rows above the first filtered
/// row with it, those below the last with that.
fn repeat_edges(
    plane: &mut Plane,
    margin: usize,
    (rows, cols): (&std::ops::Range<usize>, &std::ops::Range<usize>),
    band: std::ops::Range<usize>,
) {
    let m = margin as isize;
    let (span, filled_rows) = (plane.width() + 2 * margin, plane.height() + 2 * margin);
    let (first, stride) = (plane.index(-m, -m), plane.stride());
    let data = &mut plane.data_mut()[first..];
    for r in band.clone() {
        let row = &mut data[r * stride..r * stride + span];
        let (left, right) = (row[cols.start], row[cols.end - 1]);
        row[..cols.start].fill(left);
        row[cols.end..].fill(right);
    }
    if band.contains(&rows.start) {
        for r in 0..rows.start {
            data.copy_within(rows.start * stride..rows.start * stride + span, r * stride);
        }
    }
    if band.contains(&(rows.end - 1)) {
        for r in rows.end..filled_rows {
            let last = (rows.end - 1) * stride;
            data.copy_within(last..last + span, r * stride);
        }
    }
}

/// Signature of a 16x16 block copy: `(a, a_stride, out)`, `out` in rows
/// of 16.
pub type CopyFn = fn(&[u8], usize, &mut [u8]);

/// Signature of a block average: `((a, a_stride), (c, c_stride), out)`,
/// `(u + v + 1) >> 1` of the two blocks, `out` in rows of the block's
/// width.
pub type AverageFn = fn((&[u8], usize), (&[u8], usize), &mut [u8]);

/// Box sums of a buffer: `(data, stride, rows, side, out)`, `out[p]` the
/// sum of the `side x side` block at `data[p]` ([`super::sea`]).
pub type BoxSumsFn = fn(&[u8], usize, usize, usize, &mut [u16]);

/// The sums of 8-column groups over a band of rows: `(data, stride, (width,
/// rows), out)`, `out[g]` the sum of columns `8g .. 8g + 8` (fewer for the
/// last group of a width not a multiple of 8) of the band's `rows` rows
/// (at most 8); `out` holds `width.div_ceil(8)` sums. An 8x8 block's sum
/// each (the weighted prediction's statistics).
pub type GroupSumsFn = fn(&[u8], usize, (usize, usize), &mut [u32]);

/// Distances of a picture's samples from a level: `(data, stride, (width,
/// rows), c)`, the sum of `|v - c|` and how many `v <= c` over the `rows`
/// rows of `width` samples (a plane's mean deviation in one pass: the sum
/// about `c + 1` follows from the count).
pub type AbsCountFn = fn(&[u8], usize, (usize, usize), u8) -> (u64, u64);

/// The quadrants' absolute differences of sums along a row of positions:
/// `(rows, current, out)` ([`super::sea::ads`], x264's `ads4`); returns
/// the least of them.
pub type AdsFn = fn([&[u16]; 4], [u16; 4], &mut [u16]) -> u16;

/// The SADs of a 16x16 block against the 16 blocks one column apart along
/// a row of a reference: `(a, sa, b, sb, out)`, `out[k]` the SAD of `a`
/// and the block at `b[k..]`. `b` must hold `15 sb + 32` samples (a column
/// past the last block's, which the wide kernel loads and does not use).
/// Returns the least of them. For exhaustive search where most positions
/// are evaluated.
pub type SadRowFn = fn(&[u8], usize, &[u8], usize, &mut [u32; 16]) -> u32;

/// The pixel kernels of one CPU level.
#[derive(Clone, Copy)]
pub struct PixelDsp {
    /// Sum of absolute differences.
    pub sad: CostFn,
    /// Sum of absolute 4x4 Hadamard coefficients, halved.
    pub satd: CostFn,
    /// SATD of two 4x4 tiles at once (4x4 intra mode search).
    pub satd_4x4_pair: PairFn,
    /// SATD of four 4x4 tiles at once (4x4 intra mode search).
    pub satd_4x4_quad: QuadFn,
    /// SATD of the vertical, horizontal and DC 16x16 intra predictions
    /// from one transform of the source (16x16 intra mode search).
    pub intra_satd_x3_16x16: IntraSatdX3Fn,
    /// 16x16 SATD that may stop half way above a cap (block search).
    pub satd_16x16_capped: CappedFn,
    /// The half-pel planes of a reference.
    pub halfpel_planes: HalfpelFn,
    /// A 16x16 block's half-pel patch ([`PatchFn`]).
    pub halfpel_patch18: PatchFn,
    /// 16x16 copy (a half-pel candidate).
    pub copy_16x16: CopyFn,
    /// 16x16 average (a quarter-pel candidate).
    pub average_16x16: AverageFn,
    /// 8x8 average (a partition's quarter-pel candidate).
    pub average_8x8: AverageFn,
    /// Box sums of a reference (successive elimination).
    pub box_sums: BoxSumsFn,
    /// The bounds of a row of positions (successive elimination).
    pub ads: AdsFn,
    /// Sums of 8-column groups over up to 8 rows (8x8 block sums).
    pub group_sums: GroupSumsFn,
    /// Distances from a level and the count at or below it.
    pub abs_count: AbsCountFn,
    /// 16x16 SADs at 16 consecutive columns (exhaustive search).
    pub sad_16x16_row: SadRowFn,
}

impl std::fmt::Debug for PixelDsp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PixelDsp").finish_non_exhaustive()
    }
}

/// The scalar kernels (the reference every other table must equal).
const SCALAR: PixelDsp = PixelDsp {
    sad,
    satd,
    satd_4x4_pair,
    satd_4x4_quad,
    intra_satd_x3_16x16,
    satd_16x16_capped,
    halfpel_planes: halfpel_planes_scalar,
    halfpel_patch18: halfpel_patch18_scalar,
    copy_16x16: |a, sa, out| copy_rows(16, a, sa, out),
    average_16x16: |a, c, out| average_rows(16, a, c, out),
    average_8x8: |a, c, out| average_rows(8, a, c, out),
    box_sums: super::sea::box_sums,
    ads: super::sea::ads,
    group_sums,
    abs_count,
    sad_16x16_row: |a, sa, b, sb, out| sad_16x16_row_with(sad, a, sa, b, sb, out),
};

/// The scalar [`AbsCountFn`].
pub fn abs_count(data: &[u8], stride: usize, (width, rows): (usize, usize), c: u8) -> (u64, u64) {
    check_abs_count(data, stride, (width, rows));
    let (mut total, mut at_or_below) = (0u64, 0u64);
    for r in 0..rows {
        for &v in &data[r * stride..r * stride + width] {
            total += u64::from(v.abs_diff(c));
            at_or_below += u64::from(v <= c);
        }
    }
    (total, at_or_below)
}

/// Panics unless `rows` rows of `width` samples at `stride` lie in `data`.
fn check_abs_count(data: &[u8], stride: usize, (width, rows): (usize, usize)) {
    assert!(width <= stride || rows <= 1, "rows that do not overlap");
    assert!(
        rows == 0 || data.len() >= (rows - 1) * stride + width,
        "the rows inside the data"
    );
}

/// The scalar [`GroupSumsFn`].
pub fn group_sums(data: &[u8], stride: usize, (width, rows): (usize, usize), out: &mut [u32]) {
    check_group_sums(data, stride, (width, rows), out);
    out[..width.div_ceil(8)].fill(0);
    for r in 0..rows {
        let row = &data[r * stride..r * stride + width];
        for (o, group) in out.iter_mut().zip(row.chunks(8)) {
            *o += group.iter().map(|&v| u32::from(v)).sum::<u32>();
        }
    }
}

/// The bounds every [`GroupSumsFn`] relies on.
#[inline]
fn check_group_sums(data: &[u8], stride: usize, (width, rows): (usize, usize), out: &[u32]) {
    assert!(
        rows <= 8 && width <= stride,
        "a band of at most 8 rows of the buffer"
    );
    assert!(
        rows == 0 || data.len() >= (rows - 1) * stride + width,
        "the band inside the data"
    );
    assert!(out.len() >= width.div_ceil(8), "a sum per group");
}

/// [`SadRowFn`] as 16 calls of a SAD kernel.
#[inline(always)]
fn sad_16x16_row_with(kernel: CostFn, a: &[u8], sa: usize, b: &[u8], sb: usize, out: &mut [u32; 16]) -> u32 {
    check_sad_row(a, sa, b, sb);
    for (k, o) in out.iter_mut().enumerate() {
        *o = kernel(a, sa, &b[k..], sb, 16, 16);
    }
    out.iter().copied().fold(u32::MAX, u32::min)
}

/// Panics unless `a` holds a 16x16 block and `b` the 16 blocks of a
/// [`SadRowFn`] and the column after them.
fn check_sad_row(a: &[u8], sa: usize, b: &[u8], sb: usize) {
    assert!(
        15 * sa + 16 <= a.len() && 15 * sb + 32 <= b.len(),
        "sad_16x16_row: blocks outside their slices"
    );
}

/// The tables, lowest level first.
pub static PIXEL: PerLevel<PixelDsp> = PerLevel([
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    x86::SSE2,
    #[cfg(target_arch = "x86_64")]
    x86::AVX2,
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn pixel() -> &'static PixelDsp {
    PIXEL.get()
}

/// Sum of absolute differences.
pub fn sad(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
    (0..h)
        .map(|r| {
            let (ra, rb) = (&a[r * sa..r * sa + w], &b[r * sb..r * sb + w]);
            ra.iter()
                .zip(rb)
                .map(|(&x, &y)| u32::from(x.abs_diff(y)))
                .sum::<u32>()
        })
        .sum()
}

/// `sum |H D H^T|` of one 4x4 tile, with H the 4x4 Hadamard matrix (not
/// halved).
fn hadamard_abs_4x4(a: &[u8], sa: usize, b: &[u8], sb: usize) -> u32 {
    let mut d = [[0i32; 4]; 4];
    for (r, row) in d.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = i32::from(a[r * sa + c]) - i32::from(b[r * sb + c]);
        }
    }
    let mut t = [[0i32; 4]; 4];
    for r in 0..4 {
        let (s01, d01) = (d[r][0] + d[r][1], d[r][0] - d[r][1]);
        let (s23, d23) = (d[r][2] + d[r][3], d[r][2] - d[r][3]);
        t[r] = [s01 + s23, s01 - s23, d01 - d23, d01 + d23];
    }
    let column = |c: usize| [t[0][c], t[1][c], t[2][c], t[3][c]];
    let sum: u32 = (0..4)
        .map(column)
        .map(|[a, b, c, d]| {
            let (s01, d01, s23, d23) = (a + b, a - b, c + d, c - d);
            (s01 + s23).unsigned_abs()
                + (s01 - s23).unsigned_abs()
                + (d01 - d23).unsigned_abs()
                + (d01 + d23).unsigned_abs()
        })
        .sum();
    sum
}

/// SATD over 4x4 tiles (`w` and `h` multiples of 4).
pub fn satd(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
    debug_assert!(
        w % 4 == 0 && h % 4 == 0,
        "SATD needs sides that are multiples of 4"
    );
    let mut sum = 0u32;
    for ty in (0..h).step_by(4) {
        for tx in (0..w).step_by(4) {
            sum += hadamard_abs_4x4(&a[ty * sa + tx..], sa, &b[ty * sb + tx..], sb);
        }
    }
    sum.div_ceil(2)
}

/// The scalar capped 16x16 SATD.
pub fn satd_16x16_capped(a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
    capped_by_halves(satd, a, sa, b, sb, cap)
}

/// [`CappedFn`] from a SATD kernel, one 16x8 half at a time (halves add up
/// exactly: every 4x4 tile's coefficient sum is even).
#[inline]
fn capped_by_halves(satd: CostFn, a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
    let top = satd(a, sa, b, sb, 16, 8);
    if top > cap {
        return top;
    }
    top + satd(&a[8 * sa..], sa, &b[8 * sb..], sb, 16, 8)
}

/// The scalar paired 4x4 SATD.
pub fn satd_4x4_pair(a: &[u8; 32], b: &[u8; 32]) -> [u32; 2] {
    [0, 4].map(|o| satd(&a[o..], 8, &b[o..], 8, 4, 4))
}

/// Panics unless both blocks lie inside their slices: the SIMD kernels read
/// through raw pointers and rely on this.
#[inline]
fn check_bounds(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) {
    assert!(
        h == 0 || ((h - 1) * sa + w <= a.len() && (h - 1) * sb + w <= b.len()),
        "block {w}x{h} outside its slice"
    );
}

/// `out` (rows of `n`) = the rounded average of `n x n` blocks `a` and `c`
/// (each a slice from its first sample and a stride).
#[inline(always)]
pub(crate) fn average_rows(n: usize, (a, sa): (&[u8], usize), (c, sc): (&[u8], usize), out: &mut [u8]) {
    for (r, o) in out.chunks_exact_mut(n).take(n).enumerate() {
        for ((o, &u), &v) in o
            .iter_mut()
            .zip(&a[r * sa..r * sa + n])
            .zip(&c[r * sc..r * sc + n])
        {
            *o = ((u16::from(u) + u16::from(v) + 1) >> 1) as u8;
        }
    }
}

/// `out` (rows of `n`) = the `n x n` block `a` (stride `sa`).
#[inline(always)]
pub(crate) fn copy_rows(n: usize, a: &[u8], sa: usize, out: &mut [u8]) {
    for (r, o) in out.chunks_exact_mut(n).take(n).enumerate() {
        o.copy_from_slice(&a[r * sa..r * sa + n]);
    }
}

/// The half-pel filter: the codec's 8-tap luma filter at phase 1/2, in
/// 16 bits for the kernels.
pub(crate) const HALF: [i16; 8] = {
    let taps = crate::codec::interp::LUMA_TAPS[2];
    let mut half = [0i16; 8];
    let mut k = 0;
    while k < 8 {
        half[k] = taps[k] as i16;
        k += 1;
    }
    half
};

fn halfpel_planes_scalar(reference: &Plane, band: HalfpelBand<'_>) {
    // SAFETY: AVX2 off.
    unsafe { halfpel_planes_body::<false>(reference, band) }
}

/// The scalar patch ([`PatchFn`]): the planes' scalar kernel over the
/// patch's rectangle.
fn halfpel_patch18_scalar(reference: &Plane, origin: (isize, isize), out: &mut [u8]) {
    let (h, rest) = out.split_at_mut(PATCH18_PHASE);
    let (v, rest) = rest.split_at_mut(PATCH18_PHASE);
    let band = HalfpelBand {
        origin,
        rows: PATCH18_ROWS,
        span: PATCH18_STRIDE,
        out: [h, v, &mut rest[..PATCH18_PHASE]],
        out_x: 0,
        stride: PATCH18_STRIDE,
    };
    halfpel_planes_scalar(reference, band);
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::HalfpelBand;
    use crate::codec::Plane;
    crate::codec::compiled_for! { "avx2":
        fn halfpel_planes(reference: &Plane, band: HalfpelBand<'_>)
            => super::halfpel_planes_body::<true>;
        fn halfpel_patch18(reference: &Plane, origin: (isize, isize), out: &mut [u8])
            => super::x86_halfpel::patch18_avx2;
        fn box_sums(data: &[u8], stride: usize, rows: usize, side: usize, out: &mut [u16])
            => crate::me::sea::box_sums;
        fn ads(rows: [&[u16]; 4], current: [u16; 4], out: &mut [u16]) -> u16 => crate::me::sea::ads;
    }
}

/// The planes, for any instruction set; `AVX2` takes the diagonal phase's
/// vertical pass to AVX2 intrinsics.
///
/// # Safety
/// `AVX2` is true only where the CPU has AVX2.
#[inline(always)]
unsafe fn halfpel_planes_body<const AVX2: bool>(reference: &Plane, band: HalfpelBand<'_>) {
    let clip = |v: i32| v.clamp(0, 255) as u8;
    // The rounding of a pass's 16-bit sum in 16 bits (exact: the sum is at
    // most 22440), which vectorises twice as wide as in 32.
    let round16 = |v: i16| ((v + 32) >> 6).clamp(0, 255) as u8;
    let HalfpelBand {
        origin: (left, top),
        rows: band_rows,
        span,
        out: [plane_h, plane_v, plane_d],
        out_x: x0,
        stride,
    } = band;
    // Unrounded horizontal pass (within i16: -6120..=22440) of the rows
    // the band's vertical filters read: top - 3 .. top + rows + 4.
    let rows = band_rows + 7;
    let mut hpass = HPASS.with(|b| std::mem::take(&mut *b.borrow_mut()));
    // Every entry is assigned by the first tap below: no need to clear
    // what a previous picture left.
    hpass.resize(rows * span, 0);
    for (r, out) in hpass[..rows * span].chunks_exact_mut(span).enumerate() {
        let src = &reference.data()[reference.index(left - 3, top + r as isize - 3)..];
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: the caller's contract: AVX2 only where the CPU has it.
            unsafe { x86_halfpel::horizontal_row_avx2(&src[..span + 7], out) };
            continue;
        }
        filter_run(out, |k| &src[k..k + span]);
    }
    let hrow = |i: usize| &hpass[i * span..(i + 1) * span];
    // The scalar passes' rows (not allocated where AVX2 does without).
    let mut acc16 = if AVX2 { Vec::new() } else { vec![0i16; span] };
    let mut acc32 = if AVX2 { Vec::new() } else { vec![0i32; span] };
    for i in 0..band_rows {
        let (y, at) = (top + i as isize, i * stride + x0);
        for (o, &v) in plane_h[at..at + span].iter_mut().zip(hrow(i + 3)) {
            *o = round16(v);
        }
        let taps: [&[u8]; 8] = std::array::from_fn(|k| {
            let from = reference.index(left, y - 3 + k as isize);
            &reference.data()[from..from + span]
        });
        #[cfg(target_arch = "x86_64")]
        let vertical_done = AVX2 && {
            // SAFETY: the caller's contract: AVX2 only where the CPU has it.
            unsafe { x86_halfpel::vertical_row_avx2(&taps, &mut plane_v[at..at + span]) };
            true
        };
        #[cfg(not(target_arch = "x86_64"))]
        let vertical_done = false;
        if !vertical_done {
            filter_run(&mut acc16, |k| taps[k]);
            for (o, &v) in plane_v[at..at + span].iter_mut().zip(&acc16) {
                *o = round16(v);
            }
        }
        let out = &mut plane_d[at..at + span];
        let rows: [&[i16]; 8] = std::array::from_fn(|k| hrow(i + k));
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: the caller's contract: AVX2 only where the CPU has it.
            unsafe { x86_halfpel::diagonal_row_avx2(&rows, out) };
            continue;
        }
        acc32.fill(0);
        for (&t, row) in HALF.iter().zip(rows) {
            for (a, &v) in acc32.iter_mut().zip(row) {
                *a += i32::from(t) * i32::from(v);
            }
        }
        for (o, &v) in out.iter_mut().zip(&acc32) {
            *o = clip(((v >> 6) + 32) >> 6);
        }
    }
    HPASS.with(|b| *b.borrow_mut() = hpass);
}

/// `out[x] = sum_k HALF[k] * tap(k)[x]`, sixteen outputs at a time with
/// all eight taps summed in registers (one store per output, not one per
/// tap; a bounds check per tap and run). Each `tap(k)` holds `out.len()`
/// samples. Unrounded: within i16 for 8-bit samples (-6120..=22440).
#[inline(always)]
fn filter_run<'a>(out: &mut [i16], tap: impl Fn(usize) -> &'a [u8]) {
    const RUN: usize = 16;
    let n = out.len();
    let taps: [&[u8]; 8] = std::array::from_fn(|k| &tap(k)[..n]);
    let mut runs = out.chunks_exact_mut(RUN);
    for (i, run) in runs.by_ref().enumerate() {
        let x0 = i * RUN;
        let mut acc = [0i16; RUN];
        for (&t, samples) in HALF.iter().zip(&taps) {
            let window: &[u8; RUN] = samples[x0..x0 + RUN].try_into().expect("a run inside the row");
            for (a, &v) in acc.iter_mut().zip(window) {
                *a += t * i16::from(v);
            }
        }
        run.copy_from_slice(&acc);
    }
    let whole = n / RUN * RUN;
    for (j, o) in runs.into_remainder().iter_mut().enumerate() {
        *o = HALF
            .iter()
            .zip(&taps)
            .map(|(&t, s)| t * i16::from(s[whole + j]))
            .sum();
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{capped_by_halves, check_bounds, PixelDsp};

    pub const SSE2: PixelDsp = PixelDsp {
        sad: sad_sse2,
        satd: satd_sse2,
        satd_4x4_pair: satd_4x4_pair_sse2,
        satd_4x4_quad: satd_4x4_quad_sse2,
        intra_satd_x3_16x16: super::intra_satd_x3_16x16,
        satd_16x16_capped: satd_16x16_capped_sse2,
        halfpel_planes: super::halfpel_planes_scalar,
        halfpel_patch18: super::halfpel_patch18_scalar,
        copy_16x16: super::x86_halfpel::copy_16x16,
        average_16x16: super::x86_halfpel::average_16x16,
        average_8x8: super::x86_halfpel::average_8x8,
        box_sums: crate::me::sea::box_sums,
        ads: crate::me::sea::ads,
        group_sums: group_sums_sse2,
        abs_count: abs_count_sse2,
        sad_16x16_row: |a, sa, b, sb, out| super::sad_16x16_row_with(sad_sse2, a, sa, b, sb, out),
    };

    /// [`super::AbsCountFn`] 16 samples at a time: `psadbw` against the
    /// level for the distances; `v <= c` where `v - c` saturates to 0,
    /// counted by `psadbw` of those bytes' ones. The columns past the last
    /// multiple of 16 by the scalar kernel.
    fn abs_count_sse2(data: &[u8], stride: usize, (width, rows): (usize, usize), c: u8) -> (u64, u64) {
        super::check_abs_count(data, stride, (width, rows));
        let wide = width - width % 16;
        // SAFETY: SSE2 is part of x86-64; each row's first `wide` samples
        // lie inside the checked rows.
        let (mut total, mut at_or_below) = unsafe {
            let (level, ones, zero) = (_mm_set1_epi8(c as i8), _mm_set1_epi8(1), _mm_setzero_si128());
            let (mut distance, mut count) = (zero, zero);
            for r in 0..rows {
                let row = data.as_ptr().add(r * stride);
                for x in (0..wide).step_by(16) {
                    let v = _mm_loadu_si128(row.add(x) as *const __m128i);
                    distance = _mm_add_epi64(distance, _mm_sad_epu8(v, level));
                    let below = _mm_cmpeq_epi8(_mm_subs_epu8(v, level), zero);
                    count = _mm_add_epi64(count, _mm_sad_epu8(_mm_and_si128(below, ones), zero));
                }
            }
            let lanes =
                |v: __m128i| _mm_cvtsi128_si64(v) as u64 + _mm_cvtsi128_si64(_mm_unpackhi_epi64(v, v)) as u64;
            (lanes(distance), lanes(count))
        };
        if wide < width && rows > 0 {
            let (t, n) = super::abs_count(&data[wide..], stride, (width - wide, rows), c);
            total += t;
            at_or_below += n;
        }
        (total, at_or_below)
    }

    /// [`super::GroupSumsFn`] by `psadbw` against zero: 16 samples of a row
    /// give two groups' sums, added down the band's rows; the columns past
    /// the last multiple of 16 by the scalar kernel.
    fn group_sums_sse2(data: &[u8], stride: usize, (width, rows): (usize, usize), out: &mut [u32]) {
        super::check_group_sums(data, stride, (width, rows), out);
        let wide = width - width % 16;
        for x in (0..wide).step_by(16) {
            // SAFETY: SSE2 is part of x86-64; each row's 16 samples from x
            // lie inside the checked band.
            let (a, b) = unsafe {
                let mut acc = _mm_setzero_si128();
                for r in 0..rows {
                    let v = _mm_loadu_si128(data.as_ptr().add(r * stride + x) as *const __m128i);
                    acc = _mm_add_epi64(acc, _mm_sad_epu8(v, _mm_setzero_si128()));
                }
                (
                    _mm_cvtsi128_si32(acc),
                    _mm_cvtsi128_si32(_mm_unpackhi_epi64(acc, acc)),
                )
            };
            out[x / 8] = a as u32;
            out[x / 8 + 1] = b as u32;
        }
        if wide < width {
            super::group_sums(&data[wide..], stride, (width - wide, rows), &mut out[wide / 8..]);
        }
    }
    pub const AVX2: PixelDsp = PixelDsp {
        sad: sad_avx2,
        satd: satd_avx2,
        satd_4x4_pair: satd_4x4_pair_sse2,
        satd_4x4_quad: super::intra::x86::satd_4x4_quad_avx2,
        intra_satd_x3_16x16: super::intra::x86::intra_satd_x3_16x16_avx2,
        satd_16x16_capped: satd_16x16_capped_avx2,
        halfpel_planes: super::avx2::halfpel_planes,
        halfpel_patch18: super::avx2::halfpel_patch18,
        box_sums: super::avx2::box_sums,
        ads: super::avx2::ads,
        sad_16x16_row: sad_16x16_row_avx2,
        abs_count: abs_count_avx2,
        group_sums: group_sums_avx2,
        ..SSE2
    };

    /// [`super::GroupSumsFn`] 32 samples a row at a time: `psadbw` against
    /// zero gives the four groups' sums in the four 64-bit lanes; the
    /// columns past the last multiple of 32 by the SSE2 kernel.
    fn group_sums_avx2(data: &[u8], stride: usize, (width, rows): (usize, usize), out: &mut [u32]) {
        super::check_group_sums(data, stride, (width, rows), out);
        let wide = width - width % 32;
        for x in (0..wide).step_by(32) {
            // SAFETY: AVX2 was detected before this set was chosen; each
            // row's 32 samples from x lie inside the checked band.
            let sums = unsafe { group_sums_32(data, stride, rows, x) };
            for (o, &s) in out[x / 8..x / 8 + 4].iter_mut().zip(&sums) {
                *o = s as u32;
            }
        }
        if wide < width {
            group_sums_sse2(&data[wide..], stride, (width - wide, rows), &mut out[wide / 8..]);
        }
    }

    #[target_feature(enable = "avx2")]
    unsafe fn group_sums_32(data: &[u8], stride: usize, rows: usize, x: usize) -> [u64; 4] {
        let mut acc = _mm256_setzero_si256();
        for r in 0..rows {
            // SAFETY: the caller's: 32 samples from x on each row.
            let v = unsafe { _mm256_loadu_si256(data.as_ptr().add(r * stride + x) as *const __m256i) };
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(v, _mm256_setzero_si256()));
        }
        let mut sums = [0u64; 4];
        // SAFETY: 32 bytes into a 32-byte array.
        unsafe { _mm256_storeu_si256(sums.as_mut_ptr() as *mut __m256i, acc) };
        sums
    }

    /// [`abs_count_sse2`] 32 samples at a time; the columns past the last
    /// multiple of 32 by the SSE2 kernel.
    fn abs_count_avx2(data: &[u8], stride: usize, (width, rows): (usize, usize), c: u8) -> (u64, u64) {
        super::check_abs_count(data, stride, (width, rows));
        let wide = width - width % 32;
        // SAFETY: AVX2 was detected before this set was chosen; the rows
        // were checked above.
        let (mut total, mut at_or_below) = unsafe { abs_count_avx2_raw(data, stride, (wide, rows), c) };
        if wide < width && rows > 0 {
            let (t, n) = abs_count_sse2(&data[wide..], stride, (width - wide, rows), c);
            total += t;
            at_or_below += n;
        }
        (total, at_or_below)
    }

    #[target_feature(enable = "avx2")]
    unsafe fn abs_count_avx2_raw(
        data: &[u8],
        stride: usize,
        (wide, rows): (usize, usize),
        c: u8,
    ) -> (u64, u64) {
        let (level, ones, zero) = (
            _mm256_set1_epi8(c as i8),
            _mm256_set1_epi8(1),
            _mm256_setzero_si256(),
        );
        let (mut distance, mut count) = (zero, zero);
        for r in 0..rows {
            // SAFETY: the caller's rows hold `wide` samples each.
            let row = unsafe { data.as_ptr().add(r * stride) };
            for x in (0..wide).step_by(32) {
                // SAFETY: as above, x + 32 <= wide.
                let v = unsafe { _mm256_loadu_si256(row.add(x) as *const __m256i) };
                distance = _mm256_add_epi64(distance, _mm256_sad_epu8(v, level));
                let below = _mm256_cmpeq_epi8(_mm256_subs_epu8(v, level), zero);
                count = _mm256_add_epi64(count, _mm256_sad_epu8(_mm256_and_si256(below, ones), zero));
            }
        }
        let lanes = |v: __m256i| {
            let mut l = [0u64; 4];
            // SAFETY: 32 bytes into a 32-byte array.
            unsafe { _mm256_storeu_si256(l.as_mut_ptr() as *mut __m256i, v) };
            l.iter().sum::<u64>()
        };
        (lanes(distance), lanes(count))
    }

    fn sad_16x16_row_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, out: &mut [u32; 16]) -> u32 {
        super::check_sad_row(a, sa, b, sb);
        // SAFETY: AVX2 was detected before this set was chosen; bounds
        // checked above.
        unsafe { sad_16x16_row_avx2_raw(a.as_ptr(), sa, b.as_ptr(), sb, out) }
    }

    /// `mpsadbw` gives, per 128-bit lane, the SADs of one 4-byte group of
    /// the block against 8 consecutive windows of the reference: lane 0
    /// reads from column 0 (positions 0-7), lane 1 from column 8 (8-15).
    /// Group g of a row needs the reference from column 4g: the immediate
    /// picks the group (bits 0-1, 3-4) and a 4-column step (bits 2, 5), so
    /// two loads serve the four groups. Sums stay within u16 (at most
    /// 256 x 255).
    #[target_feature(enable = "avx2")]
    unsafe fn sad_16x16_row_avx2_raw(
        a: *const u8,
        sa: usize,
        b: *const u8,
        sb: usize,
        out: &mut [u32; 16],
    ) -> u32 {
        let mut acc = _mm256_setzero_si256();
        for r in 0..16 {
            let block = _mm256_broadcastsi128_si256(_mm_loadu_si128(a.add(r * sa) as *const __m128i));
            let row = b.add(r * sb);
            let from0 = _mm256_loadu2_m128i(row.add(8) as *const __m128i, row as *const __m128i);
            let from8 = _mm256_loadu2_m128i(row.add(16) as *const __m128i, row.add(8) as *const __m128i);
            let g0 = _mm256_mpsadbw_epu8::<0b000_000>(from0, block);
            let g1 = _mm256_mpsadbw_epu8::<0b101_101>(from0, block);
            let g2 = _mm256_mpsadbw_epu8::<0b010_010>(from8, block);
            let g3 = _mm256_mpsadbw_epu8::<0b111_111>(from8, block);
            let sum = _mm256_add_epi16(_mm256_add_epi16(g0, g1), _mm256_add_epi16(g2, g3));
            acc = _mm256_add_epi16(acc, sum);
        }
        let (lo, hi) = (_mm256_castsi256_si128(acc), _mm256_extracti128_si256::<1>(acc));
        _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, _mm256_cvtepu16_epi32(lo));
        _mm256_storeu_si256(out.as_mut_ptr().add(8) as *mut __m256i, _mm256_cvtepu16_epi32(hi));
        // The least of the 16 (phminposuw: the least u16 of a register).
        (_mm_cvtsi128_si32(_mm_minpos_epu16(_mm_min_epu16(lo, hi))) & 0xffff) as u32
    }

    fn satd_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        if w == 8 && h % 8 == 0 {
            // SAFETY: AVX2 was detected before this set was chosen; every
            // 8x8 block lies inside the checked one.
            return unsafe { satd_8xn_avx2(a.as_ptr(), sa, b.as_ptr(), sb, h) };
        }
        if w % 16 != 0 || h % 4 != 0 {
            return satd_sse2(a, sa, b, sb, w, h);
        }
        // SAFETY (both calls): AVX2 was detected before this set was
        // chosen; every 16x4 region lies inside the checked block.
        if w == 16 && h == 16 {
            // The macroblock: its four strips in one call, one reduction.
            return unsafe { satd_16x16_avx2(a.as_ptr(), sa, b.as_ptr(), sb, u32::MAX) };
        }
        let mut acc = [0u32; 8];
        {
            for ty in (0..h).step_by(4) {
                for tx in (0..w).step_by(16) {
                    unsafe {
                        hadamard_abs_16x4_avx2(
                            a.as_ptr().add(ty * sa + tx),
                            sa,
                            b.as_ptr().add(ty * sb + tx),
                            sb,
                            &mut acc,
                        )
                    };
                }
            }
        }
        acc.iter().sum::<u32>().div_ceil(2)
    }

    /// SATD of an 8-wide block of `h` rows (a multiple of 8), an 8x8 block
    /// a step (one step of the 16x4 region's transform each).
    #[target_feature(enable = "avx2")]
    unsafe fn satd_8xn_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm256_setzero_si256();
        for ty in (0..h).step_by(8) {
            let pairs = hadamard_8x8_last_pairs(a.add(ty * sa), sa, b.add(ty * sb), sb);
            acc = _mm256_add_epi32(acc, abs_sum_lanes(pairs));
        }
        let mut lanes = [0u32; 8];
        _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, acc);
        lanes.iter().sum::<u32>().div_ceil(2)
    }

    fn satd_16x16_capped_sse2(a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
        capped_by_halves(satd_sse2, a, sa, b, sb, cap)
    }

    fn satd_16x16_capped_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, cap: u32) -> u32 {
        check_bounds(a, sa, b, sb, 16, 16);
        // SAFETY: AVX2 was detected before this set was chosen; the blocks
        // lie inside the checked slices.
        unsafe { satd_16x16_avx2(a.as_ptr(), sa, b.as_ptr(), sb, cap) }
    }

    /// The SATD of a 16x16 block: [`hadamard_abs_16x4_avx2`] over its four
    /// strips with x264's shortcut for the last butterfly, |p + q| +
    /// |p - q| = 2 max(|p|, |q|), so that the halved sum is the sum of the
    /// maxima (at most 8 * 255 each, eight a lane: they add up in 16 bits).
    /// Stops after the top half when its SATD exceeds `cap` ([`CappedFn`]).
    #[target_feature(enable = "avx2")]
    unsafe fn satd_16x16_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, cap: u32) -> u32 {
        let mut sum16 = _mm256_setzero_si256();
        for ty in (0..16).step_by(4) {
            if ty == 8 {
                let top = sum_u16_lanes(sum16);
                if top > cap {
                    return top;
                }
            }
            let (pq0, pq1) = hadamard_16x4_last_pairs(a.add(ty * sa), sa, b.add(ty * sb), sb);
            for (p, q) in [pq0, pq1] {
                sum16 = _mm256_add_epi16(sum16, _mm256_max_epi16(_mm256_abs_epi16(p), _mm256_abs_epi16(q)));
            }
        }
        sum_u16_lanes(sum16)
    }

    /// The sum of the sixteen 16-bit lanes (each at most 2^15).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn sum_u16_lanes(v: __m256i) -> u32 {
        let v = _mm256_madd_epi16(v, _mm256_set1_epi16(1));
        let s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b01_00_11_10>(s));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b10_11_00_01>(s));
        _mm_cvtsi128_si32(s) as u32
    }

    /// The 16x4 region's transform up to its last butterfly: the two
    /// (p, q) pairs whose sums and differences are the coefficients.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_16x4_last_pairs(
        a: *const u8,
        sa: usize,
        b: *const u8,
        sb: usize,
    ) -> ((__m256i, __m256i), (__m256i, __m256i)) {
        let row = |r: usize| {
            let x = _mm256_cvtepu8_epi16(_mm_loadu_si128(a.add(r * sa) as *const __m128i));
            let y = _mm256_cvtepu8_epi16(_mm_loadu_si128(b.add(r * sb) as *const __m128i));
            _mm256_sub_epi16(x, y)
        };
        last_pairs([row(0), row(1), row(2), row(3)])
    }

    /// [`hadamard_16x4_last_pairs`] of an 8x8 block: rows r and r + 4 side
    /// by side make the sixteen columns (the 4x4 tiles are independent, so
    /// their coefficients are the block's).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_8x8_last_pairs(
        a: *const u8,
        sa: usize,
        b: *const u8,
        sb: usize,
    ) -> ((__m256i, __m256i), (__m256i, __m256i)) {
        let halves = |p: *const u8, stride: usize, r: usize| {
            let top = _mm_loadl_epi64(p.add(r * stride) as *const __m128i);
            let bottom = _mm_loadl_epi64(p.add((r + 4) * stride) as *const __m128i);
            _mm256_cvtepu8_epi16(_mm_unpacklo_epi64(top, bottom))
        };
        let row = |r: usize| _mm256_sub_epi16(halves(a, sa, r), halves(b, sb, r));
        last_pairs([row(0), row(1), row(2), row(3)])
    }

    /// The transform of four rows of sixteen differences up to its last
    /// butterfly.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn last_pairs([r0, r1, r2, r3]: [__m256i; 4]) -> ((__m256i, __m256i), (__m256i, __m256i)) {
        let (s01, d01) = (_mm256_add_epi16(r0, r1), _mm256_sub_epi16(r0, r1));
        let (s23, d23) = (_mm256_add_epi16(r2, r3), _mm256_sub_epi16(r2, r3));
        let v0 = _mm256_add_epi16(s01, s23);
        let v1 = _mm256_sub_epi16(s01, s23);
        let v2 = _mm256_sub_epi16(d01, d23);
        let v3 = _mm256_add_epi16(d01, d23);
        let (t0, t1) = (_mm256_unpacklo_epi16(v0, v1), _mm256_unpacklo_epi16(v2, v3));
        let (t2, t3) = (_mm256_unpackhi_epi16(v0, v1), _mm256_unpackhi_epi16(v2, v3));
        let pair = |lo: __m256i, hi: __m256i| {
            let c01 = _mm256_unpacklo_epi32(lo, hi);
            let c23 = _mm256_unpackhi_epi32(lo, hi);
            let x = _mm256_unpacklo_epi64(c01, c23);
            let y = _mm256_unpackhi_epi64(c01, c23);
            let (s, d) = (_mm256_add_epi16(x, y), _mm256_sub_epi16(x, y));
            (_mm256_unpacklo_epi64(s, d), _mm256_unpackhi_epi64(s, d))
        };
        (pair(t0, t1), pair(t2, t3))
    }

    /// Adds the 16x4 region's absolute Hadamard coefficients to `acc`
    /// (eight partial sums).
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_abs_16x4_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, acc: &mut [u32; 8]) {
        let prior = _mm256_loadu_si256(acc.as_ptr() as *const __m256i);
        let v = _mm256_add_epi32(prior, hadamard_abs_16x4_lanes(a, sa, b, sb));
        _mm256_storeu_si256(acc.as_mut_ptr() as *mut __m256i, v);
    }

    /// The 16x4 region's absolute Hadamard coefficients in eight partial
    /// sums (columns 0-7 of the region in the low 128-bit lane, 8-15 in
    /// the high one: AVX2 unpacks work within lanes), by the last
    /// butterfly's shortcut |p + q| + |p - q| = 2 max(|p|, |q|).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hadamard_abs_16x4_lanes(a: *const u8, sa: usize, b: *const u8, sb: usize) -> __m256i {
        abs_sum_lanes(hadamard_16x4_last_pairs(a, sa, b, sb))
    }

    /// [`hadamard_abs_16x4_lanes`] of the pairs of a transform.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn abs_sum_lanes((pq0, pq1): ((__m256i, __m256i), (__m256i, __m256i))) -> __m256i {
        let mut acc = _mm256_setzero_si256();
        for (p, q) in [pq0, pq1] {
            let m = _mm256_max_epi16(_mm256_abs_epi16(p), _mm256_abs_epi16(q));
            acc = _mm256_add_epi32(acc, _mm256_madd_epi16(m, _mm256_set1_epi16(2)));
        }
        acc
    }

    fn satd_sse2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        if w % 8 != 0 || h % 4 != 0 {
            return super::satd(a, sa, b, sb, w, h);
        }
        let mut sum = 0u32;
        for ty in (0..h).step_by(4) {
            for tx in (0..w).step_by(8) {
                // SAFETY: SSE2 is part of x86-64; the 8x4 region lies inside
                // the checked block.
                sum += unsafe {
                    hadamard_abs_8x4_sse2(a.as_ptr().add(ty * sa + tx), sa, b.as_ptr().add(ty * sb + tx), sb)
                };
            }
        }
        sum.div_ceil(2)
    }

    /// Two pairs.
    fn satd_4x4_quad_sse2(a: &[u8; 32], b: &[[u8; 32]; 2]) -> [u32; 4] {
        let ([w, x], [y, z]) = (satd_4x4_pair_sse2(a, &b[0]), satd_4x4_pair_sse2(a, &b[1]));
        [w, x, y, z]
    }

    fn satd_4x4_pair_sse2(a: &[u8; 32], b: &[u8; 32]) -> [u32; 2] {
        // SAFETY: SSE2 is part of x86-64; both 8x4 blocks are the arrays.
        let [l, r] = unsafe { hadamard_abs_tiles_sse2(a.as_ptr(), 8, b.as_ptr(), 8) };
        [l.div_ceil(2), r.div_ceil(2)]
    }

    /// `sum |H D H^T|` over two side-by-side 4x4 tiles of `a - b`.
    #[target_feature(enable = "sse2")]
    unsafe fn hadamard_abs_8x4_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize) -> u32 {
        let [l, r] = hadamard_abs_tiles_sse2(a, sa, b, sb);
        l + r
    }

    /// `sum |H D H^T|` of each of two side-by-side 4x4 tiles of `a - b`.
    #[target_feature(enable = "sse2")]
    unsafe fn hadamard_abs_tiles_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize) -> [u32; 2] {
        let zero = _mm_setzero_si128();
        let row = |r: usize| {
            let x = _mm_unpacklo_epi8(_mm_loadl_epi64(a.add(r * sa) as *const __m128i), zero);
            let y = _mm_unpacklo_epi8(_mm_loadl_epi64(b.add(r * sb) as *const __m128i), zero);
            _mm_sub_epi16(x, y)
        };
        let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
        // Vertical butterflies (across rows), both tiles at once.
        let (s01, d01) = (_mm_add_epi16(r0, r1), _mm_sub_epi16(r0, r1));
        let (s23, d23) = (_mm_add_epi16(r2, r3), _mm_sub_epi16(r2, r3));
        let v0 = _mm_add_epi16(s01, s23);
        let v1 = _mm_sub_epi16(s01, s23);
        let v2 = _mm_sub_epi16(d01, d23);
        let v3 = _mm_add_epi16(d01, d23);
        // Transpose each tile into vectors holding two columns of four.
        let (t0, t1) = (_mm_unpacklo_epi16(v0, v1), _mm_unpacklo_epi16(v2, v3));
        let (t2, t3) = (_mm_unpackhi_epi16(v0, v1), _mm_unpackhi_epi16(v2, v3));
        let mut sums = [0u32; 2];
        for (tile, (lo, hi)) in [(t0, t1), (t2, t3)].into_iter().enumerate() {
            let mut acc = _mm_setzero_si128();
            let c01 = _mm_unpacklo_epi32(lo, hi); // columns 0 | 1
            let c23 = _mm_unpackhi_epi32(lo, hi); // columns 2 | 3
                                                  // Horizontal butterflies (across columns).
            let x = _mm_unpacklo_epi64(c01, c23); // c0 | c2
            let y = _mm_unpackhi_epi64(c01, c23); // c1 | c3
            let (s, d) = (_mm_add_epi16(x, y), _mm_sub_epi16(x, y));
            let p = _mm_unpacklo_epi64(s, d); // c0+c1 | c0-c1
            let q = _mm_unpackhi_epi64(s, d); // c2+c3 | c2-c3
            for v in [_mm_add_epi16(p, q), _mm_sub_epi16(p, q)] {
                // |v| for 16-bit lanes as max(v, -v): values stay within +-4080.
                let abs = _mm_max_epi16(v, _mm_sub_epi16(zero, v));
                acc = _mm_add_epi32(acc, _mm_madd_epi16(abs, _mm_set1_epi16(1)));
            }
            let s = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, 0b01_00_11_10));
            let s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0b10_11_00_01));
            sums[tile] = _mm_cvtsi128_si32(s) as u32;
        }
        sums
    }

    fn sad_sse2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        // SAFETY: SSE2 is part of x86-64; bounds checked above.
        unsafe {
            match w {
                16 => sad_w16_sse2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                8 => sad_w8_sse2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                _ if w % 16 == 0 => (0..w / 16)
                    .map(|k| sad_w16_sse2(a.as_ptr().add(16 * k), sa, b.as_ptr().add(16 * k), sb, h))
                    .sum(),
                _ => super::sad(a, sa, b, sb, w, h),
            }
        }
    }

    fn sad_avx2(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        check_bounds(a, sa, b, sb, w, h);
        // SAFETY: AVX2 was detected before this set was chosen; bounds
        // checked above.
        unsafe {
            match w {
                16 => sad_w16_avx2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                32 => sad_w32_avx2(a.as_ptr(), sa, b.as_ptr(), sb, h),
                _ => sad_sse2(a, sa, b, sb, w, h),
            }
        }
    }

    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn hsum_sad(v: __m128i) -> u32 {
        // psadbw leaves two 64-bit partial sums.
        (_mm_cvtsi128_si32(v) + _mm_cvtsi128_si32(_mm_unpackhi_epi64(v, v))) as u32
    }

    #[target_feature(enable = "sse2")]
    unsafe fn sad_w16_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm_setzero_si128();
        for r in 0..h {
            let x = _mm_loadu_si128(a.add(r * sa) as *const __m128i);
            let y = _mm_loadu_si128(b.add(r * sb) as *const __m128i);
            acc = _mm_add_epi64(acc, _mm_sad_epu8(x, y));
        }
        hsum_sad(acc)
    }

    #[target_feature(enable = "sse2")]
    unsafe fn sad_w8_sse2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm_setzero_si128();
        for r in 0..h {
            let x = _mm_loadl_epi64(a.add(r * sa) as *const __m128i);
            let y = _mm_loadl_epi64(b.add(r * sb) as *const __m128i);
            acc = _mm_add_epi64(acc, _mm_sad_epu8(x, y));
        }
        hsum_sad(acc)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn hsum_sad256(v: __m256i) -> u32 {
        let s = _mm_add_epi64(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
        hsum_sad(s)
    }

    #[target_feature(enable = "avx2")]
    unsafe fn sad_w16_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm256_setzero_si256();
        let mut r = 0;
        while r + 1 < h {
            let x = _mm256_loadu2_m128i(
                a.add((r + 1) * sa) as *const __m128i,
                a.add(r * sa) as *const __m128i,
            );
            let y = _mm256_loadu2_m128i(
                b.add((r + 1) * sb) as *const __m128i,
                b.add(r * sb) as *const __m128i,
            );
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(x, y));
            r += 2;
        }
        let mut sum = hsum_sad256(acc);
        if r < h {
            sum += sad_w16_sse2(a.add(r * sa), sa, b.add(r * sb), sb, 1);
        }
        sum
    }

    #[target_feature(enable = "avx2")]
    unsafe fn sad_w32_avx2(a: *const u8, sa: usize, b: *const u8, sb: usize, h: usize) -> u32 {
        let mut acc = _mm256_setzero_si256();
        for r in 0..h {
            let x = _mm256_loadu_si256(a.add(r * sa) as *const __m256i);
            let y = _mm256_loadu_si256(b.add(r * sb) as *const __m256i);
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(x, y));
        }
        hsum_sad256(acc)
    }
}

#[cfg(target_arch = "x86_64")]
mod x86_halfpel {
    use std::arch::x86_64::*;

    use super::HALF;

    /// The half-pel filter's constants in registers, made once per call of
    /// a kernel, and its three passes on one vector of outputs each.
    #[derive(Clone, Copy)]
    struct Filter {
        /// Tap pairs (2k, 2k + 1) as signed bytes, for `pmaddubsw` on
        /// sample pairs (each pair's sum is within i16: at most 40 * 255;
        /// the four pairs' sum too, -6120..=22440, as the scalar pass).
        taps: [__m256i; 4],
        /// The horizontal pass' shuffles of a row's samples into pairs:
        /// lane 0 from sample x (outputs x..x + 8), lane 1 from x + 7
        /// (outputs x + 8..x + 16: one sample later in the lane), so that
        /// the last load ends at the sixteenth output's last sample.
        order: [__m256i; 4],
        /// Tap pairs (k, k + 1) as 16-bit words, for `pmaddwd` on the
        /// diagonal pass' interleaved rows.
        pairs16: [__m256i; 4],
    }

    impl Filter {
        #[target_feature(enable = "avx2")]
        fn new() -> Filter {
            let taps = std::array::from_fn(|k| {
                let pair = (i32::from(HALF[2 * k + 1] as i8 as u8) << 8) | i32::from(HALF[2 * k] as i8 as u8);
                _mm256_set1_epi16(pair as i16)
            });
            let order = std::array::from_fn(|k| {
                let index = |lane: usize, b: usize| (b / 2 + 2 * k + b % 2 + lane) as i8;
                let lane = |l: usize| std::array::from_fn::<i8, 16, _>(|b| index(l, b));
                let (a, c) = (lane(0), lane(1));
                // SAFETY: 16 bytes each, unaligned loads.
                unsafe {
                    _mm256_inserti128_si256::<1>(
                        _mm256_castsi128_si256(_mm_loadu_si128(a.as_ptr() as *const __m128i)),
                        _mm_loadu_si128(c.as_ptr() as *const __m128i),
                    )
                }
            });
            let pairs16 = std::array::from_fn(|p| {
                let k = 2 * p;
                _mm256_set1_epi32((i32::from(HALF[k + 1]) << 16) | (i32::from(HALF[k]) & 0xffff))
            });
            Filter { taps, order, pairs16 }
        }

        /// Sixteen unrounded horizontal outputs, `sum_k HALF[k] p[x + k]`.
        ///
        /// # Safety
        /// `p` points at 23 readable samples.
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn horizontal16(&self, p: *const u8) -> __m256i {
            // SAFETY: the caller's 23 samples.
            let samples = unsafe {
                _mm256_inserti128_si256::<1>(
                    _mm256_castsi128_si256(_mm_loadu_si128(p as *const __m128i)),
                    _mm_loadu_si128(p.add(7) as *const __m128i),
                )
            };
            let mut acc = _mm256_maddubs_epi16(_mm256_shuffle_epi8(samples, self.order[0]), self.taps[0]);
            for k in 1..4 {
                let pairs = _mm256_shuffle_epi8(samples, self.order[k]);
                acc = _mm256_add_epi16(acc, _mm256_maddubs_epi16(pairs, self.taps[k]));
            }
            acc
        }

        /// 32 vertical outputs, rounded: `clip((sum_k HALF[k] rows[k][x] +
        /// 32) >> 6)`, rows interleaved in pairs for one `pmaddubsw` per
        /// tap pair, rounded in 16 bits, packed (the in-lane unpacks and
        /// the pack undo each other's order).
        ///
        /// # Safety
        /// Each of `rows` points at 32 readable samples.
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn vertical32(&self, rows: [*const u8; 8]) -> __m256i {
            let (mut lo, mut hi) = (_mm256_setzero_si256(), _mm256_setzero_si256());
            for (k, t) in self.taps.iter().enumerate() {
                // SAFETY: the caller's 32 samples a row.
                let (a, b) = unsafe {
                    (
                        _mm256_loadu_si256(rows[2 * k] as *const __m256i),
                        _mm256_loadu_si256(rows[2 * k + 1] as *const __m256i),
                    )
                };
                lo = _mm256_add_epi16(lo, _mm256_maddubs_epi16(_mm256_unpacklo_epi8(a, b), *t));
                hi = _mm256_add_epi16(hi, _mm256_maddubs_epi16(_mm256_unpackhi_epi8(a, b), *t));
            }
            let round = _mm256_set1_epi16(32);
            let lo = _mm256_srai_epi16::<6>(_mm256_add_epi16(lo, round));
            let hi = _mm256_srai_epi16::<6>(_mm256_add_epi16(hi, round));
            _mm256_packus_epi16(lo, hi)
        }

        /// Sixteen diagonal outputs: the filter down eight rows of the
        /// unrounded horizontal pass, taps in pairs, each pair one
        /// `pmaddwd` of two interleaved rows (exact 32-bit sums, as the
        /// scalar pass), then `((v >> 6) + 32) >> 6` saturated to 8 bits.
        ///
        /// # Safety
        /// Each of `rows` points at 16 readable values.
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn diagonal16(&self, rows: [*const i16; 8]) -> __m128i {
            let round = _mm256_set1_epi32(32);
            let finish =
                |v: __m256i| _mm256_srai_epi32::<6>(_mm256_add_epi32(_mm256_srai_epi32::<6>(v), round));
            let (mut lo, mut hi) = (_mm256_setzero_si256(), _mm256_setzero_si256());
            for (p, c) in self.pairs16.iter().enumerate() {
                // SAFETY: the caller's 16 values (32 bytes) a row.
                let (a, b) = unsafe {
                    (
                        _mm256_loadu_si256(rows[2 * p] as *const __m256i),
                        _mm256_loadu_si256(rows[2 * p + 1] as *const __m256i),
                    )
                };
                lo = _mm256_add_epi32(lo, _mm256_madd_epi16(_mm256_unpacklo_epi16(a, b), *c));
                hi = _mm256_add_epi32(hi, _mm256_madd_epi16(_mm256_unpackhi_epi16(a, b), *c));
            }
            // Per 128-bit lane lo holds columns 0-3 and hi 4-7 (then 8-11,
            // 12-15): the packs restore column order within each lane.
            let words = _mm256_packs_epi32(finish(lo), finish(hi));
            let bytes = _mm256_permute4x64_epi64::<0b00_00_10_00>(_mm256_packus_epi16(words, words));
            _mm256_castsi256_si128(bytes)
        }
    }

    /// A 16x16 block's half-pel patch ([`super::PatchFn`]) in one pass:
    /// the horizontal pass of its 25 rows into registers' worth of a
    /// local buffer, then each row's three phases, with the filter's
    /// constants made once (the planes' row kernels, called per row of 32,
    /// spend more on their set-up than on the row).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn patch18_avx2(
        reference: &crate::codec::Plane,
        (x0, y0): (isize, isize),
        out: &mut [u8],
    ) {
        use super::{PATCH18_PHASE as PHASE, PATCH18_ROWS as ROWS, PATCH18_STRIDE as W};
        assert!(out.len() >= 3 * PHASE, "a half-pel patch past its buffer");
        let stride = reference.stride();
        // Samples read: rows y0 - 3 ..= y0 + ROWS + 3, columns x0 - 3 ..
        // x0 + W + 4 (the last horizontal load's).
        let first = reference.index(x0 - 3, y0 - 3);
        assert!(
            first + (ROWS + 6) * stride + W + 7 <= reference.data().len(),
            "a half-pel patch past its reference"
        );
        // SAFETY: `first` is inside the reference's buffer (asserted).
        let base = unsafe { reference.data().as_ptr().add(first) };
        let filter = Filter::new();
        // Every value is stored below before any is read: not cleared
        // first (1600 bytes a searched macroblock).
        let mut first_pass = std::mem::MaybeUninit::<[[i16; W]; ROWS + 7]>::uninit();
        let rows = first_pass.as_mut_ptr() as *mut i16;
        for r in 0..ROWS + 7 {
            // SAFETY: row r's 39 samples from `base` (asserted), and the
            // 32 values of row r of `first_pass`.
            unsafe {
                let (p, row) = (base.add(r * stride), rows.add(r * W));
                _mm256_storeu_si256(row as *mut __m256i, filter.horizontal16(p));
                _mm256_storeu_si256(row.add(16) as *mut __m256i, filter.horizontal16(p.add(16)));
            }
        }
        // SAFETY: all ROWS + 7 rows of W values were stored above.
        let hpass = unsafe { first_pass.assume_init_ref() };
        let (h, rest) = out.split_at_mut(PHASE);
        let (v, rest) = rest.split_at_mut(PHASE);
        let d = &mut rest[..PHASE];
        let round = _mm256_set1_epi16(32);
        for i in 0..ROWS {
            let at = i * W;
            // SAFETY: every load is within `hpass` or the asserted
            // reference rows; every store within its phase's row `i`.
            unsafe {
                let centre = hpass[i + 3].as_ptr();
                let a = _mm256_loadu_si256(centre as *const __m256i);
                let b = _mm256_loadu_si256(centre.add(16) as *const __m256i);
                let a = _mm256_srai_epi16::<6>(_mm256_add_epi16(a, round));
                let b = _mm256_srai_epi16::<6>(_mm256_add_epi16(b, round));
                // The pack interleaves the halves' lanes: back in order.
                let bytes = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packus_epi16(a, b));
                _mm256_storeu_si256(h.as_mut_ptr().add(at) as *mut __m256i, bytes);
                let taps = std::array::from_fn(|k| base.add((i + k) * stride + 3));
                _mm256_storeu_si256(v.as_mut_ptr().add(at) as *mut __m256i, filter.vertical32(taps));
                for half in [0, 16] {
                    let rows = std::array::from_fn(|k| hpass[i + k].as_ptr().add(half));
                    _mm_storeu_si128(
                        d.as_mut_ptr().add(at + half) as *mut __m128i,
                        filter.diagonal16(rows),
                    );
                }
            }
        }
    }

    /// The unrounded horizontal pass of one row, `out[x] = sum_k HALF[k]
    /// src[x + k]` (`src` holds `out.len() + 7` samples), sixteen outputs
    /// at a time ([`Filter::horizontal16`]). The columns past the last
    /// multiple of 16 as the row's last sixteen (scalar in rows shorter
    /// than that).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn horizontal_row_avx2(src: &[u8], out: &mut [i16]) {
        let n = out.len();
        assert!(
            src.len() >= n + 7,
            "a row of the horizontal pass past its samples"
        );
        let filter = Filter::new();
        // Sixteen outputs from x (x + 16 <= n: the loads end within src).
        let chunk = |x: usize, out: &mut [i16]| {
            debug_assert!(x + 16 <= n);
            // SAFETY: x + 7 + 16 <= n + 7 <= src.len() (asserted above);
            // x + 16 <= out.len().
            unsafe {
                let acc = filter.horizontal16(src.as_ptr().add(x));
                _mm256_storeu_si256(out.as_mut_ptr().add(x) as *mut __m256i, acc);
            }
        };
        let mut x = 0;
        while x + 16 <= n {
            chunk(x, out);
            x += 16;
        }
        // The last columns as the last sixteen again (the same values
        // written twice), where the row has sixteen.
        if x < n && n >= 16 {
            chunk(n - 16, out);
            return;
        }
        for (j, o) in out.iter_mut().enumerate().skip(x) {
            *o = HALF
                .iter()
                .enumerate()
                .map(|(k, &t)| t * i16::from(src[j + k]))
                .sum();
        }
    }

    /// The vertical phase of one row, rounded: `out[x] = clip((sum_k
    /// HALF[k] rows[k][x] + 32) >> 6)` (each row holds `out.len()`
    /// samples), 32 outputs at a time ([`Filter::vertical32`]). The
    /// columns past the last multiple of 32 as the row's last 32 (scalar
    /// in rows shorter than that).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn vertical_row_avx2(rows: &[&[u8]; 8], out: &mut [u8]) {
        let n = out.len();
        assert!(
            rows.iter().all(|r| r.len() >= n),
            "a row of the vertical pass past its samples"
        );
        let filter = Filter::new();
        let chunk = |x: usize, out: &mut [u8]| {
            debug_assert!(x + 32 <= n);
            // SAFETY: x + 32 <= n <= every row's length (asserted) and
            // out's.
            unsafe {
                let v = filter.vertical32(rows.map(|r| r.as_ptr().add(x)));
                _mm256_storeu_si256(out.as_mut_ptr().add(x) as *mut __m256i, v);
            }
        };
        let mut x = 0;
        while x + 32 <= n {
            chunk(x, out);
            x += 32;
        }
        // The last columns as the last 32 again, where the row has 32.
        if x < n && n >= 32 {
            chunk(n - 32, out);
            return;
        }
        for (j, o) in out.iter_mut().enumerate().skip(x) {
            let v: i16 = HALF.iter().zip(rows).map(|(&t, r)| t * i16::from(r[j])).sum();
            *o = ((v + 32) >> 6).clamp(0, 255) as u8;
        }
    }

    /// Panics unless a `16 x 16` block at stride `stride` fits in `len`.
    fn check_16x16(len: usize, stride: usize) {
        assert!(
            stride >= 16 && len >= 15 * stride + 16,
            "16x16 block past its slice"
        );
    }

    /// [`super::copy_rows`] at 16 in SSE2 moves (bounds checked once).
    pub(super) fn copy_16x16(a: &[u8], sa: usize, out: &mut [u8]) {
        check_16x16(a.len(), sa);
        check_16x16(out.len(), 16);
        for r in 0..16 {
            // SAFETY: rows 0..16 of both blocks lie inside their slices
            // (checked above); SSE2 is part of x86-64.
            unsafe {
                let v = _mm_loadu_si128(a.as_ptr().add(r * sa) as *const __m128i);
                _mm_storeu_si128(out.as_mut_ptr().add(r * 16) as *mut __m128i, v);
            }
        }
    }

    /// [`super::average_rows`] at 16: `pavgb` is exactly
    /// `(u + v + 1) >> 1` (bounds checked once).
    pub(super) fn average_16x16((a, sa): (&[u8], usize), (c, sc): (&[u8], usize), out: &mut [u8]) {
        check_16x16(a.len(), sa);
        check_16x16(c.len(), sc);
        check_16x16(out.len(), 16);
        for r in 0..16 {
            // SAFETY: as in copy_16x16.
            unsafe {
                let x = _mm_loadu_si128(a.as_ptr().add(r * sa) as *const __m128i);
                let y = _mm_loadu_si128(c.as_ptr().add(r * sc) as *const __m128i);
                _mm_storeu_si128(out.as_mut_ptr().add(r * 16) as *mut __m128i, _mm_avg_epu8(x, y));
            }
        }
    }

    /// [`super::average_rows`] at 8 (the partitions' blocks), as
    /// [`average_16x16`] with 8-byte loads.
    pub(super) fn average_8x8((a, sa): (&[u8], usize), (c, sc): (&[u8], usize), out: &mut [u8]) {
        let fits = |len: usize, stride: usize| stride >= 8 && len >= 7 * stride + 8;
        assert!(
            fits(a.len(), sa) && fits(c.len(), sc) && fits(out.len(), 8),
            "8x8 block past its slice"
        );
        for r in 0..8 {
            // SAFETY: rows 0..8 of the three blocks lie inside their
            // slices (checked above); SSE2 is part of x86-64.
            unsafe {
                let x = _mm_loadl_epi64(a.as_ptr().add(r * sa) as *const __m128i);
                let y = _mm_loadl_epi64(c.as_ptr().add(r * sc) as *const __m128i);
                _mm_storel_epi64(out.as_mut_ptr().add(r * 8) as *mut __m128i, _mm_avg_epu8(x, y));
            }
        }
    }

    /// One row of the diagonal phase, sixteen outputs at a time
    /// ([`Filter::diagonal16`]); the columns past the last multiple of 16
    /// as the row's last sixteen (scalar in rows shorter than that).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn diagonal_row_avx2(rows: &[&[i16]; 8], out: &mut [u8]) {
        let n = out.len();
        assert!(
            rows.iter().all(|r| r.len() >= n),
            "a row of the diagonal pass past its samples"
        );
        let filter = Filter::new();
        let chunk = |x: usize, out: &mut [u8]| {
            debug_assert!(x + 16 <= n);
            // SAFETY: x + 16 <= n <= every row's length (asserted) and
            // out's.
            unsafe {
                let v = filter.diagonal16(rows.map(|r| r.as_ptr().add(x)));
                _mm_storeu_si128(out.as_mut_ptr().add(x) as *mut __m128i, v);
            }
        };
        let mut x = 0;
        while x + 16 <= n {
            chunk(x, out);
            x += 16;
        }
        // The last columns as the last sixteen again, where the row has
        // sixteen.
        if x < n && n >= 16 {
            chunk(n - 16, out);
            return;
        }
        for (c, o) in out.iter_mut().enumerate().skip(x) {
            let v: i32 = HALF
                .iter()
                .zip(rows)
                .map(|(&t, r)| i32::from(t) * i32::from(r[c]))
                .sum();
            *o = (((v >> 6) + 32) >> 6).clamp(0, 255) as u8;
        }
    }
}
