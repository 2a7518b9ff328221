//! Frame interpolation: a frame at any time `t` in (0, 1) between two
//! frames, from dense flow both ways (ffmpeg's `minterpolate` does this
//! with block vectors and OBMC; here the motion is per pixel).
//!
//! 1. DIS flow from frame 0 to 1 and from 1 to 0; the forward-backward
//!    check marks the pixels each frame has that the other does not show.
//! 2. Each frame's pixels are splatted to where they are at time `t`
//!    ([`splat`]), giving per pixel the flow to both frames and whether it
//!    is seen in each. With the motion of the pairs either side
//!    ([`PairMotion::accelerate`]) a pixel moves along a parabola through
//!    three frames instead of a straight line: a hand-held camera or a
//!    moving hand seldom moves at a constant speed.
//! 3. Both frames are read along those flows (bicubic) and blended, each
//!    by its nearness in time and by whether the pixel is seen in it.
//! 4. Where the two reads disagree about as much as the frames do in
//!    place, the flow has not followed the motion (bubbles, spray, blur:
//!    a forward-backward check passes on a field that is consistently
//!    wrong), and the frames' plain average is blended in, weighed against
//!    the reads by the two disagreements over a window of a few pixels
//!    ([`InterpolateParams::fallback_cells`]). minterpolate's overlapped
//!    blocks blur such places the same way; a per-pixel flow alone puts
//!    sharp content in the wrong place.
//!
//! Where too few pixels pass the forward-backward check and the luma
//! histogram changed (a scene cut), the nearer frame is repeated instead.
//!
//! ```
//! use mocomp::codec::Frame;
//! use mocomp::interpolate::{Interpolator, InterpolateParams};
//! let a = Frame::filled(64, 48, 100, 128, 128).unwrap();
//! let mut interp = Interpolator::new(&InterpolateParams::default()).unwrap();
//! let pair = interp.pair(&a, &a);
//! let mid = interp.at(&pair, &a, &a, 0.5);
//! assert_eq!(mid.y().get(10, 10), 100);
//! ```

pub mod splat;

use ndarray::Array2;
use rayon::prelude::*;

use crate::codec::{Frame, Plane};
use crate::flow::consistency::inconsistent;
use crate::flow::warp::{bilinear_clamped, sample_bicubic};
use crate::flow::{Flow, FlowEstimator, FlowOptions, Preset};
use crate::imgproc::pyramid::blur;
use crate::raster::plane_to_array;
use splat::{intermediate, Intermediate, Side};

/// How frames are interpolated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterpolateParams {
    /// DIS preset of both flows.
    pub preset: Preset,
    /// Below this share of pixels passing the forward-backward check, the
    /// pair is a cut and the nearer frame is repeated...
    pub cut_below: f64,
    /// ... if its luma histogram changed by at least this much too
    /// ([`histogram_change`]); below it (fast motion within one shot) the
    /// flows are used as they are.
    pub cut_histogram: f64,
    /// Where the two frames read along the flows disagree (motion the flow
    /// cannot follow: bubbles, spray, blur), the frames' plain average is
    /// blended in, weighed against the reads as two estimates with those
    /// errors; the window over which the two are compared, in cells of
    /// [`FALLBACK_CELL`] pixels (Gaussian sigma). 0 turns the fallback off.
    pub fallback_cells: f32,
}

impl Default for InterpolateParams {
    /// DIS fast; a cut below 40 % consistent pixels with 30 % of the
    /// histogram moved; the fallback compared over a window of 4 pixels'
    /// sigma.
    fn default() -> InterpolateParams {
        InterpolateParams {
            preset: Preset::Fast,
            cut_below: 0.4,
            cut_histogram: 0.3,
            fallback_cells: 1.0,
        }
    }
}

/// Why interpolation could not start.
#[derive(Debug, thiserror::Error)]
pub enum InterpolateError {
    /// A setting out of range.
    #[error("{0}")]
    Params(String),
}

