//! SSIM as encoders report it: x264's `--ssim` and ffmpeg's `ssim`
//! filter.
//!
//! Statistics over 8x8 windows without weighting, one window every 4
//! pixels in each direction (so each 4x4 block's sums serve four windows),
//! sample (not population) variances, and the mean over all windows:
//! `(w / 4 - 1) * (h / 4 - 1)` of them. It costs a few additions per
//! pixel, against some hundred multiplications for [`ssim`](super::ssim)'s
//! 11x11 Gaussian, which is why an encoder measuring every frame uses it;
//! the two agree closely but are not the same number.
//!
//! Pictures less than 8 pixels wide or high have no window: one window
//! covering the whole picture stands in.

use crate::codec::Plane;

/// Per 4x4 block: sum of a, sum of b, sum of a^2 + b^2, sum of a * b.
type BlockSums = [u32; 4];

/// Wang's constants are `(0.01 * 255)^2` and `(0.03 * 255)^2`; x264 (and
/// ffmpeg after it) scale the first by the window's 64 samples where the
/// means' products it guards carry 64^2, so its luminance constant is 1/64
/// of Wang's. Kept, so that the numbers are theirs (it shows on dark
/// pictures only).
const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0) / 64.0;
const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

/// SSIM of one window of `n` samples from its sums, with sample variances.
#[inline(always)]
fn window_ssim(n: f64, s: [f64; 4]) -> f64 {
    let [s1, s2, ss, s12] = s;
    let (ma, mb) = (s1 / n, s2 / n);
    let vars = (ss - (s1 * s1 + s2 * s2) / n) / (n - 1.0);
    let covar = (s12 - s1 * s2 / n) / (n - 1.0);
    ((2.0 * ma * mb + C1) * (2.0 * covar + C2)) / ((ma * ma + mb * mb + C1) * (vars + C2))
}

/// Per-column sums of a row of blocks, one array per statistic (so that
/// the column loop vectorises).
#[derive(Default)]
struct ColumnSums {
    s: [Vec<u32>; 4],
}

/// The 4x4 block sums of one row of blocks (rows y0 .. y0 + 4), into `out`
/// (one entry per whole block).
fn block_row_sums(a: &Plane, b: &Plane, y0: usize, cols: &mut ColumnSums, out: &mut [BlockSums]) {
    #[cfg(target_arch = "x86_64")]
    {
        // std caches the answer after the first call.
        if crate::codec::cpu::at_least(crate::codec::cpu::CpuLevel::Avx2) {
            // SAFETY: the CPU has AVX2; the function is the safe code below
            // compiled with AVX2 (integer arithmetic: the same sums).
            unsafe { block_row_sums_avx2(a, b, y0, cols, out) };
            return;
        }
    }
    block_row_sums_body(a, b, y0, cols, out);
}

/// [`block_row_sums_body`] compiled for AVX2: the baseline build has no
/// 32-bit vector multiply for the squares and products.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn block_row_sums_avx2(a: &Plane, b: &Plane, y0: usize, cols: &mut ColumnSums, out: &mut [BlockSums]) {
    block_row_sums_body(a, b, y0, cols, out);
}

#[inline(always)]
fn block_row_sums_body(a: &Plane, b: &Plane, y0: usize, cols: &mut ColumnSums, out: &mut [BlockSums]) {
    let w = out.len() * 4;
    let [s1, s2, ss, s12] = &mut cols.s;
    for v in [&mut *s1, &mut *s2, &mut *ss, &mut *s12] {
        v.clear();
        v.resize(w, 0);
    }
    for r in y0..y0 + 4 {
        let (ra, rb) = (&a.row(r)[..w], &b.row(r)[..w]);
        for (((((c1, c2), css), c12), &p), &q) in s1
            .iter_mut()
            .zip(s2.iter_mut())
            .zip(ss.iter_mut())
            .zip(s12.iter_mut())
            .zip(ra)
            .zip(rb)
        {
            let (p, q) = (u32::from(p), u32::from(q));
            *c1 += p;
            *c2 += q;
            *css += p * p + q * q;
            *c12 += p * q;
        }
    }
    for (x, o) in out.iter_mut().enumerate() {
        for (k, v) in cols.s.iter().enumerate() {
            o[k] = v[4 * x..4 * x + 4].iter().sum();
        }
    }
}

