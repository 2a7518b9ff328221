//! RANSAC over minimal samples, then iteratively reweighted least squares.

use super::model::{fit, Correspondence, Transform};
use super::{GlobalError, GlobalMotion, GlobalParams};

/// The model of `params` that most of `points` follow: the RANSAC sample
/// whose model has the lowest truncated squared error (MSAC: inliers cost
/// their squared distance, the rest the threshold's square), refitted to
/// its inliers and refined by reweighted least squares (Cauchy weights at
/// the threshold's scale, points beyond three thresholds left out).
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

/// Reweighted least squares from `start`.
fn refine(points: &[Correspondence], p: &GlobalParams, start: Transform) -> Transform {
    let mut t = start;
    let inlier_weights = |t: &Transform| -> Vec<f64> {
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
    };
    if let Some(refit) = fit(p.model, points, &inlier_weights(&t)) {
        t = refit;
    }
    for _ in 0..p.refinements {
        let weights: Vec<f64> = points
            .iter()
            .map(|c| {
                let r = c.residual(&t) / p.threshold;
                if r <= 3.0 {
                    c.weight / (1.0 + r * r)
                } else {
                    0.0
                }
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
