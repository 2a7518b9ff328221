//! Float picture operations for flow and features: separable filtering,
//! Gaussian pyramids, image gradients. Borders repeat the edge samples.
//! Everything works on contiguous row-major `Array2<f32>` (`[[y, x]]`).

use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;

use super::dsp::imgproc;
use super::Luma;

/// A normalised 1-D Gaussian of standard deviation `sigma`, truncated at
/// `ceil(3 sigma)` on each side (at least one tap each side).
pub fn gaussian_kernel(sigma: f32) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil().max(1.0) as usize;
    let mut k: Vec<f32> = (0..=2 * radius)
        .map(|i| {
            let d = i as f32 - radius as f32;
            (-d * d / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    k
}

/// Rows per parallel task: about 4096 samples, so that small pyramid levels
/// are not split into tasks too short to pay for themselves.
pub(crate) fn rows_per_task(w: usize) -> usize {
    (4096 / w.max(1)).max(1)
}

/// Whether a pass over `n` samples is worth splitting across threads: not
/// with one thread (rayon's bookkeeping would be pure cost) nor for small
/// pyramid levels. Either way each row is computed the same way.
pub(crate) fn parallel_worth(n: usize) -> bool {
    n >= 32768 && rayon::current_num_threads() > 1
}

/// Convolves every row of the row-major `h x w` picture `src` with `kernel`
/// (odd length, centred), edges repeated, into `out`. Bands of rows run in
/// parallel when that pays; each row is computed the same way whatever the
/// number of threads.
pub fn filter_rows_slice(src: &[f32], h: usize, w: usize, kernel: &[f32], out: &mut [f32]) {
    assert!(src.len() >= h * w && out.len() >= h * w && kernel.len() % 2 == 1);
    let (src, out) = (&src[..h * w], &mut out[..h * w]);
    let rows_band = imgproc().filter_rows;
    if parallel_worth(h * w) {
        let band = rows_per_task(w) * w;
        out.par_chunks_mut(band)
            .zip(src.par_chunks(band))
            .for_each(|(o, s)| rows_band(s, w, kernel, o));
    } else {
        rows_band(src, w, kernel, out);
    }
}

/// Convolves every column of the row-major `h x w` picture `src` with
/// `kernel` (odd length), edges repeated, into `out`; bands of output rows
/// in parallel when that pays.
pub fn filter_cols_slice(src: &[f32], h: usize, w: usize, kernel: &[f32], out: &mut [f32]) {
    assert!(src.len() >= h * w && out.len() >= h * w && kernel.len() % 2 == 1);
    let (src, out) = (&src[..h * w], &mut out[..h * w]);
    let cols_band = imgproc().filter_cols;
    if parallel_worth(h * w) {
        let rows = rows_per_task(w);
        out.par_chunks_mut(rows * w)
            .enumerate()
            .for_each(|(t, o)| cols_band(src, h, w, t * rows, kernel, o));
    } else {
        cols_band(src, h, w, 0, kernel, out);
    }
}

/// Separable convolution of a row-major `h x w` picture, through `tmp`.
pub fn separable_slice(src: &[f32], h: usize, w: usize, kernel: &[f32], tmp: &mut [f32], out: &mut [f32]) {
    filter_rows_slice(src, h, w, kernel, tmp);
    filter_cols_slice(tmp, h, w, kernel, out);
}

fn filter_rows(src: &Array2<f32>, kernel: &[f32], dst: &mut Array2<f32>) {
    let (h, w) = src.dim();
    filter_rows_slice(
        src.as_slice().expect("contiguous"),
        h,
        w,
        kernel,
        dst.as_slice_mut().expect("contiguous"),
    )
}

fn filter_cols(src: &Array2<f32>, kernel: &[f32], dst: &mut Array2<f32>) {
    let (h, w) = src.dim();
    filter_cols_slice(
        src.as_slice().expect("contiguous"),
        h,
        w,
        kernel,
        dst.as_slice_mut().expect("contiguous"),
    )
}

/// Separable convolution with the same kernel along both axes.
pub fn separable(src: &Array2<f32>, kernel: &[f32]) -> Array2<f32> {
    let src = src.as_standard_layout();
    let mut tmp = Array2::zeros(src.dim());
    let mut out = Array2::zeros(src.dim());
    filter_rows(&src.to_owned(), kernel, &mut tmp);
    filter_cols(&tmp, kernel, &mut out);
    out
}

/// Gaussian blur with standard deviation `sigma`.
pub fn blur(src: &Array2<f32>, sigma: f32) -> Array2<f32> {
    separable(src, &gaussian_kernel(sigma))
}

/// Local contrast normalisation: each pixel minus the Gaussian-weighted
/// (`sigma`) mean around it, over the weighted standard deviation there
/// (plus `noise` grey levels, so that flat areas are not amplified into
/// noise), scaled to about the contrast of a photograph around mid-grey.
/// A gain, an offset or a slow ramp between two pictures drops out, which
/// brightness constancy alone cannot follow.
pub fn normalize_contrast(img: &Array2<f32>, sigma: f32, noise: f32) -> Array2<f32> {
    let kernel = gaussian_kernel(sigma);
    let mut detail = separable(img, &kernel);
    detail.zip_mut_with(img, |m, &i| *m = i - *m);
    let variance = separable(&detail.mapv(|d| d * d), &kernel);
    ndarray::Zip::from(&detail)
        .and(&variance)
        .map_collect(|&d, &v| 128.0 + NORMALIZED_CONTRAST * d / (v + noise * noise).sqrt())
}

/// The standard deviation [`normalize_contrast`] gives a textured area.
const NORMALIZED_CONTRAST: f32 = 40.0;

/// Every level of a pyramid contrast-normalised in place, as the flow
/// methods that match normalised pictures use it: a window of 3 pixels of
/// each level, noise of 5 grey levels not amplified.
pub fn normalize_levels(levels: &mut [Array2<f32>]) {
    for level in levels {
        *level = normalize_contrast(level, 3.0, 5.0);
    }
}

/// The number of pyramid levels that halves a `w x h` picture until its
/// longer side is under 32 pixels: the depth a coarse-to-fine method with
/// a reach of a pixel or two per level needs for motion of tens of pixels.
pub fn full_depth(w: usize, h: usize) -> usize {
    let mut levels = 1;
    let mut long = w.max(h);
    while long >= 32 {
        long = long.div_ceil(2);
        levels += 1;
    }
    levels
}

/// Half-size picture: blurred (sigma 1, which removes what 2x decimation
/// would alias) and averaged over each 2x2 pair of samples (pixel centres
/// of the small picture at 2x + 0.5 of the large one). The blur and the
/// average are one filter, `0.5 (g[t] + g[t - 1])`, evaluated only where
/// the small picture has samples: every other column in the row pass, every
/// other row in the column pass.
pub fn downsample(src: &Array2<f32>) -> Array2<f32> {
    let (h, w) = src.dim();
    let mut out = Array2::zeros((h.div_ceil(2), w.div_ceil(2)));
    downsample_into(&src.as_standard_layout().to_owned(), &mut Vec::new(), &mut out);
    out
}

/// [`downsample`] into `out` (of the half size), with `tmp` as the row
/// pass's buffer (grown as needed): no allocation once sizes settle.
pub fn downsample_into(src: &Array2<f32>, tmp: &mut Vec<f32>, out: &mut Array2<f32>) {
    let s = src.as_slice().expect("standard");
    let (h, w) = src.dim();
    let (nh, nw) = (h.div_ceil(2), w.div_ceil(2));
    assert_eq!(out.dim(), (nh, nw), "downsample_into: output size");
    let g = gaussian_kernel(1.0);
    let r = (g.len() / 2) as isize;
    // Taps for input offsets -r ..= r + 1 around 2x.
    let taps: Vec<f32> = (-r..=r + 1)
        .map(|t| {
            let at = |k: isize| {
                if (-r..=r).contains(&k) {
                    g[(k + r) as usize]
                } else {
                    0.0
                }
            };
            0.5 * (at(t) + at(t - 1))
        })
        .collect();
    let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    // Row pass at even columns: h x nw.
    tmp.resize(h * nw, 0.0);
    for y in 0..h {
        let row = &s[y * w..(y + 1) * w];
        let dst = &mut tmp[y * nw..(y + 1) * nw];
        for (x, o) in dst.iter_mut().enumerate() {
            let base = 2 * x as isize - r;
            let interior = base >= 0 && base + taps.len() as isize <= w as isize;
            *o = if interior {
                let window = &row[base as usize..base as usize + taps.len()];
                window.iter().zip(&taps).map(|(a, b)| a * b).sum()
            } else {
                taps.iter()
                    .enumerate()
                    .map(|(k, &t)| t * row[clamp(base + k as isize, w)])
                    .sum()
            };
        }
    }
    // Column pass at even rows: nh x nw.
    let o = out.as_slice_mut().expect("standard");
    o.fill(0.0);
    for y in 0..nh {
        let dst = &mut o[y * nw..(y + 1) * nw];
        for (k, &t) in taps.iter().enumerate() {
            let sy = clamp(2 * y as isize - r + k as isize, h);
            for (d, &v) in dst.iter_mut().zip(&tmp[sy * nw..(sy + 1) * nw]) {
                *d += t * v;
            }
        }
    }
}

/// Twice-size picture of `h x w` (each at most twice the input's, at least
/// twice minus one), linear between samples: [`upsample_levels`] by one
/// level. Multiplies every value by `scale`.
pub fn upsample2(src: &Array2<f32>, h: usize, w: usize, scale: f32) -> Array2<f32> {
    upsample_levels(src, h, w, 1, scale)
}

/// Taps of linear interpolation from `n_src` samples to `n` outputs
/// `levels` pyramid levels finer: output x sits at input position
/// `(x + 0.5) / 2^levels - 0.5` (the pyramid's geometry: a coarse pixel is
/// the centre of the block of fine pixels it averages), clamped at the edges.
fn linear_taps(n: usize, n_src: usize, levels: usize) -> Vec<(usize, usize, f32)> {
    let f = (1usize << levels) as f32;
    (0..n)
        .map(|x| {
            let p = ((x as f32 + 0.5) / f - 0.5).clamp(0.0, (n_src - 1) as f32);
            let i = p as usize;
            ((i), (i + 1).min(n_src - 1), p - i as f32)
        })
        .collect()
}

/// The weights of the outputs inside an interval between two samples,
/// `levels` levels finer: `t = (j + 0.5) / 2^levels`, the same at every
/// interval (what [`upsample_row`] takes).
fn interval_weights(levels: usize) -> Vec<f32> {
    let f = 1usize << levels;
    (0..f).map(|j| (j as f32 + 0.5) / f as f32).collect()
}

/// One row of [`upsample_levels`]' first pass: `dst[x]` linear between
/// the samples of `src` that `cols[x]` names. Between two samples the
/// `2^levels` outputs have the same weights at every interval (the
/// dyadic positions of [`linear_taps`], exact in `f32`), so the inside of
/// the row goes an interval at a time without looking the taps up; the
/// same sums as the taps give.
#[inline(always)]
fn upsample_row(src: &[f32], cols: &[(usize, usize, f32)], levels: usize, ts: &[f32], dst: &mut [f32]) {
    let (f, w) = (1usize << levels, dst.len());
    let half = f / 2;
    // Interval i (between samples i and i + 1) holds outputs
    // half + f i .. half + f (i + 1), at t = (j + 0.5) / f.
    let full = (w.saturating_sub(half) / f).min(src.len().saturating_sub(1));
    let tap = |&(a, b, t): &(usize, usize, f32)| src[a] + t * (src[b] - src[a]);
    let lead = if levels == 0 { w } else { half.min(w) };
    for (d, c) in dst[..lead].iter_mut().zip(cols) {
        *d = tap(c);
    }
    if levels == 0 {
        return;
    }
    for (i, out) in dst[half..half + f * full].chunks_exact_mut(f).enumerate() {
        let (p, q) = (src[i], src[i + 1]);
        for (o, &t) in out.iter_mut().zip(ts) {
            *o = p + t * (q - p);
        }
    }
    let rest = half + f * full;
    for (d, c) in dst[rest..].iter_mut().zip(&cols[rest..]) {
        *d = tap(c);
    }
}

/// A field `levels` pyramid levels finer, of `h x w`, linear between
/// samples (edges repeat), every value multiplied by `scale`: a flow of a
/// coarse level brought to a finer one in one pass.
pub fn upsample_levels(src: &Array2<f32>, h: usize, w: usize, levels: usize, scale: f32) -> Array2<f32> {
    // Zeroed by the allocator: fresh pages on a first call, a clearing
    // pass where it hands back used memory. A caller that keeps its field
    // calls [`upsample_levels_into`] and pays neither.
    let mut out = Array2::zeros((h, w));
    upsample_levels_into(src, levels, scale, &mut out);
    out
}

/// [`upsample_levels`] written over `out`, whose size is the field's
/// (`h x w`): a caller that keeps its field from frame to frame allocates
/// and clears nothing. Panics unless `out` is in standard layout.
pub fn upsample_levels_into(src: &Array2<f32>, levels: usize, scale: f32, out: &mut Array2<f32>) {
    let (h, w) = out.dim();
    let out = out.as_slice_mut().expect("upsample_levels_into: standard layout");
    (super::dsp::imgproc().upsample_levels)(src, (h, w), levels, scale, out)
}

/// [`upsample_levels`] of the two components of a field at once, written
/// as (u, v) pairs row by row into `out` (`2 h w` floats, the layout of
/// OpenCV's flow and of .flo files): no planar field to interleave
/// afterwards. The same values as [`upsample_levels`] of each. Halves of
/// the rows run on two workers where that pays. Panics unless `u` and `v`
/// are of one size and in standard layout.
#[allow(clippy::too_many_arguments)]
pub fn upsample_levels_interleaved(
    u: &Array2<f32>,
    v: &Array2<f32>,
    h: usize,
    w: usize,
    levels: usize,
    scale: f32,
    out: &mut [f32],
) {
    assert_eq!(
        u.dim(),
        v.dim(),
        "upsample_levels_interleaved: components differ in size"
    );
    assert_eq!(out.len(), 2 * h * w, "upsample_levels_interleaved: output size");
    let pair = super::dsp::imgproc().upsample_levels_pair;
    if parallel_worth(h * w) && h >= 2 {
        let (top, bottom) = out.split_at_mut(h / 2 * 2 * w);
        rayon::join(
            || pair(u, v, (h, w), levels, scale, 0, top),
            || pair(u, v, (h, w), levels, scale, h / 2, bottom),
        );
    } else {
        pair(u, v, (h, w), levels, scale, 0, out);
    }
}

/// Rows `y0..` (as many as `out` holds, `2 w` floats each) of
/// [`upsample_levels_interleaved`], for any instruction set.
#[inline(always)]
pub(crate) fn upsample_levels_pair_body(
    u: &Array2<f32>,
    v: &Array2<f32>,
    (h, w): (usize, usize),
    levels: usize,
    scale: f32,
    y0: usize,
    out: &mut [f32],
) {
    let (sh, sw) = u.dim();
    let (su, sv) = (u.as_slice().expect("standard"), v.as_slice().expect("standard"));
    let n_out = out.len() / (2 * w).max(1);
    let rows = &linear_taps(h, sh, levels)[y0..y0 + n_out];
    let (Some(&(first, _, _)), Some(&(_, last, _))) = (rows.first(), rows.last()) else {
        return;
    };
    // The first pass on the source rows these output rows read (the taps
    // run in order), both components.
    let cols = linear_taps(w, sw, levels);
    let ts = interval_weights(levels);
    let n = last - first + 1;
    let (mut tu, mut tv) = (vec![0f32; n * w], vec![0f32; n * w]);
    for (k, (du, dv)) in tu.chunks_exact_mut(w).zip(tv.chunks_exact_mut(w)).enumerate() {
        let row = (first + k) * sw;
        upsample_row(&su[row..row + sw], &cols, levels, &ts, du);
        upsample_row(&sv[row..row + sw], &cols, levels, &ts, dv);
    }
    for (&(a, b, t), dst) in rows.iter().zip(out.chunks_exact_mut(2 * w)) {
        let (a, b) = ((a - first) * w, (b - first) * w);
        let (ua, ub, va, vb) = (&tu[a..a + w], &tu[b..b + w], &tv[a..a + w], &tv[b..b + w]);
        for ((((o, &pu), &qu), &pv), &qv) in dst.chunks_exact_mut(2).zip(ua).zip(ub).zip(va).zip(vb) {
            o[0] = scale * (pu + t * (qu - pu));
            o[1] = scale * (pv + t * (qv - pv));
        }
    }
}

/// [`upsample_levels`] for any instruction set.
#[inline(always)]
pub(crate) fn upsample_levels_body(
    src: &Array2<f32>,
    (h, w): (usize, usize),
    levels: usize,
    scale: f32,
    out: &mut [f32],
) {
    assert_eq!(out.len(), h * w, "upsample_levels: output size");
    let (sh, sw) = src.dim();
    let s = src.as_standard_layout();
    let s = s.as_slice().expect("standard");
    let (cols, rows) = (linear_taps(w, sw, levels), linear_taps(h, sh, levels));
    // Rows first: (sh, w), then each output row one straight loop that
    // vectorises.
    let ts = interval_weights(levels);
    let mut tmp = vec![0f32; sh * w];
    for (src_row, dst) in s.chunks_exact(sw).zip(tmp.chunks_exact_mut(w.max(1))) {
        upsample_row(src_row, &cols, levels, &ts, dst);
    }
    for (&(a, b, t), dst) in rows.iter().zip(out.chunks_exact_mut(w.max(1))) {
        let (ra, rb) = (&tmp[a * w..][..w], &tmp[b * w..][..w]);
        for ((o, &p), &q) in dst.iter_mut().zip(ra).zip(rb) {
            *o = scale * (p + t * (q - p));
        }
    }
}

/// Half-size picture (sizes rounded up) through the binomial filter
/// `[1, 3, 3, 1] / 8` along each axis (output k from inputs 2k - 1 ..= 2k + 2,
/// edges repeated): the cheap pyramid of the patch matcher. Centred like
/// [`downsample`] (output k at input 2k + 0.5), with a quarter of its taps,
/// and far less aliasing than 2x2 block means.
pub fn downsample_binomial_into(src: &Array2<f32>, tmp: &mut Vec<f32>, out: &mut Array2<f32>) {
    (super::dsp::imgproc().downsample_binomial)(src.view(), tmp, out)
}

/// [`downsample_binomial_into`] from 8-bit samples (0..255 as grey levels),
/// the conversion done in the first pass: the same values as converting
/// `src` to float first, without that full-size pass.
pub fn downsample_binomial_u8_into(src: ArrayView2<'_, u8>, tmp: &mut Vec<f32>, out: &mut Array2<f32>) {
    (super::dsp::imgproc().downsample_binomial_u8)(src, tmp, out)
}

/// [`downsample_binomial_into`] for any instruction set.
#[inline(always)]
pub(crate) fn downsample_binomial_body(src: ArrayView2<'_, f32>, tmp: &mut Vec<f32>, out: &mut Array2<f32>) {
    let s = src.to_slice().expect("standard");
    downsample_binomial_samples(s, src.dim(), tmp, out)
}

/// [`downsample_binomial_u8_into`] for any instruction set.
#[inline(always)]
pub(crate) fn downsample_binomial_u8_body(
    src: ArrayView2<'_, u8>,
    tmp: &mut Vec<f32>,
    out: &mut Array2<f32>,
) {
    let s = src.to_slice().expect("standard");
    downsample_binomial_samples(s, src.dim(), tmp, out)
}

/// The binomial halving of the row-major `h x w` samples `s`.
#[inline(always)]
fn downsample_binomial_samples<T: Copy + Into<f32>>(
    s: &[T],
    (h, w): (usize, usize),
    tmp: &mut Vec<f32>,
    out: &mut Array2<f32>,
) {
    let (nh, nw) = (h.div_ceil(2), w.div_ceil(2));
    assert_eq!(out.dim(), (nh, nw), "downsample_binomial_into: output size");
    let at = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    // Columns first, on whole rows (contiguous, vectorised), then rows on
    // the half-height result: the strided pass sees half the rows.
    // Grown, never shrunk: the levels share it, largest first, and a
    // shrink made the next picture's first level clear it all again (3 %
    // of ultrafast flow's time on 640x360). Every value is written.
    if tmp.len() < nh * w {
        tmp.resize(nh * w, 0.0);
    }
    let tmp = &mut tmp[..nh * w];
    for (y, dst) in tmp.chunks_exact_mut(w).enumerate() {
        let c = 2 * y as isize;
        let r = |k: isize| &s[at(c + k, h) * w..][..w];
        // Zipped slices, not indices: no bounds check left in the loop, so
        // it vectorises in every build (indexed, one build of the Python
        // extension left it scalar at 2.4 times the time).
        for ((((d, &a), &b), &c), &e) in dst.iter_mut().zip(r(-1)).zip(r(0)).zip(r(1)).zip(r(2)) {
            let (a, b, c, e): (f32, f32, f32, f32) = (a.into(), b.into(), c.into(), e.into());
            *d = 0.125 * (a + e) + 0.375 * (b + c);
        }
    }
    let tap = |row: &[f32], x: usize| {
        let c = 2 * x as isize;
        let (a, b, cc, e) = (
            row[at(c - 1, w)],
            row[at(c, w)],
            row[at(c + 1, w)],
            row[at(c + 2, w)],
        );
        0.125 * (a + e) + 0.375 * (b + cc)
    };
    // Outputs 1 .. inner read inputs 2x - 1 ..= 2x + 2 inside the row: no
    // clamping there.
    let inner = if w >= 4 { (w - 3) / 2 + 1 } else { 1 }.min(nw);
    let o = out.as_slice_mut().expect("standard");
    // The row's even and odd samples apart, so that outputs 1 .. inner,
    // `0.125 (odd[x-1] + even[x+1]) + 0.375 (even[x] + odd[x])`, are
    // straight loops over four contiguous slices (the same sums as `tap`).
    let (mut even, mut odd) = (vec![0f32; nw + 1], vec![0f32; nw + 1]);
    for (row, dst) in tmp.chunks_exact(w).zip(o.chunks_exact_mut(nw)) {
        for ((e, o), pair) in even.iter_mut().zip(odd.iter_mut()).zip(row.chunks_exact(2)) {
            (*e, *o) = (pair[0], pair[1]);
        }
        if w % 2 == 1 {
            even[w / 2] = row[w - 1];
        }
        dst[0] = tap(row, 0);
        if inner > 1 {
            let m = inner - 1;
            let (a, e) = (&odd[..m], &even[2..m + 2]);
            let (b, c) = (&even[1..m + 1], &odd[1..m + 1]);
            for (k, d) in dst[1..inner].iter_mut().enumerate() {
                *d = 0.125 * (a[k] + e[k]) + 0.375 * (b[k] + c[k]);
            }
        }
        for (x, d) in dst.iter_mut().enumerate().skip(inner.max(1)) {
            *d = tap(row, x);
        }
    }
}

/// A Gaussian pyramid: level 0 is the picture, each next level half the
/// size of the one before, until `levels` levels or the picture would fall
/// below `min_size` pixels on a side.
pub fn pyramid(src: &Array2<f32>, levels: usize, min_size: usize) -> Vec<Array2<f32>> {
    let mut p = Pyramid::default();
    p.build(src, levels, min_size);
    p.levels
}

/// A pyramid whose levels are rebuilt in place when the picture size does
/// not change (no allocation after the first build).
#[derive(Debug, Default, Clone)]
pub struct Pyramid {
    /// Level 0 (full size) first.
    pub levels: Vec<Array2<f32>>,
    tmp: Vec<f32>,
}

impl Pyramid {
    /// Rebuilds the levels from `src`, as [`pyramid`] does.
    pub fn build(&mut self, src: &Array2<f32>, levels: usize, min_size: usize) {
        self.build_with(src.view(), levels, min_size, false, true)
    }

    /// Rebuilds the levels from `src` with the binomial filter
    /// ([`downsample_binomial_into`]) instead of the Gaussian.
    pub fn build_binomial(&mut self, src: &Array2<f32>, levels: usize, min_size: usize) {
        self.build_with(src.view(), levels, min_size, true, true)
    }

    /// As [`Pyramid::build_binomial`] for a reader of the levels from 1 up
    /// only: level 0 is sized but not filled (its copy of `src` is the one
    /// full-size pass that reader does not need).
    pub fn build_binomial_above_full_size(&mut self, src: &Array2<f32>, levels: usize, min_size: usize) {
        self.build_with(src.view(), levels, min_size, true, false)
    }

    /// As [`Pyramid::build_binomial`] (`full`) or
    /// [`Pyramid::build_binomial_above_full_size`], from 8-bit or float
    /// samples: 8-bit ones are made float in the first halving's pass (and
    /// in level 0's copy when `full`), with no conversion pass of their own.
    pub fn build_binomial_luma(&mut self, src: Luma<'_>, levels: usize, min_size: usize, full: bool) {
        let src = match src {
            Luma::F32(a) => return self.build_with(a, levels, min_size, true, full),
            Luma::U8(a) => a,
        };
        let contiguous = src.is_standard_layout();
        self.size_levels(src.dim(), levels, min_size);
        let full = full || !contiguous;
        if full {
            self.levels[0].zip_mut_with(&src, |d, &s| *d = f32::from(s));
        }
        let (lower, upper) = self.levels.split_at_mut(1);
        if let Some(level1) = upper.first_mut() {
            if full {
                downsample_binomial_into(&lower[0], &mut self.tmp, level1);
            } else {
                downsample_binomial_u8_into(src, &mut self.tmp, level1);
            }
        }
        self.halve_from(2);
    }

    /// Levels of the sizes a pyramid of `size` has (`levels` at most, none
    /// under `min_size` on a side), allocated only where a size changed.
    fn size_levels(&mut self, size: (usize, usize), levels: usize, min_size: usize) {
        let mut dims = vec![size];
        while dims.len() < levels.max(1) {
            let (h, w) = dims[dims.len() - 1];
            if h.div_ceil(2) < min_size || w.div_ceil(2) < min_size {
                break;
            }
            dims.push((h.div_ceil(2), w.div_ceil(2)));
        }
        self.levels.truncate(dims.len());
        for (i, &d) in dims.iter().enumerate() {
            if i >= self.levels.len() {
                self.levels.push(Array2::zeros(d));
            } else if self.levels[i].dim() != d {
                self.levels[i] = Array2::zeros(d);
            }
        }
    }

    /// Binomial levels `from..` each from the one below.
    fn halve_from(&mut self, from: usize) {
        for i in from..self.levels.len() {
            let (lower, upper) = self.levels.split_at_mut(i);
            downsample_binomial_into(&lower[i - 1], &mut self.tmp, &mut upper[0]);
        }
    }

    fn build_with(
        &mut self,
        src: ArrayView2<'_, f32>,
        levels: usize,
        min_size: usize,
        binomial: bool,
        full: bool,
    ) {
        self.size_levels(src.dim(), levels, min_size);
        // The level-1 pass reads rows of a standard layout: another layout
        // goes through level 0's copy (as the Gaussian's levels always do).
        let full = full || !binomial || src.as_slice().is_none();
        if full {
            match (self.levels[0].as_slice_mut(), src.as_slice()) {
                (Some(dst), Some(s)) => dst.copy_from_slice(s),
                _ => self.levels[0].assign(&src),
            }
        }
        if !binomial {
            for i in 1..self.levels.len() {
                let (lower, upper) = self.levels.split_at_mut(i);
                downsample_into(&lower[i - 1], &mut self.tmp, &mut upper[0]);
            }
            return;
        }
        let (lower, upper) = self.levels.split_at_mut(1);
        if let Some(level1) = upper.first_mut() {
            let below = if full { lower[0].view() } else { src };
            (imgproc().downsample_binomial)(below, &mut self.tmp, level1);
        }
        self.halve_from(2);
    }
}

/// The 5-tap central difference `(1, -8, 0, 8, -1) / 12`, as a correlation
/// kernel (exact for cubic polynomials).
pub const DERIVATIVE: [f32; 5] = [1.0 / 12.0, -8.0 / 12.0, 0.0, 8.0 / 12.0, -1.0 / 12.0];

/// Horizontal and vertical derivatives with the 5-tap central difference,
/// edges repeated.
pub fn gradients(src: &Array2<f32>) -> (Array2<f32>, Array2<f32>) {
    let src = src.as_standard_layout().to_owned();
    let mut gx = Array2::zeros(src.dim());
    let mut gy = Array2::zeros(src.dim());
    filter_rows(&src, &DERIVATIVE, &mut gx);
    filter_cols(&src, &DERIVATIVE, &mut gy);
    (gx, gy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_depth_stops_under_32_pixels() {
        assert_eq!(full_depth(640, 480), 6);
        assert_eq!(full_depth(352, 288), 5);
        assert_eq!(full_depth(31, 20), 1);
        assert_eq!(full_depth(32, 1), 2);
    }

    #[test]
    fn contrast_normalisation_drops_gain_offset_and_ramp() {
        let f = |x: f32, y: f32| 100.0 + 40.0 * (x / 3.0).sin() * (y / 4.0).cos();
        let a = Array2::from_shape_fn((40, 48), |(y, x)| f(x as f32, y as f32));
        let b = Array2::from_shape_fn((40, 48), |(y, x)| {
            0.7 * f(x as f32, y as f32) + 30.0 + 0.3 * x as f32
        });
        let (na, nb) = (normalize_contrast(&a, 3.0, 1.0), normalize_contrast(&b, 3.0, 1.0));
        // Away from the borders (where the window is cut) the two agree to
        // a few per cent of the normalised contrast.
        for y in 10..30 {
            for x in 10..38 {
                assert!(
                    (na[[y, x]] - nb[[y, x]]).abs() < 2.0,
                    "({x},{y}): {} {}",
                    na[[y, x]],
                    nb[[y, x]]
                );
            }
        }
        let flat = normalize_contrast(&Array2::from_elem((16, 16), 77.0), 3.0, 5.0);
        assert!(flat.iter().all(|&v| (v - 128.0).abs() < 1e-3));
    }

    #[test]
    fn kernels_are_normalised_and_symmetric() {
        for sigma in [0.5f32, 1.0, 2.5] {
            let k = gaussian_kernel(sigma);
            assert!((k.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            assert_eq!(k.len() % 2, 1);
            for i in 0..k.len() {
                assert_eq!(k[i], k[k.len() - 1 - i]);
            }
        }
    }

    #[test]
    fn blur_keeps_constants_and_linear_ramps() {
        let ramp = Array2::from_shape_fn((20, 30), |(y, x)| 3.0 * x as f32 - 2.0 * y as f32 + 7.0);
        let b = blur(&ramp, 1.5);
        // Away from the edges (where the repeated border bends the ramp) a
        // symmetric blur leaves a linear function unchanged.
        for y in 6..14 {
            for x in 6..24 {
                assert!((b[[y, x]] - ramp[[y, x]]).abs() < 1e-3, "({x},{y})");
            }
        }
    }

    #[test]
    fn gradients_of_a_cubic_are_exact_inside() {
        let f = |x: f32, y: f32| 0.01 * x * x * x - 0.5 * y * y + 2.0 * x * y;
        let img = Array2::from_shape_fn((16, 16), |(y, x)| f(x as f32, y as f32));
        let (gx, gy) = gradients(&img);
        for y in 2..14 {
            for x in 2..14 {
                let (xf, yf) = (x as f32, y as f32);
                assert!((gx[[y, x]] - (0.03 * xf * xf + 2.0 * yf)).abs() < 1e-3);
                assert!((gy[[y, x]] - (-yf + 2.0 * xf)).abs() < 1e-3);
            }
        }
    }

    #[test]
    fn pyramids_halve_and_stop_at_the_minimum_size() {
        let img = Array2::from_shape_fn((37, 50), |(y, x)| (x * y) as f32);
        let p = pyramid(&img, 10, 8);
        let dims: Vec<_> = p.iter().map(|l| l.dim()).collect();
        assert_eq!(dims, vec![(37, 50), (19, 25), (10, 13)]);
        assert_eq!(pyramid(&img, 1, 8).len(), 1);
    }

    #[test]
    fn upsampling_matches_bilinear_sampling_at_the_pixel_centres() {
        let small = Array2::from_shape_fn((7, 9), |(y, x)| (x * x) as f32 + 3.0 * y as f32);
        let big = upsample2(&small, 13, 18, 2.0);
        for y in 0..13 {
            for x in 0..18 {
                let want = 2.0
                    * crate::flow::warp::sample_bilinear(
                        &small,
                        (x as f32 - 0.5) / 2.0,
                        (y as f32 - 0.5) / 2.0,
                    );
                assert!(
                    (big[[y, x]] - want).abs() < 1e-4,
                    "({x},{y}): {} vs {want}",
                    big[[y, x]]
                );
            }
        }
    }

    #[test]
    fn upsampling_by_several_levels_matches_bilinear_sampling() {
        let small = Array2::from_shape_fn((5, 7), |(y, x)| ((x * 13 + y * 7) % 11) as f32 + 0.25 * x as f32);
        for (levels, h, w) in [(2, 20, 28), (2, 17, 25), (3, 40, 56), (3, 33, 49)] {
            let f = (1usize << levels) as f32;
            let big = upsample_levels(&small, h, w, levels, 3.0);
            for ((y, x), &got) in big.indexed_iter() {
                let at = |p: usize| (p as f32 + 0.5) / f - 0.5;
                let want = 3.0 * crate::flow::warp::sample_bilinear(&small, at(x), at(y));
                assert!(
                    (got - want).abs() < 1e-4,
                    "{levels} levels ({x},{y}): {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn the_binomial_halving_matches_its_definition() {
        for (h, w) in [(1, 1), (3, 2), (7, 9), (10, 12), (5, 4)] {
            let img = Array2::from_shape_fn((h, w), |(y, x)| ((x * 37 + y * 11) % 23) as f32);
            let mut out = Array2::zeros((h.div_ceil(2), w.div_ceil(2)));
            downsample_binomial_into(&img, &mut Vec::new(), &mut out);
            let at = |y: isize, x: isize| {
                img[[
                    y.clamp(0, h as isize - 1) as usize,
                    x.clamp(0, w as isize - 1) as usize,
                ]]
            };
            let k = [0.125f32, 0.375, 0.375, 0.125];
            for ((y, x), &got) in out.indexed_iter() {
                let mut want = 0.0;
                for (j, kj) in k.iter().enumerate() {
                    let (yy, xx) = (2 * y as isize - 1 + j as isize, 2 * x as isize - 1);
                    let row: f32 = k
                        .iter()
                        .enumerate()
                        .map(|(i, ki)| ki * at(yy, xx + i as isize))
                        .sum();
                    want += kj * row;
                }
                assert!((got - want).abs() < 1e-4, "{h}x{w} ({x},{y}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn the_halving_of_bytes_is_the_halving_of_their_floats() {
        for (h, w) in [(1, 1), (3, 2), (7, 9), (38, 61)] {
            let bytes = Array2::from_shape_fn((h, w), |(y, x)| ((x * 97 + y * 31) % 256) as u8);
            let (mut a, mut b) = (
                Array2::zeros((h.div_ceil(2), w.div_ceil(2))),
                Array2::zeros((h.div_ceil(2), w.div_ceil(2))),
            );
            downsample_binomial_u8_into(bytes.view(), &mut Vec::new(), &mut a);
            downsample_binomial_into(&bytes.mapv(f32::from), &mut Vec::new(), &mut b);
            assert!(
                a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{h}x{w}"
            );
            // The pyramid from bytes, with and without level 0, as from floats.
            let mut p = Pyramid::default();
            let mut q = Pyramid::default();
            for full in [true, false] {
                p.build_binomial_luma(Luma::U8(bytes.view()), 4, 1, full);
                q.build_binomial(&bytes.mapv(f32::from), 4, 1);
                assert_eq!(p.levels.len(), q.levels.len());
                let from = if full { 0 } else { 1 };
                assert!(
                    p.levels[from..] == q.levels[from..],
                    "{h}x{w} pyramid, level 0 {full}"
                );
            }
        }
    }

    #[test]
    fn the_interleaved_upsampling_pairs_the_planar_ones() {
        let u = Array2::from_shape_fn((9, 11), |(y, x)| ((x * 13 + y * 7) % 11) as f32 - 4.5);
        let v = Array2::from_shape_fn((9, 11), |(y, x)| (x as f32 * 0.37 - y as f32).sin());
        // 2 threads and more than 32768 samples: the two halves of the rows
        // run apart (odd heights, so the halves differ by a row).
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for (levels, h, w) in [(0, 9, 11), (2, 33, 41), (3, 70, 87), (5, 287, 351)] {
            let (pu, pv) = (
                upsample_levels(&u, h, w, levels, 1.75),
                upsample_levels(&v, h, w, levels, 1.75),
            );
            let mut out = vec![f32::NAN; 2 * h * w];
            pool.install(|| upsample_levels_interleaved(&u, &v, h, w, levels, 1.75, &mut out));
            let pairs: Vec<f32> = pu.iter().zip(&pv).flat_map(|(&a, &b)| [a, b]).collect();
            assert!(
                out.iter().zip(&pairs).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{levels} levels to {w}x{h}"
            );
        }
    }

    #[test]
    fn downsampling_a_constant_is_constant() {
        let img = Array2::from_elem((9, 11), 42.0f32);
        let d = downsample(&img);
        assert!(d.iter().all(|&v| (v - 42.0).abs() < 1e-4));
    }
}
