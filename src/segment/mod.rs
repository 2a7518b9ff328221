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
//! judged by the other), smoothed by a Gaussian, thresholded, and cleaned
//! by an opening and a closing (3x3).

use ndarray::Array2;

use crate::codec::{Frame, Plane};
use crate::flow::consistency::inconsistent;
use crate::flow::warp::sample_bilinear;
use crate::flow::{Flow, FlowEstimator, FlowOptions, Preset};
use crate::global::sources::from_flow;
use crate::global::{estimate, GlobalParams, Model, Transform};
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
}

impl Default for SegmentParams {
    /// DIS fast, 1 pixel plus 10 % of the motion, smoothing sigma 1.5.
    fn default() -> SegmentParams {
        SegmentParams {
            preset: Preset::Fast,
            tolerance: 1.0,
            relative: 0.1,
            smoothing: 1.5,
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
}

impl Segmenter {
    /// A segmenter with `params`.
    pub fn new(params: &SegmentParams) -> Result<Segmenter, SegmentError> {
        let positive = |v: f32| v.is_finite() && v >= 0.0;
        if !(positive(params.tolerance)
            && params.tolerance > 0.0
            && positive(params.relative)
            && positive(params.smoothing))
        {
            return Err(SegmentError::Params(
                "tolerance must be > 0, relative and smoothing >= 0".into(),
            ));
        }
        let options = FlowOptions {
            preset: params.preset,
            ..FlowOptions::default()
        };
        let make = || FlowEstimator::new(&options).map_err(|e| SegmentError::Params(e.to_string()));
        Ok(Segmenter {
            params: *params,
            flows: [make()?, make()?],
        })
    }

    /// The motion score of `frame` against each neighbour given (the frame
    /// before and/or after): above 1 means moving against the camera. Also
    /// the camera-compensated difference: per pixel, the least over the
    /// neighbours of the 3x3 mean absolute difference to the neighbour
    /// warped by the camera (small where the background shows).
    pub fn score(&mut self, frame: &Frame, neighbours: &[&Frame]) -> (Array2<f32>, Array2<f32>) {
        let me = plane_to_array(frame.y());
        let mut total = Array2::<f32>::zeros(me.dim());
        let mut still = Array2::<f32>::from_elem(me.dim(), f32::INFINITY);
        for other in neighbours {
            let other = plane_to_array(other.y());
            let [a, b] = &mut self.flows;
            let (forward, backward) = rayon::join(|| a.compute(&me, &other), || b.compute(&other, &me));
            let (score, camera) = direction_score(&forward, &inconsistent(&forward, &backward), &self.params);
            total += &score;
            let diff = camera_difference(&me, &other, &camera);
            still.zip_mut_with(&diff, |s, &d| *s = s.min(d));
        }
        if !neighbours.is_empty() {
            total /= neighbours.len() as f32;
        }
        if self.params.smoothing > 0.0 {
            total = blur(&total, self.params.smoothing);
        }
        (total, still)
    }

    /// The mask of `frame`: 255 where something moves against the camera.
    /// Near the mask's edge (within 4 pixels), where the flow blurs the
    /// motion boundary, the camera-compensated difference decides where it
    /// is clear: the background matches its neighbour under the camera's
    /// motion, a moving textured surface does not.
    pub fn mask(&mut self, frame: &Frame, neighbours: &[&Frame]) -> Plane {
        let (score, still) = self.score(frame, neighbours);
        let raw = score.mapv(|s| s > 1.0);
        let mut mask = close(&open(&raw));
        let (mut outer, mut inner) = (mask.clone(), mask.clone());
        for _ in 0..EDGE_BAND {
            outer = morph(&outer, true);
            inner = morph(&inner, false);
        }
        for ((m, (&o, &i)), &d) in mask
            .iter_mut()
            .zip(outer.iter().zip(inner.iter()))
            .zip(still.iter())
        {
            if o && !i {
                if d < BACKGROUND_DIFFERENCE {
                    *m = false;
                } else if d > MOVING_DIFFERENCE {
                    *m = true;
                }
            }
        }
        let mask = close(&open(&mask));
        let (h, w) = mask.dim();
        Plane::from_fn(w, h, |x, y| if mask[[y, x]] { 255 } else { 0 }).expect("a frame's own size")
    }
}

/// Pixels either side of the mask's edge that the difference may relabel.
const EDGE_BAND: usize = 4;
/// Camera-compensated difference (grey levels, 3x3 mean) below which a
/// pixel near the edge is background, and above which it moves.
const BACKGROUND_DIFFERENCE: f32 = 6.0;
const MOVING_DIFFERENCE: f32 = 16.0;

/// |me(p) - other(camera(p))|, averaged over 3x3.
fn camera_difference(me: &Array2<f32>, other: &Array2<f32>, camera: &Transform) -> Array2<f32> {
    let (h, w) = me.dim();
    let diff = Array2::from_shape_fn((h, w), |(y, x)| match camera.apply(x as f64, y as f64) {
        Some((cx, cy)) => (me[[y, x]] - sample_bilinear(other, cx as f32, cy as f32)).abs(),
        None => 255.0,
    });
    Array2::from_shape_fn((h, w), |(y, x)| {
        let (mut sum, mut n) = (0.0, 0.0);
        for yy in y.saturating_sub(1)..(y + 2).min(h) {
            for xx in x.saturating_sub(1)..(x + 2).min(w) {
                sum += diff[[yy, xx]];
                n += 1.0;
            }
        }
        sum / n
    })
}

/// One direction's score: the residual against the camera's homography
/// over the tolerance (doubled where the flow fails its check).
fn direction_score(flow: &Flow, occluded: &Array2<bool>, p: &SegmentParams) -> (Array2<f32>, Transform) {
    let camera = estimate(&from_flow(flow, 8), &GlobalParams::new(Model::Homography))
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

/// 3x3 dilation (`grow`) or erosion, the border replicated.
fn morph(mask: &Array2<bool>, grow: bool) -> Array2<bool> {
    let (h, w) = mask.dim();
    Array2::from_shape_fn((h, w), |(y, x)| {
        let mut any = false;
        let mut all = true;
        for yy in y.saturating_sub(1)..(y + 2).min(h) {
            for xx in x.saturating_sub(1)..(x + 2).min(w) {
                any |= mask[[yy, xx]];
                all &= mask[[yy, xx]];
            }
        }
        if grow {
            any
        } else {
            all
        }
    })
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
