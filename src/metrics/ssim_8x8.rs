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

use super::dsp::{metrics, ColumnSums};
use crate::codec::Plane;

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
    let block_row_sums = metrics().ssim_8x8_row_sums;
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
