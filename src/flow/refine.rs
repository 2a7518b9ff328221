//! Variational refinement of a dense flow: a few fixed-point iterations of
//! the energy of Brox et al. (2004) with Zimmer et al.'s (2011) constraint
//! normalisation, as DIS uses it after each level.
//!
//! Around the current flow `w`, with the second picture warped back by it,
//! the increment `dw` minimises
//!
//! `sum  delta Psi(|I_z + grad I . dw|^2 / N) + gamma Psi(|grad I_z + H(I) dw|^2 / N_g)
//!      + alpha Psi(|grad (w + dw)|^2)`
//!
//! with `Psi(s^2) = sqrt(s^2 + eps^2)` (robust: outliers, occlusions and
//! motion boundaries are not squared away), `N`, `N_g` the squared
//! gradient norms plus `zeta^2` (so the data terms measure misfit in
//! pixels, whatever the contrast), the brightness term `delta` and the
//! gradient-constancy term `gamma` (which holds under additive brightness
//! changes). Each fixed-point iteration freezes the robust weights and
//! solves the linear system with a few red-black SOR sweeps.
//!
//! Pixels whose warped position leaves the picture get no data term: the
//! smoothness term fills them from their neighbours.

use ndarray::Array2;

/// Settings of the variational refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineParams {
    /// Fixed-point iterations (robust weights recomputed); 0 = off.
    pub iterations: usize,
    /// SOR sweeps per fixed-point iteration.
    pub sor_iterations: usize,
    /// Smoothness weight (30: OpenCV's DIS uses 20, which on the flow
    /// benchmark left every kind of pair a little less accurate with the
    /// medium and accurate presets).
    pub alpha: f32,
    /// Brightness-constancy weight.
    pub delta: f32,
    /// Gradient-constancy weight.
    pub gamma: f32,
    /// Over-relaxation factor, in (0, 2).
    pub omega: f32,
}

impl Default for RefineParams {
    fn default() -> RefineParams {
        RefineParams {
            iterations: 5,
            sor_iterations: 5,
            alpha: 30.0,
            delta: 5.0,
            gamma: 10.0,
            omega: 1.6,
        }
    }
}

impl RefineParams {
    /// Checks the settings, saying which is out of range.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.omega > 0.0 && self.omega < 2.0) {
            return Err(format!("SOR factor {} is not in (0, 2)", self.omega));
        }
        for (name, x) in [
            ("alpha", self.alpha),
            ("delta", self.delta),
            ("gamma", self.gamma),
        ] {
            if !(x >= 0.0 && x.is_finite()) {
                return Err(format!(
                    "refinement weight {name} = {x} is not a finite non-negative number"
                ));
            }
        }
        Ok(())
    }
}

/// Squared regularisers of the normalisation and of the robust function
/// (gradients in grey levels per pixel, misfits in pixels).
const ZETA2: f32 = 0.01;
const EPS2: f32 = 1e-6;

/// A field stored with a one-sample border, `(h + 2) x (w + 2)`, so that
/// the stencils need no edge cases.
struct Padded {
    w: usize,
    h: usize,
}

impl Padded {
    fn stride(&self) -> usize {
        self.w + 2
    }
    fn len(&self) -> usize {
        (self.w + 2) * (self.h + 2)
    }
    fn at(&self, x: usize, y: usize) -> usize {
        (y + 1) * (self.w + 2) + x + 1
    }
}

