//! Dense pyramidal Lucas-Kanade.
//!
//! Every pixel solves the Lucas-Kanade normal equations over a Gaussian
//! window of standard deviation `sigma`:
//!
//! `[sum w Ix^2, sum w IxIy; sum w IxIy, sum w Iy^2] d = -[sum w Ix It, sum w Iy It]`
//!
//! The window sums are separable Gaussian filters of whole gradient-product
//! pictures, so the cost per pixel does not grow with the number of pixels
//! in the window, only with its radius. The tensor (left side) comes from
//! the first picture's gradients and is filtered once per level; each
//! Gauss-Newton iteration warps the second picture by the current flow
//! (bilinear), filters the two right-hand sides, and adds the solution.
//! Levels run coarse to fine, each starting from the coarser level's flow,
//! so motions of many pixels are found.
//!
//! Where the tensor is ill-conditioned (its smaller eigenvalue below
//! `min_eigen`, the aperture problem: flat regions, straight edges), the
//! update is not trusted: the pixel keeps the flow it had from the coarser
//! level. The returned confidence is that smaller eigenvalue at the finest
//! level; pixels below `min_eigen` are the ones that fell back.

use ndarray::{Array2, Zip};

use super::pyramid::{gaussian_kernel, gradients, pyramid, separable};
use super::warp::sample_bilinear;
use super::Flow;

/// Settings of dense Lucas-Kanade.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LkParams {
    /// Pyramid levels (1 = the full-size pictures only).
    pub levels: usize,
    /// Standard deviation of the Gaussian window, pixels.
    pub sigma: f32,
    /// Gauss-Newton iterations per level.
    pub iterations: usize,
    /// Smallest eigenvalue of the window tensor (per window weight, i.e. of
    /// mean squared gradients, grey levels^2) below which a pixel keeps the
    /// coarser level's flow.
    pub min_eigen: f32,
}

impl Default for LkParams {
    fn default() -> LkParams {
        LkParams {
            levels: 4,
            sigma: 3.0,
            iterations: 3,
            min_eigen: 1.0,
        }
    }
}

/// A dense flow and how far each pixel's estimate can be trusted.
#[derive(Debug, Clone)]
pub struct LkResult {
    /// The flow from the first picture to the second.
    pub flow: Flow,
    /// The smaller eigenvalue of each pixel's window tensor at the finest
    /// level (mean squared gradient, grey levels^2).
    pub confidence: Array2<f32>,
    /// Pixels whose tensor was ill-conditioned and which kept the coarser
    /// level's flow.
    pub fallback: Array2<bool>,
}

/// Upsamples a flow component to `(h, w)`: each pixel samples the coarse
/// field at its own centre ((x - 0.5) / 2) and doubles the motion.
fn upsample(u: &Array2<f32>, h: usize, w: usize) -> Array2<f32> {
    Array2::from_shape_fn((h, w), |(y, x)| {
        2.0 * sample_bilinear(u, (x as f32 - 0.5) / 2.0, (y as f32 - 0.5) / 2.0)
    })
}

#[inline]
fn min_eigen(a: f32, b: f32, c: f32) -> f32 {
    let half_trace = 0.5 * (a + c);
    let half_diff = 0.5 * (a - c);
    half_trace - (half_diff * half_diff + b * b).sqrt()
}

/// Dense flow from `i1` to `i2` (same size, grey levels 0..255).
///
/// ```
/// use mocomp::flow::lk::{dense_lk, LkParams};
/// use ndarray::Array2;
/// let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos();
/// let i1 = Array2::from_shape_fn((64, 64), |(y, x)| f(x as f32, y as f32));
/// let i2 = Array2::from_shape_fn((64, 64), |(y, x)| f(x as f32 - 1.5, y as f32 + 0.5));
/// let r = dense_lk(&i1, &i2, &LkParams::default());
/// let (u, v) = r.flow.get(32, 32);
/// assert!((u - 1.5).abs() < 0.05 && (v + 0.5).abs() < 0.05);
/// ```
pub fn dense_lk(i1: &Array2<f32>, i2: &Array2<f32>, p: &LkParams) -> LkResult {
    assert_eq!(i1.dim(), i2.dim(), "dense_lk: pictures of different sizes");
    let window = gaussian_kernel(p.sigma);
    let min_size = window.len().max(8);
    let (p1, p2) = (pyramid(i1, p.levels, min_size), pyramid(i2, p.levels, min_size));
    let coarsest = p1.len() - 1;
    let (mut u, mut v) = {
        let (h, w) = p1[coarsest].dim();
        (Array2::<f32>::zeros((h, w)), Array2::<f32>::zeros((h, w)))
    };
    let mut confidence = Array2::zeros(i1.dim());
    let mut fallback = Array2::from_elem(i1.dim(), false);
    for level in (0..=coarsest).rev() {
        let (a1, a2) = (&p1[level], &p2[level]);
        let (h, w) = a1.dim();
        if u.dim() != (h, w) {
            u = upsample(&u, h, w);
            v = upsample(&v, h, w);
        }
        let (gx, gy) = gradients(a1);
        let txx = separable(&(&gx * &gx), &window);
        let txy = separable(&(&gx * &gy), &window);
        let tyy = separable(&(&gy * &gy), &window);
        let lambda = Zip::from(&txx)
            .and(&txy)
            .and(&tyy)
            .map_collect(|&a, &b, &c| min_eigen(a, b, c));
        let good = lambda.mapv(|l| l >= p.min_eigen);
        for _ in 0..p.iterations {
            // Temporal difference after warping the second picture by the flow.
            let it = Array2::from_shape_fn((h, w), |(y, x)| {
                sample_bilinear(a2, x as f32 + u[[y, x]], y as f32 + v[[y, x]]) - a1[[y, x]]
            });
            let bx = separable(&(&gx * &it), &window);
            let by = separable(&(&gy * &it), &window);
            let slices = [&txx, &txy, &tyy, &bx, &by].map(|a| a.as_slice().expect("standard layout"));
            let [sa, sb, sc, sbx, sby] = slices;
            let ok = good.as_slice().expect("standard layout");
            let (us, vs) = (
                u.as_slice_mut().expect("standard layout"),
                v.as_slice_mut().expect("standard layout"),
            );
            for i in 0..us.len() {
                if ok[i] {
                    let (a, b, c) = (sa[i], sb[i], sc[i]);
                    let det = a * c - b * b;
                    us[i] -= (c * sbx[i] - b * sby[i]) / det;
                    vs[i] -= (a * sby[i] - b * sbx[i]) / det;
                }
            }
        }
        if level == 0 {
            confidence = lambda;
            fallback = good.mapv(|g| !g);
        }
    }
    LkResult {
        flow: Flow::from_uv(u, v),
        confidence,
        fallback,
    }
}
