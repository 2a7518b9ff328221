//! Sparse tracking: Shi-Tomasi corners followed by a pyramidal Lucas-Kanade
//! point tracker with a forward-backward check.
//!
//! [`good_features`] keeps pixels whose structure tensor's smaller
//! eigenvalue (Shi and Tomasi 1994) is a local maximum, above `quality`
//! times the best one, at least `min_distance` apart, strongest first.
//! [`track`] follows each point from one picture to the next with
//! Lucas-Kanade on a square patch (Bouguet's pyramidal scheme, as OpenCV's
//! `calcOpticalFlowPyrLK`): sub-pixel positions through bilinear sampling,
//! coarse to fine, iterating until the step is below `epsilon` or
//! `iterations` steps are done. A point is lost when it leaves the picture
//! or its patch has no texture; with the forward-backward check, also when
//! tracking it back does not return within `fb_threshold` pixels of where it
//! started (occlusions and drift).

use ndarray::Array2;
use rayon::prelude::*;

use super::warp::sample_bilinear;
use crate::imgproc::pyramid::{gradients, pyramid};

/// A tracked point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Track {
    /// Position in the second picture (x).
    pub x: f32,
    /// Position in the second picture (y).
    pub y: f32,
    /// Whether the point was followed.
    pub found: bool,
    /// Mean absolute difference between the patches, grey levels.
    pub error: f32,
}

/// Settings of the point tracker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Patch half-size: the patch is `2 * radius + 1` square.
    pub radius: usize,
    /// Pyramid levels.
    pub levels: usize,
    /// Most Lucas-Kanade steps per level.
    pub iterations: usize,
    /// Steps stop below this length, pixels.
    pub epsilon: f32,
    /// Smallest eigenvalue of the patch tensor (mean squared gradient)
    /// below which a point is lost.
    pub min_eigen: f32,
    /// Forward-backward distance above which a point is dropped; `None`
    /// disables the check.
    pub fb_threshold: Option<f32>,
}

impl Default for TrackParams {
    fn default() -> TrackParams {
        TrackParams {
            radius: 7,
            levels: 3,
            iterations: 20,
            epsilon: 0.01,
            min_eigen: 1.0,
            fb_threshold: Some(0.5),
        }
    }
}

/// Shi-Tomasi corners of `img`: at most `max` points, strongest first.
///
/// ```
/// use mocomp::flow::track::good_features;
/// use ndarray::Array2;
/// // One bright square: its four corners are the best features.
/// let img = Array2::from_shape_fn((40, 40), |(y, x)| if (10..30).contains(&x) && (10..30).contains(&y) { 200.0 } else { 20.0 });
/// let pts = good_features(&img, 4, 0.1, 5.0);
/// assert_eq!(pts.len(), 4);
/// ```
pub fn good_features(img: &Array2<f32>, max: usize, quality: f32, min_distance: f32) -> Vec<(f32, f32)> {
    let (h, w) = img.dim();
    let lambda = crate::imgproc::corners::min_eigen(img);
    let best = lambda.iter().copied().fold(0f32, f32::max);
    if best <= 0.0 {
        return Vec::new();
    }
    let threshold = quality * best;
    // Local maxima (3x3) above the threshold, away from the border.
    let mut candidates: Vec<(f32, usize, usize)> = Vec::new();
    for y in 2..h.saturating_sub(2) {
        for x in 2..w.saturating_sub(2) {
            let l = lambda[[y, x]];
            if l < threshold {
                continue;
            }
            let is_max = (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| lambda[[yy, xx]] <= l));
            if is_max {
                candidates.push((l, x, y));
            }
        }
    }
    // Strongest first; ties in raster order, so the result is deterministic.
    candidates.sort_by(|p, q| q.0.total_cmp(&p.0).then((p.2, p.1).cmp(&(q.2, q.1))));
    let mut kept: Vec<(f32, f32)> = Vec::new();
    let d2 = min_distance * min_distance;
    for (_, x, y) in candidates {
        if kept.len() >= max {
            break;
        }
        let (fx, fy) = (x as f32, y as f32);
        if kept
            .iter()
            .all(|&(kx, ky)| (kx - fx).powi(2) + (ky - fy).powi(2) >= d2)
        {
            kept.push((fx, fy));
        }
    }
    kept
}

/// One direction of tracking: every point from `p1` (pyramid of the first
/// picture) to `p2`.
fn track_one_way(
    p1: &[Array2<f32>],
    g1: &[Gradients],
    p2: &[Array2<f32>],
    points: &[(f32, f32)],
    p: &TrackParams,
) -> Vec<Track> {
    // Points in parallel, each on its own: the same result for any number
    // of threads.
    points
        .par_iter()
        .map(|&point| track_point((p1, g1, p2), point, p))
        .collect()
}

