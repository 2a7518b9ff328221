//! The patch search of DIS: inverse-compositional Lucas-Kanade per patch,
//! with spatial propagation between neighbouring patches.
//!
//! Each patch's Hessian comes from the first picture's gradients alone
//! (inverse composition), so one Gauss-Newton step costs one bilinear
//! sampling of the second picture over the patch and four sums. The grid
//! is searched in fixed horizontal stripes, each twice (forward in raster
//! order, then backward), every patch first trying the vectors of the
//! neighbours already searched in that pass: vectors found in textured
//! places spread to weak patches. The stripes are the same whatever the
//! number of threads, so the result does not depend on it.

use ndarray::Array2;
use rayon::prelude::*;

use super::DisParams;
use crate::imgproc::pyramid::parallel_worth;

/// Stripes of patch rows searched independently (fixed: the result must
/// not depend on the number of threads).
const STRIPES: usize = 8;

/// Vectors on the patch grid of one level.
#[derive(Debug, Clone)]
pub(crate) struct SparseFlow {
    /// Patch side at this level.
    pub patch: usize,
    /// Left edges of the patch columns.
    pub xs: Vec<usize>,
    /// Top edges of the patch rows.
    pub ys: Vec<usize>,
    /// Horizontal components, `[row * xs.len() + col]`.
    pub u: Vec<f32>,
    /// Vertical components.
    pub v: Vec<f32>,
}

/// Patch origins along a side of `n` pixels: every `stride` pixels, and a
/// last one flush with the far edge so that every pixel is covered.
pub(super) fn patch_origins(n: usize, patch: usize, stride: usize) -> Vec<usize> {
    let mut out: Vec<usize> = (0..)
        .map(|k| k * stride)
        .take_while(|&p| p + patch <= n)
        .collect();
    if out.last().is_none_or(|&p| p + patch < n) {
        out.push(n.saturating_sub(patch));
    }
    out
}

/// Sobel gradients divided by 8 (true derivatives of a smoothed picture),
/// edges repeated.
fn sobel(img: &[f32], w: usize, h: usize) -> (Vec<f32>, Vec<f32>) {
    let mut gx = vec![0f32; w * h];
    let mut gy = vec![0f32; w * h];
    let at = |x: isize, y: isize| {
        img[y.clamp(0, h as isize - 1) as usize * w + x.clamp(0, w as isize - 1) as usize]
    };
    for y in 0..h as isize {
        for x in 0..w as isize {
            let i = y as usize * w + x as usize;
            let (l, r) = (
                at(x - 1, y - 1) + 2.0 * at(x - 1, y) + at(x - 1, y + 1),
                at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1),
            );
            let (t, b) = (
                at(x - 1, y - 1) + 2.0 * at(x, y - 1) + at(x + 1, y - 1),
                at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1),
            );
            gx[i] = (r - l) * 0.125;
            gy[i] = (b - t) * 0.125;
        }
    }
    (gx, gy)
}

/// A picture with a replicated border of `pad` pixels on every side, so
/// that a patch displaced up to `pad` pixels out of the picture is read
/// without bounds checks.
pub(crate) struct Padded {
    data: Vec<f32>,
    stride: usize,
    pad: usize,
    w: usize,
    h: usize,
}

