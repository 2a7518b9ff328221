//! The linear system of one fixed-point iteration on the padded grid:
//! the linearisation around the current flow, the data and smoothness
//! terms with their robust weights, and the fold of what the SOR sweeps
//! do not change. Each term is computed per row, so a band of rows can run
//! on its own thread ([`super::Band`]) with the same result.

use std::ops::Range;

use super::RefineParams;

/// Squared regularisers of the normalisation and of the robust function
/// (gradients in grey levels per pixel, misfits in pixels).
const ZETA2: f32 = 0.01;
const EPS2: f32 = 1e-6;

/// A field stored with a one-sample border, `(h + 2) x (w + 2)`, so that
/// the stencils need no edge cases.
pub(crate) struct Padded {
    pub(super) w: usize,
    pub(super) h: usize,
}

impl Padded {
    pub(super) fn stride(&self) -> usize {
        self.w + 2
    }
    pub(super) fn len(&self) -> usize {
        (self.w + 2) * (self.h + 2)
    }
    pub(super) fn at(&self, x: usize, y: usize) -> usize {
        (y + 1) * (self.w + 2) + x + 1
    }

    /// Zeroes the border of the field `a`.
    pub(super) fn zero_border(&self, a: &mut [f32]) {
        let s = self.stride();
        a[..s].fill(0.0);
        a[(self.h + 1) * s..].fill(0.0);
        for y in 1..=self.h {
            a[y * s] = 0.0;
            a[y * s + s - 1] = 0.0;
        }
    }
}

/// The rows `0..h` of a grid with `stride` samples a row and one padding
/// row above, whose samples lie in the band of whole rows that starts at
/// sample `base` and holds `len` samples.
pub(super) fn band_rows(base: usize, len: usize, stride: usize, h: usize) -> Range<usize> {
    let (first, end) = (base / stride, (base + len) / stride);
    first.saturating_sub(1).min(h)..end.saturating_sub(1).min(h)
}

/// The image derivatives the energy is linearised with, on the padded grid.
pub(crate) struct Linearised {
    ix: Vec<f32>,
    iy: Vec<f32>,
    iz: Vec<f32>,
    ixx: Vec<f32>,
    ixy: Vec<f32>,
    iyy: Vec<f32>,
    ixz: Vec<f32>,
    iyz: Vec<f32>,
    /// 1 where the warped position is inside the second picture, else 0.
    inside: Vec<f32>,
}

impl Linearised {
    /// Every array, for sizing them.
    fn arrays(&mut self) -> [&mut Vec<f32>; 9] {
        [
            &mut self.ix,
            &mut self.iy,
            &mut self.iz,
            &mut self.ixx,
            &mut self.ixy,
            &mut self.iyy,
            &mut self.ixz,
            &mut self.iyz,
            &mut self.inside,
        ]
    }

    /// Room for `n` samples in every array without a new allocation.
    pub(super) fn reserve(&mut self, n: usize) {
        for a in self.arrays() {
            a.reserve(n.saturating_sub(a.len()));
        }
    }

    /// Arrays of `n` samples (their padding is never read, and the rest
    /// is written before it is read).
    pub(super) fn resize(&mut self, n: usize) {
        for a in self.arrays() {
            a.resize(n, 0.0);
        }
    }

    pub(super) fn new(n: usize) -> Linearised {
        let z = || vec![0f32; n];
        Linearised {
            ix: z(),
            iy: z(),
            iz: z(),
            ixx: z(),
            ixy: z(),
            iyy: z(),
            ixz: z(),
            iyz: z(),
            inside: z(),
        }
    }

