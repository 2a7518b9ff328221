//! TV-L1 optical flow: Zach, Pock and Bischof (2007), "A duality based
//! approach for realtime TV-L1 optical flow", with the improvements of
//! Wedel et al. (2009): median filtering of the field between warps (3x3) and a
//! structure-texture decomposition of the pictures (robust to lighting
//! changes). The method of OpenCV's `DualTVL1OpticalFlow`, following the
//! scheme of Sanchez Perez, Meinhardt-Llopis and Facciolo (IPOL 2013).
//!
//! The flow minimises `sum |grad u1| + |grad u2| + lambda |rho(u)|` with
//! `rho` the linearised brightness difference: the L1 data term is robust
//! to outliers and occlusions, total variation keeps motion boundaries
//! sharp. An auxiliary field `v` splits the problem in two: a pointwise
//! thresholding step for the data term and Chambolle's dual projection for
//! total variation, alternated until the change falls below `epsilon`.
//! Coarse to fine over a Gaussian pyramid, each level warping the second
//! picture `warps` times. Every update is pointwise (Jacobi), so the
//! result does not depend on the number of threads.

use ndarray::Array2;
use rayon::prelude::*;

use super::warp::{sample_bicubic, sample_bilinear};
use super::Flow;
use crate::imgproc::pyramid::{blur, gradients, parallel_worth, pyramid, upsample2};

/// Settings of TV-L1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tvl1Params {
    /// Weight of the data term (OpenCV's default 0.15, grey levels 0..255).
    pub lambda: f32,
    /// Coupling of `u` and the auxiliary `v` (0.3).
    pub theta: f32,
    /// Time step of the dual update (0.25; stable up to 1/4).
    pub tau: f32,
    /// Pyramid levels, at most (a level stays at least 16 px on a side).
    pub levels: usize,
    /// Warps (re-linearisations) per level.
    pub warps: usize,
    /// Most iterations per warp.
    pub iterations: usize,
    /// Iterations stop once the mean squared change of `u` falls below
    /// `epsilon^2`.
    pub epsilon: f32,
    /// Median filter (3x3) of the field after each warp (Wedel et al.).
    pub median: bool,
    /// Structure-texture decomposition (Wedel et al.; here each pyramid
    /// level minus its Gaussian-smoothed self, sigma 3, times this gain):
    /// offsets and ramps of lighting drop out and a gain change only scales
    /// the texture. 0 = off, the default: on the flow benchmark it solves
    /// the lighting changes (EPE 16.9 to 0.24 px) but loses large pans and
    /// layers (9.2 to 13.6, 2.7 to 5.4 px); 3 is a good value when the
    /// lighting changes.
    pub texture: f32,
}

impl Default for Tvl1Params {
    fn default() -> Tvl1Params {
        Tvl1Params {
            lambda: 0.15,
            theta: 0.3,
            tau: 0.25,
            levels: 6,
            warps: 5,
            iterations: 50,
            epsilon: 0.01,
            median: true,
            texture: 0.0,
        }
    }
}

impl Tvl1Params {
    /// Checks the settings, saying which is out of range.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.tau > 0.0 && self.tau <= 0.25) {
            return Err(format!("tau {} is not in (0, 0.25]", self.tau));
        }
        for (name, x) in [("lambda", self.lambda), ("theta", self.theta)] {
            if !(x > 0.0 && x.is_finite()) {
                return Err(format!("{name} = {x} is not a positive number"));
            }
        }
        if !(self.texture >= 0.0 && self.texture <= 100.0) {
            return Err(format!("texture gain {} is not in [0, 100]", self.texture));
        }
        if self.warps == 0 || self.iterations == 0 || self.levels == 0 {
            return Err("levels, warps and iterations must be at least 1".into());
        }
        Ok(())
    }
}

