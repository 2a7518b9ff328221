//! Global (camera) motion: one plane-to-plane model per picture pair
//! (translation, similarity, affine or homography) fitted robustly to
//! point correspondences, with the mask of those that follow it. The
//! correspondences come from dense flow, block vectors or feature matches
//! ([`sources`]); the fit is RANSAC, then iteratively reweighted least
//! squares over every correspondence (as OpenCV's `estimateAffine2D` /
//! `findHomography` with a refinement, and vid.stab's robust fit).
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
    /// refitted to its inliers only).
    pub refinements: usize,
    /// Seed of the sampling: the same input and seed, the same result.
    pub seed: u64,
}

impl GlobalParams {
    /// `model` with a threshold of 1 pixel, 1000 samples, 10 refinements.
    pub fn new(model: Model) -> GlobalParams {
        GlobalParams {
            model,
            threshold: 1.0,
            max_samples: 1000,
            refinements: 10,
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
