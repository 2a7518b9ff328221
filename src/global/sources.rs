//! Correspondences for the global fit from each kind of motion the toolkit
//! finds: a dense flow sampled on a grid, block vectors, feature matches.
//! Each gives pairs from the first (earlier) picture to the second.

use super::Correspondence;
use crate::features::Match;
use crate::flow::Flow;
use crate::me::MotionField;

/// The flow from the first picture to the second at every `step`-th pixel
/// of each row and column (from `step / 2`), its invalid pixels left out.
pub fn from_flow(flow: &Flow, step: usize) -> Vec<Correspondence> {
    let step = step.max(1);
    let mut out = Vec::new();
    for y in (step / 2..flow.height()).step_by(step) {
        for x in (step / 2..flow.width()).step_by(step) {
            let (u, v) = flow.get(x, y);
            if flow.is_valid(x, y) && u.is_finite() && v.is_finite() {
                let (x, y) = (x as f64, y as f64);
                out.push(Correspondence::new((x, y), (x + f64::from(u), y + f64::from(v))));
            }
        }
    }
    out
}

/// A block search of the second picture (current) against the first
/// (reference): each block's centre in the second picture and where its
/// vector finds it in the first, as pairs from the first to the second.
/// Blocks whose match cost is among the worst tenth, or that lie on the
/// picture's border row or column, are left out (their vectors are the
/// least reliable).
pub fn from_vectors(field: &MotionField) -> Vec<Correspondence> {
    let b = field.block() as f64;
    let (cols, rows) = (field.cols(), field.rows());
    let mut costs: Vec<u32> = field.costs().to_vec();
    costs.sort_unstable();
    let worst = costs.get(costs.len() * 9 / 10).copied().unwrap_or(u32::MAX);
    let mut out = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let inner = cols < 3 || rows < 3 || (c > 0 && r > 0 && c + 1 < cols && r + 1 < rows);
            if !inner || field.cost(c, r) > worst {
                continue;
            }
            let mv = field.vector(c, r);
            let (x, y) = (c as f64 * b + (b - 1.0) / 2.0, r as f64 * b + (b - 1.0) / 2.0);
            let (dx, dy) = (f64::from(mv.x) / 4.0, f64::from(mv.y) / 4.0);
            out.push(Correspondence::new((x + dx, y + dy), (x, y)));
        }
    }
    out
}

/// Feature matches from the first picture to the second.
pub fn from_matches(matches: &[Match]) -> Vec<Correspondence> {
    matches
        .iter()
        .map(|m| {
            Correspondence::new(
                (f64::from(m.x1), f64::from(m.y1)),
                (f64::from(m.x2), f64::from(m.y2)),
            )
        })
        .collect()
}
