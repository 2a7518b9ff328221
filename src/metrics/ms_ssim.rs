//! Multi-scale SSIM (Wang, Simoncelli, Bovik 2003) as libvmaf's
//! `float_ms_ssim` computes it: the figure AWCY reports as "MS-SSIM
//! (libvmaf)" and codec comparisons quote.
//!
//! At each of five scales the luminance, contrast and structure terms are
//! averaged separately over the positions where the 11x11 Gaussian window
//! (sigma 1.5) lies inside the picture; the score is the product of the
//! scales' mean contrast and structure raised to Wang's weights, times the
//! coarsest scale's mean luminance raised to its weight. Between scales the
//! picture is low-passed by the 9/7 wavelet's analysis filter (half-sample
//! symmetric edges) and every other sample kept, the odd last one included.
//!
//! libvmaf refuses pictures under 176 samples on a side (five scales of an
//! 11-sample window). Here such pictures use as many scales as fit, with the
//! same weights for those scales: a figure for small pictures that is not
//! comparable with full-size ones. Under 11 samples there is no window
//! position, and the result is SSIM from the whole picture's statistics.

use crate::codec::Plane;

const WIN: usize = 11;
const SIGMA: f64 = 1.5;
const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);
const C3: f64 = C2 / 2.0;
/// Wang et al.'s exponents per scale, finest first (the luminance term
/// only at the coarsest).
const WEIGHTS: [f64; 5] = [0.0448, 0.2856, 0.3001, 0.2363, 0.1333];
/// The 9/7 analysis low-pass, normalised to unit gain, as libvmaf's tables
/// hold it (centre tap first).
const LOWPASS: [f64; 5] = [0.602914, 0.266846, -0.078201, -0.016828, 0.026727];

/// One scale's picture, in floating point after the first.
struct Image {
    width: usize,
    height: usize,
    samples: Vec<f64>,
}

impl Image {
    fn from_plane(p: &Plane) -> Image {
        let samples = p.rows().flat_map(|r| r.iter().map(|&v| f64::from(v))).collect();
        Image {
            width: p.width(),
            height: p.height(),
            samples,
        }
    }

    fn row(&self, y: usize) -> &[f64] {
        &self.samples[y * self.width..(y + 1) * self.width]
    }
}

/// The means of the luminance, contrast and structure maps.
#[derive(Debug, Clone, Copy)]
struct Terms {
    l: f64,
    c: f64,
    s: f64,
}

/// MS-SSIM of `b` against `a` (same size), between 0 and 1. Panics if the
/// sizes differ.
///
/// ```
/// use mocomp::codec::Plane;
/// let a = Plane::from_fn(200, 180, |x, y| ((x * 37 + y * 11) % 251) as u8).unwrap();
/// assert!((mocomp::metrics::ms_ssim(&a, &a) - 1.0).abs() < 1e-9);
/// let b = Plane::from_fn(200, 180, |x, y| ((x * 37 + y * 11) % 251) as u8 / 2 + 40).unwrap();
/// assert!(mocomp::metrics::ms_ssim(&a, &b) < 0.9);
/// ```
pub fn ms_ssim(a: &Plane, b: &Plane) -> f64 {
    assert!(
        a.width() == b.width() && a.height() == b.height(),
        "ms_ssim: planes of different sizes"
    );
    let scales = scales_that_fit(a.width().min(a.height()));
    let (mut x, mut y) = (Image::from_plane(a), Image::from_plane(b));
    if scales == 0 {
        let t = whole_picture_terms(&x, &y);
        return t.l * t.c * t.s;
    }
    let g = gaussian_window();
    let mut score = 1.0;
    for (scale, &weight) in WEIGHTS.iter().enumerate().take(scales) {
        let t = scale_terms(&x, &y, &g);
        score *= (t.c * t.s).powf(weight);
        if scale + 1 == scales {
            score *= t.l.powf(weight);
        } else {
            x = decimate(&x);
            y = decimate(&y);
        }
    }
    score
}

/// Scales whose picture is at least the window's size, at most five.
fn scales_that_fit(shorter_side: usize) -> usize {
    (0..WEIGHTS.len())
        .take_while(|&k| shorter_side >> k >= WIN)
        .count()
}

fn gaussian_window() -> [f64; WIN] {
    let c = (WIN / 2) as f64;
    let g: [f64; WIN] = std::array::from_fn(|i| {
        let d = i as f64 - c;
        (-d * d / (2.0 * SIGMA * SIGMA)).exp()
    });
    let sum: f64 = g.iter().sum();
    g.map(|w| w / sum)
}

/// Means of the three maps over the window positions inside the picture
/// (separable filtering of x, y, x^2, y^2, xy).
fn scale_terms(a: &Image, b: &Image, g: &[f64; WIN]) -> Terms {
    let (w, h) = (a.width, a.height);
    let (ow, oh) = (w - WIN + 1, h - WIN + 1);
    // Horizontally filtered statistics of every input row.
    let mut hf: [Vec<f64>; 5] = std::array::from_fn(|_| vec![0.0; h * ow]);
    for r in 0..h {
        let (ra, rb) = (a.row(r), b.row(r));
        for x in 0..ow {
            let mut s = [0.0; 5];
            for (k, &gk) in g.iter().enumerate() {
                let (p, q) = (ra[x + k], rb[x + k]);
                s[0] += gk * p;
                s[1] += gk * q;
                s[2] += gk * p * p;
                s[3] += gk * q * q;
                s[4] += gk * p * q;
            }
            for (plane, v) in hf.iter_mut().zip(s) {
                plane[r * ow + x] = v;
            }
        }
    }
    let mut sum = Terms {
        l: 0.0,
        c: 0.0,
        s: 0.0,
    };
    for r in 0..oh {
        for x in 0..ow {
            let mut s = [0.0; 5];
            for (k, &gk) in g.iter().enumerate() {
                for (acc, plane) in s.iter_mut().zip(&hf) {
                    *acc += gk * plane[(r + k) * ow + x];
                }
            }
            let t = terms_from_stats(s);
            sum.l += t.l;
            sum.c += t.c;
            sum.s += t.s;
        }
    }
    let n = (ow * oh) as f64;
    Terms {
        l: sum.l / n,
        c: sum.c / n,
        s: sum.s / n,
    }
}

