//! Camera models and their weighted least-squares fits to point
//! correspondences.

use serde::Serialize;

/// A plane-to-plane camera model, by its degrees of freedom.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// A shift: 2 parameters.
    Translation,
    /// Rotation, uniform scale and shift: 4.
    Similarity,
    /// Any linear map and shift: 6.
    Affine,
    /// A projective map (a plane seen by a moving camera): 8.
    Homography,
}

impl Model {
    /// Every model, fewest parameters first.
    pub const ALL: [Model; 4] = [
        Model::Translation,
        Model::Similarity,
        Model::Affine,
        Model::Homography,
    ];

    /// `translation`, `similarity`, `affine` or `homography`.
    pub fn name(self) -> &'static str {
        match self {
            Model::Translation => "translation",
            Model::Similarity => "similarity",
            Model::Affine => "affine",
            Model::Homography => "homography",
        }
    }

    /// Correspondences that determine the model: RANSAC's sample size.
    pub fn min_points(self) -> usize {
        match self {
            Model::Translation => 1,
            Model::Similarity => 2,
            Model::Affine => 3,
            Model::Homography => 4,
        }
    }
}

impl std::str::FromStr for Model {
    type Err = String;
    fn from_str(s: &str) -> Result<Model, String> {
        Model::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown model '{s}' (translation, similarity, affine, homography)"))
    }
}

impl std::fmt::Display for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A 3x3 matrix, row by row, mapping a point `(x, y)` of the first picture
/// to `(x', y')` of the second in homogeneous coordinates (pixel centres at
/// integers, as the flow's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Transform(pub [f64; 9]);

impl Transform {
    /// The identity.
    pub const IDENTITY: Transform = Transform([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);

    /// Where `(x, y)` goes; `None` at the homography's horizon.
    pub fn apply(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let m = &self.0;
        let w = m[6] * x + m[7] * y + m[8];
        if w.abs() < 1e-12 {
            return None;
        }
        Some(((m[0] * x + m[1] * y + m[2]) / w, (m[3] * x + m[4] * y + m[5]) / w))
    }

    /// The matrix product `self * other` (first `other`, then `self`).
    pub fn then_after(&self, other: &Transform) -> Transform {
        let (a, b) = (&self.0, &other.0);
        let mut m = [0.0; 9];
        for r in 0..3 {
            for c in 0..3 {
                m[r * 3 + c] = (0..3).map(|k| a[r * 3 + k] * b[k * 3 + c]).sum();
            }
        }
        Transform(m)
    }

    /// The inverse, if the matrix is regular.
    pub fn inverse(&self) -> Option<Transform> {
        let m = &self.0;
        let cof = [
            m[4] * m[8] - m[5] * m[7],
            m[2] * m[7] - m[1] * m[8],
            m[1] * m[5] - m[2] * m[4],
            m[5] * m[6] - m[3] * m[8],
            m[0] * m[8] - m[2] * m[6],
            m[2] * m[3] - m[0] * m[5],
            m[3] * m[7] - m[4] * m[6],
            m[1] * m[6] - m[0] * m[7],
            m[0] * m[4] - m[1] * m[3],
        ];
        let det = m[0] * cof[0] + m[1] * cof[3] + m[2] * cof[6];
        if det.abs() < 1e-300 || !det.is_finite() {
            return None;
        }
        Some(Transform(cof.map(|c| c / det)))
    }

    /// The matrix scaled so that its last entry is 1 (where it is not 0).
    fn normalised(self) -> Transform {
        let s = self.0[8];
        if s.abs() < 1e-300 {
            return self;
        }
        Transform(self.0.map(|v| v / s))
    }
}

/// A point of the first picture and where it is in the second, with the
/// weight the fit gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    /// Position in the first picture.
    pub from: (f64, f64),
    /// Position in the second.
    pub to: (f64, f64),
    /// Relative weight (1 for equal ones).
    pub weight: f64,
}

impl Correspondence {
    /// `from -> to`, weight 1.
    pub fn new(from: (f64, f64), to: (f64, f64)) -> Correspondence {
        Correspondence {
            from,
            to,
            weight: 1.0,
        }
    }

    /// Distance in pixels between where `t` takes `from` and `to`.
    pub fn residual(&self, t: &Transform) -> f64 {
        self.residual_squared(t).sqrt()
    }

    /// [`Correspondence::residual`] squared (what the fits compare, without
    /// a square root per point).
    pub fn residual_squared(&self, t: &Transform) -> f64 {
        match t.apply(self.from.0, self.from.1) {
            Some((x, y)) => (x - self.to.0).powi(2) + (y - self.to.1).powi(2),
            None => f64::INFINITY,
        }
    }
}

