//! The camera path: frame-to-frame motions chained into each frame's pose
//! against the first, its Gaussian smoothing (vid.stab's), and the zoom
//! that keeps the picture's border out of view.
//!
//! Every transform here is in centred coordinates (the origin at the
//! picture's centre), so that rotation and zoom turn about the centre.

use crate::global::Transform;

/// A similarity's parameters: shift (pixels), rotation (radians),
/// natural log of the scale. Smoothing works on these, as vid.stab's.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Pose {
    /// Horizontal shift.
    pub x: f64,
    /// Vertical shift.
    pub y: f64,
    /// Rotation, radians (counter-clockwise in a y-down picture's maths).
    pub angle: f64,
    /// ln(scale).
    pub log_scale: f64,
}

impl Pose {
    /// The similarity nearest to `t`'s linear part: its rotation from the
    /// antisymmetric part, its scale from the determinant.
    pub fn of(t: &Transform) -> Pose {
        let m = &t.0;
        let det = (m[0] * m[4] - m[1] * m[3]).abs().max(1e-12);
        Pose {
            x: m[2],
            y: m[5],
            angle: (m[3] - m[1]).atan2(m[0] + m[4]),
            log_scale: 0.5 * det.ln(),
        }
    }

    /// The similarity.
    pub fn transform(&self) -> Transform {
        let s = self.log_scale.exp();
        let (sin, cos) = self.angle.sin_cos();
        Transform([s * cos, -s * sin, self.x, s * sin, s * cos, self.y, 0.0, 0.0, 1.0])
    }

    fn components(&self) -> [f64; 4] {
        [self.x, self.y, self.angle, self.log_scale]
    }

    fn from_components(c: [f64; 4]) -> Pose {
        Pose {
            x: c[0],
            y: c[1],
            angle: c[2],
            log_scale: c[3],
        }
    }
}

/// Pixel coordinates to centred ones and back, for a `width` x `height`
/// picture.
#[derive(Debug, Clone, Copy)]
pub struct Centre {
    cx: f64,
    cy: f64,
}

impl Centre {
    /// The centre of a `width` x `height` picture.
    pub fn new(width: usize, height: usize) -> Centre {
        Centre {
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
        }
    }

    /// Half the picture's extent from its centre to its corner pixels.
    pub fn half(&self) -> (f64, f64) {
        (self.cx, self.cy)
    }

    /// `t` (pixel coordinates) in centred coordinates.
    pub fn centred(&self, t: &Transform) -> Transform {
        self.shift(-1.0).then_after(&t.then_after(&self.shift(1.0)))
    }

    /// `t` (centred coordinates) in pixel coordinates.
    pub fn to_pixels(&self, t: &Transform) -> Transform {
        self.shift(1.0).then_after(&t.then_after(&self.shift(-1.0)))
    }

    fn shift(&self, sign: f64) -> Transform {
        Transform([1.0, 0.0, sign * self.cx, 0.0, 1.0, sign * self.cy, 0.0, 0.0, 1.0])
    }
}

/// Each frame's camera transform, mapping its coordinates to the first
/// frame's: `C_0 = I`, `C_t = C_(t-1) M_t`, where `motions[t - 1]` is
/// `M_t` (frame `t` to frame `t - 1`).
pub fn chain(motions: &[Transform]) -> Vec<Transform> {
    let mut path = Vec::with_capacity(motions.len() + 1);
    path.push(Transform::IDENTITY);
    for m in motions {
        let last = *path.last().expect("starts with one");
        path.push(last.then_after(m));
    }
    path
}

/// Each component of `poses` averaged over a Gaussian window of
/// `radius` frames either side (sigma = radius / 2, as vid.stab's
/// `smoothing`); the window is cut at the ends and renormalised.
pub fn gaussian(poses: &[Pose], radius: usize) -> Vec<Pose> {
    let sigma = (radius as f64 / 2.0).max(1e-9);
    let weights: Vec<f64> = (0..=radius)
        .map(|i| (-(i as f64).powi(2) / (2.0 * sigma * sigma)).exp())
        .collect();
    let n = poses.len();
    (0..n)
        .map(|t| {
            let (lo, hi) = (t.saturating_sub(radius), (t + radius).min(n.saturating_sub(1)));
            let mut sum = [0.0; 4];
            let mut total = 0.0;
            for (k, p) in poses.iter().enumerate().take(hi + 1).skip(lo) {
                let w = weights[k.abs_diff(t)];
                total += w;
                for (s, c) in sum.iter_mut().zip(p.components()) {
                    *s += w * c;
                }
            }
            Pose::from_components(sum.map(|s| s / total))
        })
        .collect()
}

