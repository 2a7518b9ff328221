//! Moving-object segmentation with a moving camera: where the flow departs
//! from the camera's motion (unlike background subtraction, which needs a
//! still camera).
//!
//! For each frame: DIS flow to the next frame and to the one before; a
//! homography fitted to each (RANSAC, then reweighted least squares) is
//! the camera; each pixel's residual (flow minus camera motion) is
//! normalised by a tolerance that grows with the motion (flow is less
//! certain where it is large) and doubled where the forward-backward check
//! fails (occlusions). The two directions' scores are averaged (a pixel
//! that moves in both is surely moving; one occluded in one direction is
//! judged by the other), smoothed by a Gaussian, then capped and spread
//! within the frame's regions of like brightness by an edge-aware filter
//! (the domain transform's, guided by the luma: a flat background that
//! took a mover's motion is outvoted by the rest of its region),
//! thresholded, and cleaned by an opening and a closing (3x3).

use ndarray::Array2;

use crate::codec::{Frame, Plane};
use crate::flow::consistency::inconsistent;
use crate::flow::warp::sample_bilinear;
use crate::flow::{Flow, FlowEstimator, FlowOptions, Preset};
use crate::global::sources::from_flow;
use crate::global::{estimate, GlobalParams, Model, Refinement, Transform};
use crate::imgproc::domain::domain_transform;
use crate::imgproc::pyramid::blur;
use crate::raster::plane_to_array;

/// How moving pixels are told apart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentParams {
    /// DIS preset of the flows.
    pub preset: Preset,
    /// Residual (pixels) at which a still pixel of a still camera counts
    /// as moving.
    pub tolerance: f32,
    /// The tolerance's growth with the flow's length (share of it).
    pub relative: f32,
    /// Sigma of the score's smoothing, pixels.
    pub smoothing: f32,
    /// How far the score then spreads within the frame's regions of like
    /// brightness, as a share of the picture's smaller side (0: not at
    /// all): a flat background beside something that moves takes its
    /// motion in the flow, and the rest of its region outvotes it.
    pub region_reach: f32,
    /// The brightness step (grey levels) that stretches the distance
    /// across it by the whole reach: the regions' edges.
    pub region_edge: f32,
    /// The most a pixel's score counts for in that vote (above 1, the
    /// threshold): a few pixels far off the camera's motion must not
    /// carry a region.
    pub evidence_cap: f32,
}

impl SegmentParams {
    /// The score's spatial reach in pixels on a picture of `dim`
    /// (height, width), when it spreads at all.
    fn region_reach(&self, (h, w): (usize, usize)) -> Option<f32> {
        let reach = h.min(w) as f32 * self.region_reach;
        (reach >= 1.0).then_some(reach)
    }
}

impl Default for SegmentParams {
    /// DIS fast, 1 pixel plus 10 % of the motion, smoothing sigma 1.5;
    /// the score capped at 1.5 and spread over half the smaller side
    /// within edges of 10 grey levels. On six real clips with a pasted
    /// disc (benches/segment_composite.sh) the mean IoU was 0.887 with
    /// these, 0.771 without the spreading; an edge of 5 or 20 levels
    /// gave 0.859 and 0.849, a cap of 2 0.875, the whole side 0.877 (frame
    /// by frame, before [`Segmenter::masks`]' median in time: 0.897 with it).
    fn default() -> SegmentParams {
        SegmentParams {
            preset: Preset::Fast,
            tolerance: 1.0,
            relative: 0.1,
            smoothing: 1.5,
            region_reach: 0.5,
            region_edge: 10.0,
            evidence_cap: 1.5,
        }
    }
}

/// Why segmentation failed.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    /// A setting out of range.
    #[error("{0}")]
    Params(String),
}

/// Segments frames, its flow estimators kept from frame to frame.
pub struct Segmenter {
    params: SegmentParams,
    flows: [FlowEstimator; 2],
    /// The last pair of frames whose flows were computed, with both flows:
    /// frame t's pair with t + 1 is frame t + 1's pair with t.
    last_pair: Option<PairFlows>,
}

/// Two lumas and the flow each way between them.
struct PairFlows {
    a: Array2<f32>,
    b: Array2<f32>,
    a_to_b: Flow,
    b_to_a: Flow,
}

