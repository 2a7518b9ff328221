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
//! (bicubic), filters the two right-hand sides, and adds the solution.
//! Levels run coarse to fine, each starting from the coarser level's flow,
//! so motions of many pixels are found.
//!
//! Where the tensor is ill-conditioned (its smaller eigenvalue below
//! `min_eigen`, the aperture problem: flat regions, straight edges), the
//! update is not trusted: the pixel keeps the flow it had from the coarser
//! level. The returned confidence is that smaller eigenvalue at the finest
//! level; pixels below `min_eigen` are the ones that fell back.

use ndarray::Array2;
use rayon::prelude::*;

use super::warp::{cubic_weights, sample_bicubic};
use super::Flow;
use crate::imgproc::pyramid::{
    filter_cols_slice, filter_rows_slice, full_depth, gaussian_kernel, normalize_levels, parallel_worth,
    rows_per_task, separable_slice, upsample2, Pyramid, DERIVATIVE,
};

/// Settings of dense Lucas-Kanade.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LkParams {
    /// Pyramid levels (1 = the full-size pictures only; 0 = as many as the
    /// picture allows, down to a coarsest level 16-31 pixels on its longer
    /// side: LK's update reaches a pixel or two per level, so motion of
    /// tens of pixels needs the deep pyramid).
    pub levels: usize,
    /// Standard deviation of the Gaussian window, pixels.
    pub sigma: f32,
    /// Gauss-Newton iterations per level.
    pub iterations: usize,
    /// Smallest eigenvalue of the window tensor (per window weight, i.e. of
    /// mean squared gradients, grey levels^2) below which a pixel keeps the
    /// coarser level's flow.
    pub min_eigen: f32,
    /// Finest pyramid level computed (0 = full size); the flow of that
    /// level is upsampled to full size. 1 costs a quarter of the work.
    pub finest: usize,
    /// Match locally contrast-normalised pictures
    /// ([`crate::imgproc::pyramid::normalize_contrast`]) instead of grey levels: robust to gain,
    /// offset and ramps of the lighting, which coarse levels otherwise
    /// mistake for motion. Off by default (the encoder's flow and the
    /// small-motion tests were measured without it; on a small noise-free
    /// scene with flat areas it costs accuracy); the CLI's presets use it.
    pub normalize: bool,
}