/// The motion between two frames, found once for any number of times.
pub struct PairMotion {
    luma: [Array2<f32>; 2],
    flow: [Flow; 2],
    occluded: [Array2<bool>; 2],
    /// Per side, the trajectory's second difference (see [`PairMotion::accelerate`]).
    acceleration: [Option<Flow>; 2],
    /// Whether the pair is a cut (the nearer frame is repeated).
    pub cut: bool,
    /// Share of frame 0's pixels that pass the forward-backward check.
    pub consistent: f64,
}

impl PairMotion {
    /// Bends the pair's straight paths into parabolas through the frames
    /// either side (the quadratic motion of QVI, Xu et al. 2019, without
    /// its learned refinement). `before` is the motion of the frame before
    /// and frame 0, `after` that of frame 1 and the frame after, at the
    /// same spacing. A pixel of frame 0 moves along
    /// `p(t) = t * f01 + (t^2 - t) / 2 * a` with `a = f01 + f0,-1` (and
    /// frame 1's the same way backwards). Where the outer flow fails its
    /// forward-backward check, or either neighbour is a cut, the path stays
    /// straight; accelerations within flow noise ([`ACCELERATION_NOISE`])
    /// are shrunk to nothing, so a steady pan stays straight. With both
    /// neighbours, each frame's second difference is averaged with the
    /// other's along the pair's flow: halfway, the path is then the cubic
    /// through the four frames (weights -1, 9, 9, -1 over 16), which
    /// follows a change of acceleration better than either parabola.
    pub fn accelerate(&mut self, before: Option<&PairMotion>, after: Option<&PairMotion>) {
        if self.cut {
            self.acceleration = [None, None];
            return;
        }
        let [ahead0, ahead1] = &self.flow;
        let (a0, a1) = rayon::join(
            || before.and_then(|b| second_difference(ahead0, b, 1)),
            || after.and_then(|a| second_difference(ahead1, a, 0)),
        );
        self.acceleration = match (a0, a1) {
            (Some(a0), Some(a1)) => {
                let (m0, m1) = rayon::join(|| mean_along(&a0, &a1, ahead0), || mean_along(&a1, &a0, ahead1));
                [Some(m0), Some(m1)]
            }
            (a0, a1) => [a0, a1],
        };
    }
}

/// The mean of `own` and `other`, the latter read where `flow` takes each
/// pixel (bilinear): both frames' second differences of one path.
fn mean_along(own: &Flow, other: &Flow, flow: &Flow) -> Flow {
    let (w, h) = (own.width(), own.height());
    let [au, av, ou, ov, fu, fv] = [own.u(), own.v(), other.u(), other.v(), flow.u(), flow.v()]
        .map(|a| a.as_slice().expect("standard layout"));
    let (mut u, mut v) = (Vec::with_capacity(w * h), Vec::with_capacity(w * h));
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (px, py) = (x as f32 + fu[i], y as f32 + fv[i]);
            let (c, d) = if px.is_finite() && py.is_finite() {
                (
                    bilinear_clamped(ou, w, h, px, py),
                    bilinear_clamped(ov, w, h, px, py),
                )
            } else {
                // No flow to follow: no bend.
                (-au[i], -av[i])
            };
            u.push(0.5 * (au[i] + c));
            v.push(0.5 * (av[i] + d));
        }
    }
    let field = |d: Vec<f32>| Array2::from_shape_vec((h, w), d).expect("w * h values");
    Flow::from_uv(field(u), field(v))
}

/// Flow noise (px) below which an acceleration is taken as none; larger
/// ones are shrunk by it (soft thresholding).
pub const ACCELERATION_NOISE: f32 = 0.4;

/// The second difference of a path at one frame: its flow `ahead` to the
/// next frame plus its flow to the frame before, which is side `side` of
/// the neighbouring pair `behind`; none where `behind` is a cut or of
/// another size.
fn second_difference(ahead: &Flow, behind: &PairMotion, side: usize) -> Option<Flow> {
    let back = &behind.flow[side];
    let occluded = &behind.occluded[side];
    if behind.cut || (back.width(), back.height()) != (ahead.width(), ahead.height()) {
        return None;
    }
    let (mut u, mut v) = (ahead.u() + back.u(), ahead.v() + back.v());
    ndarray::Zip::from(&mut u)
        .and(&mut v)
        .and(occluded)
        .for_each(|u, v, &occluded| {
            let length = u.hypot(*v);
            let keep = if occluded || !length.is_finite() || length <= ACCELERATION_NOISE {
                0.0
            } else {
                1.0 - ACCELERATION_NOISE / length
            };
            *u *= keep;
            *v *= keep;
        });
    Some(Flow::from_uv(u, v))
}

