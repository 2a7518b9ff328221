//! Video stabilisation: the camera path from global motion, smoothed, and
//! each frame warped onto the smooth path with a crop that keeps the
//! border out of view (ffmpeg's vid.stab, OpenCV's videostab).
//!
//! Two passes, as vid.stab's detect and transform: [`MotionTrack`] finds
//! each frame's motion to the one before; [`plan`] turns the motions into
//! one warp per frame; [`apply`] warps a frame. [`quality`] measures any
//! stabiliser's output the way the literature does, and [`shake`] makes
//! test material with a known shake.
//!
//! ```
//! use mocomp::global::Transform;
//! use mocomp::stabilize::{plan, StabilizeParams};
//! // A still camera that jumps 4 pixels right every other frame.
//! let shift = |x: f64| Transform([1.0, 0.0, x, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
//! let motions: Vec<Option<Transform>> = (0..20).map(|t| Some(shift(if t % 2 == 0 { -4.0 } else { 4.0 }))).collect();
//! let plan = plan(&motions, 320, 240, &StabilizeParams::default()).unwrap();
//! assert_eq!(plan.warps.len(), 21);
//! assert!(plan.zoom[0] > 1.0 && plan.zoom[0] < 1.05);
//! ```

pub mod l1;
pub mod path;
pub mod quality;
pub mod shake;

use crate::codec::{Frame, Plane};
use crate::flow::Preset;
use crate::global::sources::{PairCorrespondences, Source};
use crate::global::{GlobalError, GlobalParams, Model, Transform};
use crate::imgproc::warp::{warp_frame, warp_frame_onto, Border};
use path::{adaptive_zoom, chain, gaussian, least_zoom, zoom_in, Centre, Pose};

/// How the camera path is smoothed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Smoothing {
    /// A Gaussian window of this many frames either side (vid.stab's
    /// `smoothing`, default 10).
    Gaussian(usize),
    /// The L1-optimal path (Grundmann et al. 2011): still where it can be,
    /// then constant velocity, then constant acceleration, inside the crop.
    L1,
}

/// How much the output is zoomed to keep the border out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Zoom {
    /// The least fixed zoom with no border in any frame (vid.stab's
    /// `optzoom=1`), at most `max_zoom`.
    Auto,
    /// A per-frame zoom that follows the least one smoothly (`optzoom=2`).
    Adaptive,
    /// This zoom (1: none; the border shows where the path needs it).
    Fixed(f64),
}

/// What the stabiliser does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilizeParams {
    /// Camera model: [`Model::Translation`] or [`Model::Similarity`].
    pub model: Model,
    /// Path smoothing.
    pub smoothing: Smoothing,
    /// Border handling.
    pub zoom: Zoom,
    /// The largest zoom [`Zoom::Auto`] and [`Zoom::Adaptive`] use.
    pub max_zoom: f64,
    /// The share of frames whose border [`Zoom::Auto`] hides; the others
    /// show a little of it, filled from the output frame before
    /// ([`FrameWarper`]). 1: no border anywhere. The default, 0.75, is
    /// about what vid.stab's `optzoom=1` hides once rotation is counted:
    /// it sizes its zoom from the shifts alone, 10 % trimmed at each end
    /// of each axis.
    pub coverage: f64,
    /// Where the motion comes from. [`Source::Auto`] (the default): block
    /// vectors, a pair where they fit no motion tried again with flow: on
    /// nine still-camera clips under a known shake
    /// (`docs/results/applications.md`) blocks left
    /// less jitter than flow on seven and took less time, but a fish
    /// tank's flat water left most of its pairs unfitted.
    pub source: Source,
    /// The flow preset with [`Source::Flow`] (and [`Source::Auto`]'s).
    pub preset: Preset,
    /// Inlier threshold of the global fit, pixels.
    pub threshold: f64,
}

impl Default for StabilizeParams {
    /// Similarity, Gaussian over 10 frames either side, the least fixed
    /// zoom up to 1.5, motion from 16x16 blocks (EPZS, quarter-pel),
    /// DIS ultrafast where they fit none.
    fn default() -> StabilizeParams {
        StabilizeParams {
            model: Model::Similarity,
            smoothing: Smoothing::Gaussian(10),
            zoom: Zoom::Auto,
            max_zoom: 1.5,
            coverage: 0.75,
            source: Source::Auto,
            preset: Preset::Ultrafast,
            threshold: 1.0,
        }
    }
}

/// Why stabilisation failed.
#[derive(Debug, thiserror::Error)]
pub enum StabilizeError {
    /// A setting out of range.
    #[error("{0}")]
    Params(String),
    /// The motion could not be estimated.
    #[error(transparent)]
    Motion(#[from] GlobalError),
}

/// Each frame's warp and how it came about.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Output pixel to input pixel, one per frame.
    pub warps: Vec<Transform>,
    /// The zoom of each frame's output.
    pub zoom: Vec<f64>,
    /// The camera's pose in each frame, against the first (centred).
    pub camera: Vec<Pose>,
    /// The smoothed pose the output follows.
    pub smoothed: Vec<Pose>,
}