/// `x.floor()` for |x| < 2^31, without the library call that baseline
/// x86-64 makes for it.
#[inline(always)]
fn floor(x: f32) -> f32 {
    let t = x as i32 as f32;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

impl Padded {
    /// Where a `P x P` patch displaced to top-left (x, y) is read: the
    /// index of its top-left sample and the bilinear weights of the
    /// samples (0,0), (1,0), (0,1), (1,1) around each of its pixels. The
    /// position is clamped so the patch stays inside the padding.
    #[inline(always)]
    pub(super) fn patch_at<const P: usize>(&self, x: f32, y: f32) -> (usize, [f32; 4]) {
        let lim = |p: f32, n: usize| p.clamp(-(self.pad as f32) + 1.0, (n + self.pad - P - 2) as f32);
        let (x, y) = (lim(x, self.w), lim(y, self.h));
        let (fx, fy) = (floor(x), floor(y));
        let (ax, ay) = (x - fx, y - fy);
        let base = (fy as isize + self.pad as isize) as usize * self.stride
            + (fx as isize + self.pad as isize) as usize;
        (
            base,
            [(1.0 - ax) * (1.0 - ay), ax * (1.0 - ay), (1.0 - ax) * ay, ax * ay],
        )
    }

    /// Whether a `P x P` patch with top-left (x, y) lies within the
    /// picture, up to an eighth of a patch past its edges. Farther out,
    /// its samples are mostly the replicated border: the content it is
    /// looking for has left the picture, and nothing there says where.
    #[inline(always)]
    pub(super) fn holds<const P: usize>(&self, x: f32, y: f32) -> bool {
        let slack = P as f32 / 8.0;
        let within = |p: f32, n: usize| p >= -slack && p + P as f32 <= n as f32 + slack;
        within(x, self.w) && within(y, self.h)
    }

    /// Row `r` of the patch at `base` and the row below, each `P + 1` long.
    #[inline(always)]
    pub(super) fn rows<const P: usize>(&self, base: usize, r: usize) -> (&[f32], &[f32]) {
        (
            &self.data[base + r * self.stride..][..P + 1],
            &self.data[base + (r + 1) * self.stride..][..P + 1],
        )
    }

    /// The picture `img` (`w x h`, row-major) with a border of `pad`.
    pub(super) fn new(img: &[f32], w: usize, h: usize, pad: usize) -> Padded {
        let stride = w + 2 * pad;
        let mut data = vec![0f32; stride * (h + 2 * pad)];
        for (py, row) in data.chunks_exact_mut(stride).enumerate() {
            let src = &img[(py as isize - pad as isize).clamp(0, h as isize - 1) as usize * w..][..w];
            row[..pad].fill(src[0]);
            row[pad..pad + w].copy_from_slice(src);
            row[pad + w..].fill(src[w - 1]);
        }
        Padded {
            data,
            stride,
            pad,
            w,
            h,
        }
    }
}

/// What one patch of the first picture needs for its search: its samples
/// and gradients, and the inverse of its (mean-normalised) Hessian.
struct Template<const P: usize> {
    i0: [[f32; P]; P],
    gx: [[f32; P]; P],
    gy: [[f32; P]; P],
    /// Means of the gradients (for mean normalisation), else zero.
    mean_gx: f32,
    mean_gy: f32,
    inv: [f32; 3],
    /// The smaller eigenvalue of the (mean-normalised) Hessian per pixel:
    /// how well the patch pins down motion in every direction.
    texture: f32,
    /// [`Level::avx2`].
    avx2: bool,
}

impl<const P: usize> Template<P> {
    #[inline(always)]
    fn new(lv: &Level, x0: usize, y0: usize, mean_normalize: bool) -> Template<P> {
        let mut t = Template {
            i0: [[0.0; P]; P],
            gx: [[0.0; P]; P],
            gy: [[0.0; P]; P],
            mean_gx: 0.0,
            mean_gy: 0.0,
            inv: [0.0; 3],
            texture: 0.0,
            avx2: lv.avx2,
        };
        let (mut sxx, mut sxy, mut syy, mut sx, mut sy) = (0f32, 0f32, 0f32, 0f32, 0f32);
        for r in 0..P {
            let o = (y0 + r) * lv.w + x0;
            t.i0[r].copy_from_slice(&lv.i0[o..o + P]);
            t.gx[r].copy_from_slice(&lv.gx[o..o + P]);
            t.gy[r].copy_from_slice(&lv.gy[o..o + P]);
            for c in 0..P {
                let (a, b) = (t.gx[r][c], t.gy[r][c]);
                sxx += a * a;
                sxy += a * b;
                syy += b * b;
                sx += a;
                sy += b;
            }
        }
        let n = (P * P) as f32;
        if mean_normalize {
            t.mean_gx = sx / n;
            t.mean_gy = sy / n;
            sxx -= sx * sx / n;
            sxy -= sx * sy / n;
            syy -= sy * sy / n;
        }
        // The damping on the diagonal keeps flat patches' steps finite
        // and short (DisParams::damping).
        let half_trace = 0.5 * (sxx + syy);
        t.texture = (half_trace - ((0.5 * (sxx - syy)).powi(2) + sxy * sxy).sqrt()) / n;
        let floor = lv.damping * n;
        let (a, b, c) = (sxx + floor, sxy, syy + floor);
        let det = a * c - b * b;
        t.inv = [c / det, -b / det, a / det];
        t
    }

    /// The second picture sampled bilinearly over the patch displaced to
    /// (x, y) (clamped into the padded picture), minus the template:
    /// returns (sum d, sum d^2, sum d gx, sum d gy).
    #[inline(always)]
    fn residual(&self, i1: &Padded, x: f32, y: f32) -> [f32; 4] {
        let (base, weights) = i1.patch_at::<P>(x, y);
        #[cfg(target_arch = "x86_64")]
        if P == 8 && self.avx2 {
            // SAFETY: `avx2` is set only by the AVX2 table's entry, which
            // the tables hand out only on a CPU that runs AVX2.
            return unsafe {
                crate::flow::dsp::x86::dis_residual8(
                    &i1.data,
                    i1.stride,
                    base,
                    weights,
                    [&self.i0, &self.gx, &self.gy].map(|a| a.as_flattened()),
                )
            };
        }
        let [w00, w01, w10, w11] = weights;
        let (mut sd, mut sd2, mut sdx, mut sdy) = ([0f32; P], [0f32; P], [0f32; P], [0f32; P]);
        for r in 0..P {
            let (top, bot) = i1.rows::<P>(base, r);
            for c in 0..P {
                let d = w00 * top[c] + w01 * top[c + 1] + w10 * bot[c] + w11 * bot[c + 1] - self.i0[r][c];
                sd[c] += d;
                sd2[c] += d * d;
                sdx[c] += d * self.gx[r][c];
                sdy[c] += d * self.gy[r][c];
            }
        }
        [sd, sd2, sdx, sdy].map(|a| a.iter().sum())
    }

    /// The patch distance at displacement (u, v) from (x0, y0): SSD, or the
    /// SSD of the mean-removed difference.
    #[inline(always)]
    fn cost(&self, i1: &Padded, x0: usize, y0: usize, u: f32, v: f32, mean_normalize: bool) -> f32 {
        self.distance(self.residual(i1, x0 as f32 + u, y0 as f32 + v), mean_normalize)
    }

    /// The patch distance of a [`Template::residual`].
    #[inline(always)]
    fn distance(&self, [sd, sd2, _, _]: [f32; 4], mean_normalize: bool) -> f32 {
        if mean_normalize {
            sd2 - sd * sd / (P * P) as f32
        } else {
            sd2
        }
    }

    /// The whole-pixel displacement with the least patch distance among
    /// all that keep the patch inside the picture: the start of the
    /// coarsest level, where the picture is a few patches across and
    /// this costs little, so that no motion is out of reach.
    fn exhaustive(&self, i1: &Padded, x0: usize, y0: usize, mn: bool) -> (f32, f32) {
        let n = (P * P) as f32;
        let (mut best, mut at) = (f32::INFINITY, (0.0, 0.0));
        for y in 0..=i1.h - P {
            for x in 0..=i1.w - P {
                let (mut sd, mut sd2) = ([0f32; P], [0f32; P]);
                for r in 0..P {
                    let row = &i1.data[(y + r + i1.pad) * i1.stride + x + i1.pad..][..P];
                    for c in 0..P {
                        let d = row[c] - self.i0[r][c];
                        sd[c] += d;
                        sd2[c] += d * d;
                    }
                }
                let (sd, sd2): (f32, f32) = (sd.iter().sum(), sd2.iter().sum());
                let cost = if mn { sd2 - sd * sd / n } else { sd2 };
                if cost < best {
                    best = cost;
                    at = (x as f32 - x0 as f32, y as f32 - y0 as f32);
                }
            }
        }
        at
    }

    /// Gauss-Newton from (u, v): steps until the distance stops falling or
    /// `steps` are done; returns the best vector found and its distance.
    #[inline(always)]
    fn descend(
        &self,
        i1: &Padded,
        x0: usize,
        y0: usize,
        (u, v): (f32, f32),
        steps: usize,
        mn: bool,
    ) -> (f32, f32) {
        self.descend_from(i1, x0, y0, (u, v), None, steps, mn)
    }

    /// [`Template::descend`], given the residual at the start when the
    /// caller has it already (the candidates' comparison computes it).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn descend_from(
        &self,
        i1: &Padded,
        x0: usize,
        y0: usize,
        (u, v): (f32, f32),
        mut known: Option<[f32; 4]>,
        steps: usize,
        mn: bool,
    ) -> (f32, f32) {
        let n = (P * P) as f32;
        let (mut u, mut v) = (u, v);
        let mut best = f32::INFINITY;
        let mut last = (u, v);
        for _ in 0..steps {
            let [sd, sd2, sdx, sdy] = known
                .take()
                .unwrap_or_else(|| self.residual(i1, x0 as f32 + u, y0 as f32 + v));
            let (cost, bx, by) = if mn {
                (
                    sd2 - sd * sd / n,
                    sdx - sd * self.mean_gx,
                    sdy - sd * self.mean_gy,
                )
            } else {
                (sd2, sdx, sdy)
            };
            if cost >= best {
                return last;
            }
            best = cost;
            last = (u, v);
            let (du, dv) = (
                self.inv[0] * bx + self.inv[1] * by,
                self.inv[1] * bx + self.inv[2] * by,
            );
            u -= du;
            v -= dv;
            if du * du + dv * dv < STEP_EPS2 {
                return (u, v);
            }
        }
        // The last step's result was not evaluated: keep it (each step so
        // far lowered the distance).
        (u, v)
    }
}

