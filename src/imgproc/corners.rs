//! Corner response: the structure tensor's smaller eigenvalue (Shi and
//! Tomasi 1994), what keypoint detection and sparse tracking both select
//! points by.

use ndarray::Array2;

use super::pyramid::{gaussian_kernel, gradients, separable};

/// The smaller eigenvalue of the structure tensor, smoothed over a
/// Gaussian window of sigma 1.5.
pub fn min_eigen(img: &Array2<f32>) -> Array2<f32> {
    let (gx, gy) = gradients(img);
    let k = gaussian_kernel(1.5);
    let (a, b, c) = (
        separable(&(&gx * &gx), &k),
        separable(&(&gx * &gy), &k),
        separable(&(&gy * &gy), &k),
    );
    ndarray::Zip::from(&a)
        .and(&b)
        .and(&c)
        .map_collect(|&a, &b, &c| 0.5 * (a + c) - (0.25 * (a - c) * (a - c) + b * b).sqrt())
}
