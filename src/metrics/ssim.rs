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

use super::dsp::{metrics, ssim_from_stats, BandScratch, WIN};
use crate::codec::Plane;

const SIGMA: f64 = 1.5;

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
    let band_sum = metrics().ssim_band;
    let partial: Vec<f64> = tasks
        .par_iter()
        .map_init(BandScratch::default, |scratch, &y0| {
            band_sum(scratch, a, b, &g, y0, ROWS_PER_TASK.min(oh - y0), ow)
        })
        .collect();
    partial.iter().sum::<f64>() / (ow * oh) as f64
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
    use crate::metrics::dsp::C1;

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
    fn one_pixel_pictures_do_not_fail() {
        let a = Plane::filled(1, 1, 0).unwrap();
        let b = Plane::filled(1, 1, 255).unwrap();
        let s = ssim(&a, &b);
        assert!(s.is_finite() && s < 0.01, "{s}");
    }
}