/// Squared length of a Gauss-Newton step (pixels of the level) after
/// which the descent stops: the rest would move the patch by less.
const STEP_EPS2: f32 = STEP_EPS * STEP_EPS;
const STEP_EPS: f32 = 0.005;

/// The first picture of a level, its gradients, and the second picture
/// padded.
struct Level<'a> {
    i0: &'a [f32],
    gx: Vec<f32>,
    gy: Vec<f32>,
    i1: &'a Padded,
    w: usize,
    damping: f32,
    /// Whether this is the AVX2 build (its table entry): 8-pixel patches
    /// then sample the second picture with the AVX2 kernel.
    avx2: bool,
}

/// What a level's search works on: the two pictures of the level, the
/// dense flow from the coarser level (at this level's size), an optional
/// extra candidate field, the settings, and whether this is the coarsest
/// level's global search.
pub(crate) struct LevelSearch<'a> {
    pub a1: &'a Array2<f32>,
    /// The second picture, padded by at least the patch size + 2.
    pub a2: &'a Padded,
    pub u: &'a Array2<f32>,
    pub v: &'a Array2<f32>,
    pub hint: Option<&'a (Array2<f32>, Array2<f32>)>,
    pub params: &'a DisParams,
    pub exhaustive: bool,
    /// Added to the Hessian's diagonal per pixel of the patch.
    pub damping: f32,
    /// Whether `u`, `v` come from a coarser level (every level but the
    /// coarsest): then a patch whose start leaves the picture keeps it.
    pub refines: bool,
}