/// One point followed from the coarsest level to the finest; lost where a
/// level's patch has too little texture or it leaves the picture.
fn track_point(
    (p1, g1, p2): (&[Array2<f32>], &[Gradients], &[Array2<f32>]),
    (x0, y0): (f32, f32),
    p: &TrackParams,
) -> Track {
    let r = p.radius as isize;
    let n = ((2 * r + 1) * (2 * r + 1)) as f32;
    let (mut dx, mut dy) = (0f32, 0f32); // motion at the current level
    let mut found = true;
    for level in (0..p1.len()).rev() {
        let scale = (1u32 << level) as f32;
        let centre = (x0 / scale, y0 / scale);
        let tensor = PatchTensor::of(&p1[level], &g1[level], centre, r);
        let (a, b, c) = (tensor.a, tensor.b, tensor.c);
        let min_eig = (0.5 * (a + c) - (0.25 * (a - c) * (a - c) + b * b).sqrt()) / n;
        if min_eig < p.min_eigen || tensor.det().abs() < f32::EPSILON {
            found = false;
            break;
        }
        (dx, dy) = tensor.iterate(&p2[level], centre, (dx, dy), p);
        if level > 0 {
            dx *= 2.0;
            dy *= 2.0;
        }
    }
    let (x, y) = (x0 + dx, y0 + dy);
    let (h, w) = p2[0].dim();
    if found && (x < 0.0 || y < 0.0 || x > (w - 1) as f32 || y > (h - 1) as f32) {
        found = false;
    }
    let error = match found {
        true => patch_error((&p1[0], &p2[0]), (x0, y0), (x, y), r) / n,
        false => 0.0,
    };
    Track { x, y, found, error }
}

/// A level's horizontal and vertical gradients.
type Gradients = (Array2<f32>, Array2<f32>);

/// A patch of the first picture at one level: its samples and gradients,
/// and the sums of its structure tensor (fixed through the iterations).
struct PatchTensor {
    samples: Vec<(f32, f32, f32)>,
    a: f32,
    b: f32,
    c: f32,
}

impl PatchTensor {
    /// The patch of radius `r` around (cx, cy) of `img1` with its
    /// gradients `(gx, gy)`.
    fn of(img1: &Array2<f32>, (gx, gy): &Gradients, (cx, cy): (f32, f32), r: isize) -> PatchTensor {
        let (mut a, mut b, mut c) = (0f32, 0f32, 0f32);
        let mut samples = Vec::with_capacity(((2 * r + 1) * (2 * r + 1)) as usize);
        for j in -r..=r {
            for i in -r..=r {
                let (px, py) = (cx + i as f32, cy + j as f32);
                let (ix, iy) = (sample_bilinear(gx, px, py), sample_bilinear(gy, px, py));
                samples.push((sample_bilinear(img1, px, py), ix, iy));
                a += ix * ix;
                b += ix * iy;
                c += iy * iy;
            }
        }
        PatchTensor { samples, a, b, c }
    }

    /// The tensor's determinant.
    fn det(&self) -> f32 {
        self.a * self.c - self.b * self.b
    }

    /// Lucas-Kanade's iterations on `img2` from the motion (dx, dy) until
    /// a step is under `p.epsilon` (at most `p.iterations`): the motion.
    fn iterate(
        &self,
        img2: &Array2<f32>,
        (cx, cy): (f32, f32),
        (mut dx, mut dy): (f32, f32),
        p: &TrackParams,
    ) -> (f32, f32) {
        let r = p.radius as isize;
        let (a, b, c) = (self.a, self.b, self.c);
        let det = self.det();
        for _ in 0..p.iterations {
            let (mut ex, mut ey) = (0f32, 0f32);
            let mut k = 0;
            for j in -r..=r {
                for i in -r..=r {
                    let (v1, ix, iy) = self.samples[k];
                    k += 1;
                    let diff = sample_bilinear(img2, cx + dx + i as f32, cy + dy + j as f32) - v1;
                    ex += ix * diff;
                    ey += iy * diff;
                }
            }
            let (sx, sy) = (-(c * ex - b * ey) / det, -(a * ey - b * ex) / det);
            dx += sx;
            dy += sy;
            if sx * sx + sy * sy < p.epsilon * p.epsilon {
                break;
            }
        }
        (dx, dy)
    }
}

/// The sum of absolute differences between the patches of radius `r` at
/// (x0, y0) of `i1` and at (x, y) of `i2`.
fn patch_error(
    (i1, i2): (&Array2<f32>, &Array2<f32>),
    (x0, y0): (f32, f32),
    (x, y): (f32, f32),
    r: isize,
) -> f32 {
    let mut error = 0f32;
    for j in -r..=r {
        for i in -r..=r {
            let (ox, oy) = (i as f32, j as f32);
            error += (sample_bilinear(i2, x + ox, y + oy) - sample_bilinear(i1, x0 + ox, y0 + oy)).abs();
        }
    }
    error
}

/// Follows `points` from `i1` to `i2`.
pub fn track(i1: &Array2<f32>, i2: &Array2<f32>, points: &[(f32, f32)], p: &TrackParams) -> Vec<Track> {
    assert_eq!(i1.dim(), i2.dim(), "track: pictures of different sizes");
    let min_size = 2 * p.radius + 1;
    let (p1, p2) = (pyramid(i1, p.levels, min_size), pyramid(i2, p.levels, min_size));
    let levels = p1.len().min(p2.len());
    let (p1, p2) = (&p1[..levels], &p2[..levels]);
    let g1: Vec<_> = p1.iter().map(gradients).collect();
    let mut forward = track_one_way(p1, &g1, p2, points, p);
    if let Some(limit) = p.fb_threshold {
        let g2: Vec<_> = p2.iter().map(gradients).collect();
        let ends: Vec<(f32, f32)> = forward.iter().map(|t| (t.x, t.y)).collect();
        let back = track_one_way(p2, &g2, p1, &ends, p);
        for ((t, b), &(x0, y0)) in forward.iter_mut().zip(&back).zip(points) {
            if t.found && (!b.found || (b.x - x0).hypot(b.y - y0) > limit) {
                t.found = false;
            }
        }
    }
    forward
}