/// The dual variables of total variation, one pair per flow component.
struct Duals {
    p11: Vec<f32>,
    p12: Vec<f32>,
    p21: Vec<f32>,
    p22: Vec<f32>,
}

impl Duals {
    fn zeros(n: usize) -> Duals {
        Duals {
            p11: vec![0.0; n],
            p12: vec![0.0; n],
            p21: vec![0.0; n],
            p22: vec![0.0; n],
        }
    }

    fn upsampled(&self, (h0, w0): (usize, usize), (h, w): (usize, usize)) -> Duals {
        let up = |p: &[f32]| {
            let a = Array2::from_shape_vec((h0, w0), p.to_vec()).expect("level size");
            upsample2(&a, h, w, 1.0).into_raw_vec_and_offset().0
        };
        Duals {
            p11: up(&self.p11),
            p12: up(&self.p12),
            p21: up(&self.p21),
            p22: up(&self.p22),
        }
    }
}

/// Row `y` of the divergence of the dual field `(px, py)` (the negative
/// adjoint of the forward differences, zero flux across the border).
#[inline(always)]
fn divergence_row(px: &[f32], py: &[f32], w: usize, h: usize, y: usize, out: &mut [f32]) {
    let row = y * w;
    for (x, o) in out.iter_mut().enumerate().take(w) {
        let i = row + x;
        let dx = if x == 0 {
            px[i]
        } else if x + 1 == w {
            -px[i - 1]
        } else {
            px[i] - px[i - 1]
        };
        let dy = if y == 0 {
            py[i]
        } else if y + 1 == h {
            -py[i - w]
        } else {
            py[i] - py[i - w]
        };
        *o = dx + dy;
    }
}

/// The linearisation of one warp: the second picture's gradients at the
/// warped positions, their squared norm, and the constant part of `rho`.
struct Warped {
    ix: Vec<f32>,
    iy: Vec<f32>,
    grad2: Vec<f32>,
    rho_c: Vec<f32>,
}

fn linearise(
    a: &Array2<f32>,
    b: &Array2<f32>,
    bx: &Array2<f32>,
    by: &Array2<f32>,
    u1: &[f32],
    u2: &[f32],
) -> Warped {
    let (h, w) = a.dim();
    let n = w * h;
    let mut out = Warped {
        ix: vec![0.0; n],
        iy: vec![0.0; n],
        grad2: vec![0.0; n],
        rho_c: vec![0.0; n],
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (px, py) = (x as f32 + u1[i], y as f32 + u2[i]);
            // Pixels that leave the picture get no data term: total
            // variation fills them from their neighbours.
            if px < 0.0 || py < 0.0 || px > (w - 1) as f32 || py > (h - 1) as f32 {
                continue;
            }
            let (gx, gy) = (sample_bilinear(bx, px, py), sample_bilinear(by, px, py));
            out.ix[i] = gx;
            out.iy[i] = gy;
            out.grad2[i] = gx * gx + gy * gy;
            out.rho_c[i] = sample_bicubic(b, px, py) - gx * u1[i] - gy * u2[i] - a[[y, x]];
        }
    }
    out
}

/// Runs `f(y, row_a, row_b)` over the rows of two `w`-wide buffers, in
/// parallel for large pictures.
fn rows2<F>(a: &mut [f32], b: &mut [f32], w: usize, f: F)
where
    F: Fn(usize, &mut [f32], &mut [f32]) + Sync,
{
    if parallel_worth(a.len()) {
        a.par_chunks_mut(w)
            .zip(b.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (ra, rb))| f(y, ra, rb));
    } else {
        for (y, (ra, rb)) in a.chunks_mut(w).zip(b.chunks_mut(w)).enumerate() {
            f(y, ra, rb);
        }
    }
}