impl PairFlows {
    /// The flows from `from` to `to` and back, when this pair holds them.
    fn flows(&self, from: &Array2<f32>, to: &Array2<f32>) -> Option<(Flow, Flow)> {
        if self.a == from && self.b == to {
            Some((self.a_to_b.clone(), self.b_to_a.clone()))
        } else if self.a == to && self.b == from {
            Some((self.b_to_a.clone(), self.a_to_b.clone()))
        } else {
            None
        }
    }
}

impl Segmenter {
    /// A segmenter with `params`.
    pub fn new(params: &SegmentParams) -> Result<Segmenter, SegmentError> {
        let positive = |v: f32| v.is_finite() && v >= 0.0;
        if !(positive(params.tolerance)
            && params.tolerance > 0.0
            && positive(params.relative)
            && positive(params.smoothing)
            && positive(params.region_reach)
            && params.region_edge > 0.0
            && params.region_edge.is_finite()
            && params.evidence_cap > 1.0)
        {
            return Err(SegmentError::Params(
                "tolerance and region_edge must be > 0, relative, smoothing and region_reach >= 0, evidence_cap > 1".into(),
            ));
        }
        let options = FlowOptions {
            preset: params.preset,
            fine_on_small: true,
            ..FlowOptions::default()
        };
        let make = || FlowEstimator::new(&options).map_err(|e| SegmentError::Params(e.to_string()));
        Ok(Segmenter {
            params: *params,
            flows: [make()?, make()?],
            last_pair: None,
        })
    }

    /// The motion score of `frame` against each neighbour given (the frame
    /// before and/or after): above 1 means moving against the camera; and
    /// each direction's flow and camera for the edge's relabelling.
    fn evidence(&mut self, frame: &Frame, neighbours: &[&Frame]) -> Evidence {
        let me = plane_to_array(frame.y());
        let mut total = Array2::<f32>::zeros(me.dim());
        let mut directions = Vec::new();
        for other in neighbours {
            let other = plane_to_array(other.y());
            let (forward, backward) = self.pair_flows(&me, &other);
            let (score, camera) = direction_score(&forward, &inconsistent(&forward, &backward), &self.params);
            total += &score;
            directions.push(Direction {
                other,
                flow: forward,
                camera,
            });
        }
        if !neighbours.is_empty() {
            total /= neighbours.len() as f32;
        }
        if self.params.smoothing > 0.0 {
            total = blur(&total, self.params.smoothing);
        }
        if let Some(reach) = self.params.region_reach(total.dim()) {
            let cap = self.params.evidence_cap;
            total.mapv_inplace(|v| v.min(cap));
            total = domain_transform(&me, &total, reach, self.params.region_edge, 3);
        }
        Evidence {
            me,
            score: total,
            directions,
        }
    }

    /// The flows from `me` to `other` and back: the last pair's again
    /// when it was this one, else computed (both at once) and kept.
    fn pair_flows(&mut self, me: &Array2<f32>, other: &Array2<f32>) -> (Flow, Flow) {
        if let Some(flows) = self.last_pair.as_ref().and_then(|p| p.flows(me, other)) {
            return flows;
        }
        let [a, b] = &mut self.flows;
        let (forward, backward) = rayon::join(|| a.compute(me, other), || b.compute(other, me));
        self.last_pair = Some(PairFlows {
            a: me.clone(),
            b: other.clone(),
            a_to_b: forward.clone(),
            b_to_a: backward.clone(),
        });
        (forward, backward)
    }

    /// The motion score of `frame` (above 1: moving against the camera).
    pub fn score(&mut self, frame: &Frame, neighbours: &[&Frame]) -> Array2<f32> {
        self.evidence(frame, neighbours).score
    }

    /// The mask of `frame`: 255 where something moves against the camera.
    /// Near the mask's edge (within 4 pixels), where the flow blurs the
    /// motion boundary, each pixel is given to whichever motion matches
    /// its 3x3 neighbourhood better in some neighbour frame: the camera's,
    /// or the moving region's (the mean flow of the mask's interior within
    /// 8 pixels); where neither is clearly better it stays.
    pub fn mask(&mut self, frame: &Frame, neighbours: &[&Frame]) -> Plane {
        mask_of(&self.evidence(frame, neighbours))
    }

