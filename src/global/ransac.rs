//! RANSAC over minimal samples, then iteratively reweighted least squares.

use super::model::{fit, Correspondence, Transform};
use super::{GlobalError, GlobalMotion, GlobalParams, Refinement};

/// The model of `params` that most of `points` follow: the RANSAC sample
/// whose model has the lowest truncated squared error (MSAC: inliers cost
/// their squared distance, the rest the threshold's square), refitted to
/// its inliers and refined by reweighted least squares (Cauchy weights;
/// [`Refinement`] says at which scale).
pub fn estimate(points: &[Correspondence], params: &GlobalParams) -> Result<GlobalMotion, GlobalError> {
    check(params)?;
    let model = params.model;
    let usable: Vec<Correspondence> = points
        .iter()
        .copied()
        .filter(|c| {
            [c.from.0, c.from.1, c.to.0, c.to.1, c.weight]
                .iter()
                .all(|v| v.is_finite())
                && c.weight > 0.0
        })
        .collect();
    let need = model.min_points();
    if usable.len() < need {
        return Err(GlobalError::TooFewPoints {
            model,
            need,
            have: usable.len(),
        });
    }
    let best = sample_consensus(&usable, params).ok_or(GlobalError::Degenerate(model))?;
    let refined = refine(&usable, params, best);
    Ok(summary(points, params, refined))
}

fn check(p: &GlobalParams) -> Result<(), GlobalError> {
    if !(p.threshold > 0.0 && p.threshold.is_finite()) {
        return Err(GlobalError::Params(format!(
            "threshold {} must be a positive number of pixels",
            p.threshold
        )));
    }
    if p.max_samples == 0 {
        return Err(GlobalError::Params("at least one RANSAC sample is needed".into()));
    }
    Ok(())
}

/// MSAC cost of `t` over `points`.
fn cost(points: &[Correspondence], t: &Transform, threshold: f64) -> f64 {
    let t2 = threshold * threshold;
    points
        .iter()
        .map(|c| c.residual_squared(t).min(t2) * c.weight)
        .sum()
}

/// The best minimal-sample model, or `None` if every sample was degenerate.
fn sample_consensus(points: &[Correspondence], p: &GlobalParams) -> Option<Transform> {
    let (n, s) = (points.len(), p.model.min_points());
    if n < s {
        return None;
    }
    let mut rng = p.seed | 1;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    let mut best: Option<(f64, Transform)> = None;
    let mut samples_needed = p.max_samples;
    let mut drawn = 0;
    // Reused from sample to sample (at most 4 points, weights all 1).
    let (mut sample, mut chosen) = (Vec::with_capacity(s), Vec::with_capacity(s));
    let ones = [1.0; 4];
    while drawn < samples_needed.min(p.max_samples) {
        drawn += 1;
        sample.clear();
        while sample.len() < s {
            let i = (next() % n as u64) as usize;
            if !sample.contains(&i) {
                sample.push(i);
            }
        }
        chosen.clear();
        chosen.extend(sample.iter().map(|&i| points[i]));
        let Some(t) = fit(p.model, &chosen, &ones[..s]) else {
            continue;
        };
        let c = cost(points, &t, p.threshold);
        if best.as_ref().is_none_or(|(b, _)| c < *b) {
            let t2 = p.threshold * p.threshold;
            let inliers = points.iter().filter(|q| q.residual_squared(&t) <= t2).count();
            samples_needed = samples_for(inliers as f64 / n as f64, s);
            best = Some((c, t));
        }
    }
    // Small sets: every sample may have been degenerate by chance; the
    // least-squares fit of all of them is the last resort.
    best.map(|(_, t)| t).or_else(|| {
        fit(
            p.model,
            points,
            &points.iter().map(|c| c.weight).collect::<Vec<_>>(),
        )
    })
}

/// Samples that hold one all-inlier sample with 99.9 % confidence when a
/// share `w` of the points are inliers.
fn samples_for(w: f64, s: usize) -> usize {
    let clean = w.powi(s as i32);
    if clean >= 1.0 - 1e-12 {
        return 1;
    }
    if clean <= 1e-12 {
        return usize::MAX;
    }
    ((1.0f64 - 0.999).ln() / (1.0 - clean).ln()).ceil() as usize
}