/// The image derivatives the energy is linearised with, on the padded grid.
struct Linearised {
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
    fn new(n: usize) -> Linearised {
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
    fn compute(&mut self, i1: &[f32], i2: &[f32], u: &[f32], v: &[f32], avg: &mut [f32], g: &Padded) {
        let (w, h) = (g.w, g.h);
        for y in 0..h {
            for x in 0..w {
                let (i, j) = (y * w + x, g.at(x, y));
                let (px, py) = (x as f32 + u[j], y as f32 + v[j]);
                let ok = px >= 0.0 && py >= 0.0 && px <= (w - 1) as f32 && py <= (h - 1) as f32;
                let warped = super::warp::bilinear_clamped(i2, w, h, px, py);
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

/// The linear system of one fixed-point iteration, per pixel:
/// `[a11 a12; a12 a22] dw + smoothness = [b1; b2]`.
struct System {
    a11: Vec<f32>,
    a12: Vec<f32>,
    a22: Vec<f32>,
    b1: Vec<f32>,
    b2: Vec<f32>,
    /// Smoothness weights of the edge to the right and the edge below
    /// (zero on the border, so border pixels have fewer neighbours).
    right: Vec<f32>,
    down: Vec<f32>,
}

impl System {
    fn new(n: usize) -> System {
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

    /// Data terms with the robust weights at the current increment.
    #[inline(always)]
    fn data(&mut self, l: &Linearised, du: &[f32], dv: &[f32], p: &RefineParams, g: &Padded) {
        let n = g.w;
        for y in 0..g.h {
            // Every slice cut to the row's length, so that the loop runs
            // without bounds checks and vectorises.
            let r = g.at(0, y)..g.at(0, y) + n;
            let (ix, iy, iz) = (&l.ix[r.clone()], &l.iy[r.clone()], &l.iz[r.clone()]);
            let (ixx, ixy, iyy) = (&l.ixx[r.clone()], &l.ixy[r.clone()], &l.iyy[r.clone()]);
            let (ixz, iyz, inside) = (&l.ixz[r.clone()], &l.iyz[r.clone()], &l.inside[r.clone()]);
            let (du, dv) = (&du[r.clone()], &dv[r.clone()]);
            let (a11, a12, a22) = (
                &mut self.a11[r.clone()],
                &mut self.a12[r.clone()],
                &mut self.a22[r.clone()],
            );
            let (b1, b2) = (&mut self.b1[r.clone()], &mut self.b2[r]);
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
    }

    /// Robust smoothness weights of the flow `w + dw` (forward differences).
    #[inline(always)]
    fn smoothness(&mut self, u: &[f32], v: &[f32], du: &[f32], dv: &[f32], p: &RefineParams, g: &Padded) {
        let (s, n) = (g.stride(), g.w);
        for y in 0..g.h {
            // The last row and column have no edge below / to the right:
            // their differences there are zero and their weights too.
            let below = if y + 1 < g.h { s } else { 0 };
            let start = g.at(0, y);
            // The row and its neighbours to the right and below, each
            // `n - 1` long (the last pixel is done after the loop).
            let m = n - 1;
            let (uc, dc) = (&u[start..start + m], &du[start..start + m]);
            let (vc, ec) = (&v[start..start + m], &dv[start..start + m]);
            let (ur, dur) = (&u[start + 1..start + 1 + m], &du[start + 1..start + 1 + m]);
            let (vr, dvr) = (&v[start + 1..start + 1 + m], &dv[start + 1..start + 1 + m]);
            let (ub, dub) = (
                &u[start + below..start + below + m],
                &du[start + below..start + below + m],
            );
            let (vb, dvb) = (
                &v[start + below..start + below + m],
                &dv[start + below..start + below + m],
            );
            let (right, down) = (
                &mut self.right[start..start + m],
                &mut self.down[start..start + m],
            );
            let keep_down = if below != 0 { 1.0 } else { 0.0 };
            for k in 0..m {
                let (uk, vk) = (uc[k] + dc[k], vc[k] + ec[k]);
                let (ux, vx) = (ur[k] + dur[k] - uk, vr[k] + dvr[k] - vk);
                let (uy, vy) = (ub[k] + dub[k] - uk, vb[k] + dvb[k] - vk);
                let weight = p.alpha / (ux * ux + uy * uy + vx * vx + vy * vy + EPS2).sqrt();
                right[k] = weight;
                down[k] = weight * keep_down;
            }
            let i = start + m;
            let (uy, vy) = (
                u[i + below] + du[i + below] - u[i] - du[i],
                v[i + below] + dv[i + below] - v[i] - dv[i],
            );
            self.right[i] = 0.0;
            self.down[i] = keep_down * p.alpha / (uy * uy + vy * vy + EPS2).sqrt();
        }
    }

    /// Folds what the sweeps do not change into per-pixel constants, in
    /// place: `b` becomes `c = b + sum_n e_n (w_n - w)` (the neighbours'
    /// current flow) and `a11`, `a22` the reciprocals of `a + sum_n e_n`,
    /// so that a sweep's update is
    /// `du = (c_u + sum_n e_n du_n - a12 dv) / (a11 + sum_n e_n)`.
    #[inline(always)]
    fn fold_in_place(&mut self, u: &[f32], v: &[f32], g: &Padded) {
        let (s, n) = (g.stride(), g.w);
        for y in 0..g.h {
            let i = g.at(0, y);
            let (el, er) = (&self.right[i - 1..i - 1 + n], &self.right[i..i + n]);
            let (eu, ed) = (&self.down[i - s..i - s + n], &self.down[i..i + n]);
            let (uc, ul, ur) = (&u[i..i + n], &u[i - 1..i - 1 + n], &u[i + 1..i + 1 + n]);
            let (uu, ud) = (&u[i - s..i - s + n], &u[i + s..i + s + n]);
            let (vc, vl, vr) = (&v[i..i + n], &v[i - 1..i - 1 + n], &v[i + 1..i + 1 + n]);
            let (vu, vd) = (&v[i - s..i - s + n], &v[i + s..i + s + n]);
            let (b1, b2) = (&mut self.b1[i..i + n], &mut self.b2[i..i + n]);
            let (a11, a22) = (&mut self.a11[i..i + n], &mut self.a22[i..i + n]);
            for k in 0..n {
                let (l, r, up, d) = (el[k], er[k], eu[k], ed[k]);
                b1[k] +=
                    l * (ul[k] - uc[k]) + r * (ur[k] - uc[k]) + up * (uu[k] - uc[k]) + d * (ud[k] - uc[k]);
                b2[k] +=
                    l * (vl[k] - vc[k]) + r * (vr[k] - vc[k]) + up * (vu[k] - vc[k]) + d * (vd[k] - vc[k]);
                let sum = l + r + up + d;
                a11[k] = 1.0 / (a11[k] + sum);
                a22[k] = 1.0 / (a22[k] + sum);
            }
        }
    }
}

/// `dst[k] = src[2 k]` for every `k` of `dst`.
#[inline(always)]
fn every_other(dst: &mut [f32], src: &[f32]) {
    let pairs = dst.len().min(src.len() / 2);
    // Both cut to length first: a plain indexed loop without bounds checks
    // (over two-sample chunks it cost the fast preset 5 % more
    // instructions on CIF).
    let (d, s) = (&mut dst[..pairs], &src[..2 * pairs]);
    for k in 0..pairs {
        d[k] = s[2 * k];
    }
    if pairs < dst.len() {
        dst[pairs] = src[2 * pairs];
    }
}

/// The SOR updates of a run of one colour's samples: each pixel's increment
/// `(du, dv)` from the weights to its four neighbours (left, right, up,
/// down), the neighbours' `du` and `dv`, `c_u`, `c_v`, the reciprocal
/// diagonals and the coupling `a12` (see [`Sweeps::fold`]). Every slice
/// cut to the run's length first, so that the loop runs without bounds
/// checks and vectorises.
#[inline(always)]
fn sweep_row(
    omega: f32,
    du: &mut [f32],
    dv: &mut [f32],
    [el, er, eu, ed]: [&[f32]; 4],
    [ul, ur, uu, ud]: [&[f32]; 4],
    [vl, vr, vu, vd]: [&[f32]; 4],
    [cu, cv, iu, iv, a12]: [&[f32]; 5],
) {
    let n = du.len().min(dv.len());
    let (el, er, eu, ed) = (&el[..n], &er[..n], &eu[..n], &ed[..n]);
    let (ul, ur, uu, ud) = (&ul[..n], &ur[..n], &uu[..n], &ud[..n]);
    let (vl, vr, vu, vd) = (&vl[..n], &vr[..n], &vu[..n], &vd[..n]);
    let (cu, cv, iu, iv, a12) = (&cu[..n], &cv[..n], &iu[..n], &iv[..n], &a12[..n]);
    for k in 0..n {
        let nu = el[k] * ul[k] + er[k] * ur[k] + eu[k] * uu[k] + ed[k] * ud[k];
        let nv = el[k] * vl[k] + er[k] * vr[k] + eu[k] * vu[k] + ed[k] * vd[k];
        let new_u = (cu[k] + nu - a12[k] * dv[k]) * iu[k];
        du[k] += omega * (new_u - du[k]);
        let new_v = (cv[k] + nv - a12[k] * du[k]) * iv[k];
        dv[k] += omega * (new_v - dv[k]);
    }
}

/// The coefficients of a sweep and the increment, split into four blocks:
/// red and black pixels (`(x + y)` even and odd), each split again by the
/// parity of the first such pixel in its row (`first`, 0 or 1). Block
/// `(c, first)` holds the rows `y` of that parity (every other row), row
/// `r` holding pixels `x = first + 2 k` at samples `k`. Then every pixel
/// of a block finds its neighbours at the same offsets: left and right in
/// block `(1 - c, 1 - first)` at `k - 1 + first` and `k + first` of the
/// same row, up and down in block `(1 - c, first)` at sample `k` of rows
/// `r - 1 + q` and `r + q` (`q` the parity of the block's rows). So one
/// colour's update is two flat loops, one per block, over whole pictures
/// rather than rows, without per-row set-up or remainder (on CIF's
/// quarter-size level, rows are 44 samples and the row-wise loop spent a
/// fifth of its time in scalar remainders). Every row has one sample of
/// padding on each side and a block one padding row above and below, all
/// zero, as are the weights towards them.
struct Sweeps {
    /// Samples per block row, padding included.
    stride: usize,
    w: usize,
    h: usize,
    /// Per block (`2 c + first`): weights to the left, right, upper and
    /// lower neighbour; the folded right-hand sides; the reciprocal
    /// diagonals; the coupling; the increment.
    el: [Vec<f32>; 4],
    er: [Vec<f32>; 4],
    eu: [Vec<f32>; 4],
    ed: [Vec<f32>; 4],
    cu: [Vec<f32>; 4],
    cv: [Vec<f32>; 4],
    iu: [Vec<f32>; 4],
    iv: [Vec<f32>; 4],
    a12: [Vec<f32>; 4],
    du: [Vec<f32>; 4],
    dv: [Vec<f32>; 4],
}

/// A block of [`Sweeps`]: its index, the parity `q` of its rows, its row
/// count and the samples per row.
#[derive(Clone, Copy)]
struct Block {
    index: usize,
    first: usize,
    q: usize,
    rows: usize,
    len: usize,
}

impl Sweeps {
    fn new(w: usize, h: usize) -> Sweeps {
        let stride = w.div_ceil(2) + 2;
        let n = stride * (h.div_ceil(2) + 2);
        let z = || std::array::from_fn(|_| vec![0f32; n]);
        Sweeps {
            stride,
            w,
            h,
            el: z(),
            er: z(),
            eu: z(),
            ed: z(),
            cu: z(),
            cv: z(),
            iu: z(),
            iv: z(),
            a12: z(),
            du: z(),
            dv: z(),
        }
    }

    fn block(&self, c: usize, first: usize) -> Block {
        let q = (c + first) % 2;
        Block {
            index: 2 * c + first,
            first,
            q,
            rows: self.h.saturating_sub(q).div_ceil(2),
            len: self.w.saturating_sub(first).div_ceil(2),
        }
    }

    /// Where sample `k` of row `r` of a block is.
    fn at(&self, r: usize, k: usize) -> usize {
        (r + 1) * self.stride + 1 + k
    }

    /// Folds what the sweeps do not change into per-pixel constants (the
    /// increment itself stays in the split layout between iterations): with
    /// `c = b + sum_n e_n (w_n - w)` (the neighbours' current flow) and the
    /// reciprocal of `a + sum_n e_n`, a sweep's update is
    /// `du = (c_u + sum_n e_n du_n - a12 dv) / (a11 + sum_n e_n)`.
    #[inline(always)]
    fn fold(&mut self, sys: &mut System, u: &[f32], v: &[f32], g: &Padded) {
        sys.fold_in_place(u, v, g);
        let s = g.stride();
        for (c, first) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            let b = self.block(c, first);
            for r in 0..b.rows {
                let i = g.at(first, b.q + 2 * r);
                let o = self.at(r, 0)..self.at(r, b.len);
                let j = b.index;
                every_other(&mut self.el[j][o.clone()], &sys.right[i - 1..]);
                every_other(&mut self.er[j][o.clone()], &sys.right[i..]);
                every_other(&mut self.eu[j][o.clone()], &sys.down[i - s..]);
                every_other(&mut self.ed[j][o.clone()], &sys.down[i..]);
                every_other(&mut self.cu[j][o.clone()], &sys.b1[i..]);
                every_other(&mut self.cv[j][o.clone()], &sys.b2[i..]);
                every_other(&mut self.iu[j][o.clone()], &sys.a11[i..]);
                every_other(&mut self.iv[j][o.clone()], &sys.a22[i..]);
                every_other(&mut self.a12[j][o], &sys.a12[i..]);
            }
        }
    }

    /// One red-black SOR sweep.
    #[inline(always)]
    fn sweep(&mut self, omega: f32) {
        for c in 0..2 {
            for first in 0..2 {
                let b = self.block(c, first);
                if b.rows > 0 && b.len > 0 {
                    self.sweep_block(omega, b, c);
                }
            }
        }
    }

    /// The updates of one block, from its row's first sample to its last
    /// row's last (the padding between rows has zero coefficients and
    /// stays zero).
    #[inline(always)]
    fn sweep_block(&mut self, omega: f32, b: Block, c: usize) {
        let s = self.stride;
        let (lr, ud) = (2 * (1 - c) + 1 - b.first, 2 * (1 - c) + b.first);
        let (start, n) = (self.at(0, 0), (b.rows - 1) * s + b.len);
        let (left, up, down) = (start + b.first - 1, start + b.q * s - s, start + b.q * s);
        let r = start..start + n;
        let j = b.index;
        let (mut du, mut dv) = (std::mem::take(&mut self.du[j]), std::mem::take(&mut self.dv[j]));
        let (du_lr, dv_lr, du_ud, dv_ud) = (&self.du[lr], &self.dv[lr], &self.du[ud], &self.dv[ud]);
        sweep_row(
            omega,
            &mut du[r.clone()],
            &mut dv[r.clone()],
            [
                &self.el[j][r.clone()],
                &self.er[j][r.clone()],
                &self.eu[j][r.clone()],
                &self.ed[j][r.clone()],
            ],
            [&du_lr[left..], &du_lr[left + 1..], &du_ud[up..], &du_ud[down..]],
            [&dv_lr[left..], &dv_lr[left + 1..], &dv_ud[up..], &dv_ud[down..]],
            [
                &self.cu[j][r.clone()],
                &self.cv[j][r.clone()],
                &self.iu[j][r.clone()],
                &self.iv[j][r.clone()],
                &self.a12[j][r],
            ],
        );
        self.du[j] = du;
        self.dv[j] = dv;
    }

    /// Copies the increment back to the padded full grid.
    #[inline(always)]
    fn unfold(&self, du: &mut [f32], dv: &mut [f32], g: &Padded) {
        for (c, first) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            let b = self.block(c, first);
            for r in 0..b.rows {
                let row = g.at(0, b.q + 2 * r)..g.at(0, b.q + 2 * r) + g.w;
                let split = self.at(r, 0);
                let (su, sv) = (&self.du[b.index][split..], &self.dv[b.index][split..]);
                for (d, &v) in du[row.clone()].iter_mut().skip(first).step_by(2).zip(su) {
                    *d = v;
                }
                for (d, &v) in dv[row].iter_mut().skip(first).step_by(2).zip(sv) {
                    *d = v;
                }
            }
        }
    }
}

/// Refines the flow `(u, v)` from `i1` to `i2` in place (a one-off
/// [`Refiner`]; keep one to refine pictures of the same size again).
pub fn refine(
    i1: &Array2<f32>,
    i2: &Array2<f32>,
    u: &mut Array2<f32>,
    v: &mut Array2<f32>,
    p: &RefineParams,
) {
    Refiner::default().refine(i1, i2, u, v, p)
}

/// The variational refinement with its buffers, kept from one call to the
/// next for pictures of the same size (a per-level refiner in a pyramid
/// does not allocate after the first pair).
#[derive(Default)]
pub struct Refiner {
    g: Option<Padded>,
    lin: Option<Linearised>,
    scratch: Vec<f32>,
    u: Vec<f32>,
    v: Vec<f32>,
    du: Vec<f32>,
    dv: Vec<f32>,
    sys: Option<System>,
    sweeps: Option<Sweeps>,
}

impl std::fmt::Debug for Refiner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let size = self.g.as_ref().map(|g| (g.w, g.h));
        f.debug_struct("Refiner").field("size", &size).finish()
    }
}

impl Refiner {
    /// Refines the flow `(u, v)` from `i1` to `i2` in place. Panics if the
    /// sizes differ.
    pub fn refine(
        &mut self,
        i1: &Array2<f32>,
        i2: &Array2<f32>,
        u: &mut Array2<f32>,
        v: &mut Array2<f32>,
        p: &RefineParams,
    ) {
        assert!(
            i1.dim() == i2.dim() && u.dim() == i1.dim() && v.dim() == i1.dim(),
            "refine: sizes differ"
        );
        if p.iterations == 0 {
            return;
        }
        // The flow kernels of the CPU level in force (the AVX2 build is
        // this source compiled for AVX2, without FMA: the same bits).
        (super::dsp::flow().refine)(self, i1, i2, u, v, p)
    }

    /// Sizes the buffers for a `w x h` picture; the increments start at 0.
    fn prepare(&mut self, w: usize, h: usize) {
        if self.g.as_ref().map(|g| (g.w, g.h)) != Some((w, h)) {
            let g = Padded { w, h };
            let n = g.len();
            self.lin = Some(Linearised::new(n));
            self.sys = Some(System::new(n));
            self.sweeps = Some(Sweeps::new(w, h));
            for b in [
                &mut self.scratch,
                &mut self.u,
                &mut self.v,
                &mut self.du,
                &mut self.dv,
            ] {
                *b = vec![0f32; n];
            }
            self.g = Some(g);
        } else {
            self.du.fill(0.0);
            self.dv.fill(0.0);
            let sw = self.sweeps.as_mut().expect("sized with g");
            for b in 0..4 {
                sw.du[b].fill(0.0);
                sw.dv[b].fill(0.0);
            }
        }
    }

    #[inline(always)]
    pub(crate) fn refine_body(
        &mut self,
        i1: &Array2<f32>,
        i2: &Array2<f32>,
        u: &mut Array2<f32>,
        v: &mut Array2<f32>,
        p: &RefineParams,
    ) {
        let (h, w) = i1.dim();
        self.prepare(w, h);
        let Refiner {
            g: Some(g),
            lin: Some(lin),
            sys: Some(sys),
            sweeps: Some(sweeps),
            ..
        } = self
        else {
            unreachable!("prepare sizes every buffer")
        };
        let (us, vs) = (
            u.as_slice_mut().expect("standard"),
            v.as_slice_mut().expect("standard"),
        );
        let (up, vp) = (&mut self.u, &mut self.v);
        for y in 0..h {
            up[g.at(0, y)..g.at(0, y) + w].copy_from_slice(&us[y * w..(y + 1) * w]);
            vp[g.at(0, y)..g.at(0, y) + w].copy_from_slice(&vs[y * w..(y + 1) * w]);
        }
        let (a1, a2) = (i1.as_slice().expect("standard"), i2.as_slice().expect("standard"));
        lin.compute(a1, a2, up, vp, &mut self.scratch, g);
        let (du, dv) = (&mut self.du, &mut self.dv);
        for _ in 0..p.iterations {
            sys.data(lin, du, dv, p, g);
            sys.smoothness(up, vp, du, dv, p, g);
            sweeps.fold(sys, up, vp, g);
            for _ in 0..p.sor_iterations {
                sweeps.sweep(p.omega);
            }
            sweeps.unfold(du, dv, g);
        }
        for y in 0..h {
            let row = g.at(0, y)..g.at(0, y) + w;
            for (o, &d) in us[y * w..(y + 1) * w].iter_mut().zip(&du[row.clone()]) {
                *o += d;
            }
            for (o, &d) in vs[y * w..(y + 1) * w].iter_mut().zip(&dv[row]) {
                *o += d;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Red-black SOR written plainly over the full padded grid: the
    /// reference for the split layout of [`Sweeps`].
    fn plain_sweeps(sys: &System, g: &Padded, omega: f32, sweeps: usize) -> (Vec<f32>, Vec<f32>) {
        let s = g.stride();
        let (mut du, mut dv) = (vec![0f32; g.len()], vec![0f32; g.len()]);
        for _ in 0..sweeps {
            for c in 0..2 {
                for (x, y) in (0..g.h).flat_map(|y| (0..g.w).map(move |x| (x, y))) {
                    if (x + y) % 2 != c {
                        continue;
                    }
                    let i = g.at(x, y);
                    let e = [sys.right[i - 1], sys.right[i], sys.down[i - s], sys.down[i]];
                    let n = [i - 1, i + 1, i - s, i + s];
                    let nu = e[0] * du[n[0]] + e[1] * du[n[1]] + e[2] * du[n[2]] + e[3] * du[n[3]];
                    let nv = e[0] * dv[n[0]] + e[1] * dv[n[1]] + e[2] * dv[n[2]] + e[3] * dv[n[3]];
                    let new_u = (sys.b1[i] + nu - sys.a12[i] * dv[i]) * sys.a11[i];
                    du[i] += omega * (new_u - du[i]);
                    let new_v = (sys.b2[i] + nv - sys.a12[i] * du[i]) * sys.a22[i];
                    dv[i] += omega * (new_v - dv[i]);
                }
            }
        }
        (du, dv)
    }

    #[test]
    fn split_sweeps_equal_plain_red_black_sor() {
        // Odd and even sizes, single rows and columns: each block's rows and
        // samples per row differ with the parities.
        for (w, h) in [(1, 1), (1, 6), (7, 1), (2, 3), (5, 4), (6, 6), (53, 37), (44, 36)] {
            let g = Padded { w, h };
            let mut sys = System::new(g.len());
            let mut seed = 0x2545_f491u32 ^ (w * 131 + h) as u32;
            let mut next = move || {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                (seed % 2001) as f32 / 1000.0 - 1.0
            };
            let (mut u, mut v) = (vec![0f32; g.len()], vec![0f32; g.len()]);
            for (x, y) in (0..h).flat_map(|y| (0..w).map(move |x| (x, y))) {
                let i = g.at(x, y);
                sys.a11[i] = 2.0 + next();
                sys.a22[i] = 2.0 + next();
                sys.a12[i] = 0.5 * next();
                sys.b1[i] = next();
                sys.b2[i] = next();
                // The smoothness term's zero weights past the last column and row.
                sys.right[i] = if x + 1 < w { 1.0 + next() } else { 0.0 };
                sys.down[i] = if y + 1 < h { 1.0 + next() } else { 0.0 };
                (u[i], v[i]) = (3.0 * next(), 3.0 * next());
            }
            let mut sweeps = Sweeps::new(w, h);
            sweeps.fold(&mut sys, &u, &v, &g);
            for _ in 0..4 {
                sweeps.sweep(1.6);
            }
            let (mut du, mut dv) = (vec![0f32; g.len()], vec![0f32; g.len()]);
            sweeps.unfold(&mut du, &mut dv, &g);
            let (pu, pv) = plain_sweeps(&sys, &g, 1.6, 4);
            assert!(du == pu && dv == pv, "{w}x{h}: split and plain sweeps differ");
            assert!(
                du.iter().any(|&d| d.abs() > 0.01),
                "{w}x{h}: the sweeps should move"
            );
        }
    }

    #[test]
    fn every_level_refines_as_the_scalar_build() {
        for level in crate::codec::cpu::available() {
            let f = |x: f32, y: f32| {
                128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos() + 20.0 * ((x + y) / 3.0).cos()
            };
            let i1 = Array2::from_shape_fn((37, 53), |(y, x)| f(x as f32, y as f32));
            let i2 = Array2::from_shape_fn((37, 53), |(y, x)| 0.9 * f(x as f32 - 1.3, y as f32 + 0.6) + 7.0);
            let start = Array2::from_shape_fn((37, 53), |(y, x)| 0.02 * (x as f32 - y as f32));
            let run = |scalar: bool| {
                let (mut u, mut v) = (start.clone(), start.mapv(|x| -0.5 * x));
                let mut r = Refiner::default();
                if scalar {
                    r.refine_body(&i1, &i2, &mut u, &mut v, &RefineParams::default())
                } else {
                    (super::super::dsp::FLOW.at(level).refine)(
                        &mut r,
                        &i1,
                        &i2,
                        &mut u,
                        &mut v,
                        &RefineParams::default(),
                    )
                }
                (u, v)
            };
            let (a, b) = (run(true), run(false));
            assert!(
                a.0 == b.0 && a.1 == b.1,
                "{level:?} and scalar refinements differ"
            );
            assert!(
                a.0.iter().any(|&x| x > 0.5),
                "the refinement should move the flow"
            );
        }
    }

    #[test]
    fn a_known_shift_is_approached() {
        let f = |x: f32, y: f32| {
            128.0 + 50.0 * (x / 6.0).sin() * (y / 9.0).cos() + 30.0 * ((x - 2.0 * y) / 11.0).cos()
        };
        let i1 = Array2::from_shape_fn((48, 64), |(y, x)| f(x as f32, y as f32));
        let i2 = Array2::from_shape_fn((48, 64), |(y, x)| f(x as f32 - 1.2, y as f32 + 0.7));
        let (mut u, mut v) = (
            Array2::from_elem((48, 64), 1.0f32),
            Array2::from_elem((48, 64), -0.5f32),
        );
        // The smoothness weight pinned (the default's is tuned on the flow
        // benchmark; a stiffer one carries a global offset more slowly).
        let p = RefineParams {
            iterations: 10,
            alpha: 20.0,
            ..RefineParams::default()
        };
        refine(&i1, &i2, &mut u, &mut v, &p);
        // One linearisation: the error of the start, 0.28 px, shrinks by
        // at least 40 % everywhere (measured 0.14 px left at the centre;
        // the stiff smoothness term carries a global offset slowly).
        for (y, x) in [(24, 32), (5, 5), (40, 60)] {
            let err = (u[[y, x]] - 1.2).hypot(v[[y, x]] + 0.7);
            assert!(
                err < 0.6 * 0.2f32.hypot(0.2),
                "({x},{y}): ({}, {})",
                u[[y, x]],
                v[[y, x]]
            );
        }
    }
}
