//! Descriptor matching: nearest neighbour in Hamming distance with Lowe's
//! ratio test and a mutual check, then a neighbourhood-consensus filter
//! (as GMS reasons: a right match has neighbours that move alike, a wrong
//! one rarely does), which keeps layered and non-rigid motion that a
//! single global model would throw away.

use rayon::prelude::*;

use super::describe::Descriptor;
use super::Match;
use super::{Keypoint, MatchParams};

/// For each descriptor of `a`, its nearest and second-nearest distances in
/// `b` and the index of the nearest.
fn nearest(a: &[Descriptor], b: &[Descriptor]) -> Vec<(usize, u32, u32)> {
    let nearest_one = super::dsp::features().nearest;
    a.par_iter().map(|da| nearest_one(da, b)).collect()
}

/// Matches passing the distance bound, the ratio test and the mutual check.
pub(super) fn mutual_matches(
    k1: &[Keypoint],
    d1: &[Descriptor],
    k2: &[Keypoint],
    d2: &[Descriptor],
    p: &MatchParams,
) -> Vec<Match> {
    if d1.is_empty() || d2.is_empty() {
        return Vec::new();
    }
    let (forward, backward) = (nearest(d1, d2), nearest(d2, d1));
    forward
        .iter()
        .enumerate()
        .filter(|&(i, &(j, best, second))| {
            best <= p.max_distance && (best as f32) < p.ratio * second as f32 && backward[j].0 == i
        })
        .map(|(i, &(j, best, _))| Match {
            x1: k1[i].x,
            y1: k1[i].y,
            x2: k2[j].x,
            y2: k2[j].y,
            distance: best,
        })
        .collect()
}

/// Keeps the matches whose displacement at least `p.min_support` of their
/// `p.neighbours` nearest matches (in the first picture) share, within
/// `4 px + 0.3 x` their distance (room for rotation and zoom between
/// neighbours).
pub(super) fn consensus(matches: Vec<Match>, p: &MatchParams) -> Vec<Match> {
    let k = p.neighbours.min(matches.len().saturating_sub(1));
    if k == 0 {
        return Vec::new();
    }
    let support = p.min_support.min(k);
    let keep: Vec<bool> = matches
        .par_iter()
        .map(|m| {
            let (du, dv) = (m.x2 - m.x1, m.y2 - m.y1);
            // The k nearest others by position in the first picture.
            let mut near: Vec<(f32, &Match)> = matches
                .iter()
                .filter(|o| !std::ptr::eq(*o, m))
                .map(|o| ((o.x1 - m.x1).hypot(o.y1 - m.y1), o))
                .collect();
            near.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
            near[..k]
                .iter()
                .filter(|(dist, o)| {
                    let (ou, ov) = (o.x2 - o.x1, o.y2 - o.y1);
                    (ou - du).hypot(ov - dv) <= 4.0 + 0.3 * dist
                })
                .count()
                >= support
        })
        .collect();
    matches
        .into_iter()
        .zip(keep)
        .filter_map(|(m, k)| k.then_some(m))
        .collect()
}