/// Frame-to-frame camera motion of a sequence fed one frame at a time.
pub struct MotionTrack {
    source: PairCorrespondences,
    params: GlobalParams,
    previous: Option<Plane>,
    motions: Vec<Option<Transform>>,
}

impl MotionTrack {
    /// A tracker for `params`' model and source.
    pub fn new(params: &StabilizeParams) -> Result<MotionTrack, StabilizeError> {
        check(params)?;
        Ok(MotionTrack {
            source: PairCorrespondences::new(params.source, params.preset),
            params: GlobalParams {
                threshold: params.threshold,
                ..GlobalParams::new(params.model)
            },
            previous: None,
            motions: Vec::new(),
        })
    }

    /// Adds the next frame's luma; from the second on, its motion to the
    /// one before (`None` where no model fits: a cut, a blank frame).
    /// The picture is halved until it is at most
    /// [`MotionTrack::MOTION_WIDTH`] wide (the camera's motion needs no
    /// finer flow), the model scaled back.
    pub fn push(&mut self, luma: &Plane) -> Result<(), StabilizeError> {
        let mut small = luma.clone();
        let mut scale = 1.0;
        while small.width() > Self::MOTION_WIDTH && small.height() >= 64 {
            small = halved(&small);
            scale *= 2.0;
        }
        if let Some(prev) = &self.previous {
            // A fit that too few points follow is a cut (or a picture
            // without texture), where the path goes straight on.
            let pair = self.source.fit(&small, prev, &self.params)?;
            let motion = pair.camera().map(|f| to_full_size(&f.transform, scale));
            self.motions.push(motion);
        }
        self.previous = Some(small);
        Ok(())
    }

    /// The widest picture the motion is found on.
    pub const MOTION_WIDTH: usize = 320;
    /// `M_t` for t = 1.. (frame t to frame t - 1, pixel coordinates),
    /// `None` where frame t starts a new shot.
    pub fn motions(&self) -> &[Option<Transform>] {
        &self.motions
    }
}

/// `plane` at half size, each pixel the rounded mean of a 2x2 block
/// (an odd last row or column dropped).
fn halved(plane: &Plane) -> Plane {
    let (w, h) = (plane.width() / 2, plane.height() / 2);
    Plane::from_fn(w, h, |x, y| {
        let (a, b) = (plane.row(2 * y), plane.row(2 * y + 1));
        let sum =
            u16::from(a[2 * x]) + u16::from(a[2 * x + 1]) + u16::from(b[2 * x]) + u16::from(b[2 * x + 1]);
        ((sum + 2) / 4) as u8
    })
    .expect("half of a valid size")
}

/// A motion found on pictures scaled down by `scale` (a power of two, by
/// [`halved`]), in full-size pixels: small pixel `x` covers full-size
/// pixels `scale x` to `scale x + scale - 1`, centred at
/// `scale x + (scale - 1) / 2`.
fn to_full_size(m: &Transform, scale: f64) -> Transform {
    let o = (scale - 1.0) / 2.0;
    let to_full = Transform([scale, 0.0, o, 0.0, scale, o, 0.0, 0.0, 1.0]);
    let to_small = Transform([
        1.0 / scale,
        0.0,
        -o / scale,
        0.0,
        1.0 / scale,
        -o / scale,
        0.0,
        0.0,
        1.0,
    ]);
    to_full.then_after(&m.then_after(&to_small))
}

fn check(p: &StabilizeParams) -> Result<(), StabilizeError> {
    if !matches!(p.model, Model::Translation | Model::Similarity) {
        return Err(StabilizeError::Params(format!(
            "the stabiliser's camera model is translation or similarity, not {}",
            p.model
        )));
    }
    let zoom_ok = match p.zoom {
        Zoom::Fixed(z) => z.is_finite() && (1.0..=4.0).contains(&z),
        _ => true,
    };
    if !(zoom_ok && p.max_zoom.is_finite() && (1.0..=4.0).contains(&p.max_zoom)) {
        return Err(StabilizeError::Params("zoom must be between 1 and 4".into()));
    }
    if !(p.coverage > 0.0 && p.coverage <= 1.0) {
        return Err(StabilizeError::Params(format!(
            "coverage {} must be in (0, 1]",
            p.coverage
        )));
    }
    if let Smoothing::Gaussian(r) = p.smoothing {
        if r == 0 || r > 1000 {
            return Err(StabilizeError::Params(format!(
                "smoothing {r} must be 1 to 1000 frames"
            )));
        }
    }
    Ok(())
}