/// Refits to the inliers before reweighting at their scale, at most (they
/// settle in two or three).
const MAX_REFITS: usize = 8;

/// Cauchy's tuning constant, in units of the inliers' scale (95 %
/// efficiency where their distances are normal).
const CAUCHY_TUNING: f64 = 2.385;

/// `start` refitted to its inliers, then reweighted least squares with
/// Cauchy weights, as `p.refinement` says: at the inliers' own scale
/// after their refits settle (LO-RANSAC's local step), or at the
/// threshold's out to three thresholds after one refit.
fn refine(points: &[Correspondence], p: &GlobalParams, start: Transform) -> Transform {
    let refits = match p.refinement {
        Refinement::InlierScale => MAX_REFITS,
        Refinement::ThresholdScale => 1,
    };
    let mut t = refit_to_inliers(points, p, start, refits);
    for _ in 0..p.refinements {
        let (c, reach) = match p.refinement {
            Refinement::InlierScale => match inlier_scale(points, p, &t) {
                Some(scale) => (CAUCHY_TUNING * scale, p.threshold),
                None => break,
            },
            Refinement::ThresholdScale => (p.threshold, 3.0 * p.threshold),
        };
        let weights: Vec<f64> = points
            .iter()
            .map(|q| match q.residual(&t) {
                r if r <= reach => q.weight / (1.0 + (r / c) * (r / c)),
                _ => 0.0,
            })
            .collect();
        let Some(next) = fit(p.model, points, &weights) else {
            break;
        };
        let moved = next
            .0
            .iter()
            .zip(t.0)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        t = next;
        if moved < 1e-10 {
            break;
        }
    }
    t
}

/// The points within the threshold of `t`, weighed as given (0 elsewhere).
fn inlier_weights(points: &[Correspondence], p: &GlobalParams, t: &Transform) -> Vec<f64> {
    points
        .iter()
        .map(|c| {
            if c.residual(t) <= p.threshold {
                c.weight
            } else {
                0.0
            }
        })
        .collect()
}

/// `start` refitted to its inliers, again to the new inliers, until they
/// are the same twice or `rounds` refits are done.
fn refit_to_inliers(
    points: &[Correspondence],
    p: &GlobalParams,
    start: Transform,
    rounds: usize,
) -> Transform {
    let mut t = start;
    let mut weights = inlier_weights(points, p, &t);
    for _ in 0..rounds {
        let Some(next) = fit(p.model, points, &weights) else {
            break;
        };
        t = next;
        let again = inlier_weights(points, p, &t);
        if again == weights {
            break;
        }
        weights = again;
    }
    t
}

/// The inliers' scale: their median distance to `t` times 1.4826 (a
/// normal distribution's standard deviation), at least 2 % of the
/// threshold (exact correspondences would give 0).
fn inlier_scale(points: &[Correspondence], p: &GlobalParams, t: &Transform) -> Option<f64> {
    let mut distances: Vec<f64> = points
        .iter()
        .map(|c| c.residual(t))
        .filter(|&r| r <= p.threshold)
        .collect();
    if distances.is_empty() {
        return None;
    }
    let mid = distances.len() / 2;
    let (_, median, _) = distances.select_nth_unstable_by(mid, f64::total_cmp);
    Some((1.4826 * *median).max(0.02 * p.threshold))
}

/// The inlier mask over every input point (non-finite ones are outliers)
/// and the inliers' RMS distance.
fn summary(points: &[Correspondence], p: &GlobalParams, t: Transform) -> GlobalMotion {
    let inliers: Vec<bool> = points
        .iter()
        .map(|c| c.weight > 0.0 && c.residual(&t) <= p.threshold)
        .collect();
    let count = inliers.iter().filter(|&&i| i).count();
    let sum: f64 = points
        .iter()
        .zip(&inliers)
        .filter(|(_, &i)| i)
        .map(|(c, _)| c.residual_squared(&t))
        .sum();
    GlobalMotion {
        model: p.model,
        transform: t,
        inliers,
        inlier_count: count,
        rms: if count > 0 {
            (sum / count as f64).sqrt()
        } else {
            f64::NAN
        },
    }
}
