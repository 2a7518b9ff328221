//! Sparse feature matching for large displacements: keypoints at several
//! scales, binary descriptors, mutual nearest-neighbour matching with a
//! ratio test and a neighbourhood-consensus filter, and the matches spread
//! into a dense initial flow that dense inverse search starts from (as
//! LDOF, DeepFlow and EpicFlow start their dense methods from matches).
//!
//! ```
//! use mocomp::features::{match_pictures, MatchParams};
//! use ndarray::Array2;
//! let f = |x: f32, y: f32| 128.0 + 50.0 * (x / 4.0).sin() * (y / 6.0).cos() + 40.0 * ((x * y) / 300.0).sin();
//! let i1 = Array2::from_shape_fn((160, 200), |(y, x)| f(x as f32, y as f32));
//! let i2 = Array2::from_shape_fn((160, 200), |(y, x)| f(x as f32 - 30.0, y as f32 - 12.0));
//! let matches = match_pictures(&i1, &i2, &MatchParams::default());
//! assert!(matches.len() > 10);
//! let right = matches.iter().filter(|m| (m.x2 - m.x1 - 30.0).abs() < 1.5 && (m.y2 - m.y1 - 12.0).abs() < 1.5);
//! assert!(right.count() * 10 >= matches.len() * 9);
//! ```

mod describe;
mod detect;
pub mod dsp;
mod matching;

use ndarray::Array2;
use rayon::prelude::*;

pub use describe::{hamming, Descriptor};
pub use detect::Keypoint;

use crate::imgproc::pyramid::{blur, pyramid};

/// Settings of detection and matching.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchParams {
    /// Keypoints per picture, at most (shared over the levels by area).
    pub max_features: usize,
    /// Pyramid levels searched for keypoints (scale factor 2 each).
    pub levels: usize,
    /// At most one keypoint per `cell x cell` square of each level.
    pub cell: usize,
    /// Lowe's ratio: the nearest descriptor must be closer than this times
    /// the second nearest.
    pub ratio: f32,
    /// Hamming distance above which no match is taken (of 256 bits).
    pub max_distance: u32,
    /// Matches consulted around each match by the consensus filter.
    pub neighbours: usize,
    /// How many of them must move alike for the match to be kept.
    pub min_support: usize,
}

impl Default for MatchParams {
    fn default() -> MatchParams {
        MatchParams {
            max_features: 2000,
            levels: 3,
            cell: 12,
            ratio: 0.85,
            max_distance: 80,
            neighbours: 8,
            min_support: 3,
        }
    }
}

/// A match: a point of the first picture and where it is in the second
/// (full-size pixels), with the descriptors' Hamming distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Column in the first picture.
    pub x1: f32,
    /// Row in the first picture.
    pub y1: f32,
    /// Column in the second picture.
    pub x2: f32,
    /// Row in the second picture.
    pub y2: f32,
    /// Hamming distance of the descriptors (0..=256).
    pub distance: u32,
}

/// Keypoints of a picture (grey levels 0..255) and their descriptors.
pub fn detect_and_describe(img: &Array2<f32>, p: &MatchParams) -> (Vec<Keypoint>, Vec<Descriptor>) {
    let levels = pyramid(img, p.levels.max(1), 2 * detect::BORDER + 2);
    let per_level: Vec<(Vec<Keypoint>, Vec<Descriptor>)> = levels
        .par_iter()
        .enumerate()
        .map(|(level, lv)| {
            // Each level gets a share of the budget by area (3/4, 3/16, ...).
            let share = (3 * p.max_features).div_ceil(4 << (2 * level)).max(16);
            let kps = detect::detect_level(lv, level, share, p.cell.max(2));
            // BRIEF compares single pixels: smooth first (ORB's sigma 2).
            let smoothed = blur(lv, 2.0);
            let descs = kps.iter().map(|k| describe::describe(&smoothed, k)).collect();
            (kps, descs)
        })
        .collect();
    let (mut kps, mut descs) = (Vec::new(), Vec::new());
    for (k, d) in per_level {
        kps.extend(k);
        descs.extend(d);
    }
    (kps, descs)
}

/// Matches from `i1` to `i2` (same size or not, grey levels 0..255).
pub fn match_pictures(i1: &Array2<f32>, i2: &Array2<f32>, p: &MatchParams) -> Vec<Match> {
    let ((k1, d1), (k2, d2)) = rayon::join(|| detect_and_describe(i1, p), || detect_and_describe(i2, p));
    matching::consensus(matching::mutual_matches(&k1, &d1, &k2, &d2, p), p)
}