/// Interpolates frames; its flow estimator (and buffers) is kept from
/// pair to pair.
pub struct Interpolator {
    params: InterpolateParams,
    /// One estimator per direction, so that both flows run at once.
    flows: [FlowEstimator; 2],
}

impl Interpolator {
    /// An interpolator with `params`.
    pub fn new(params: &InterpolateParams) -> Result<Interpolator, InterpolateError> {
        for (what, value) in [
            ("cut threshold", params.cut_below),
            ("cut histogram change", params.cut_histogram),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(InterpolateError::Params(format!(
                    "{what} {value} must be between 0 and 1"
                )));
            }
        }
        if !(0.0..=16.0).contains(&params.fallback_cells) {
            return Err(InterpolateError::Params(format!(
                "fallback window {} must be between 0 and 16 cells",
                params.fallback_cells
            )));
        }
        let options = FlowOptions {
            preset: params.preset,
            fine_on_small: true,
            ..FlowOptions::default()
        };
        let make = || FlowEstimator::new(&options).map_err(|e| InterpolateError::Params(e.to_string()));
        Ok(Interpolator {
            params: *params,
            flows: [make()?, make()?],
        })
    }

    /// The flows both ways between `f0` and `f1` (one size), their
    /// occlusions, and whether the pair is a cut.
    pub fn pair(&mut self, f0: &Frame, f1: &Frame) -> PairMotion {
        let luma = [plane_to_array(f0.y()), plane_to_array(f1.y())];
        let [fwd, bwd] = &mut self.flows;
        let (forward, backward) = rayon::join(
            || fwd.compute(&luma[0], &luma[1]),
            || bwd.compute(&luma[1], &luma[0]),
        );
        let (occ0, occ1) = rayon::join(
            || inconsistent(&forward, &backward),
            || inconsistent(&backward, &forward),
        );
        let occluded = [occ0, occ1];
        let total = occluded[0].len().max(1) as f64;
        let consistent = occluded[0].iter().filter(|&&o| !o).count() as f64 / total;
        PairMotion {
            luma,
            flow: [forward, backward],
            occluded,
            acceleration: [None, None],
            cut: consistent < self.params.cut_below
                && histogram_change(f0.y(), f1.y()) >= self.params.cut_histogram,
            consistent,
        }
    }

    /// The frame at time `t` (0: `f0`, 1: `f1`) of a pair whose motion is
    /// `motion`.
    pub fn at(&self, motion: &PairMotion, f0: &Frame, f1: &Frame, t: f64) -> Frame {
        let t = t.clamp(0.0, 1.0);
        if motion.cut || t <= 0.0 || t >= 1.0 {
            // At a cut the new shot starts with the later frame.
            return if t <= 0.5 { f0.clone() } else { f1.clone() };
        }
        let side = |k: usize| Side {
            image: &motion.luma[k],
            other: &motion.luma[1 - k],
            flow: &motion.flow[k],
            occluded: &motion.occluded[k],
            acceleration: motion.acceleration[k].as_ref(),
        };
        let mid = intermediate(&side(0), &side(1), t as f32);
        let half = halve(&mid);
        // Luma as the flows saw it (converted once, in `pair`).
        let window = self.params.fallback_cells;
        let y = blend(&motion.luma[0], &motion.luma[1], &mid, t as f32, window);
        let chroma =
            |p: &Plane, q: &Plane| blend(&plane_to_array(p), &plane_to_array(q), &half, t as f32, window);
        let (u, v) = (chroma(f0.u(), f1.u()), chroma(f0.v(), f1.v()));
        Frame::from_planes(y, u, v).expect("planes of one frame's sizes")
    }
}