/// The three terms from local means of x, y, x^2, y^2, xy. Variances are
/// clamped at 0 (rounding can make them negative on flat areas), and a
/// negative covariance where both deviations are 0 counts as 0, so that
/// identical pictures score exactly 1.
fn terms_from_stats([mx, my, xx, yy, xy]: [f64; 5]) -> Terms {
    let vx = (xx - mx * mx).max(0.0);
    let vy = (yy - my * my).max(0.0);
    let sxy = (vx * vy).sqrt();
    let mut cov = xy - mx * my;
    if cov < 0.0 && sxy <= 0.0 {
        cov = 0.0;
    }
    Terms {
        l: (2.0 * mx * my + C1) / (mx * mx + my * my + C1),
        c: (2.0 * sxy + C2) / (vx + vy + C2),
        s: (cov + C3) / (sxy + C3),
    }
}

fn whole_picture_terms(a: &Image, b: &Image) -> Terms {
    let n = a.samples.len().max(1) as f64;
    let mut s = [0.0; 5];
    for (&p, &q) in a.samples.iter().zip(&b.samples) {
        s[0] += p;
        s[1] += q;
        s[2] += p * p;
        s[3] += q * q;
        s[4] += p * q;
    }
    terms_from_stats(s.map(|v| v / n))
}

/// Half-sample symmetric index: -1 -> 0, n -> n - 1.
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let i = if i < 0 {
        -1 - i
    } else if i >= n {
        2 * n - 1 - i
    } else {
        i
    };
    i.clamp(0, n - 1) as usize
}

/// Low-pass with the 9/7 filter, then keep samples 0, 2, 4, ... in each
/// direction (ceil(n / 2) of them).
fn decimate(img: &Image) -> Image {
    let (w, h) = (img.width, img.height);
    let (dw, dh) = (w.div_ceil(2), h.div_ceil(2));
    let tap = |k: isize| LOWPASS[k.unsigned_abs()];
    // Horizontal pass at the kept columns, every row.
    let mut hp = vec![0.0; h * dw];
    for y in 0..h {
        let row = img.row(y);
        for x in 0..dw {
            let cx = (2 * x) as isize;
            hp[y * dw + x] = (-4..=4).map(|k| tap(k) * row[reflect(cx + k, w)]).sum();
        }
    }
    let mut out = vec![0.0; dh * dw];
    for y in 0..dh {
        let cy = (2 * y) as isize;
        for x in 0..dw {
            out[y * dw + x] = (-4..=4).map(|k| tap(k) * hp[reflect(cy + k, h) * dw + x]).sum();
        }
    }
    Image {
        width: dw,
        height: dh,
        samples: out,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lowpass_has_unit_gain() {
        let sum = LOWPASS[0] + 2.0 * LOWPASS[1..].iter().sum::<f64>();
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
    }

    #[test]
    fn scales_follow_the_shorter_side() {
        assert_eq!(scales_that_fit(176), 5);
        assert_eq!(scales_that_fit(175), 4);
        assert_eq!(scales_that_fit(144), 4);
        assert_eq!(scales_that_fit(22), 2);
        assert_eq!(scales_that_fit(10), 0);
    }

    #[test]
    fn decimation_keeps_flat_pictures_and_halves_sizes_rounding_up() {
        let img = Image {
            width: 7,
            height: 4,
            samples: vec![90.0; 28],
        };
        let d = decimate(&img);
        assert_eq!((d.width, d.height), (4, 2));
        assert!(d.samples.iter().all(|&v| (v - 90.0).abs() < 1e-2));
    }

    #[test]
    fn reflection_is_half_sample_symmetric() {
        assert_eq!(reflect(-1, 5), 0);
        assert_eq!(reflect(-3, 5), 2);
        assert_eq!(reflect(5, 5), 4);
        assert_eq!(reflect(6, 5), 3);
    }

    #[test]
    fn a_contrast_loss_lowers_the_score_more_than_a_small_offset() {
        let a = Plane::from_fn(180, 180, |x, y| (((x / 3) * 7 + (y / 5) * 13) % 200) as u8 + 20).unwrap();
        let offset = Plane::from_fn(180, 180, |x, y| a.get(x, y) + 2).unwrap();
        let flat = Plane::from_fn(180, 180, |x, y| (a.get(x, y) / 4) + 90).unwrap();
        let (so, sf) = (ms_ssim(&a, &offset), ms_ssim(&a, &flat));
        assert!(so > 0.99 && sf < 0.8, "{so} {sf}");
    }

    #[test]
    fn tiny_pictures_do_not_fail() {
        let a = Plane::filled(3, 2, 100).unwrap();
        let b = Plane::filled(3, 2, 120).unwrap();
        let want = (2.0 * 100.0 * 120.0 + C1) / (100.0f64 * 100.0 + 120.0 * 120.0 + C1);
        assert!((ms_ssim(&a, &b) - want).abs() < 1e-12);
    }
}