    /// The masks of a whole sequence, in order, each handed to `each`
    /// with its frame's index: [`Segmenter::mask`]'s, but each frame's
    /// score consistent in time first ([`in_time`]): the median of its
    /// own and the frame before's and after's, read along the flow to
    /// them (at either end the mean of the two there are), so that a
    /// frame whose flow lost the object, or found one that is in no frame
    /// beside it, takes its neighbours' word. Frames of one size; the
    /// flows and scores are each made once, as for [`Segmenter::mask`]
    /// called frame by frame.
    pub fn masks<E>(
        &mut self,
        frames: &[Frame],
        mut each: impl FnMut(usize, Plane) -> Result<(), E>,
    ) -> Result<(), E> {
        let neighbours = |t: usize| neighbours(frames, t);
        let mut before: Option<Array2<f32>> = None;
        let mut now = match frames.first() {
            Some(f) => self.evidence(f, &neighbours(0)),
            None => return Ok(()),
        };
        for t in 0..frames.len() {
            let after = frames.get(t + 1).map(|f| self.evidence(f, &neighbours(t + 1)));
            let score = in_time(&now, before.as_ref(), after.as_ref().map(|e| &e.score));
            let own = std::mem::replace(&mut now.score, score);
            each(t, mask_of(&now))?;
            // The frame after reads this one's own score, not the median.
            before = Some(own);
            match after {
                Some(next) => now = next,
                None => break,
            }
        }
        Ok(())
    }
}

/// The frames either side of frame `t` of `frames` that there are, the
/// one before first: what [`Segmenter::mask`] takes as its neighbours in
/// a sequence.
pub fn neighbours(frames: &[Frame], t: usize) -> Vec<&Frame> {
    [t.checked_sub(1), Some(t + 1)]
        .into_iter()
        .flatten()
        .filter_map(|k| frames.get(k))
        .collect()
}

/// `now`'s score made consistent with the frames either side: at each
/// pixel the median of its own score and `before`'s and `after`'s read
/// where the flow to each carries it; with one of them only,
/// the mean of the two. A mover's score follows it from frame to frame,
/// a flow's failure in one frame does not.
fn in_time(now: &Evidence, before: Option<&Array2<f32>>, after: Option<&Array2<f32>>) -> Array2<f32> {
    let (h, w) = now.score.dim();
    // The directions are the neighbours' in order: the frame before first.
    let (to_before, to_after) = (now.directions.first(), now.directions.last());
    // (A neighbour of another size has no say.)
    let alike = |s: &&Array2<f32>| s.dim() == (h, w);
    let b = before
        .filter(alike)
        .zip(to_before)
        .map(|(s, d)| Reading::new(s, &d.flow));
    let a = after
        .filter(alike)
        .zip(to_after)
        .map(|(s, d)| Reading::new(s, &d.flow));
    let own = now.score.as_standard_layout();
    let own = own.as_slice().expect("standard layout");
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let s = own[y * w + x];
            out.push(match (&b, &a) {
                (Some(b), Some(a)) => median3(s, b.at(x, y), a.at(x, y)),
                (Some(one), None) | (None, Some(one)) => 0.5 * (s + one.at(x, y)),
                (None, None) => s,
            });
        }
    }
    Array2::from_shape_vec((h, w), out).expect("the frame's own size")
}

/// A neighbour's score read along the flow to it.
struct Reading<'a> {
    score: std::borrow::Cow<'a, [f32]>,
    u: std::borrow::Cow<'a, [f32]>,
    v: std::borrow::Cow<'a, [f32]>,
    w: usize,
    h: usize,
}

impl<'a> Reading<'a> {
    fn new(score: &'a Array2<f32>, flow: &'a Flow) -> Reading<'a> {
        let (h, w) = score.dim();
        let flat = |a: &'a Array2<f32>| match a.as_slice() {
            Some(s) => std::borrow::Cow::Borrowed(s),
            None => std::borrow::Cow::Owned(a.iter().copied().collect()),
        };
        Reading {
            score: flat(score),
            u: flat(flow.u()),
            v: flat(flow.v()),
            w,
            h,
        }
    }

    /// The score at the pixel nearest to where (x, y)'s flow lands
    /// (clamped into the picture; the scores are smooth: bilinear reads
    /// took 15 % of segmentation's time).
    fn at(&self, x: usize, y: usize) -> f32 {
        let i = y * self.w + x;
        let near = |p: usize, d: f32, n: usize| (p as f32 + d + 0.5).clamp(0.0, (n - 1) as f32) as usize;
        let (tx, ty) = (near(x, self.u[i], self.w), near(y, self.v[i], self.h));
        self.score[ty * self.w + tx]
    }
}

