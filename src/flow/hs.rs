//! Horn-Schunck optical flow, coarse to fine with warping.
//!
//! The flow minimises, over the whole picture,
//!
//! `sum (Ix du + Iy dv + It)^2 + alpha^2 (|grad u|^2 + |grad v|^2)`
//!
//! where the data term is linearised around the current flow `(u0, v0)`:
//! the second picture is warped by it (bicubic), `It` is the difference to
//! the first, and `(Ix, Iy)` the mean of both pictures' gradients. The
//! Euler-Lagrange equations, with the 4-neighbour Laplacian and reflecting
//! borders, give the classical per-pixel update
//!
//! `u = (alpha^2 sum_n u_n + Ix^2 u0 - Ix Iy (v - v0) - Ix It) / (Ix^2 + alpha^2 N)`
//!
//! (and the same for `v`), applied in place in raster order (Gauss-Seidel)
//! with over-relaxation `omega` (SOR). Each warp runs sweeps until the
//! largest change falls below `tolerance` or `iterations` sweeps are done;
//! each level warps `warps` times; levels run coarse to fine, so motions of
//! several pixels are found. A larger `alpha` gives a smoother field that
//! fills textureless regions from their surroundings.

use ndarray::Array2;

use super::warp::sample_bicubic;
use super::Flow;
use crate::imgproc::pyramid::{gradients, pyramid, upsample2};

/// Settings of Horn-Schunck.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HsParams {
    /// Smoothness weight, grey levels per pixel of motion gradient.
    pub alpha: f32,
    /// Pyramid levels.
    pub levels: usize,
    /// Warps (re-linearisations) per level.
    pub warps: usize,
    /// Most SOR sweeps per warp.
    pub iterations: usize,
    /// Sweeps stop once no pixel's flow changes by more than this (pixels).
    pub tolerance: f32,
    /// Over-relaxation factor, in (0, 2).
    pub omega: f32,
    /// Weight of the gradient-constancy term (Brox et al. 2004):
    /// `gamma ((Ixx du + Ixy dv + Ixt)^2 + (Ixy du + Iyy dv + Iyt)^2)` beside
    /// the brightness term, which holds where the lighting adds an offset
    /// or a ramp. 0 = off (the classical method).
    pub gamma: f32,
}

impl Default for HsParams {
    fn default() -> HsParams {
        HsParams {
            alpha: 20.0,
            levels: 5,
            warps: 1,
            iterations: 60,
            tolerance: 0.002,
            omega: 1.8,
            gamma: 0.0,
        }
    }
}

/// What one run did, for reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HsStats {
    /// SOR sweeps run in all, over every level and warp.
    pub sweeps: usize,
}

/// The data terms' normal equations per pixel, `A dw = -b` with `A` from
/// the brightness term (and the gradient term when `gamma > 0`).
struct Normal {
    a11: Vec<f32>,
    a12: Vec<f32>,
    a22: Vec<f32>,
    b1: Vec<f32>,
    b2: Vec<f32>,
}

impl Normal {
    fn new(
        ix: &Array2<f32>,
        iy: &Array2<f32>,
        it: &Array2<f32>,
        (ixt, iyt): (Array2<f32>, Array2<f32>),
        gamma: f32,
    ) -> Normal {
        let n = ix.len();
        let mut out = Normal {
            a11: ix.iter().map(|g| g * g).collect(),
            a12: ix.iter().zip(iy).map(|(a, b)| a * b).collect(),
            a22: iy.iter().map(|g| g * g).collect(),
            b1: ix.iter().zip(it).map(|(a, t)| a * t).collect(),
            b2: iy.iter().zip(it).map(|(a, t)| a * t).collect(),
        };
        if gamma > 0.0 {
            let ((ixx, ixy), (_, iyy)) = (gradients(ix), gradients(iy));
            let s = |a: &Array2<f32>| a.as_slice().expect("standard").to_vec();
            let (ixx, ixy, iyy, ixt, iyt) = (s(&ixx), s(&ixy), s(&iyy), s(&ixt), s(&iyt));
            for i in 0..n {
                let (xx, xy, yy) = (ixx[i], ixy[i], iyy[i]);
                let (xt, yt) = (ixt[i], iyt[i]);
                out.a11[i] += gamma * (xx * xx + xy * xy);
                out.a12[i] += gamma * (xx * xy + xy * yy);
                out.a22[i] += gamma * (xy * xy + yy * yy);
                out.b1[i] += gamma * (xx * xt + xy * yt);
                out.b2[i] += gamma * (xy * xt + yy * yt);
            }
        }
        out
    }
}