/// Searches every patch of the level with patches of side `patch`, by the
/// flow kernels of the CPU level in force (the AVX2 build is this source
/// compiled for AVX2, without FMA: the same bits; a row of an 8-pixel
/// patch is one register).
pub(super) fn search_level(input: &LevelSearch, patch: usize) -> SparseFlow {
    (crate::flow::dsp::flow().dis_search_level)(input, patch)
}

/// [`search_level`] for any instruction set; `AVX2` only in the AVX2
/// table's entry (8x8 patches then run `dsp::x86::dis_residual8`).
#[inline(always)]
pub(crate) fn search_level_body<const AVX2: bool>(input: &LevelSearch, patch: usize) -> SparseFlow {
    match patch {
        16 => search_sized::<16>(input, AVX2),
        12 => search_sized::<12>(input, AVX2),
        8 => search_sized::<8>(input, AVX2),
        4..=7 => search_sized::<4>(input, AVX2),
        2..=3 => search_sized::<2>(input, AVX2),
        _ => search_sized::<1>(input, AVX2),
    }
}

#[inline(always)]
fn search_sized<const P: usize>(input: &LevelSearch, avx2: bool) -> SparseFlow {
    let &LevelSearch {
        a1,
        a2,
        u,
        v,
        hint,
        params: p,
        exhaustive,
        damping,
        refines,
    } = input;
    let (h, w) = a1.dim();
    let i0 = a1.as_slice().expect("standard");
    let (gx, gy) = sobel(i0, w, h);
    let lv = Level {
        i0,
        gx,
        gy,
        i1: a2,
        w,
        damping,
        avx2,
    };
    let stride = p.stride.min(P);
    let (xs, ys) = (patch_origins(w, P, stride), patch_origins(h, P, stride));
    let mut sparse = SparseFlow {
        patch: P,
        u: vec![0.0; xs.len() * ys.len()],
        v: vec![0.0; xs.len() * ys.len()],
        xs,
        ys,
    };
    let ws = sparse.xs.len();
    let rows_per = sparse.ys.len().div_ceil(STRIPES).max(1);
    let global = exhaustive.then(|| global_matches::<P>(&lv, &sparse.xs, &sparse.ys, p.mean_normalize));
    let ctx = StripeContext {
        lv: &lv,
        xs: &sparse.xs,
        ys: &sparse.ys,
        u: u.as_slice().expect("standard"),
        v: v.as_slice().expect("standard"),
        hint: hint.map(|(a, b)| (a.as_slice().expect("standard"), b.as_slice().expect("standard"))),
        p,
        refines,
        global: global.as_ref().map(|(a, b)| (a.as_slice(), b.as_slice())),
    };
    let chunk = rows_per * ws;
    if parallel_worth(w * h) {
        sparse
            .u
            .par_chunks_mut(chunk)
            .zip(sparse.v.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(k, (su, sv))| ctx.search_stripe::<P>(k * rows_per, su, sv));
    } else {
        for (k, (su, sv)) in sparse
            .u
            .chunks_mut(chunk)
            .zip(sparse.v.chunks_mut(chunk))
            .enumerate()
        {
            ctx.search_stripe::<P>(k * rows_per, su, sv);
        }
    }
    sparse
}