/// The iterations of one warp, from the flow `(u1, u2)` and duals `d`.
fn solve_warp(
    lin: &Warped,
    u1: &mut [f32],
    u2: &mut [f32],
    d: &mut Duals,
    w: usize,
    h: usize,
    p: &Tvl1Params,
) {
    let n = w * h;
    let lt = p.lambda * p.theta;
    let step = p.tau / p.theta;
    let (mut v1, mut v2) = (vec![0f32; n], vec![0f32; n]);
    for _ in 0..p.iterations {
        // Thresholding: v from the data term at the current u.
        {
            let (u1r, u2r): (&[f32], &[f32]) = (u1, u2);
            rows2(&mut v1, &mut v2, w, |y, r1, r2| {
                for x in 0..w {
                    let i = y * w + x;
                    let (gx, gy, g2) = (lin.ix[i], lin.iy[i], lin.grad2[i]);
                    let rho = lin.rho_c[i] + gx * u1r[i] + gy * u2r[i];
                    let (d1, d2) = if rho < -lt * g2 {
                        (lt * gx, lt * gy)
                    } else if rho > lt * g2 {
                        (-lt * gx, -lt * gy)
                    } else if g2 > 1e-6 {
                        (-rho * gx / g2, -rho * gy / g2)
                    } else {
                        (0.0, 0.0)
                    };
                    r1[x] = u1r[i] + d1;
                    r2[x] = u2r[i] + d2;
                }
            });
        }
        // u = v + theta div p, and its change.
        let mut change = 0f64;
        {
            let dd: &Duals = d;
            let (v1r, v2r) = (&v1, &v2);
            let changes: Vec<f64> = if parallel_worth(n) {
                u1.par_chunks_mut(w)
                    .zip(u2.par_chunks_mut(w))
                    .enumerate()
                    .map(|(y, (r1, r2))| update_u_row(dd, v1r, v2r, r1, r2, w, h, y, p.theta))
                    .collect()
            } else {
                u1.chunks_mut(w)
                    .zip(u2.chunks_mut(w))
                    .enumerate()
                    .map(|(y, (r1, r2))| update_u_row(dd, v1r, v2r, r1, r2, w, h, y, p.theta))
                    .collect()
            };
            change += changes.iter().sum::<f64>();
        }
        update_duals(d, u1, u2, w, h, step);
        if change / (n as f64) < (p.epsilon as f64).powi(2) {
            break;
        }
    }
}

/// Row `y` of `u = v + theta div p`; returns the row's squared change.
#[allow(clippy::too_many_arguments)]
fn update_u_row(
    d: &Duals,
    v1: &[f32],
    v2: &[f32],
    r1: &mut [f32],
    r2: &mut [f32],
    w: usize,
    h: usize,
    y: usize,
    theta: f32,
) -> f64 {
    // Two rows of divergence on the stack for common widths, else the heap.
    let mut stack = [0f32; 2 * 1024];
    let mut heap = Vec::new();
    let buf: &mut [f32] = if w <= 1024 {
        &mut stack[..2 * w]
    } else {
        heap.resize(2 * w, 0.0);
        &mut heap
    };
    let (div1, div2) = buf.split_at_mut(w);
    divergence_row(&d.p11, &d.p12, w, h, y, div1);
    divergence_row(&d.p21, &d.p22, w, h, y, div2);
    let (v1, v2) = (&v1[y * w..(y + 1) * w], &v2[y * w..(y + 1) * w]);
    let mut change = 0f32;
    for x in 0..w {
        let (n1, n2) = (v1[x] + theta * div1[x], v2[x] + theta * div2[x]);
        change += (n1 - r1[x]).powi(2) + (n2 - r2[x]).powi(2);
        r1[x] = n1;
        r2[x] = n2;
    }
    change as f64
}