    /// The derivatives around the flow `(u, v)` (padded), with `avg` as
    /// scratch: the second picture warped back, its difference to the
    /// first, and the derivatives of their average and of the difference.
    #[inline(always)]
    pub(super) fn compute(
        &mut self,
        i1: &[f32],
        i2: &[f32],
        u: &[f32],
        v: &[f32],
        avg: &mut [f32],
        g: &Padded,
    ) {
        let (w, h) = (g.w, g.h);
        for y in 0..h {
            for x in 0..w {
                let (i, j) = (y * w + x, g.at(x, y));
                let (px, py) = (x as f32 + u[j], y as f32 + v[j]);
                let ok = px >= 0.0 && py >= 0.0 && px <= (w - 1) as f32 && py <= (h - 1) as f32;
                let warped = crate::flow::warp::bilinear_clamped(i2, w, h, px, py);
                avg[j] = 0.5 * (warped + i1[i]);
                self.iz[j] = warped - i1[i];
                self.inside[j] = if ok { 1.0 } else { 0.0 };
            }
        }
        derivatives(avg, g, &mut self.ix, &mut self.iy);
        derivatives(&self.iz, g, &mut self.ixz, &mut self.iyz);
        derivatives(&self.ix, g, &mut self.ixx, &mut self.ixy);
        derivatives(&self.iy, g, avg, &mut self.iyy);
    }
}

/// Central differences of the padded field `f`, edges repeated, written
/// into the padded `dx`, `dy` (their borders untouched).
#[inline(always)]
fn derivatives(f: &[f32], g: &Padded, dx: &mut [f32], dy: &mut [f32]) {
    let (w, h) = (g.w, g.h);
    for y in 0..h {
        let (up, down) = (g.at(0, y.saturating_sub(1)), g.at(0, (y + 1).min(h - 1)));
        let row = g.at(0, y);
        // Whole rows as straight loops (the edges' clamped taps apart).
        let (fu, fd) = (&f[up..up + w], &f[down..down + w]);
        for ((o, &a), &b) in dy[row..row + w].iter_mut().zip(fd).zip(fu) {
            *o = 0.5 * (a - b);
        }
        let (fr, out) = (&f[row..row + w], &mut dx[row..row + w]);
        if w < 3 {
            for x in 0..w {
                out[x] = 0.5 * (fr[(x + 1).min(w - 1)] - fr[x.saturating_sub(1)]);
            }
            continue;
        }
        out[0] = 0.5 * (fr[1] - fr[0]);
        for ((o, &a), &b) in out[1..w - 1].iter_mut().zip(&fr[2..]).zip(&fr[..w - 2]) {
            *o = 0.5 * (a - b);
        }
        out[w - 1] = 0.5 * (fr[w - 1] - fr[w - 2]);
    }
}

/// The data terms of one row with the robust weights at the current
/// increment: `out` is `[a11, a12, a22, b1, b2]` of the row's `w` pixels,
/// `start` the row's first sample in the padded grid, `[du, dv]` the
/// row's increment.
#[inline(always)]
pub(super) fn data_row(
    out: [&mut [f32]; 5],
    l: &Linearised,
    start: usize,
    [du, dv]: [&[f32]; 2],
    p: &RefineParams,
) {
    let [a11, a12, a22, b1, b2] = out;
    let n = a11.len();
    // Every slice cut to the row's length, so that the loop runs without
    // bounds checks and vectorises.
    let r = start..start + n;
    let (ix, iy, iz) = (&l.ix[r.clone()], &l.iy[r.clone()], &l.iz[r.clone()]);
    let (ixx, ixy, iyy) = (&l.ixx[r.clone()], &l.ixy[r.clone()], &l.iyy[r.clone()]);
    let (ixz, iyz, inside) = (&l.ixz[r.clone()], &l.iyz[r.clone()], &l.inside[r]);
    let (du, dv) = (&du[..n], &dv[..n]);
    let (a12, a22, b1, b2) = (&mut a12[..n], &mut a22[..n], &mut b1[..n], &mut b2[..n]);
    for k in 0..n {
        let (ix, iy) = (ix[k], iy[k]);
        let n1 = ix * ix + iy * iy + ZETA2;
        let r = iz[k] + ix * du[k] + iy * dv[k];
        let wd = inside[k] * p.delta / (r * r / n1 + EPS2).sqrt() / n1;
        let (ixx, ixy, iyy) = (ixx[k], ixy[k], iyy[k]);
        let (n2, n3) = (ixx * ixx + ixy * ixy + ZETA2, ixy * ixy + iyy * iyy + ZETA2);
        let rx = ixz[k] + ixx * du[k] + ixy * dv[k];
        let ry = iyz[k] + ixy * du[k] + iyy * dv[k];
        let wg = inside[k] * p.gamma / (rx * rx / n2 + ry * ry / n3 + EPS2).sqrt();
        let (g2, g3) = (wg / n2, wg / n3);
        a11[k] = wd * ix * ix + g2 * ixx * ixx + g3 * ixy * ixy + ZETA2;
        a12[k] = wd * ix * iy + g2 * ixx * ixy + g3 * ixy * iyy;
        a22[k] = wd * iy * iy + g2 * ixy * ixy + g3 * iyy * iyy + ZETA2;
        b1[k] = -(wd * iz[k] * ix + g2 * ixx * ixz[k] + g3 * ixy * iyz[k]);
        b2[k] = -(wd * iz[k] * iy + g2 * ixy * ixz[k] + g3 * iyy * iyz[k]);
    }
}