/// How much of the luma histogram (32 bins) moved between two planes: 0
/// for the same distribution, 1 for disjoint ones.
pub fn histogram_change(a: &Plane, b: &Plane) -> f64 {
    let hist = |p: &Plane| {
        let mut h = [0u64; 32];
        for row in p.rows() {
            for &v in row {
                h[usize::from(v >> 3)] += 1;
            }
        }
        h
    };
    let (ha, hb) = (hist(a), hist(b));
    let (na, nb) = (
        ha.iter().sum::<u64>().max(1) as f64,
        hb.iter().sum::<u64>().max(1) as f64,
    );
    let common: f64 = ha
        .iter()
        .zip(&hb)
        .map(|(&x, &y)| (x as f64 / na).min(y as f64 / nb))
        .sum();
    1.0 - common
}

/// The side of the square cells over which the interpolation's fallback
/// sums its measures before smoothing them.
pub const FALLBACK_CELL: usize = 4;

/// One pixel at time `t`: both frames read along the intermediate flows
/// and blended (`mc`), the frames' plain average in place (`plain`).
#[derive(Clone, Copy, Default)]
struct Read {
    mc: f32,
    plain: f32,
}

/// What [`fallback_shares`] weighs the two reads of a pixel by: the squared
/// difference of the two frames' reads along the flows where both frames
/// see the pixel (times `both`, the share seen in both) and the squared
/// difference of the frames in place (`apart`); summed over cells, with
/// their `pixels` (fewer in the last row and column of cells).
#[derive(Clone, Copy, Default)]
struct Disagreement {
    reads: f32,
    both: f32,
    apart: f32,
    pixels: f32,
}

/// One plane at time `t`: both frames read along the intermediate flows
/// (bicubic), weighted by nearness in time and by visibility, then the
/// frames' plain average blended in where the reads disagree (over a
/// window of `window` cells, [`fallback_shares`]; 0: not at all); bands
/// of a cell's rows in parallel.
fn blend(a: &Array2<f32>, b: &Array2<f32>, mid: &Intermediate, t: f32, window: f32) -> Plane {
    let (h, w) = a.dim();
    let c = FALLBACK_CELL;
    let cw = w.div_ceil(c);
    let mut reads = vec![Read::default(); w * h];
    let mut cells = vec![Disagreement::default(); cw * h.div_ceil(c)];
    reads
        .par_chunks_mut(w * c)
        .zip(cells.par_chunks_mut(cw))
        .enumerate()
        .for_each(|(band, (rows, cells))| {
            for (i, read) in rows.iter_mut().enumerate() {
                let at = [band * c + i / w, i % w];
                let (r, d) = read_at(a, b, mid, t, at);
                *read = r;
                let cell = &mut cells[at[1] / c];
                cell.reads += d.reads;
                cell.both += d.both;
                cell.apart += d.apart;
                cell.pixels += 1.0;
            }
        });
    let shares = (window > 0.0).then(|| fallback_shares(&cells, cw, window));
    let mut packed = vec![0u8; w * h];
    packed.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let reads = &reads[y * w..(y + 1) * w];
        let Some(shares) = &shares else {
            for (out, r) in row.iter_mut().zip(reads) {
                *out = (r.mc + 0.5).clamp(0.0, 255.0) as u8;
            }
            return;
        };
        let share_row = shares_of_row(shares, cw, y);
        for (x, (out, r)) in row.iter_mut().zip(reads).enumerate() {
            let share = share_row.at(x);
            *out = (r.mc + share * (r.plain - r.mc) + 0.5).clamp(0.0, 255.0) as u8;
        }
    });
    Plane::from_packed(w, h, &packed).expect("a plane's own size")
}

/// The shares of cells along one pixel row, between the centres of the
/// cell rows either side (as bilinear interpolation between cell centres,
/// the vertical half done once a row).
struct ShareRow(Vec<f32>);

impl ShareRow {
    /// The share at pixel column `x`: linear between the centres of the
    /// cells either side, the edge cells' beyond their centres.
    #[inline]
    fn at(&self, x: usize) -> f32 {
        let c = FALLBACK_CELL;
        let pos = (x as f32 + 0.5) / c as f32 - 0.5;
        let last = self.0.len() - 1;
        let left = (pos.max(0.0) as usize).min(last);
        let right = (left + 1).min(last);
        let frac = (pos - left as f32).clamp(0.0, 1.0);
        self.0[left] + frac * (self.0[right] - self.0[left])
    }
}