/// The middle one of three values.
fn median3(a: f32, b: f32, c: f32) -> f32 {
    a.max(b).min(a.min(b).max(c))
}

/// [`Segmenter::mask`]'s mask from its evidence.
fn mask_of(ev: &Evidence) -> Plane {
    let raw = ev.score.mapv(|s| s > 1.0);
    let mut mask = close(&open(&raw));
    let (mut outer, mut inner) = (mask.clone(), mask.clone());
    for _ in 0..EDGE_BAND {
        outer = morph(&outer, true);
        inner = morph(&inner, false);
    }
    let interiors: Vec<InteriorFlow> = ev
        .directions
        .iter()
        .map(|d| InteriorFlow::new(&inner, &d.flow))
        .collect();
    let (h, w) = mask.dim();
    for y in 0..h {
        for x in 0..w {
            if !outer[[y, x]] || inner[[y, x]] {
                continue;
            }
            let (mut cam, mut obj) = (f32::INFINITY, f32::INFINITY);
            for (d, interior) in ev.directions.iter().zip(&interiors) {
                let Some(motion) = interior.mean_near(x, y, INTERIOR_RADIUS) else {
                    continue;
                };
                cam = cam.min(patch_difference(&ev.me, &d.other, x, y, |px, py| {
                    d.camera
                        .apply(px as f64, py as f64)
                        .map(|(a, b)| (a as f32, b as f32))
                }));
                obj = obj.min(patch_difference(&ev.me, &d.other, x, y, |px, py| {
                    Some((px as f32 + motion.0, py as f32 + motion.1))
                }));
            }
            if obj + DECISION_MARGIN < cam {
                mask[[y, x]] = true;
            } else if cam + DECISION_MARGIN < obj {
                mask[[y, x]] = false;
            }
        }
    }
    let mask = close(&open(&mask));
    Plane::from_fn(w, h, |x, y| if mask[[y, x]] { 255 } else { 0 }).expect("a frame's own size")
}

/// What the mask is decided from.
struct Evidence {
    me: Array2<f32>,
    score: Array2<f32>,
    directions: Vec<Direction>,
}

/// One neighbour: its luma, the flow to it, the camera's motion to it.
struct Direction {
    other: Array2<f32>,
    flow: Flow,
    camera: Transform,
}

/// Pixels either side of the mask's edge that are decided again.
const EDGE_BAND: usize = 4;
/// The window (half-size, pixels) whose interior flow is the moving
/// region's motion near an edge pixel.
const INTERIOR_RADIUS: usize = 8;
/// How much better (grey levels, 3x3 mean) a motion must match to win.
const DECISION_MARGIN: f32 = 1.0;

/// Box sums of the flow over the interior (integral images).
struct InteriorFlow {
    width: usize,
    height: usize,
    sums: Vec<[f32; 3]>,
}

impl InteriorFlow {
    fn new(inner: &Array2<bool>, flow: &Flow) -> InteriorFlow {
        let (h, w) = inner.dim();
        let mut sums = vec![[0.0f32; 3]; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = [0.0f32; 3];
            for x in 0..w {
                if inner[[y, x]] {
                    let (u, v) = flow.get(x, y);
                    row[0] += 1.0;
                    row[1] += u;
                    row[2] += v;
                }
                let above = sums[y * (w + 1) + x + 1];
                sums[(y + 1) * (w + 1) + x + 1] = [above[0] + row[0], above[1] + row[1], above[2] + row[2]];
            }
        }
        InteriorFlow {
            width: w,
            height: h,
            sums,
        }
    }

    /// The mean interior flow within `r` of (x, y), if any interior pixel is.
    fn mean_near(&self, x: usize, y: usize, r: usize) -> Option<(f32, f32)> {
        let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
        let (x1, y1) = ((x + r + 1).min(self.width), (y + r + 1).min(self.height));
        let at = |xx: usize, yy: usize| self.sums[yy * (self.width + 1) + xx];
        let (a, b, c, d) = (at(x1, y1), at(x0, y1), at(x1, y0), at(x0, y0));
        let total: [f32; 3] = std::array::from_fn(|k| a[k] - b[k] - c[k] + d[k]);
        (total[0] >= 1.0).then(|| (total[1] / total[0], total[2] / total[0]))
    }
}