/// A row's flow `w` and increment `dw` with those of the row below (the
/// row itself for the last row, whose differences below are then zero).
#[derive(Clone, Copy)]
pub(super) struct FlowRows<'a> {
    /// `[u, v]` of the row and of the row below, `w` samples each.
    pub(super) flow: [[&'a [f32]; 2]; 2],
    /// `[du, dv]` likewise.
    pub(super) increment: [[&'a [f32]; 2]; 2],
    /// Whether there is a row below.
    pub(super) below: bool,
}

/// The robust smoothness weights of one row of the flow `w + dw` (forward
/// differences): `right` (`w` samples, 0 for the last column, which has
/// no edge to the right) and `down` (0 on the last row).
#[inline(always)]
pub(super) fn smoothness_row([right, down]: [&mut [f32]; 2], rows: FlowRows<'_>, p: &RefineParams) {
    let n = right.len();
    let [[u, v], [ub, vb]] = rows.flow;
    let [[du, dv], [dub, dvb]] = rows.increment;
    // The row and its neighbours to the right and below, each `n - 1`
    // long (the last pixel is done after the loop).
    let m = n - 1;
    let (uc, dc, vc, ec) = (&u[..m], &du[..m], &v[..m], &dv[..m]);
    let (ur, dur, vr, dvr) = (&u[1..n], &du[1..n], &v[1..n], &dv[1..n]);
    let (ub, dub, vb, dvb) = (&ub[..m], &dub[..m], &vb[..m], &dvb[..m]);
    let (r_out, d_out) = (&mut right[..m], &mut down[..m]);
    let keep_down = if rows.below { 1.0 } else { 0.0 };
    for k in 0..m {
        let (uk, vk) = (uc[k] + dc[k], vc[k] + ec[k]);
        let (ux, vx) = (ur[k] + dur[k] - uk, vr[k] + dvr[k] - vk);
        let (uy, vy) = (ub[k] + dub[k] - uk, vb[k] + dvb[k] - vk);
        let weight = p.alpha / (ux * ux + uy * uy + vx * vx + vy * vy + EPS2).sqrt();
        r_out[k] = weight;
        d_out[k] = weight * keep_down;
    }
    let [[u, v], [ub, vb]] = rows.flow;
    let [[du, dv], [dub, dvb]] = rows.increment;
    let (uy, vy) = (ub[m] + dub[m] - u[m] - du[m], vb[m] + dvb[m] - v[m] - dv[m]);
    right[m] = 0.0;
    down[m] = keep_down * p.alpha / (uy * uy + vy * vy + EPS2).sqrt();
}

/// Folds what the sweeps do not change into per-pixel constants for one
/// row, in place: `b` becomes `c = b + sum_n e_n (w_n - w)` (the
/// neighbours' current flow) and `a11`, `a22` the reciprocals of
/// `a + sum_n e_n`, so that a sweep's update is
/// `du = (c_u + sum_n e_n du_n - a12 dv) / (a11 + sum_n e_n)`. `out` is
/// `[b1, b2, a11, a22]` of the row's `w` pixels; `weights` the weights to
/// the left, right, upper and lower neighbours; `[u, v]` the flow on the
/// padded grid, `i` the row's first pixel there.
#[inline(always)]
pub(super) fn fold_row(out: [&mut [f32]; 4], weights: [&[f32]; 4], [u, v]: [&[f32]; 2], i: usize, s: usize) {
    let [b1, b2, a11, a22] = out;
    let n = b1.len();
    let [el, er, eu, ed] = weights.map(|e| &e[..n]);
    let (uc, ul, ur) = (&u[i..i + n], &u[i - 1..i - 1 + n], &u[i + 1..i + 1 + n]);
    let (uu, ud) = (&u[i - s..i - s + n], &u[i + s..i + s + n]);
    let (vc, vl, vr) = (&v[i..i + n], &v[i - 1..i - 1 + n], &v[i + 1..i + 1 + n]);
    let (vu, vd) = (&v[i - s..i - s + n], &v[i + s..i + s + n]);
    let (b2, a11, a22) = (&mut b2[..n], &mut a11[..n], &mut a22[..n]);
    for k in 0..n {
        let (l, r, up, d) = (el[k], er[k], eu[k], ed[k]);
        b1[k] += l * (ul[k] - uc[k]) + r * (ur[k] - uc[k]) + up * (uu[k] - uc[k]) + d * (ud[k] - uc[k]);
        b2[k] += l * (vl[k] - vc[k]) + r * (vr[k] - vc[k]) + up * (vu[k] - vc[k]) + d * (vd[k] - vc[k]);
        let sum = l + r + up + d;
        a11[k] = 1.0 / (a11[k] + sum);
        a22[k] = 1.0 / (a22[k] + sum);
    }
}

/// The system of a fixed-point iteration over the whole grid, a term to an
/// array, as it was computed before the assembly went row by row: the
/// reference for [`super::assemble`] and a source of made-up systems for
/// the sweeps' tests.
#[cfg(test)]
pub(super) mod plain {
    use super::*;

    /// Per pixel: `[a11 a12; a12 a22] dw + smoothness = [b1; b2]`, folded
    /// ([`fold_row`]); the smoothness weights of the edge to the right
    /// and of the edge below.
    pub(in super::super) struct System {
        pub(in super::super) a11: Vec<f32>,
        pub(in super::super) a12: Vec<f32>,
        pub(in super::super) a22: Vec<f32>,
        pub(in super::super) b1: Vec<f32>,
        pub(in super::super) b2: Vec<f32>,
        pub(in super::super) right: Vec<f32>,
        pub(in super::super) down: Vec<f32>,
    }

    impl System {
        pub(in super::super) fn new(n: usize) -> System {
            let z = || vec![0f32; n];
            System {
                a11: z(),
                a12: z(),
                a22: z(),
                b1: z(),
                b2: z(),
                right: z(),
                down: z(),
            }
        }

        /// The folded system around the flow `[u, v]` plus the increment
        /// `[du, dv]` (all padded), each term over the whole grid before
        /// the next.
        pub(in super::super) fn of(
            l: &Linearised,
            [u, v]: [&[f32]; 2],
            [du, dv]: [&[f32]; 2],
            p: &RefineParams,
            g: &Padded,
        ) -> System {
            let (w, s) = (g.w, g.stride());
            let mut sys = System::new(g.len());
            let rows = |y: usize| g.at(0, y)..g.at(0, y) + w;
            for y in 0..g.h {
                let r = rows(y);
                let System {
                    a11,
                    a12,
                    a22,
                    b1,
                    b2,
                    ..
                } = &mut sys;
                let out = [a11, a12, a22, b1, b2].map(|a| &mut a[r.clone()]);
                data_row(out, l, r.start, [&du[r.clone()], &dv[r.clone()]], p);
            }
            for y in 0..g.h {
                let (r, below) = (rows(y), y + 1 < g.h);
                let b = if below { rows(y + 1) } else { rows(y) };
                let rows = FlowRows {
                    flow: [[&u[r.clone()], &v[r.clone()]], [&u[b.clone()], &v[b.clone()]]],
                    increment: [[&du[r.clone()], &dv[r.clone()]], [&du[b.clone()], &dv[b]]],
                    below,
                };
                smoothness_row([&mut sys.right[r.clone()], &mut sys.down[r]], rows, p);
            }
            for y in 0..g.h {
                let i = g.at(0, y);
                let System {
                    a11,
                    a22,
                    b1,
                    b2,
                    right,
                    down,
                    ..
                } = &mut sys;
                let weights = [&right[i - 1..], &right[i..], &down[i - s..], &down[i..]];
                let out = [b1, b2, a11, a22].map(|a| &mut a[i..i + w]);
                fold_row(out, weights, [u, v], i, s);
            }
            sys
        }
    }
}
