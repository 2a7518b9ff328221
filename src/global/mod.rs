//! Global (camera) motion: one plane-to-plane model per picture pair
//! (translation, similarity, affine or homography) fitted robustly to
//! point correspondences, with the mask of those that follow it. The
//! correspondences come from dense flow, block vectors or feature matches
//! ([`sources`]); the fit is RANSAC, then iteratively reweighted least
//! squares at the inliers' scale (as OpenCV's `estimateAffine2D` /
//! `findHomography` with a refinement, and vid.stab's robust fit;
//! [`Refinement`]).
//!
//! ```
//! use mocomp::global::{estimate, Correspondence, GlobalParams, Model};
//! // A shift of (3, -2) seen at 20 points, one of them wrong.
//! let mut points: Vec<Correspondence> = (0..20)
//!     .map(|i| (f64::from(i % 5) * 30.0, f64::from(i / 5) * 25.0))
//!     .map(|(x, y)| Correspondence::new((x, y), (x + 3.0, y - 2.0)))
//!     .collect();
//! points[7].to.0 += 40.0;
//! let fit = estimate(&points, &GlobalParams::new(Model::Affine)).unwrap();
//! let (x, y) = fit.transform.apply(10.0, 10.0).unwrap();
//! assert!((x - 13.0).abs() < 1e-6 && (y - 8.0).abs() < 1e-6);
//! assert!(!fit.inliers[7] && fit.inliers.iter().filter(|&&i| i).count() == 19);
//! ```

mod model;
mod ransac;
pub mod sources;

pub use model::{fit, Correspondence, Model, Transform};
pub use ransac::estimate;

use serde::Serialize;

/// How to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalParams {
    /// The camera model.
    pub model: Model,
    /// A correspondence within this many pixels of the model follows it.
    pub threshold: f64,
    /// Most RANSAC samples (fewer where the inliers' share lets it stop
    /// with 99.9 % confidence).
    pub max_samples: usize,
    /// Reweighted least-squares rounds after RANSAC (0: the RANSAC model
    /// refitted to its inliers only, as [`Refinement`] refits).
    pub refinements: usize,
    /// The reweighting's scale.
    pub refinement: Refinement,
    /// Seed of the sampling: the same input and seed, the same result.
    pub seed: u64,
}

/// The scale of the reweighted least squares that refines RANSAC's model
/// (Cauchy weights).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refinement {
    /// The inliers' own (1.4826 times their median distance), after the
    /// model is refitted to its inliers until they settle (LO-RANSAC's
    /// local step); nothing beyond the threshold weighs. The default: at
    /// the threshold's scale, a second motion a pixel or two from the
    /// camera's (a face filling half of a still shot) pulled the fit
    /// towards it (face_360p shaken by a known similarity, block vectors:
    /// corners 1.1 px off against 0.18).
    InlierScale,
    /// The threshold's, out to three thresholds, after one refit to the
    /// inliers: a broader fit, which [`crate::segment`]'s tolerances were
    /// tuned with (its IoU on real footage fell by up to 0.06 at the
    /// inliers' scale).
    ThresholdScale,
}

impl GlobalParams {
    /// `model` with a threshold of 1 pixel, 1000 samples, 10 refinements
    /// at the inliers' scale.
    pub fn new(model: Model) -> GlobalParams {
        GlobalParams {
            model,
            threshold: 1.0,
            max_samples: 1000,
            refinements: 10,
            refinement: Refinement::InlierScale,
            seed: 0x9e37_79b9_7f4a_7c15,
        }
    }
}

/// A fitted camera model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GlobalMotion {
    /// The model fitted.
    pub model: Model,
    /// First picture to second.
    pub transform: Transform,
    /// Which correspondences follow it (within the threshold).
    #[serde(skip)]
    pub inliers: Vec<bool>,
    /// How many do.
    pub inlier_count: usize,
    /// Root mean square distance of the inliers to the model, pixels.
    pub rms: f64,
}

/// Why no model could be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GlobalError {
    /// Fewer correspondences than the model needs.
    #[error("{have} correspondences, the {model} model needs at least {need}")]
    TooFewPoints {
        /// The model.
        model: Model,
        /// Its sample size.
        need: usize,
        /// What there was.
        have: usize,
    },
    /// Every sample was degenerate (points on a line, or all in one place).
    #[error("the correspondences do not determine a {0} model (all in one place or on a line)")]
    Degenerate(Model),
    /// A setting out of range.
    #[error("{0}")]
    Params(String),
    /// The motion the correspondences come from could not be estimated.
    #[error("motion estimation: {0}")]
    Motion(String),
}