/// Chambolle's projection: `p = (p + step grad u) / (1 + step |grad u|)`.
fn update_duals(d: &mut Duals, u1: &[f32], u2: &[f32], w: usize, h: usize, step: f32) {
    let one = |u: &[f32], px: &mut [f32], py: &mut [f32]| {
        rows2(px, py, w, |y, rx, ry| {
            for x in 0..w {
                let i = y * w + x;
                let gx = if x + 1 < w { u[i + 1] - u[i] } else { 0.0 };
                let gy = if y + 1 < h { u[i + w] - u[i] } else { 0.0 };
                let norm = 1.0 + step * (gx * gx + gy * gy).sqrt();
                rx[x] = (rx[x] + step * gx) / norm;
                ry[x] = (ry[x] + step * gy) / norm;
            }
        });
    };
    one(u1, &mut d.p11, &mut d.p12);
    one(u2, &mut d.p21, &mut d.p22);
}

/// Median of nine values by a fixed network of 19 compare-exchanges
/// (Paeth's), branch-free.
#[inline(always)]
fn median9(mut p: [f32; 9]) -> f32 {
    let mut sort = |i: usize, j: usize| {
        let (a, b) = (p[i], p[j]);
        p[i] = a.min(b);
        p[j] = a.max(b);
    };
    for (i, j) in [
        (1, 2),
        (4, 5),
        (7, 8),
        (0, 1),
        (3, 4),
        (6, 7),
        (1, 2),
        (4, 5),
        (7, 8),
        (0, 3),
        (5, 8),
        (4, 7),
        (3, 6),
        (1, 4),
        (2, 5),
        (4, 7),
        (4, 2),
        (6, 4),
        (4, 2),
    ] {
        sort(i, j);
    }
    p[4]
}

/// 3x3 median of a `w x h` field, edges repeated (Wedel et al.'s filter
/// of the field between warps; 5x5 measured no better here, at three
/// times the cost).
fn median3(f: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0f32; w * h];
    let fill = |y: usize, row: &mut [f32]| {
        let rows = [y.saturating_sub(1), y, (y + 1).min(h - 1)].map(|r| &f[r * w..(r + 1) * w]);
        for (x, o) in row.iter_mut().enumerate() {
            let (l, r) = (x.saturating_sub(1), (x + 1).min(w - 1));
            *o = median9([
                rows[0][l], rows[0][x], rows[0][r], rows[1][l], rows[1][x], rows[1][r], rows[2][l],
                rows[2][x], rows[2][r],
            ]);
        }
    };
    if parallel_worth(w * h) {
        out.par_chunks_mut(w).enumerate().for_each(|(y, r)| fill(y, r));
    } else {
        out.chunks_mut(w).enumerate().for_each(|(y, r)| fill(y, r));
    }
    out
}

/// The texture part of the picture: minus its Gaussian-smoothed self
/// (sigma 3), times `gain`, around mid-grey: slow lighting changes
/// (offsets, ramps) drop out and a gain change only scales the texture.
fn texture_part(img: &Array2<f32>, gain: f32) -> Array2<f32> {
    if gain == 0.0 {
        return img.clone();
    }
    let smooth = blur(img, 3.0);
    ndarray::Zip::from(img)
        .and(&smooth)
        .map_collect(|&i, &s| 128.0 + gain * (i - s))
}