/// [`ShareRow`] of pixel row `y` from the cells' shares (`cw` a row).
fn shares_of_row(shares: &[f32], cw: usize, y: usize) -> ShareRow {
    let c = FALLBACK_CELL;
    let rows = shares.len() / cw;
    let pos = (y as f32 + 0.5) / c as f32 - 0.5;
    let top = (pos.max(0.0) as usize).min(rows - 1);
    let bottom = (top + 1).min(rows - 1);
    let frac = (pos - top as f32).clamp(0.0, 1.0);
    let (a, b) = (
        &shares[top * cw..(top + 1) * cw],
        &shares[bottom * cw..(bottom + 1) * cw],
    );
    ShareRow(a.iter().zip(b).map(|(&p, &q)| p + frac * (q - p)).collect())
}

/// [`Read`] and [`Disagreement`] of pixel `at`.
#[inline]
fn read_at(
    a: &Array2<f32>,
    b: &Array2<f32>,
    mid: &Intermediate,
    t: f32,
    at: [usize; 2],
) -> (Read, Disagreement) {
    let (fx, fy) = (at[1] as f32, at[0] as f32);
    let s0 = sample_bicubic(a, fx + mid.to0.0[at], fy + mid.to0.1[at]);
    let s1 = sample_bicubic(b, fx + mid.to1.0[at], fy + mid.to1.1[at]);
    let (w0, w1) = ((1.0 - t) * mid.seen0[at], t * mid.seen1[at]);
    let mc = if w0 + w1 > 1e-6 {
        (w0 * s0 + w1 * s1) / (w0 + w1)
    } else {
        (1.0 - t) * s0 + t * s1
    };
    let both = mid.seen0[at].min(mid.seen1[at]);
    let apart = a[at] - b[at];
    let read = Read {
        mc,
        plain: (1.0 - t) * a[at] + t * b[at],
    };
    let disagreement = Disagreement {
        reads: both * (s0 - s1) * (s0 - s1),
        both,
        apart: apart * apart,
        pixels: 1.0,
    };
    (read, disagreement)
}

/// Per cell of [`FALLBACK_CELL`] pixels (`cells` in raster order, `cw` a
/// row): how much of the frames' plain average to take instead of the
/// reads along the flows. Each is an estimate with an error: where both
/// frames see a pixel, the reads' mean errs by about half their
/// difference, and the plain average by about half the frames' difference
/// in place, so the two are weighed as two independent estimates are for
/// the least squared error, each by the other's mean squared difference
/// over a Gaussian window of `window` cells. Where the flow is right the
/// reads agree to the noise and the share is near 0; where it cannot
/// follow the motion (bubbles, spray) they differ as much as the frames
/// do, and the plain average, blurred but never off by a whole
/// displacement, takes half or more. Cells no pixel of which both frames
/// see (occlusions, where the reads differ by right) keep the reads.
fn fallback_shares(cells: &[Disagreement], cw: usize, window: f32) -> Vec<f32> {
    let grid = |f: fn(&Disagreement) -> f32| {
        let values = Array2::from_shape_vec((cells.len() / cw, cw), cells.iter().map(f).collect());
        blur(&values.expect("whole rows of cells"), window)
    };
    let (reads, both) = (grid(|d| d.reads), grid(|d| d.both));
    let (apart, pixels) = (grid(|d| d.apart), grid(|d| d.pixels));
    ndarray::Zip::from(&reads)
        .and(&both)
        .and(&apart)
        .and(&pixels)
        .map_collect(|&d, &m, &a, &n| {
            // `both` sums shares of pixels: under a hundredth of a pixel's
            // worth is none.
            if m < 0.01 {
                return 0.0;
            }
            let reads_err = d / m;
            let plain_err = a / n;
            reads_err / (reads_err + plain_err + 1e-3)
        })
        .into_raw_vec_and_offset()
        .0
}