/// Every patch's exhaustive match, then the median of each component over
/// the patch's 3x3 neighbourhood of patches: an isolated wrong match (a
/// flat or repetitive patch that fits many places) gives way to its
/// neighbours' agreement.
fn global_matches<const P: usize>(lv: &Level, xs: &[usize], ys: &[usize], mn: bool) -> (Vec<f32>, Vec<f32>) {
    let (ws, hs) = (xs.len(), ys.len());
    let raw: Vec<(f32, f32)> = (0..ws * hs)
        .map(|k| {
            let (x0, y0) = (xs[k % ws], ys[k / ws]);
            Template::<P>::new(lv, x0, y0, mn).exhaustive(lv.i1, x0, y0, mn)
        })
        .collect();
    let median = |pick: fn(&(f32, f32)) -> f32| -> Vec<f32> {
        (0..ws * hs)
            .map(|k| {
                let (c, r) = ((k % ws) as isize, (k / ws) as isize);
                let mut vals: Vec<f32> = (-1..=1)
                    .flat_map(|dr| (-1..=1).map(move |dc| (r + dr, c + dc)))
                    .filter(|&(rr, cc)| rr >= 0 && cc >= 0 && rr < hs as isize && cc < ws as isize)
                    .map(|(rr, cc)| pick(&raw[rr as usize * ws + cc as usize]))
                    .collect();
                vals.sort_by(f32::total_cmp);
                vals[vals.len() / 2]
            })
            .collect()
    };
    (median(|m| m.0), median(|m| m.1))
}

struct StripeContext<'a> {
    lv: &'a Level<'a>,
    xs: &'a [usize],
    ys: &'a [usize],
    u: &'a [f32],
    v: &'a [f32],
    hint: Option<(&'a [f32], &'a [f32])>,
    p: &'a DisParams,
    /// [`LevelSearch::refines`].
    refines: bool,
    /// The exhaustive search's matches on the whole grid (median-filtered),
    /// at the coarsest level.
    global: Option<(&'a [f32], &'a [f32])>,
}