impl Default for LkParams {
    fn default() -> LkParams {
        LkParams {
            levels: 4,
            sigma: 4.0,
            iterations: 1,
            min_eigen: 1.0,
            finest: 0,
            normalize: false,
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

/// `field` (of a level `scale` times smaller) at `(h, w)`, each pixel
/// taking the value of the coarse pixel it lies in.
fn nearest_upscaled(field: &Array2<f32>, scale: usize, (h, w): (usize, usize)) -> Array2<f32> {
    let (fh, fw) = field.dim();
    let src = field.as_slice().expect("standard");
    let mut out = Array2::zeros((h, w));
    for (y, mut row) in out.rows_mut().into_iter().enumerate() {
        let line = &src[(y / scale).min(fh - 1) * fw..][..fw];
        for (x, c) in row.iter_mut().enumerate() {
            *c = line[(x / scale).min(fw - 1)];
        }
    }
    out
}

#[inline]
fn min_eigen(a: f32, b: f32, c: f32) -> f32 {
    let half_trace = 0.5 * (a + c);
    let half_diff = 0.5 * (a - c);
    half_trace - (half_diff * half_diff + b * b).sqrt()
}

/// Work buffers, allocated once at the finest level's size and reused, in
/// their leading `h * w` part, by every level (and by later calls).
#[derive(Debug)]
struct Scratch {
    gx: Vec<f32>,
    gy: Vec<f32>,
    products: [Vec<f32>; 3],
    tensor: [Vec<f32>; 3],
    masked: Vec<f32>,
    it: Vec<f32>,
    inside: Vec<f32>,
    bx: Vec<f32>,
    by: Vec<f32>,
    tmp: Vec<f32>,
}

impl Scratch {
    fn new(n: usize) -> Scratch {
        let z = || vec![0f32; n];
        Scratch {
            gx: z(),
            gy: z(),
            products: [z(), z(), z()],
            tensor: [z(), z(), z()],
            masked: z(),
            it: z(),
            inside: z(),
            bx: z(),
            by: z(),
            tmp: z(),
        }
    }

    /// The window sums of the gradient products (the tensor), with the
    /// pixels marked outside left out when `masked`.
    fn window_tensor(&mut self, h: usize, w: usize, window: &[f32], masked: bool) {
        let n = h * w;
        for k in 0..3 {
            if masked {
                for i in 0..n {
                    self.masked[i] = self.products[k][i] * self.inside[i];
                }
                separable_slice(&self.masked, h, w, window, &mut self.tmp, &mut self.tensor[k]);
            } else {
                separable_slice(
                    &self.products[k],
                    h,
                    w,
                    window,
                    &mut self.tmp,
                    &mut self.tensor[k],
                );
            }
        }
    }

    /// The window sums of the gradients times the temporal difference (the
    /// right-hand sides).
    fn window_mismatch(&mut self, h: usize, w: usize, window: &[f32]) {
        let n = h * w;
        for i in 0..n {
            self.masked[i] = self.gx[i] * self.it[i];
        }
        separable_slice(&self.masked, h, w, window, &mut self.tmp, &mut self.bx);
        for i in 0..n {
            self.masked[i] = self.gy[i] * self.it[i];
        }
        separable_slice(&self.masked, h, w, window, &mut self.tmp, &mut self.by);
    }

    /// One Gauss-Newton update of the first `n` pixels' flow, where the
    /// tensor's smaller eigenvalue (kept in `lambda`) reaches `min_eigen`.
    fn solve(&self, n: usize, u: &mut [f32], v: &mut [f32], lambda: &mut [f32], threshold: f32) {
        let [sa, sb, sc] = [0, 1, 2].map(|k| &self.tensor[k][..n]);
        let (sbx, sby) = (&self.bx[..n], &self.by[..n]);
        for i in 0..n {
            let (a, b, c) = (sa[i], sb[i], sc[i]);
            lambda[i] = min_eigen(a, b, c);
            if lambda[i] >= threshold {
                let det = a * c - b * b;
                u[i] -= (c * sbx[i] - b * sby[i]) / det;
                v[i] -= (a * sby[i] - b * sbx[i]) / det;
            }
        }
    }

    /// Gradients of `a1` and their products, for a level of `h x w`.
    fn prepare(&mut self, a1: &[f32], h: usize, w: usize) {
        let n = h * w;
        filter_rows_slice(a1, h, w, &DERIVATIVE, &mut self.gx);
        filter_cols_slice(a1, h, w, &DERIVATIVE, &mut self.gy);
        let (gx, gy) = (&self.gx[..n], &self.gy[..n]);
        let [pxx, pxy, pyy] = &mut self.products;
        for i in 0..n {
            pxx[i] = gx[i] * gx[i];
            pxy[i] = gx[i] * gy[i];
            pyy[i] = gy[i] * gy[i];
        }
    }

    /// `it = i2(p + w(p)) - i1(p)` (bicubic) and the mask of pixels whose
    /// warped position stays inside; returns whether any left the picture.
    fn temporal(&mut self, s1: &[f32], a2: &Array2<f32>, su: &[f32], sv: &[f32], h: usize, w: usize) -> bool {
        let s2 = a2.as_slice().expect("standard");
        let (wmax, hmax) = ((w - 1) as f32, (h - 1) as f32);
        // Rows in parallel: each pixel is computed the same way whatever
        // the number of threads.
        let band = rows_per_task(w);
        let row_band = |(t, (it, m)): (usize, (&mut [f32], &mut [f32]))| {
            let mut any_outside = false;
            for (r, (it, m)) in it.chunks_mut(w).zip(m.chunks_mut(w)).enumerate() {
                let y = t * band + r;
                for x in 0..w {
                    let i = y * w + x;
                    let (px, py) = (x as f32 + su[i], y as f32 + sv[i]);
                    if !(px >= 0.0 && py >= 0.0 && px <= wmax && py <= hmax) {
                        it[x] = 0.0;
                        m[x] = 0.0;
                        any_outside = true;
                        continue;
                    }
                    m[x] = 1.0;
                    // Inside by at least a pixel: the 4x4 footprint needs no clamping.
                    let (ix, iy) = (px as usize, py as usize);
                    it[x] = if ix >= 1 && iy >= 1 && ix + 2 < w && iy + 2 < h {
                        let (wx, wy) = (cubic_weights(px - ix as f32), cubic_weights(py - iy as f32));
                        let mut acc = 0.0;
                        for (j, &wyj) in wy.iter().enumerate() {
                            let row = &s2[(iy + j - 1) * w + ix - 1..(iy + j - 1) * w + ix + 3];
                            acc += wyj * (wx[0] * row[0] + wx[1] * row[1] + wx[2] * row[2] + wx[3] * row[3]);
                        }
                        acc
                    } else {
                        sample_bicubic(a2, px, py)
                    } - s1[i];
                }
            }
            any_outside
        };
        let (it, inside) = (&mut self.it[..h * w], &mut self.inside[..h * w]);
        if parallel_worth(h * w) {
            it.par_chunks_mut(band * w)
                .zip(inside.par_chunks_mut(band * w))
                .enumerate()
                .map(row_band)
                .reduce(|| false, |a, b| a || b)
        } else {
            // Every band must run (it writes its rows): no short-circuit.
            let mut any_outside = false;
            for band_rows in it
                .chunks_mut(band * w)
                .zip(inside.chunks_mut(band * w))
                .enumerate()
            {
                any_outside |= row_band(band_rows);
            }
            any_outside
        }
    }
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
    Lk::new(*p).compute(i1, i2)
}

/// Dense Lucas-Kanade that keeps its pyramids and work buffers from one call
/// to the next (pictures of the same size then cost no allocation beyond
/// the result, except the contrast normalisation's, which allocates its
/// filtered copies per level when [`LkParams::normalize`] is on), for
/// sequences and for timing the method rather than the allocator.
#[derive(Debug)]
pub struct Lk {
    params: LkParams,
    p1: Pyramid,
    p2: Pyramid,
    scratch: Option<Scratch>,
}

impl Lk {
    /// An estimator with these settings.
    pub fn new(params: LkParams) -> Lk {
        assert!(
            params.sigma > 0.0 && params.sigma <= 10.0,
            "dense_lk: window sigma {} outside (0, 10]",
            params.sigma
        );
        Lk {
            params,
            p1: Pyramid::default(),
            p2: Pyramid::default(),
            scratch: None,
        }
    }

    /// Dense flow from `i1` to `i2` (same size, grey levels 0..255).
    pub fn compute(&mut self, i1: &Array2<f32>, i2: &Array2<f32>) -> LkResult {
        assert_eq!(i1.dim(), i2.dim(), "dense_lk: pictures of different sizes");
        let p = self.params;
        let window = gaussian_kernel(p.sigma);
        // Coarse levels may be smaller than the window (borders repeat): what
        // matters is that the coarsest level sees the motion as under a pixel.
        let min_size = 8;
        let levels = match p.levels {
            0 => full_depth(i1.ncols(), i1.nrows()),
            n => n,
        };
        self.p1.build(i1, levels, min_size);
        self.p2.build(i2, levels, min_size);
        if p.normalize {
            normalize_levels(&mut self.p1.levels);
            normalize_levels(&mut self.p2.levels);
        }
        let (p1, p2) = (&self.p1.levels, &self.p2.levels);
        let coarsest = p1.len() - 1;
        let finest = p.finest.min(coarsest);
        let (mut u, mut v) = {
            let (h, w) = p1[coarsest].dim();
            (Array2::<f32>::zeros((h, w)), Array2::<f32>::zeros((h, w)))
        };
        let needed = p1[finest].len();
        if self.scratch.as_ref().is_none_or(|s| s.gx.len() < needed) {
            self.scratch = Some(Scratch::new(needed));
        }
        let buf = self.scratch.as_mut().expect("just made");
        let mut lambda = Array2::zeros(p1[coarsest].dim());
        for level in (finest..=coarsest).rev() {
            let (h, w) = p1[level].dim();
            if u.dim() != (h, w) {
                u = upsample2(&u, h, w, 2.0);
                v = upsample2(&v, h, w, 2.0);
            }
            lambda = Array2::zeros((h, w));
            refine_level(
                buf,
                (&p1[level], &p2[level]),
                (&mut u, &mut v),
                &mut lambda,
                (&window, &p),
            );
        }
        // From the finest level computed up to full size.
        let (h0, w0) = i1.dim();
        for level in (1..=finest).rev() {
            let (h, w) = p1[level - 1].dim();
            u = upsample2(&u, h, w, 2.0);
            v = upsample2(&v, h, w, 2.0);
        }
        let confidence = nearest_upscaled(&lambda, 1 << finest, (h0, w0));
        let fallback = confidence.mapv(|l| l < p.min_eigen);
        LkResult {
            flow: Flow::from_uv(u, v),
            confidence,
            fallback,
        }
    }
}

/// One level's iterations: the flow `u`, `v` (the level's size, the
/// coarser level's upsampled) refined in place, and each pixel's smaller
/// eigenvalue of its window tensor into `lambda` (the level's size).
fn refine_level(
    buf: &mut Scratch,
    (a1, a2): (&Array2<f32>, &Array2<f32>),
    (u, v): (&mut Array2<f32>, &mut Array2<f32>),
    lambda: &mut Array2<f32>,
    (window, p): (&[f32], &LkParams),
) {
    let (h, w) = a1.dim();
    let s1 = a1.as_slice().expect("standard");
    buf.prepare(s1, h, w);
    let mut tensor_unmasked = false;
    for _ in 0..p.iterations {
        let any_outside = buf.temporal(
            s1,
            a2,
            u.as_slice().expect("standard"),
            v.as_slice().expect("standard"),
            h,
            w,
        );
        // The window tensor, without the pixels whose warped position
        // left the picture (they see only the repeated edge); filtered
        // once while no pixel is out.
        if any_outside || !tensor_unmasked {
            buf.window_tensor(h, w, window, any_outside);
            tensor_unmasked = !any_outside;
        }
        buf.window_mismatch(h, w, window);
        buf.solve(
            h * w,
            u.as_slice_mut().expect("standard"),
            v.as_slice_mut().expect("standard"),
            lambda.as_slice_mut().expect("standard"),
            p.min_eigen,
        );
    }
}