/// The weighted least-squares transform of `model` through `points` (each
/// with `weights[i]`), or `None` where they do not determine it.
pub fn fit(model: Model, points: &[Correspondence], weights: &[f64]) -> Option<Transform> {
    let total: f64 = weights.iter().sum();
    if points.len() < model.min_points() || total.is_nan() || total <= 0.0 {
        return None;
    }
    if model == Model::Translation {
        return Some(translation(points, weights, total));
    }
    // Centred and scaled coordinates (Hartley's normalisation): the normal
    // equations stay well conditioned at any picture size. (Each picture
    // its own scale: similarities, affine maps and homographies stay what
    // they are under it; a translation would not, and needs none.)
    let (n1, n2) = (
        Normaliser::of(points, weights, |c| c.from),
        Normaliser::of(points, weights, |c| c.to),
    );
    let scaled: Vec<Correspondence> = points
        .iter()
        .map(|c| Correspondence {
            from: n1.apply(c.from),
            to: n2.apply(c.to),
            weight: c.weight,
        })
        .collect();
    let t = match model {
        Model::Translation => unreachable!("fitted above"),
        Model::Similarity => linear::<4>(&scaled, weights, similarity_rows)?,
        Model::Affine => linear::<6>(&scaled, weights, affine_rows)?,
        Model::Homography => linear::<8>(&scaled, weights, homography_rows)?,
    };
    // Back to pixels: n2^-1 * t * n1.
    let back = n2.matrix().inverse()?.then_after(&t.then_after(&n1.matrix()));
    let back = back.normalised();
    back.0.iter().all(|v| v.is_finite()).then_some(back)
}

/// A shift and one scale that centre points on 0 at a mean distance of
/// sqrt(2).
struct Normaliser {
    centre: (f64, f64),
    scale: f64,
}

impl Normaliser {
    fn of(
        points: &[Correspondence],
        weights: &[f64],
        at: impl Fn(&Correspondence) -> (f64, f64),
    ) -> Normaliser {
        let total: f64 = weights.iter().sum();
        let (mut cx, mut cy) = (0.0, 0.0);
        for (p, &w) in points.iter().zip(weights) {
            let (x, y) = at(p);
            cx += w * x;
            cy += w * y;
        }
        let centre = (cx / total, cy / total);
        let spread: f64 = points
            .iter()
            .zip(weights)
            .map(|(p, &w)| {
                let (x, y) = at(p);
                w * (x - centre.0).hypot(y - centre.1)
            })
            .sum::<f64>()
            / total;
        let scale = if spread > 1e-9 {
            std::f64::consts::SQRT_2 / spread
        } else {
            1.0
        };
        Normaliser { centre, scale }
    }

    fn apply(&self, (x, y): (f64, f64)) -> (f64, f64) {
        ((x - self.centre.0) * self.scale, (y - self.centre.1) * self.scale)
    }

    fn matrix(&self) -> Transform {
        let s = self.scale;
        Transform([
            s,
            0.0,
            -s * self.centre.0,
            0.0,
            s,
            -s * self.centre.1,
            0.0,
            0.0,
            1.0,
        ])
    }
}

fn translation(points: &[Correspondence], weights: &[f64], total: f64) -> Transform {
    let (mut tx, mut ty) = (0.0, 0.0);
    for (p, &w) in points.iter().zip(weights) {
        tx += w * (p.to.0 - p.from.0);
        ty += w * (p.to.1 - p.from.1);
    }
    Transform([1.0, 0.0, tx / total, 0.0, 1.0, ty / total, 0.0, 0.0, 1.0])
}

/// The two equations a correspondence gives a model linear in its `N`
/// parameters: `(row, right-hand side)` each.
type Rows<const N: usize> = fn(&Correspondence) -> [([f64; N], f64); 2];

fn similarity_rows(c: &Correspondence) -> [([f64; 4], f64); 2] {
    let ((x, y), (u, v)) = (c.from, c.to);
    [([x, -y, 1.0, 0.0], u), ([y, x, 0.0, 1.0], v)]
}

fn affine_rows(c: &Correspondence) -> [([f64; 6], f64); 2] {
    let ((x, y), (u, v)) = (c.from, c.to);
    [([x, y, 1.0, 0.0, 0.0, 0.0], u), ([0.0, 0.0, 0.0, x, y, 1.0], v)]
}

