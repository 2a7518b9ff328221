//! Keypoints at several scales: Shi-Tomasi corners (the smaller eigenvalue
//! of the structure tensor) on each level of a Gaussian pyramid, one per
//! grid cell so that they spread over the picture, each with the
//! orientation of its intensity centroid (as ORB orients them).

use ndarray::Array2;

use crate::imgproc::corners::min_eigen;

/// A keypoint: position in full-size pixels, the pyramid level it was
/// found on, its orientation (radians) and corner strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keypoint {
    /// Column, full-size pixels.
    pub x: f32,
    /// Row, full-size pixels.
    pub y: f32,
    /// Pyramid level (scale `2^level`).
    pub level: usize,
    /// Orientation of the intensity centroid, radians.
    pub angle: f32,
    /// Smaller eigenvalue of the structure tensor (grey levels^2 / px^2).
    pub response: f32,
}

/// Distance from a level's border inside which no keypoint is kept: the
/// descriptor's rotated pattern must stay inside the picture.
pub(super) const BORDER: usize = 20;

/// Radius of the disc whose intensity centroid orients a keypoint.
const ORIENTATION_RADIUS: isize = 12;

/// The strongest local maximum (3x3) of `lambda` in each `cell x cell`
/// square, if above `threshold`, away from the border: (x, y, response).
fn cell_maxima(lambda: &Array2<f32>, cell: usize, threshold: f32) -> Vec<(usize, usize, f32)> {
    let (h, w) = lambda.dim();
    let mut out = Vec::new();
    if w <= 2 * BORDER || h <= 2 * BORDER {
        return out;
    }
    for cy in (BORDER..h - BORDER).step_by(cell) {
        for cx in (BORDER..w - BORDER).step_by(cell) {
            let mut best: Option<(usize, usize, f32)> = None;
            for y in cy..(cy + cell).min(h - BORDER) {
                for x in cx..(cx + cell).min(w - BORDER) {
                    let l = lambda[[y, x]];
                    if l < threshold || best.is_some_and(|b| b.2 >= l) {
                        continue;
                    }
                    let is_max = (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| lambda[[yy, xx]] <= l));
                    if is_max {
                        best = Some((x, y, l));
                    }
                }
            }
            out.extend(best);
        }
    }
    out
}

/// Orientation of the intensity centroid of the disc around (x, y).
fn orientation(img: &Array2<f32>, x: usize, y: usize) -> f32 {
    let r = ORIENTATION_RADIUS;
    let (mut m10, mut m01) = (0f32, 0f32);
    for dy in -r..=r {
        let half = ((r * r - dy * dy) as f32).sqrt() as isize;
        for dx in -half..=half {
            let v = img[[(y as isize + dy) as usize, (x as isize + dx) as usize]];
            m10 += dx as f32 * v;
            m01 += dy as f32 * v;
        }
    }
    m01.atan2(m10)
}

/// Keypoints of one pyramid level, strongest first, at most `max`.
pub(super) fn detect_level(img: &Array2<f32>, level: usize, max: usize, cell: usize) -> Vec<Keypoint> {
    let lambda = min_eigen(img);
    // Corners weaker than 1 % of the strongest, or than a floor that noise
    // alone reaches, are not kept.
    let strongest = lambda.iter().copied().fold(0f32, f32::max);
    let threshold = (0.01 * strongest).max(1.0);
    let mut found = cell_maxima(&lambda, cell, threshold);
    found.sort_by(|p, q| q.2.total_cmp(&p.2).then((p.1, p.0).cmp(&(q.1, q.0))));
    found.truncate(max);
    let scale = (1usize << level) as f32;
    found
        .into_iter()
        .map(|(x, y, response)| Keypoint {
            // Level pixel centres to full-size coordinates.
            x: (x as f32 + 0.5) * scale - 0.5,
            y: (y as f32 + 0.5) * scale - 0.5,
            level,
            angle: orientation(img, x, y),
            response,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centroid_points_to_the_bright_side() {
        let img = Array2::from_shape_fn((64, 64), |(_, x)| if x > 32 { 200.0 } else { 20.0 });
        assert!(orientation(&img, 32, 32).abs() < 0.05);
        let img = Array2::from_shape_fn((64, 64), |(y, _)| if y > 32 { 200.0 } else { 20.0 });
        assert!((orientation(&img, 32, 32) - std::f32::consts::FRAC_PI_2).abs() < 0.05);
    }

    #[test]
    fn a_square_gives_corners_at_its_corners() {
        let img = Array2::from_shape_fn((96, 96), |(y, x)| {
            if (30..66).contains(&x) && (30..66).contains(&y) {
                200.0
            } else {
                20.0
            }
        });
        let kps = detect_level(&img, 0, 100, 16);
        assert!(kps.len() >= 4, "{kps:?}");
        for k in &kps[..4] {
            let near = [(30.0, 30.0), (65.0, 30.0), (30.0, 65.0), (65.0, 65.0)]
                .iter()
                .any(|&(cx, cy): &(f32, f32)| (k.x - cx).hypot(k.y - cy) < 3.0);
            assert!(near, "{k:?}");
        }
    }
}