/// Mean SSIM of `b` against `a` (same size) over 8x8 windows at 4-pixel
/// steps, as x264 and ffmpeg compute it. 1.0 for identical planes. Panics
/// if the sizes differ.
///
/// ```
/// use mocomp::codec::Plane;
/// use mocomp::metrics::ssim_8x8;
/// let a = Plane::from_fn(64, 48, |x, y| ((x * 37 + y * 11) % 251) as u8).unwrap();
/// assert_eq!(ssim_8x8(&a, &a), 1.0);
/// let b = Plane::from_fn(64, 48, |x, y| ((x * 37 + y * 11) % 251) as u8 / 2).unwrap();
/// assert!(ssim_8x8(&a, &b) < 0.9);
/// ```
pub fn ssim_8x8(a: &Plane, b: &Plane) -> f64 {
    assert!(
        a.width() == b.width() && a.height() == b.height(),
        "ssim_8x8: planes of different sizes"
    );
    let (w4, h4) = (a.width() / 4, a.height() / 4);
    if w4 < 2 || h4 < 2 {
        return whole_picture(a, b);
    }
    let mut cols = ColumnSums::default();
    let mut above = vec![[0u32; 4]; w4];
    let mut below = vec![[0u32; 4]; w4];
    block_row_sums(a, b, 0, &mut cols, &mut above);
    let mut sum = 0.0;
    for by in 1..h4 {
        block_row_sums(a, b, by * 4, &mut cols, &mut below);
        for x in 0..w4 - 1 {
            let mut s = [0.0; 4];
            for (k, v) in s.iter_mut().enumerate() {
                *v = f64::from(above[x][k] + above[x + 1][k] + below[x][k] + below[x + 1][k]);
            }
            sum += window_ssim(64.0, s);
        }
        std::mem::swap(&mut above, &mut below);
    }
    sum / ((w4 - 1) * (h4 - 1)) as f64
}

/// One window over the whole picture.
fn whole_picture(a: &Plane, b: &Plane) -> f64 {
    let mut s = [0.0f64; 4];
    for (ra, rb) in a.rows().zip(b.rows()) {
        for (&p, &q) in ra.iter().zip(rb) {
            let (p, q) = (f64::from(p), f64::from(q));
            s[0] += p;
            s[1] += q;
            s[2] += p * p + q * q;
            s[3] += p * q;
        }
    }
    let n = (a.width() * a.height()) as f64;
    if n < 2.0 {
        // One sample has no variance: the luminance term alone.
        return (2.0 * s[0] * s[1] + C1) / (s[0] * s[0] + s[1] * s[1] + C1);
    }
    window_ssim(n, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, window by window, in the plainest form.
    fn by_definition(a: &Plane, b: &Plane) -> f64 {
        let (nx, ny) = (a.width() / 4 - 1, a.height() / 4 - 1);
        let mut sum = 0.0;
        for wy in 0..ny {
            for wx in 0..nx {
                let (mut ma, mut mb) = (0.0, 0.0);
                for y in 0..8 {
                    for x in 0..8 {
                        ma += f64::from(a.get(wx * 4 + x, wy * 4 + y)) / 64.0;
                        mb += f64::from(b.get(wx * 4 + x, wy * 4 + y)) / 64.0;
                    }
                }
                let (mut va, mut vb, mut cov) = (0.0, 0.0, 0.0);
                for y in 0..8 {
                    for x in 0..8 {
                        let da = f64::from(a.get(wx * 4 + x, wy * 4 + y)) - ma;
                        let db = f64::from(b.get(wx * 4 + x, wy * 4 + y)) - mb;
                        va += da * da / 63.0;
                        vb += db * db / 63.0;
                        cov += da * db / 63.0;
                    }
                }
                sum +=
                    ((2.0 * ma * mb + C1) * (2.0 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2));
            }
        }
        sum / (nx * ny) as f64
    }

    #[test]
    fn the_dispatched_block_sums_equal_their_baseline_twin() {
        // Extremes included: 255 squared and multiplied add up fastest.
        let a = Plane::from_fn(68, 12, |x, y| {
            if (x + y) % 5 == 0 {
                255
            } else {
                ((x * 37 + y * 11) % 256) as u8
            }
        })
        .unwrap();
        let b = Plane::from_fn(68, 12, |x, y| ((x * 13 + y * 29) % 256) as u8).unwrap();
        let (mut c1, mut c2) = (ColumnSums::default(), ColumnSums::default());
        let (mut o1, mut o2) = (vec![[0u32; 4]; 17], vec![[0u32; 4]; 17]);
        for y0 in [0, 4, 8] {
            block_row_sums(&a, &b, y0, &mut c1, &mut o1);
            block_row_sums_body(&a, &b, y0, &mut c2, &mut o2);
            assert_eq!(o1, o2, "rows from {y0}");
        }
    }

    #[test]
    fn sums_equal_the_textbook_statistics_per_window() {
        for (w, h) in [(8, 8), (19, 13), (40, 24)] {
            let a = Plane::from_fn(w, h, |x, y| ((x * 37 + y * 11) % 251) as u8).unwrap();
            let b = Plane::from_fn(w, h, |x, y| ((x * 29 + y * 7 + (x * y) % 13) % 241) as u8).unwrap();
            let (ours, plain) = (ssim_8x8(&a, &b), by_definition(&a, &b));
            assert!((ours - plain).abs() < 1e-12, "{w}x{h}: {ours} vs {plain}");
        }
    }

    #[test]
    fn flat_planes_follow_the_luminance_term_and_tiny_ones_do_not_fail() {
        let want = (2.0 * 100.0 * 120.0 + C1) / (100.0f64 * 100.0 + 120.0 * 120.0 + C1);
        for (w, h) in [(16, 16), (7, 30), (1, 1)] {
            let a = Plane::filled(w, h, 100).unwrap();
            let b = Plane::filled(w, h, 120).unwrap();
            assert!((ssim_8x8(&a, &b) - want).abs() < 1e-12, "{w}x{h}");
        }
    }
}