impl StripeContext<'_> {
    /// The start of patch `k` at the coarsest level: the exhaustive
    /// search's match, where the patch is textured and after descent the
    /// match fits it at least four times better than the local start
    /// does; else the local start.
    /// Flat and repetitive patches, which match well in many places, keep
    /// their local start, so only motion out of the local search's reach
    /// is taken from the exhaustive search.
    fn global_start<const P: usize>(
        &self,
        row0: usize,
        k: usize,
        local: (f32, f32),
        far: (f32, f32),
        steps: usize,
    ) -> (f32, f32) {
        let ws = self.xs.len();
        let (x0, y0) = (self.xs[k % ws], self.ys[row0 + k / ws]);
        let mn = self.p.mean_normalize;
        let t = Template::<P>::new(self.lv, x0, y0, mn);
        // Patches without texture in every direction (mean squared
        // gradient along the weaker direction under 4 levels^2/px^2) fit
        // many places: their exhaustive match says nothing.
        if t.texture < 4.0 {
            return local;
        }
        let i1 = self.lv.i1;
        let near = t.descend(i1, x0, y0, local, steps, mn);
        let far = t.descend(i1, x0, y0, far, steps, mn);
        let (near_cost, far_cost) = (
            t.cost(i1, x0, y0, near.0, near.1, mn),
            t.cost(i1, x0, y0, far.0, far.1, mn),
        );
        if far_cost < 0.25 * near_cost {
            far
        } else {
            local
        }
    }

    /// The patch's start: the least distant of its own vector and the
    /// candidates, with its residual (the descent's first step), or its
    /// own vector unmeasured when there is no candidate.
    #[inline(always)]
    fn best_start<const P: usize>(
        &self,
        t: &Template<P>,
        (x0, y0): (usize, usize),
        own: (f32, f32),
        candidates: [Option<(f32, f32)>; 3],
    ) -> ((f32, f32), Option<[f32; 4]>) {
        if candidates.iter().all(Option::is_none) {
            return (own, None);
        }
        let mn = self.p.mean_normalize;
        let residual = |(u, v): (f32, f32)| t.residual(self.lv.i1, x0 as f32 + u, y0 as f32 + v);
        let (mut start, mut best_residual) = (own, residual(own));
        let mut best = t.distance(best_residual, mn);
        for cand in candidates.into_iter().flatten() {
            let r = residual(cand);
            let cost = t.distance(r, mn);
            if cost < best {
                (best, best_residual, start) = (cost, r, cand);
            }
        }
        (start, Some(best_residual))
    }

    /// Searches the patch rows `row0..` held by `su`/`sv`: a forward pass
    /// then a backward pass, each patch starting from the best of its own
    /// vector and its searched neighbours'.
    #[inline(always)]
    fn search_stripe<const P: usize>(&self, row0: usize, su: &mut [f32], sv: &mut [f32]) {
        let ws = self.xs.len();
        let rows = su.len() / ws;
        let (w, mn) = (self.lv.w, self.p.mean_normalize);
        let centre = |r: usize, c: usize| (self.ys[row0 + r] + P / 2) * w + self.xs[c] + P / 2;
        let steps_per_pass = (self.p.iterations / 2).max(1);
        for k in 0..rows * ws {
            let i = centre(k / ws, k % ws);
            (su[k], sv[k]) = (self.u[i], self.v[i]);
            if let Some((gu, gv)) = self.global {
                let far = (gu[row0 * ws + k], gv[row0 * ws + k]);
                (su[k], sv[k]) = self.global_start::<P>(row0, k, (su[k], sv[k]), far, steps_per_pass);
            }
        }
        for pass in 0..2 {
            let forward = pass == 0;
            for step in 0..rows * ws {
                let k = if forward { step } else { rows * ws - 1 - step };
                let (r, c) = (k / ws, k % ws);
                let (x0, y0) = (self.xs[c], self.ys[row0 + r]);
                // Rebuilt at each visit: cheaper than keeping every
                // patch's copy between the passes.
                let t = &Template::<P>::new(self.lv, x0, y0, mn);
                let start = (su[k], sv[k]);
                let mut candidates = [None; 3];
                if self.p.propagate {
                    let (has_left, has_up) = if forward {
                        (c > 0, r > 0)
                    } else {
                        (c + 1 < ws, r + 1 < rows)
                    };
                    // Only read where the neighbour exists (above).
                    let (dc, dr) = if forward {
                        (k.wrapping_sub(1), k.wrapping_sub(ws))
                    } else {
                        (k + 1, k + ws)
                    };
                    candidates[0] = has_left.then(|| (su[dc], sv[dc]));
                    candidates[1] = has_up.then(|| (su[dr], sv[dr]));
                }
                if let Some((hu, hv)) = self.hint {
                    let i = centre(r, c);
                    candidates[2] = Some((hu[i], hv[i]));
                }
                let (start, known) = self.best_start(t, (x0, y0), start, candidates);
                // Below the coarsest level, a patch whose start takes it out
                // of the picture keeps that start (the coarser level's and
                // its neighbours' motion, extrapolated): a descent against
                // the replicated border slides along it, as far as the
                // distance check lets it. The coarsest level's starts are
                // no such estimate.
                if self.refines && !self.lv.i1.holds::<P>(x0 as f32 + start.0, y0 as f32 + start.1) {
                    (su[k], sv[k]) = start;
                    continue;
                }
                let end = t.descend_from(self.lv.i1, x0, y0, start, known, steps_per_pass, mn);
                // A step that runs further than a patch from its start has
                // most likely left the basin of the right match: keep the start.
                (su[k], sv[k]) = if (end.0 - start.0).hypot(end.1 - start.1) <= P as f32 {
                    end
                } else {
                    start
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patch_origins_cover_every_pixel() {
        assert_eq!(patch_origins(20, 8, 4), vec![0, 4, 8, 12]);
        assert_eq!(patch_origins(21, 8, 4), vec![0, 4, 8, 12, 13]);
        assert_eq!(patch_origins(8, 8, 3), vec![0]);
        assert_eq!(patch_origins(5, 8, 3), vec![0]);
    }

    #[test]
    fn sobel_of_a_ramp_is_its_slope() {
        let (w, h) = (9, 7);
        let img: Vec<f32> = (0..w * h)
            .map(|i| 3.0 * (i % w) as f32 - 2.0 * (i / w) as f32)
            .collect();
        let (gx, gy) = sobel(&img, w, h);
        assert_eq!((gx[3 * w + 4], gy[3 * w + 4]), (3.0, -2.0));
    }

    #[test]
    fn every_level_searches_as_the_scalar_build() {
        {
            let f = |x: f32, y: f32| {
                128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos() + 25.0 * ((x - y) / 3.0).cos()
            };
            let (w, h) = (61, 45);
            let a1 = Array2::from_shape_fn((h, w), |(y, x)| f(x as f32, y as f32));
            let a2 = Array2::from_shape_fn((h, w), |(y, x)| f(x as f32 - 2.3, y as f32 + 1.4));
            let padded = Padded::new(a2.as_slice().unwrap(), w, h, 10);
            let (u, v) = (Array2::from_elem((h, w), 1.5f32), Array2::zeros((h, w)));
            for (patch, global) in [(8, false), (12, true), (4, false)] {
                let params = DisParams {
                    patch,
                    stride: 3,
                    global_search: global,
                    ..DisParams::default()
                };
                let input = LevelSearch {
                    a1: &a1,
                    a2: &padded,
                    u: &u,
                    v: &v,
                    hint: None,
                    params: &params,
                    exhaustive: global,
                    damping: params.damping,
                    refines: true,
                };
                let plain = search_level_body::<false>(&input, patch);
                for level in crate::codec::cpu::available() {
                    let wide = (crate::flow::dsp::FLOW.at(level).dis_search_level)(&input, patch);
                    assert!(
                        plain.u == wide.u && plain.v == wide.v,
                        "patch {patch}: {level:?} and scalar builds differ"
                    );
                }
                // The start is 0.8 px off; the search takes a third of that at most.
                let centre = plain.u.len() / 2;
                assert!(
                    (plain.u[centre] - 2.3).abs() < 0.27,
                    "patch {patch}: {}",
                    plain.u[centre]
                );
            }
        }
    }
}