/// The direct linear transform with the last entry fixed at 1 (points are
/// centred, so a homography through the origin's image is not excluded in
/// practice).
fn homography_rows(c: &Correspondence) -> [([f64; 8], f64); 2] {
    let ((x, y), (u, v)) = (c.from, c.to);
    [
        ([x, y, 1.0, 0.0, 0.0, 0.0, -x * u, -y * u], u),
        ([0.0, 0.0, 0.0, x, y, 1.0, -x * v, -y * v], v),
    ]
}

/// Weighted least squares of a model linear in `N` parameters, by its
/// normal equations.
fn linear<const N: usize>(points: &[Correspondence], weights: &[f64], rows: Rows<N>) -> Option<Transform> {
    let mut a = [[0.0f64; N]; N];
    let mut b = [0.0f64; N];
    for (p, &w) in points.iter().zip(weights) {
        for (row, rhs) in rows(p) {
            for i in 0..N {
                b[i] += w * row[i] * rhs;
                for j in 0..N {
                    a[i][j] += w * row[i] * row[j];
                }
            }
        }
    }
    let h = solve(a, b)?;
    Some(match N {
        4 => Transform([h[0], -h[1], h[2], h[1], h[0], h[3], 0.0, 0.0, 1.0]),
        6 => Transform([h[0], h[1], h[2], h[3], h[4], h[5], 0.0, 0.0, 1.0]),
        _ => Transform([h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0]),
    })
}

/// `a x = b` by Gaussian elimination with partial pivoting; `None` where
/// `a` is singular (a degenerate set of points).
fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale.is_nan() || scale <= 0.0 || !scale.is_finite() {
        return None;
    }
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-12 * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (done, rest) = a.split_at_mut(col + 1);
        let pivot_row = &done[col];
        for (k, row) in rest.iter_mut().enumerate() {
            let f = row[col] / pivot_row[col];
            for (x, p) in row[col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            b[col + 1 + k] -= f * b[col];
        }
    }
    let mut x = [0.0; N];
    for r in (0..N).rev() {
        let s: f64 = (r + 1..N).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(t: &Transform) -> Vec<Correspondence> {
        (0..5)
            .flat_map(|i| (0..4).map(move |j| (f64::from(i) * 90.0 + 7.0, f64::from(j) * 70.0 + 3.0)))
            .map(|p| Correspondence::new(p, t.apply(p.0, p.1).unwrap()))
            .collect()
    }

    #[test]
    fn each_model_is_recovered_exactly_from_exact_points() {
        let truths = [
            (
                Model::Translation,
                Transform([1.0, 0.0, 3.5, 0.0, 1.0, -2.25, 0.0, 0.0, 1.0]),
            ),
            (
                Model::Similarity,
                Transform([0.99, -0.05, 4.0, 0.05, 0.99, -1.0, 0.0, 0.0, 1.0]),
            ),
            (
                Model::Affine,
                Transform([1.02, 0.03, -6.0, -0.01, 0.97, 2.5, 0.0, 0.0, 1.0]),
            ),
            (
                Model::Homography,
                Transform([1.01, 0.02, -3.0, 0.01, 0.98, 4.0, 2e-5, -1e-5, 1.0]),
            ),
        ];
        for (model, truth) in truths {
            let points = grid(&truth);
            let t = fit(model, &points, &vec![1.0; points.len()]).unwrap();
            for (a, b) in t.0.iter().zip(truth.0) {
                assert!((a - b).abs() < 1e-9, "{model}: {:?} against {:?}", t.0, truth.0);
            }
        }
    }

    #[test]
    fn degenerate_points_are_refused_not_solved() {
        let same = vec![Correspondence::new((5.0, 5.0), (6.0, 5.0)); 10];
        let w = vec![1.0; 10];
        assert!(fit(Model::Translation, &same, &w).is_some());
        for model in [Model::Similarity, Model::Affine, Model::Homography] {
            assert!(fit(model, &same, &w).is_none(), "{model}");
        }
        let line: Vec<_> = (0..10)
            .map(|i| Correspondence::new((f64::from(i), 2.0 * f64::from(i)), (f64::from(i), 0.0)))
            .collect();
        assert!(fit(Model::Homography, &line, &w).is_none());
        assert!(fit(Model::Affine, &line[..2], &w[..2]).is_none());
    }

    #[test]
    fn inverse_and_composition_agree() {
        let t = Transform([1.01, 0.02, -3.0, 0.01, 0.98, 4.0, 2e-5, -1e-5, 1.0]);
        let id = t.inverse().unwrap().then_after(&t);
        for (a, b) in id.0.iter().zip(Transform::IDENTITY.0) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
