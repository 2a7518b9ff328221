//! Frame interpolation: a frame at any time `t` in (0, 1) between two
//! frames, from dense flow both ways (ffmpeg's `minterpolate` does this
//! with block vectors and OBMC; here the motion is per pixel).
//!
//! 1. DIS flow from frame 0 to 1 and from 1 to 0; the forward-backward
//!    check marks the pixels each frame has that the other does not show.
//! 2. Each frame's pixels are splatted to where they are at time `t`
//!    ([`splat`]), giving per pixel the flow to both frames and whether it
//!    is seen in each.
//! 3. Both frames are read along those flows (bicubic) and blended, each
//!    by its nearness in time and by whether the pixel is seen in it.
//!
//! Where too few pixels pass the forward-backward check (a scene cut, or
//! motion the flow cannot follow), the nearer frame is repeated instead.
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
use crate::flow::warp::sample_bicubic;
use crate::flow::{Flow, FlowEstimator, FlowOptions, Preset};
use crate::raster::plane_to_array;
use splat::{intermediate, Intermediate, Side};

/// How frames are interpolated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterpolateParams {
    /// DIS preset of both flows.
    pub preset: Preset,
    /// Below this share of pixels passing the forward-backward check, the
    /// pair is a cut and the nearer frame is repeated.
    pub cut_below: f64,
}

impl Default for InterpolateParams {
    /// DIS fast; a cut below 40 % consistent pixels.
    fn default() -> InterpolateParams {
        InterpolateParams {
            preset: Preset::Fast,
            cut_below: 0.4,
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
    /// Whether the pair is a cut (the nearer frame is repeated).
    pub cut: bool,
    /// Share of frame 0's pixels that pass the forward-backward check.
    pub consistent: f64,
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
        if !(0.0..=1.0).contains(&params.cut_below) {
            return Err(InterpolateError::Params(format!(
                "cut threshold {} must be between 0 and 1",
                params.cut_below
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
            cut: consistent < self.params.cut_below,
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
        };
        let mid = intermediate(&side(0), &side(1), t as f32);
        let half = halve(&mid);
        // Luma as the flows saw it (converted once, in `pair`).
        let y = blend(&motion.luma[0], &motion.luma[1], &mid, t as f32);
        let chroma = |p: &Plane, q: &Plane| blend(&plane_to_array(p), &plane_to_array(q), &half, t as f32);
        let (u, v) = (chroma(f0.u(), f1.u()), chroma(f0.v(), f1.v()));
        Frame::from_planes(y, u, v).expect("planes of one frame's sizes")
    }
}

/// One plane at time `t`: both frames read along the intermediate flows
/// (bicubic), weighted by nearness in time and by visibility; rows in
/// parallel.
fn blend(a: &Array2<f32>, b: &Array2<f32>, mid: &Intermediate, t: f32) -> Plane {
    let (h, w) = a.dim();
    let mut packed = vec![0u8; w * h];
    packed.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let (fx, fy) = (x as f32, y as f32);
            let at = [y, x];
            let s0 = sample_bicubic(a, fx + mid.to0.0[at], fy + mid.to0.1[at]);
            let s1 = sample_bicubic(b, fx + mid.to1.0[at], fy + mid.to1.1[at]);
            let (w0, w1) = ((1.0 - t) * mid.seen0[at], t * mid.seen1[at]);
            let value = if w0 + w1 > 1e-6 {
                (w0 * s0 + w1 * s1) / (w0 + w1)
            } else {
                (1.0 - t) * s0 + t * s1
            };
            *out = (value + 0.5).clamp(0.0, 255.0) as u8;
        }
    });
    Plane::from_packed(w, h, &packed).expect("a plane's own size")
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