/// The 3x3 mean absolute difference between `me` around (x, y) and
/// `other` read where `to` maps each pixel (255 where it maps nowhere).
fn patch_difference(
    me: &Array2<f32>,
    other: &Array2<f32>,
    x: usize,
    y: usize,
    to: impl Fn(usize, usize) -> Option<(f32, f32)>,
) -> f32 {
    let (h, w) = me.dim();
    let (mut sum, mut n) = (0.0, 0.0);
    for yy in y.saturating_sub(1)..(y + 2).min(h) {
        for xx in x.saturating_sub(1)..(x + 2).min(w) {
            sum += match to(xx, yy) {
                Some((tx, ty)) => (me[[yy, xx]] - sample_bilinear(other, tx, ty)).abs(),
                None => 255.0,
            };
            n += 1.0;
        }
    }
    sum / n
}

/// One direction's score: the residual against the camera's homography
/// over the tolerance (doubled where the flow fails its check).
fn direction_score(flow: &Flow, occluded: &Array2<bool>, p: &SegmentParams) -> (Array2<f32>, Transform) {
    let params = GlobalParams {
        refinement: Refinement::ThresholdScale,
        ..GlobalParams::new(Model::Homography)
    };
    let camera = estimate(&from_flow(flow, 8), &params)
        .map(|f| f.transform)
        .unwrap_or(Transform::IDENTITY);
    let (w, h) = (flow.width(), flow.height());
    let score = Array2::from_shape_fn((h, w), |(y, x)| {
        let (u, v) = flow.get(x, y);
        let Some((cx, cy)) = camera.apply(x as f64, y as f64) else {
            return 0.0;
        };
        let (du, dv) = (u - (cx - x as f64) as f32, v - (cy - y as f64) as f32);
        let residual = (du * du + dv * dv).sqrt();
        let tolerance = p.tolerance + p.relative * (u * u + v * v).sqrt();
        let tolerance = if occluded[[y, x]] {
            2.0 * tolerance
        } else {
            tolerance
        };
        if residual.is_finite() {
            residual / tolerance
        } else {
            0.0
        }
    });
    (score, camera)
}

/// 3x3 erosion then dilation: specks smaller than the window go.
fn open(mask: &Array2<bool>) -> Array2<bool> {
    morph(&morph(mask, false), true)
}

/// 3x3 dilation then erosion: pinholes smaller than the window close.
fn close(mask: &Array2<bool>) -> Array2<bool> {
    morph(&morph(mask, true), false)
}

/// 3x3 dilation (`grow`) or erosion over the window's part inside the
/// picture: a pass along rows, then one across them (the square is both
/// lines; a 3x3 loop per pixel was half of segmentation's time).
fn morph(mask: &Array2<bool>, grow: bool) -> Array2<bool> {
    if grow {
        morph_with(mask, |a, b| a | b)
    } else {
        morph_with(mask, |a, b| a & b)
    }
}

/// [`morph`] with `pick` (or: dilation, and: erosion), on the rows as
/// slices so that the passes are plain loops over three shifted runs.
fn morph_with(mask: &Array2<bool>, pick: impl Fn(bool, bool) -> bool) -> Array2<bool> {
    let (h, w) = mask.dim();
    if h == 0 || w == 0 {
        return mask.clone();
    }
    let src = mask.as_standard_layout();
    let src = src.as_slice().expect("standard layout");
    let mut along = src.to_vec();
    for (s, d) in src.chunks_exact(w).zip(along.chunks_exact_mut(w)) {
        for (d, &left) in d[1..].iter_mut().zip(s) {
            *d = pick(*d, left);
        }
        for (d, &right) in d.iter_mut().zip(&s[1..]) {
            *d = pick(*d, right);
        }
    }
    let mut out = along.clone();
    for (y, row) in out.chunks_exact_mut(w).enumerate() {
        let mut with = |other: usize| {
            for (o, &a) in row.iter_mut().zip(&along[other * w..(other + 1) * w]) {
                *o = pick(*o, a);
            }
        };
        if y > 0 {
            with(y - 1);
        }
        if y + 1 < h {
            with(y + 1);
        }
    }
    Array2::from_shape_vec((h, w), out).expect("the mask's own size")
}