/// Dense flow from `i1` to `i2` (same size, grey levels).
///
/// ```
/// use mocomp::flow::hs::{horn_schunck, HsParams};
/// use ndarray::Array2;
/// let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos();
/// let i1 = Array2::from_shape_fn((48, 48), |(y, x)| f(x as f32, y as f32));
/// let i2 = Array2::from_shape_fn((48, 48), |(y, x)| f(x as f32 - 1.0, y as f32));
/// let (flow, _) = horn_schunck(&i1, &i2, &HsParams::default());
/// let (u, v) = flow.get(24, 24);
/// assert!((u - 1.0).abs() < 0.1 && v.abs() < 0.1);
/// ```
pub fn horn_schunck(i1: &Array2<f32>, i2: &Array2<f32>, p: &HsParams) -> (Flow, HsStats) {
    assert_eq!(i1.dim(), i2.dim(), "horn_schunck: pictures of different sizes");
    assert!(p.omega > 0.0 && p.omega < 2.0, "SOR needs 0 < omega < 2");
    let (p1, p2) = (pyramid(i1, p.levels, 8), pyramid(i2, p.levels, 8));
    let coarsest = p1.len() - 1;
    let (h, w) = p1[coarsest].dim();
    let (mut u, mut v) = (Array2::<f32>::zeros((h, w)), Array2::<f32>::zeros((h, w)));
    let alpha2 = p.alpha * p.alpha;
    let mut stats = HsStats::default();
    for level in (0..=coarsest).rev() {
        let (a1, a2) = (&p1[level], &p2[level]);
        let (h, w) = a1.dim();
        if u.dim() != (h, w) {
            u = upsample2(&u, h, w, 2.0);
            v = upsample2(&v, h, w, 2.0);
        }
        let (g1x, g1y) = gradients(a1);
        for _ in 0..p.warps {
            // Linearise around the current flow.
            let (u0, v0) = (u.clone(), v.clone());
            let warped = Array2::from_shape_fn((h, w), |(y, x)| {
                sample_bicubic(a2, x as f32 + u0[[y, x]], y as f32 + v0[[y, x]])
            });
            let (g2x, g2y) = gradients(&warped);
            let ix = (&g1x + &g2x) * 0.5;
            let iy = (&g1y + &g2y) * 0.5;
            let it = &warped - a1;
            let normal = Normal::new(&ix, &iy, &it, (&g2x - &g1x, &g2y - &g1y), p.gamma);
            let (su0, sv0) = (u0.as_slice().expect("standard"), v0.as_slice().expect("standard"));
            let us = u.as_slice_mut().expect("standard");
            let vs = v.as_slice_mut().expect("standard");
            for _ in 0..p.iterations {
                stats.sweeps += 1;
                let mut largest = 0f32;
                for y in 0..h {
                    for x in 0..w {
                        let i = y * w + x;
                        let (mut su, mut sv, mut n) = (0f32, 0f32, 0f32);
                        for (ok, j) in [
                            (x > 0, i.wrapping_sub(1)),
                            (x + 1 < w, i + 1),
                            (y > 0, i.wrapping_sub(w)),
                            (y + 1 < h, i + w),
                        ] {
                            if ok {
                                su += us[j];
                                sv += vs[j];
                                n += 1.0;
                            }
                        }
                        // A pixel with no neighbour (a 1x1 picture) and no
                        // gradient has no equation: 0 rather than 0/0.
                        let n = if w * h == 1 { f32::MIN_POSITIVE } else { n };
                        let (a11, a12, a22) = (normal.a11[i], normal.a12[i], normal.a22[i]);
                        let (b1, b2) = (normal.b1[i], normal.b2[i]);
                        let gu =
                            (alpha2 * su + a11 * su0[i] - a12 * (vs[i] - sv0[i]) - b1) / (a11 + alpha2 * n);
                        let nu = us[i] + p.omega * (gu - us[i]);
                        let gv = (alpha2 * sv + a22 * sv0[i] - a12 * (nu - su0[i]) - b2) / (a22 + alpha2 * n);
                        let nv = vs[i] + p.omega * (gv - vs[i]);
                        largest = largest.max((nu - us[i]).abs()).max((nv - vs[i]).abs());
                        us[i] = nu;
                        vs[i] = nv;
                    }
                }
                if largest < p.tolerance {
                    break;
                }
            }
        }
    }
    (Flow::from_uv(u, v), stats)
}