/// Dense TV-L1 flow from `i1` to `i2` (same size, grey levels 0..255).
/// Panics on settings that [`Tvl1Params::validate`] refuses.
///
/// ```
/// use mocomp::flow::tvl1::{tvl1, Tvl1Params};
/// use ndarray::Array2;
/// let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos();
/// let i1 = Array2::from_shape_fn((64, 80), |(y, x)| f(x as f32, y as f32));
/// let i2 = Array2::from_shape_fn((64, 80), |(y, x)| f(x as f32 - 3.5, y as f32 + 1.0));
/// let flow = tvl1(&i1, &i2, &Tvl1Params::default());
/// let (u, v) = flow.get(40, 32);
/// assert!((u - 3.5).abs() < 0.1 && (v + 1.0).abs() < 0.1);
/// ```
pub fn tvl1(i1: &Array2<f32>, i2: &Array2<f32>, p: &Tvl1Params) -> Flow {
    assert_eq!(i1.dim(), i2.dim(), "tvl1: pictures of different sizes");
    if let Err(e) = p.validate() {
        panic!("tvl1: {e}");
    }
    // The texture part per level, so that each level keeps the detail of
    // its own scale.
    let (p1, p2): (Vec<_>, Vec<_>) = pyramid(i1, p.levels, 16)
        .iter()
        .zip(&pyramid(i2, p.levels, 16))
        .map(|(a, b)| (texture_part(a, p.texture), texture_part(b, p.texture)))
        .unzip();
    let top = p1.len() - 1;
    let (h, w) = p1[top].dim();
    let (mut u1, mut u2) = (vec![0f32; w * h], vec![0f32; w * h]);
    let mut duals = Duals::zeros(w * h);
    let mut dim = (h, w);
    for level in (0..=top).rev() {
        let (a, b) = (&p1[level], &p2[level]);
        let (h, w) = a.dim();
        if dim != (h, w) {
            let up = |f: &[f32]| {
                let src = Array2::from_shape_vec(dim, f.to_vec()).expect("level size");
                upsample2(&src, h, w, 2.0).into_raw_vec_and_offset().0
            };
            (u1, u2) = (up(&u1), up(&u2));
            duals = duals.upsampled(dim, (h, w));
            dim = (h, w);
        }
        let (bx, by) = gradients(b);
        for _ in 0..p.warps {
            let lin = linearise(a, b, &bx, &by, &u1, &u2);
            solve_warp(&lin, &mut u1, &mut u2, &mut duals, w, h, p);
            if p.median {
                (u1, u2) = (median3(&u1, w, h), median3(&u2, w, h));
            }
        }
    }
    let shape = p1[0].dim();
    Flow::from_uv(
        Array2::from_shape_vec(shape, u1).expect("full size"),
        Array2::from_shape_vec(shape, u2).expect("full size"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn divergence_is_the_negative_adjoint_of_the_forward_difference() {
        // <grad u, p> = -<u, div p> for any u and p.
        let (w, h) = (7, 5);
        let u: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32 - 5.0).collect();
        let px: Vec<f32> = (0..w * h).map(|i| ((i * 13) % 7) as f32 - 3.0).collect();
        let py: Vec<f32> = (0..w * h).map(|i| ((i * 29) % 5) as f32 - 2.0).collect();
        let mut lhs = 0f32;
        let mut rhs = 0f32;
        let mut div = vec![0f32; w];
        for y in 0..h {
            divergence_row(&px, &py, w, h, y, &mut div);
            for (x, d) in div.iter().enumerate() {
                let i = y * w + x;
                let gx = if x + 1 < w { u[i + 1] - u[i] } else { 0.0 };
                let gy = if y + 1 < h { u[i + w] - u[i] } else { 0.0 };
                lhs += gx * px[i] + gy * py[i];
                rhs -= u[i] * d;
            }
        }
        assert_eq!(lhs, rhs);
    }

    #[test]
    fn the_median_removes_an_outlier() {
        let mut f = vec![1.0f32; 49];
        f[24] = 100.0;
        assert!(median3(&f, 7, 7).iter().all(|&x| x == 1.0));
    }

    #[test]
    fn the_network_finds_the_median_of_every_order() {
        // Every permutation of 9 distinct values is too many; rotations and
        // reversals of several orders cover the network's paths.
        let base = [3.0, 9.0, 1.0, 7.0, 5.0, 2.0, 8.0, 4.0, 6.0];
        for k in 0..9 {
            let mut p = base;
            p.rotate_left(k);
            assert_eq!(median9(p), 5.0);
            p.reverse();
            assert_eq!(median9(p), 5.0);
            p.sort_by(f32::total_cmp);
            assert_eq!(median9(p), 5.0);
        }
    }
}