/// Intersection over union of two masks (non-zero is set); 1 when both
/// are empty.
pub fn iou(a: &Plane, b: &Plane) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for (ra, rb) in a.rows().zip(b.rows()) {
        for (&p, &q) in ra.iter().zip(rb) {
            inter += usize::from(p > 0 && q > 0);
            union += usize::from(p > 0 || q > 0);
        }
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// What a ground-truth mask says of a pixel, in the labels of the
/// CDnet 2014 change-detection benchmark, whose masks use them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TruthLabel {
    /// 0 (static) and 50 (hard shadow, which CDnet scores as static), and
    /// any other value under 128.
    Static,
    /// 255 (motion) and any other value from 128 up but 170.
    Moving,
    /// 85 (outside the region of interest) and 170 (unknown motion): not
    /// scored.
    NotScored,
}

impl TruthLabel {
    /// The label of a truth mask's sample.
    pub fn of(v: u8) -> TruthLabel {
        match v {
            85 | 170 => TruthLabel::NotScored,
            128.. => TruthLabel::Moving,
            _ => TruthLabel::Static,
        }
    }
}

/// Intersection over union of `mask` (non-zero is moving) and a truth
/// mask in CDnet's labels ([`TruthLabel`]), over the pixels the truth
/// scores; 1 when neither marks any of them.
pub fn iou_against_truth(mask: &Plane, truth: &Plane) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for (rm, rt) in mask.rows().zip(truth.rows()) {
        for (&m, &t) in rm.iter().zip(rt) {
            let moving = match TruthLabel::of(t) {
                TruthLabel::NotScored => continue,
                label => label == TruthLabel::Moving,
            };
            inter += usize::from(m > 0 && moving);
            union += usize::from(m > 0 || moving);
        }
    }
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The 3x3 window read pixel by pixel.
    fn morph_plain(mask: &Array2<bool>, grow: bool) -> Array2<bool> {
        let (h, w) = mask.dim();
        Array2::from_shape_fn((h, w), |(y, x)| {
            let mut window = (y.saturating_sub(1)..(y + 2).min(h))
                .flat_map(|yy| (x.saturating_sub(1)..(x + 2).min(w)).map(move |xx| (yy, xx)));
            if grow {
                window.any(|p| mask[p])
            } else {
                window.all(|p| mask[p])
            }
        })
    }

    /// Evidence of a `w x h` frame whose score is 1.5 on the `side`-pixel
    /// square at `at` and 0 elsewhere, with a flow of `(u, v)` to each
    /// of `directions` neighbours.
    fn square_evidence(
        (w, h): (usize, usize),
        at: Option<(usize, usize)>,
        side: usize,
        (u, v): (f32, f32),
        directions: usize,
    ) -> Evidence {
        let score = Array2::from_shape_fn((h, w), |(y, x)| match at {
            Some((ax, ay)) if (ax..ax + side).contains(&x) && (ay..ay + side).contains(&y) => 1.5,
            _ => 0.0,
        });
        let flow = Flow::from_uv(Array2::from_elem((h, w), u), Array2::from_elem((h, w), v));
        Evidence {
            me: Array2::zeros((h, w)),
            score,
            directions: (0..directions)
                .map(|_| Direction {
                    other: Array2::zeros((h, w)),
                    flow: flow.clone(),
                    camera: Transform::IDENTITY,
                })
                .collect(),
        }
    }

    /// How many pixels of `score` are above the threshold of 1.
    fn moving(score: &Array2<f32>) -> usize {
        score.iter().filter(|&&s| s > 1.0).count()
    }

    #[test]
    fn a_score_in_one_frame_alone_is_outvoted_by_the_frames_beside_it() {
        let dim = (40, 30);
        let before = square_evidence(dim, None, 8, (0.0, 0.0), 2);
        let after = square_evidence(dim, None, 8, (0.0, 0.0), 2);
        let now = square_evidence(dim, Some((10, 10)), 8, (0.0, 0.0), 2);
        assert_eq!(moving(&now.score), 64);
        assert_eq!(moving(&in_time(&now, Some(&before.score), Some(&after.score))), 0);
    }

    #[test]
    fn a_frame_that_lost_the_object_takes_it_from_both_neighbours_along_the_flow() {
        // The object is at x = 10 before and x = 14 after; this frame's flow
        // reads the frame before 2 px left and the frame after 2 px right,
        // so both neighbours put it at x = 12 here, where this frame's own
        // score says nothing.
        let dim = (40, 30);
        let before = square_evidence(dim, Some((10, 10)), 8, (0.0, 0.0), 2);
        let after = square_evidence(dim, Some((14, 10)), 8, (0.0, 0.0), 2);
        let mut now = square_evidence(dim, None, 8, (-2.0, 0.0), 2);
        now.directions[1].flow = Flow::from_uv(Array2::from_elem((30, 40), 2.0), Array2::zeros((30, 40)));
        let score = in_time(&now, Some(&before.score), Some(&after.score));
        assert_eq!(moving(&score), 64);
        assert!(
            score[[10, 12]] > 1.0 && score[[17, 19]] > 1.0,
            "the square at (12, 10)"
        );
        assert!(score[[10, 11]] <= 1.0 && score[[10, 20]] <= 1.0);
        // Read without the flow, the neighbours disagree about the edges.
        let mut still = square_evidence(dim, None, 8, (0.0, 0.0), 2);
        still.score = now.score.clone();
        assert_eq!(
            moving(&in_time(&still, Some(&before.score), Some(&after.score))),
            32
        );
    }

    #[test]
    fn at_either_end_the_one_neighbour_and_the_frame_are_averaged() {
        let dim = (40, 30);
        let now = square_evidence(dim, Some((10, 10)), 8, (0.0, 0.0), 1);
        let beside = square_evidence(dim, Some((10, 10)), 4, (0.0, 0.0), 1);
        let score = in_time(&now, None, Some(&beside.score));
        // 1.5 where both see it, 0.75 where only this frame does.
        assert_eq!(moving(&score), 16);
        assert_eq!(score[[10, 17]], 0.75);
        assert_eq!(in_time(&now, Some(&beside.score), None), score);
        assert_eq!(in_time(&now, None, None), now.score);
        // A neighbour of another size has no say.
        assert_eq!(
            in_time(&now, Some(&Array2::from_elem((5, 5), 9.0)), None),
            now.score
        );
    }

    #[test]
    fn the_median_of_three_is_the_middle_value() {
        for (a, b, c) in [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (2.0, 3.0, 1.0), (2.0, 2.0, 0.0)] {
            let mut sorted = [a, b, c];
            sorted.sort_by(f32::total_cmp);
            assert_eq!(median3(a, b, c), sorted[1]);
        }
    }

    proptest! {
        #[test]
        fn separable_morphology_is_the_3x3_window(
            (h, w, bits) in (1usize..9, 1usize..9).prop_flat_map(|(h, w)| {
                (Just(h), Just(w), proptest::collection::vec(any::<bool>(), h * w))
            }),
        ) {
            let mask = Array2::from_shape_vec((h, w), bits).unwrap();
            for grow in [false, true] {
                prop_assert_eq!(morph(&mask, grow), morph_plain(&mask, grow));
            }
        }
    }

    fn plane(w: usize, values: &[u8]) -> Plane {
        let mut p = Plane::new(w, values.len() / w).unwrap();
        for (y, row) in values.chunks(w).enumerate() {
            p.row_mut(y).copy_from_slice(row);
        }
        p
    }

    #[test]
    fn truth_in_cdnet_labels_scores_only_what_it_knows() {
        // Mask:  moving everywhere but the last pixel.
        let mask = plane(4, &[255, 255, 255, 255, 255, 255, 255, 0]);
        // Truth: moving, moving, unknown, outside, shadow, static,
        // static, moving.
        let truth = plane(4, &[255, 200, 170, 85, 50, 0, 10, 255]);
        // Scored: six pixels; both moving at two; either at all six.
        assert!((iou_against_truth(&mask, &truth) - 2.0 / 6.0).abs() < 1e-12);
        // A truth of 0/255 alone is plain IoU.
        let plain = plane(4, &[255, 0, 0, 255, 0, 0, 255, 255]);
        assert_eq!(iou_against_truth(&mask, &plain), iou(&mask, &plain));
        // Nothing scored: 1.
        let unknown = plane(4, &[170; 8]);
        assert_eq!(iou_against_truth(&mask, &unknown), 1.0);
        assert_eq!(TruthLabel::of(128), TruthLabel::Moving);
        assert_eq!(TruthLabel::of(127), TruthLabel::Static);
    }
}
