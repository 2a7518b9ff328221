//! Peak signal-to-noise ratio of 8-bit planes.

use serde::Serialize;

use crate::codec::{Frame, Plane};

/// PSNR reported for identical planes (MSE 0), and the largest value ever
/// reported: a finite number keeps means and plots meaningful where the true
/// value would be infinite. (HM prints 99.99 in that case; ffmpeg `inf`.)
pub const PSNR_CAP_DB: f64 = 100.0;

const PEAK: f64 = 255.0;

fn assert_same_size(a: &Plane, b: &Plane) {
    assert!(
        a.width() == b.width() && a.height() == b.height(),
        "planes of different sizes: {}x{} and {}x{}",
        a.width(),
        a.height(),
        b.width(),
        b.height()
    );
}

/// Sum of squared differences over the visible pixels. Panics if the sizes
/// differ.
pub fn sse(a: &Plane, b: &Plane) -> u64 {
    assert_same_size(a, b);
    a.rows()
        .zip(b.rows())
        .map(|(ra, rb)| squared_difference_sum(ra, rb))
        .sum()
}

/// `sum (a[i] - b[i])^2` over the common length of two sample slices: the
/// kernel under [`sse`] and the encoder's block distortions.
///
/// ```
/// use mocomp::metrics::squared_difference_sum;
/// assert_eq!(squared_difference_sum(&[10, 20, 30], &[13, 16, 30]), 9 + 16);
/// ```
pub fn squared_difference_sum(a: &[u8], b: &[u8]) -> u64 {
    (super::dsp::metrics().ssd)(a, b)
}

/// Mean squared error. Panics if the sizes differ.
pub fn mse(a: &Plane, b: &Plane) -> f64 {
    sse(a, b) as f64 / (a.width() * a.height()) as f64
}

/// `10 log10(255^2 / mse)`, at most [`PSNR_CAP_DB`]; NaN for an MSE not
/// measured (NaN).
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse.is_nan() {
        return f64::NAN;
    }
    if mse <= 0.0 {
        return PSNR_CAP_DB;
    }
    (10.0 * (PEAK * PEAK / mse).log10()).min(PSNR_CAP_DB)
}

/// PSNR of `b` against `a` in dB (peak 255). Panics if the sizes differ.
///
/// ```
/// use mocomp::codec::Plane;
/// let a = Plane::filled(8, 8, 50).unwrap();
/// let b = Plane::filled(8, 8, 52).unwrap(); // MSE 4
/// assert!((mocomp::metrics::psnr(&a, &b) - 42.1102).abs() < 1e-4);
/// assert_eq!(mocomp::metrics::psnr(&a, &a), mocomp::metrics::PSNR_CAP_DB);
/// ```
pub fn psnr(a: &Plane, b: &Plane) -> f64 {
    psnr_from_mse(mse(a, b))
}

/// PSNR of each plane of a frame, and the MSEs they come from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FramePsnr {
    /// Luma PSNR (dB).
    #[serde(rename = "psnr_y")]
    pub y: f64,
    /// Cb PSNR (dB).
    #[serde(rename = "psnr_u")]
    pub u: f64,
    /// Cr PSNR (dB).
    #[serde(rename = "psnr_v")]
    pub v: f64,
    /// MSE of Y, U, V.
    pub mse: [f64; 3],
}

impl FramePsnr {
    /// The PSNRs of three planes' MSEs.
    pub fn from_mse(mse: [f64; 3]) -> FramePsnr {
        FramePsnr {
            y: psnr_from_mse(mse[0]),
            u: psnr_from_mse(mse[1]),
            v: psnr_from_mse(mse[2]),
            mse,
        }
    }

    /// The 6:1:1 weighted PSNR, `(6 Y + U + V) / 8`, as JCT-VC reports it.
    pub fn yuv(&self) -> f64 {
        (6.0 * self.y + self.u + self.v) / 8.0
    }
}

/// PSNR of every plane of `test` against `reference`. Panics if the sizes
/// differ.
pub fn frame_psnr(reference: &Frame, test: &Frame) -> FramePsnr {
    FramePsnr::from_mse([0, 1, 2].map(|i| mse(reference.plane(i), test.plane(i))))
}