/// The warps that put a `width` x `height` sequence with frame-to-frame
/// motions `motions` (`M_t`, frame t to t - 1, pixels; `None` at a cut)
/// on a smooth path. Each stretch between cuts is smoothed on its own.
pub fn plan(
    motions: &[Option<Transform>],
    width: usize,
    height: usize,
    params: &StabilizeParams,
) -> Result<Plan, StabilizeError> {
    check(params)?;
    let centre = Centre::new(width, height);
    let (mut corrections, mut camera, mut smoothed) = (Vec::new(), Vec::new(), Vec::new());
    for stretch in motions.split(Option::is_none) {
        let centred: Vec<Transform> = stretch.iter().flatten().map(|m| centre.centred(m)).collect();
        let cameras = chain(&centred);
        camera.extend(cameras.iter().map(Pose::of));
        let (c, s) = match params.smoothing {
            Smoothing::Gaussian(radius) => gaussian_corrections(&cameras, radius),
            Smoothing::L1 => l1_corrections(&centred, &cameras, &centre, params),
        };
        corrections.extend(c);
        smoothed.extend(s);
    }
    let least: Vec<f64> = corrections
        .iter()
        .map(|b: &Transform| least_zoom(b, &centre, params.max_zoom))
        .collect();
    let zoom = match params.zoom {
        Zoom::Auto => vec![quantile(&least, params.coverage); least.len()],
        Zoom::Adaptive => adaptive_zoom(&least, 15),
        Zoom::Fixed(z) => vec![z; least.len()],
    };
    let warps = corrections
        .iter()
        .zip(&zoom)
        .map(|(b, &z)| centre.to_pixels(&b.then_after(&zoom_in(z))))
        .collect();
    Ok(Plan {
        warps,
        zoom,
        camera,
        smoothed,
    })
}

/// The L1 path's crop transforms (crop window to input, centred) for a
/// window of `1 / zoom` of the frame: the fixed zoom asked for, else the
/// least with which the Gaussian path (10 frames) shows no border. The Gaussian path
/// where the LP finds none.
fn l1_corrections(
    centred: &[Transform],
    cameras: &[Transform],
    centre: &Centre,
    params: &StabilizeParams,
) -> (Vec<Transform>, Vec<Pose>) {
    let gaussian_path = gaussian_corrections(cameras, 10);
    let zoom = match params.zoom {
        Zoom::Fixed(z) => z,
        _ => {
            let least: Vec<f64> = gaussian_path
                .0
                .iter()
                .map(|b| least_zoom(b, centre, params.max_zoom))
                .collect();
            // The LP keeps its window inside every frame: a window sized
            // for a share of them only would make the path follow the shake
            // in the others.
            quantile(&least, 1.0)
        }
    };
    let rotate = params.model == Model::Similarity;
    let Some(crops) = l1::solve(centred, centre, 1.0 / zoom, rotate) else {
        return gaussian_path;
    };
    let smoothed = cameras
        .iter()
        .zip(&crops)
        .map(|(c, b)| Pose::of(&c.then_after(b)))
        .collect();
    (crops, smoothed)
}

/// `C_t^-1 P_t` for the Gaussian-smoothed path `P`, and `P`.
fn gaussian_corrections(cameras: &[Transform], radius: usize) -> (Vec<Transform>, Vec<Pose>) {
    let camera: Vec<Pose> = cameras.iter().map(Pose::of).collect();
    let smoothed = gaussian(&camera, radius);
    let corrections = cameras
        .iter()
        .zip(&smoothed)
        .map(|(c, p)| {
            c.inverse()
                .unwrap_or(Transform::IDENTITY)
                .then_after(&p.transform())
        })
        .collect();
    (corrections, smoothed)
}

/// The value that a share `q` of `values` do not exceed (1 if empty).
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let k = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len().max(1)) - 1;
    v.get(k).copied().unwrap_or(1.0).max(1.0)
}

/// Warps frames one after the other; where a frame's warp leaves its
/// input, the output frame before shows through (vid.stab's `crop=keep`),
/// and in the first frame the input's edge is replicated.
#[derive(Default)]
pub struct FrameWarper {
    previous: Option<Frame>,
}

impl FrameWarper {
    /// The next output frame: `frame` through `warp` (output pixel to
    /// input pixel).
    pub fn warp(&mut self, frame: &Frame, warp: &Transform) -> &Frame {
        match &mut self.previous {
            Some(out) if (out.width(), out.height()) == (frame.width(), frame.height()) => {
                warp_frame_onto(frame, out, &warp.0, Border::Keep);
            }
            _ => self.previous = Some(apply(frame, warp)),
        }
        self.previous.as_ref().expect("set above")
    }
}

/// `frame` warped by `warp` (output pixel to input pixel); the border,
/// where it shows, replicates the edge.
pub fn apply(frame: &Frame, warp: &Transform) -> Frame {
    warp_frame(frame, frame.width(), frame.height(), &warp.0, Border::Replicate)
}
