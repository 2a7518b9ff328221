//! Structural similarity (Wang, Bovik, Sheikh, Simoncelli 2004).
//!
//! As in the paper's reference implementation: local statistics under an
//! 11x11 Gaussian window of standard deviation 1.5 (normalised to sum 1),
//! `K1 = 0.01`, `K2 = 0.03`, `L = 255`, population (not sample) variances,
//! and the SSIM map averaged over the positions where the whole window lies
//! inside the picture; no downsampling. This is what scikit-image's
//! `structural_similarity(gaussian_weights=True, sigma=1.5,
//! use_sample_covariance=False, data_range=255)` computes.
//!
//! Pictures narrower or shorter than the window have no such position: their
//! SSIM is computed once from the statistics of the whole picture with equal
//! weights.

use rayon::prelude::*;

use crate::codec::Plane;

const WIN: usize = 11;
const SIGMA: f64 = 1.5;
const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

/// Output rows per parallel task: each task filters its own 10-row halo, so
/// the result does not depend on the number of threads.
const ROWS_PER_TASK: usize = 32;

fn gaussian_window() -> [f64; WIN] {
    let mut g = [0.0; WIN];
    let c = (WIN / 2) as f64;
    for (i, w) in g.iter_mut().enumerate() {
        let d = i as f64 - c;
        *w = (-d * d / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = g.iter().sum();
    g.map(|w| w / sum)
}

#[inline(always)]
fn ssim_from_stats(mx: f64, my: f64, xx: f64, yy: f64, xy: f64) -> f64 {
    let (vx, vy, cov) = (xx - mx * mx, yy - my * my, xy - mx * my);
    ((2.0 * mx * my + C1) * (2.0 * cov + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2))
}

/// Mean SSIM of `b` against `a` (luma planes, same size). 1.0 for identical
/// planes. Panics if the sizes differ.
///
/// ```
/// use mocomp::codec::Plane;
/// let a = Plane::from_fn(32, 32, |x, y| ((x * 37 + y * 11) % 251) as u8).unwrap();
/// assert!((mocomp::metrics::ssim(&a, &a) - 1.0).abs() < 1e-12);
/// let b = Plane::from_fn(32, 32, |x, y| ((x * 37 + y * 11) % 251) as u8 / 2).unwrap();
/// assert!(mocomp::metrics::ssim(&a, &b) < 0.9);
/// ```
pub fn ssim(a: &Plane, b: &Plane) -> f64 {
    assert!(
        a.width() == b.width() && a.height() == b.height(),
        "ssim: planes of different sizes"
    );
    let (w, h) = (a.width(), a.height());
    if w < WIN || h < WIN {
        return ssim_whole_picture(a, b);
    }
    let g = gaussian_window();
    let (ow, oh) = (w - WIN + 1, h - WIN + 1);
    let tasks: Vec<usize> = (0..oh).step_by(ROWS_PER_TASK).collect();
    let partial: Vec<f64> = tasks
        .par_iter()
        .map_init(BandScratch::default, |scratch, &y0| {
            band_sum(scratch, a, b, &g, y0, ROWS_PER_TASK.min(oh - y0), ow)
        })
        .collect();
    partial.iter().sum::<f64>() / (ow * oh) as f64
}

/// Buffers of one band, kept between the bands a worker computes (fresh
/// ones cost more in page faults than the filtering).
#[derive(Default)]
struct BandScratch {
    /// Horizontally filtered statistics.
    hf: [Vec<f64>; 5],
    /// One input row's x, y, x^2, y^2, xy.
    products: [Vec<f64>; 5],
    /// One output row's statistics.
    stats: [Vec<f64>; 5],
}

/// The sum of the SSIM map over output rows y0 .. y0 + rows.
fn band_sum(
    scratch: &mut BandScratch,
    a: &Plane,
    b: &Plane,
    g: &[f64; WIN],
    y0: usize,
    rows: usize,
    ow: usize,
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    {
        // std caches the answer after the first call.
        if crate::codec::cpu::at_least(crate::codec::cpu::CpuLevel::Avx2) {
            // SAFETY: the CPU has AVX2; the function is the safe code below
            // compiled with AVX2 (no FMA, so every sum rounds as in the
            // baseline build).
            return unsafe { band_sum_avx2(scratch, a, b, g, y0, rows, ow) };
        }
    }
    band_sum_body(scratch, a, b, g, y0, rows, ow)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn band_sum_avx2(
    scratch: &mut BandScratch,
    a: &Plane,
    b: &Plane,
    g: &[f64; WIN],
    y0: usize,
    rows: usize,
    ow: usize,
) -> f64 {
    band_sum_body(scratch, a, b, g, y0, rows, ow)
}

/// Separable Gaussian statistics, one array per statistic (x, y, x^2, y^2,
/// xy) so that the tap-outer loops vectorise.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // five statistics indexed in step
fn band_sum_body(
    scratch: &mut BandScratch,
    a: &Plane,
    b: &Plane,
    g: &[f64; WIN],
    y0: usize,
    rows: usize,
    ow: usize,
) -> f64 {
    let w = a.width();
    let in_rows = rows + WIN - 1;
    let BandScratch { hf, products, stats } = scratch;
    for v in hf.iter_mut() {
        v.clear();
        v.resize(in_rows * ow, 0.0);
    }
    for v in products.iter_mut().chain(stats.iter_mut()) {
        v.resize(w.max(ow), 0.0);
    }
    for r in 0..in_rows {
        let (ra, rb) = (a.row(y0 + r), b.row(y0 + r));
        for x in 0..w {
            let (p, q) = (f64::from(ra[x]), f64::from(rb[x]));
            products[0][x] = p;
            products[1][x] = q;
            products[2][x] = p * p;
            products[3][x] = q * q;
            products[4][x] = p * q;
        }
        for (out, src) in hf.iter_mut().zip(products.iter()) {
            let out = &mut out[r * ow..(r + 1) * ow];
            for (k, &gk) in g.iter().enumerate() {
                for (o, &v) in out.iter_mut().zip(&src[k..k + ow]) {
                    *o += gk * v;
                }
            }
        }
    }
    let mut sum = 0.0;
    for r in 0..rows {
        for (out, src) in stats.iter_mut().zip(hf.iter()) {
            let out = &mut out[..ow];
            out.fill(0.0);
            for (k, &gk) in g.iter().enumerate() {
                for (o, &v) in out.iter_mut().zip(&src[(r + k) * ow..(r + k + 1) * ow]) {
                    *o += gk * v;
                }
            }
        }
        for x in 0..ow {
            sum += ssim_from_stats(stats[0][x], stats[1][x], stats[2][x], stats[3][x], stats[4][x]);
        }
    }
    sum
}

fn ssim_whole_picture(a: &Plane, b: &Plane) -> f64 {
    let n = (a.width() * a.height()) as f64;
    let mut s = [0.0f64; 5];
    for (ra, rb) in a.rows().zip(b.rows()) {
        for (&p, &q) in ra.iter().zip(rb) {
            let (p, q) = (p as f64, q as f64);
            s[0] += p;
            s[1] += q;
            s[2] += p * p;
            s[3] += q * q;
            s[4] += p * q;
        }
    }
    let s = s.map(|v| v / n);
    ssim_from_stats(s[0], s[1], s[2], s[3], s[4])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_is_normalised_and_symmetric() {
        let g = gaussian_window();
        assert!((g.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for i in 0..WIN {
            assert_eq!(g[i], g[WIN - 1 - i]);
        }
        assert!(g[5] > g[4] && g[4] > g[0]);
    }

    #[test]
    fn constant_planes_follow_the_luminance_term() {
        // Flat planes: variances 0, so SSIM = (2 mx my + C1) / (mx^2 + my^2 + C1).
        let a = Plane::filled(20, 20, 100).unwrap();
        let b = Plane::filled(20, 20, 120).unwrap();
        let want = (2.0 * 100.0 * 120.0 + C1) / (100.0f64 * 100.0 + 120.0 * 120.0 + C1);
        assert!((ssim(&a, &b) - want).abs() < 1e-12);
        // The tiny-picture path gives the same on flat planes.
        let a = Plane::filled(3, 2, 100).unwrap();
        let b = Plane::filled(3, 2, 120).unwrap();
        assert!((ssim(&a, &b) - want).abs() < 1e-12);
    }

    #[test]
    fn the_dispatched_band_equals_its_scalar_twin() {
        let a = Plane::from_fn(70, 40, |x, y| ((x * 37 + y * 11) % 251) as u8).unwrap();
        let b = Plane::from_fn(70, 40, |x, y| ((x * 31 + y * 17) % 241) as u8).unwrap();
        let g = gaussian_window();
        let (ow, oh) = (70 - WIN + 1, 40 - WIN + 1);
        assert_eq!(
            band_sum(&mut BandScratch::default(), &a, &b, &g, 3, oh - 3, ow),
            band_sum_body(&mut BandScratch::default(), &a, &b, &g, 3, oh - 3, ow)
        );
    }

    #[test]
    fn one_pixel_pictures_do_not_fail() {
        let a = Plane::filled(1, 1, 0).unwrap();
        let b = Plane::filled(1, 1, 255).unwrap();
        let s = ssim(&a, &b);
        assert!(s.is_finite() && s < 0.01, "{s}");
    }
}