/// The intermediate flows and visibility at 4:2:0 chroma size: 2x2 means,
/// the flows halved.
fn halve(mid: &Intermediate) -> Intermediate {
    let (h, w) = mid.seen0.dim();
    let (ch, cw) = (h.div_ceil(2), w.div_ceil(2));
    let down = |a: &Array2<f32>, scale: f32| {
        Array2::from_shape_fn((ch, cw), |(y, x)| {
            let (mut sum, mut n) = (0.0, 0.0);
            for yy in 2 * y..(2 * y + 2).min(h) {
                for xx in 2 * x..(2 * x + 2).min(w) {
                    sum += a[[yy, xx]];
                    n += 1.0;
                }
            }
            scale * sum / n
        })
    };
    Intermediate {
        to0: (down(&mid.to0.0, 0.5), down(&mid.to0.1, 0.5)),
        to1: (down(&mid.to1.0, 0.5), down(&mid.to1.1, 0.5)),
        seen0: down(&mid.seen0, 1.0),
        seen1: down(&mid.seen1, 1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motion(back: (f32, f32), occluded_at: Option<(usize, usize)>, cut: bool) -> PairMotion {
        let (w, h) = (8, 6);
        let flow = |(u, v): (f32, f32)| Flow::from_fn(w, h, |_, _| (u, v));
        let mut occluded = Array2::from_elem((h, w), false);
        if let Some((x, y)) = occluded_at {
            occluded[[y, x]] = true;
        }
        PairMotion {
            luma: [Array2::zeros((h, w)), Array2::zeros((h, w))],
            flow: [flow((0.0, 0.0)), flow(back)],
            occluded: [occluded.clone(), occluded],
            acceleration: [None, None],
            cut,
            consistent: 1.0,
        }
    }

    #[test]
    fn the_second_difference_is_shrunk_by_the_noise_and_dropped_where_unsure() {
        let ahead = Flow::from_fn(8, 6, |_, _| (2.0, 1.0));
        // Flow to the frame before (-3, -1): second difference (-1, 0),
        // shrunk by the noise to (-0.6, 0); occluded pixels keep none.
        let d = second_difference(&ahead, &motion((-3.0, -1.0), Some((2, 3)), false), 1).unwrap();
        assert!(
            (d.get(0, 0).0 + (1.0 - ACCELERATION_NOISE)).abs() < 1e-6,
            "{:?}",
            d.get(0, 0)
        );
        assert_eq!(d.get(0, 0).1, 0.0);
        assert_eq!(d.get(2, 3), (0.0, 0.0));
        // Within the noise: no bend at all.
        let small = second_difference(&ahead, &motion((-2.2, -1.1), None, false), 1).unwrap();
        assert!(small.u().iter().chain(small.v()).all(|&c| c == 0.0));
        // Next to a cut, or of another size: none.
        assert!(second_difference(&ahead, &motion((-3.0, -1.0), None, true), 1).is_none());
        let other = Flow::from_fn(4, 6, |_, _| (2.0, 1.0));
        assert!(second_difference(&other, &motion((-3.0, -1.0), None, false), 1).is_none());
    }

    /// Cells of `n` 4x4 rows and columns, each as given.
    fn cells(n: usize, reads: f32, both: f32, apart: f32) -> Vec<Disagreement> {
        let pixels = (FALLBACK_CELL * FALLBACK_CELL) as f32;
        vec![
            Disagreement {
                reads,
                both,
                apart,
                pixels
            };
            n * n
        ]
    }

    #[test]
    fn the_plain_average_is_weighed_against_the_reads_by_their_disagreement() {
        let pixels = (FALLBACK_CELL * FALLBACK_CELL) as f32;
        // Reads that agree: none of the plain average.
        let agree = fallback_shares(&cells(6, 0.0, pixels, 100.0 * pixels), 6, 1.0);
        assert!(agree.iter().all(|&s| s < 1e-4), "{agree:?}");
        // Reads that differ as much as the frames do: half of it.
        let alike = fallback_shares(&cells(6, 100.0 * pixels, pixels, 100.0 * pixels), 6, 1.0);
        assert!(alike.iter().all(|&s| (s - 0.5).abs() < 1e-4), "{alike:?}");
        // Four times as much: 0.8; frames alike in place: all of it.
        let worse = fallback_shares(&cells(6, 400.0 * pixels, pixels, 100.0 * pixels), 6, 1.0);
        assert!(worse.iter().all(|&s| (s - 0.8).abs() < 1e-4), "{worse:?}");
        let still = fallback_shares(&cells(6, 400.0 * pixels, pixels, 0.0), 6, 1.0);
        assert!(still.iter().all(|&s| s > 0.99), "{still:?}");
        // Seen by one frame only (occluded): the reads are kept.
        let occluded = fallback_shares(&cells(6, 0.0, 0.0, 100.0 * pixels), 6, 1.0);
        assert!(occluded.iter().all(|&s| s == 0.0), "{occluded:?}");
    }

    #[test]
    fn a_wrong_flow_over_a_still_scene_falls_back_to_the_frames() {
        // Texture that no displacement matches, the same in both frames,
        // and flows both ways that agree with each other but are wrong;
        // sides that leave the last cells part-filled.
        let (w, h) = (66, 50);
        let texture = Plane::from_fn(w, h, |x, y| ((x * 7919 + y * 104_729) % 251) as u8).unwrap();
        let grey = Plane::from_fn(w / 2, h / 2, |_, _| 128).unwrap();
        let frame = Frame::from_planes(texture.clone(), grey.clone(), grey).unwrap();
        let flow = |(u, v): (f32, f32)| Flow::from_fn(w, h, |_, _| (u, v));
        let wrong = PairMotion {
            luma: [plane_to_array(&texture), plane_to_array(&texture)],
            flow: [flow((6.0, -4.0)), flow((-6.0, 4.0))],
            occluded: [Array2::from_elem((h, w), false), Array2::from_elem((h, w), false)],
            acceleration: [None, None],
            cut: false,
            consistent: 1.0,
        };
        let error = |fallback_cells: f32| {
            let params = InterpolateParams {
                fallback_cells,
                ..InterpolateParams::default()
            };
            let made = Interpolator::new(&params)
                .unwrap()
                .at(&wrong, &frame, &frame, 0.5);
            crate::metrics::mse(made.y(), frame.y())
        };
        let (with, without) = (error(1.0), error(0.0));
        assert!(
            with < 1.0 && without > 1000.0,
            "MSE {with} with the fallback, {without} without"
        );
        assert!(Interpolator::new(&InterpolateParams {
            fallback_cells: -1.0,
            ..InterpolateParams::default()
        })
        .is_err());
    }

    #[test]
    fn the_histogram_change_is_zero_for_moved_content_and_one_for_disjoint() {
        let ramp = |shift: usize| Plane::from_fn(64, 16, |x, _| (((x + shift) % 64) * 4) as u8).unwrap();
        assert_eq!(histogram_change(&ramp(0), &ramp(0)), 0.0);
        // The same content moved: the same histogram.
        assert!(histogram_change(&ramp(0), &ramp(17)) < 1e-12);
        let flat = |v: u8| Plane::from_fn(64, 16, |_, _| v).unwrap();
        assert_eq!(histogram_change(&flat(10), &flat(200)), 1.0);
        // Half the picture changed to a new grey level.
        let half = Plane::from_fn(64, 16, |x, _| if x < 32 { 10 } else { 200 }).unwrap();
        assert!((histogram_change(&flat(10), &half) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn both_frames_second_differences_are_averaged_along_the_flow() {
        // The other frame's field is a ramp in x; the flow moves 2 px right.
        let own = Flow::from_fn(8, 6, |_, _| (1.0, -1.0));
        let other = Flow::from_fn(8, 6, |x, _| (x as f32, 0.0));
        let flow = Flow::from_fn(8, 6, |_, _| (2.0, 0.0));
        let m = mean_along(&own, &other, &flow);
        assert_eq!(m.get(1, 2), (0.5 * (1.0 + 3.0), -0.5));
        // Beyond the edge the other field is read at its edge.
        assert_eq!(m.get(7, 0), (0.5 * (1.0 + 7.0), -0.5));
    }
}