/// Whether `warp` (output to input, centred) keeps every corner of the
/// output inside the input.
pub fn covers(warp: &Transform, centre: &Centre) -> bool {
    let (hw, hh) = centre.half();
    let slack = 1e-6;
    [(-hw, -hh), (hw, -hh), (-hw, hh), (hw, hh)]
        .into_iter()
        .all(|(x, y)| match warp.apply(x, y) {
            Some((u, v)) => u.abs() <= hw + slack && v.abs() <= hh + slack,
            None => false,
        })
}

/// Scaling about the centre: output coordinates shrunk by `zoom`.
pub fn zoom_in(zoom: f64) -> Transform {
    let s = 1.0 / zoom;
    Transform([s, 0.0, 0.0, 0.0, s, 0.0, 0.0, 0.0, 1.0])
}

/// The least zoom in `[1, max_zoom]` (to 1/1000) with which `warp`
/// covers the output; `max_zoom` where none does.
pub fn least_zoom(warp: &Transform, centre: &Centre, max_zoom: f64) -> f64 {
    let fits = |z: f64| covers(&warp.then_after(&zoom_in(z)), centre);
    if fits(1.0) {
        return 1.0;
    }
    if !fits(max_zoom) {
        return max_zoom;
    }
    let (mut lo, mut hi) = (1.0, max_zoom);
    while hi - lo > 1e-3 {
        let mid = 0.5 * (lo + hi);
        if fits(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// A per-frame zoom that follows `least` smoothly and never falls below
/// it: the largest value within `radius` frames, then Gaussian-smoothed,
/// then raised to `least` again (vid.stab's `optzoom=2`).
pub fn adaptive_zoom(least: &[f64], radius: usize) -> Vec<f64> {
    let n = least.len();
    let peak: Vec<Pose> = (0..n)
        .map(|t| {
            let window = &least[t.saturating_sub(radius)..(t + radius + 1).min(n)];
            Pose {
                x: window.iter().copied().fold(1.0, f64::max),
                ..Pose::default()
            }
        })
        .collect();
    gaussian(&peak, radius)
        .iter()
        .zip(least)
        .map(|(p, &l)| p.x.max(l))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_round_trips_a_similarity() {
        let p = Pose {
            x: 3.5,
            y: -2.0,
            angle: 0.03,
            log_scale: 0.05,
        };
        let q = Pose::of(&p.transform());
        for (a, b) in p.components().iter().zip(q.components()) {
            assert!((a - b).abs() < 1e-12, "{p:?} {q:?}");
        }
    }

    #[test]
    fn gaussian_keeps_a_line_inside_and_flattens_a_zigzag() {
        let line: Vec<Pose> = (0..40)
            .map(|t| Pose {
                x: 2.0 * t as f64,
                ..Pose::default()
            })
            .collect();
        let smooth = gaussian(&line, 6);
        for t in 6..34 {
            assert!((smooth[t].x - line[t].x).abs() < 1e-9);
        }
        let zigzag: Vec<Pose> = (0..40)
            .map(|t| Pose {
                y: if t % 2 == 0 { 5.0 } else { -5.0 },
                ..Pose::default()
            })
            .collect();
        let smooth = gaussian(&zigzag, 6);
        assert!(smooth[6..34].iter().all(|p| p.y.abs() < 0.1));
    }

    #[test]
    fn least_zoom_hides_a_shift() {
        // A 10-pixel shift of a 101-pixel-wide picture needs 50 / 40.
        let centre = Centre::new(101, 81);
        let shift = Transform([1.0, 0.0, 10.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let z = least_zoom(&shift, &centre, 2.0);
        assert!((z - 1.25).abs() < 2e-3, "{z}");
        assert_eq!(least_zoom(&Transform::IDENTITY, &centre, 2.0), 1.0);
    }

    #[test]
    fn centred_and_back_is_the_same_transform() {
        let c = Centre::new(64, 48);
        let t = Pose {
            x: 1.0,
            y: 2.0,
            angle: 0.1,
            log_scale: 0.0,
        }
        .transform();
        let back = c.to_pixels(&c.centred(&t));
        assert!(back.0.iter().zip(t.0).all(|(a, b)| (a - b).abs() < 1e-9));
    }
}
