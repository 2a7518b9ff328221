//! Bjontegaard delta rate and delta PSNR between two rate-distortion
//! curves, in the two common variants:
//!
//! * cubic (VCEG-M33): a least-squares cubic of log-rate against PSNR (for
//!   BD-rate; PSNR against log-rate for BD-PSNR) per curve, integrated
//!   exactly over the overlapping range;
//! * pchip: the piecewise-cubic Hermite interpolant through the points
//!   (Fritsch-Carlson slopes, as MATLAB's and SciPy's `pchip`), integrated
//!   exactly.
//!
//! Negative BD-rate: the test curve needs fewer bits for the same PSNR.
//!
//! ```
//! use mocomp::rd::bdrate::{bd_rate, Fit};
//! let anchor = [(100.0, 30.0), (200.0, 33.0), (400.0, 36.0), (800.0, 39.0)];
//! let test: Vec<(f64, f64)> = anchor.iter().map(|&(r, p)| (0.8 * r, p)).collect();
//! let d = bd_rate(&anchor, &test, Fit::Cubic).unwrap();
//! assert!((d + 20.0).abs() < 1e-9);
//! ```

/// Which curve fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fit {
    /// Least-squares cubic polynomial (VCEG-M33).
    Cubic,
    /// Piecewise cubic Hermite interpolation (pchip).
    Pchip,
}

/// Why a BD figure cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BdError {
    /// Fewer than four points in a curve.
    #[error("a curve needs at least 4 rate-distortion points (got {0})")]
    TooFewPoints(usize),
    /// A rate that is not positive, or a value that is not finite.
    #[error("rates must be positive and PSNRs finite (got rate {0}, PSNR {1})")]
    BadPoint(f64, f64),
    /// The curves' ranges do not overlap.
    #[error("the curves' {0} ranges do not overlap")]
    NoOverlap(&'static str),
    /// Two points at the same abscissa (pchip needs distinct ones).
    #[error("two points of a curve have the same {0}")]
    Duplicate(&'static str),
}

/// (x, y) points sorted by x.
fn sorted(mut pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts
}

fn check(curve: &[(f64, f64)]) -> Result<(), BdError> {
    if curve.len() < 4 {
        return Err(BdError::TooFewPoints(curve.len()));
    }
    for &(r, p) in curve {
        if !(r > 0.0 && r.is_finite() && p.is_finite()) {
            return Err(BdError::BadPoint(r, p));
        }
    }
    Ok(())
}

/// BD-rate of `test` against `anchor`, percent. Points are (rate, PSNR).
pub fn bd_rate(anchor: &[(f64, f64)], test: &[(f64, f64)], fit: Fit) -> Result<f64, BdError> {
    check(anchor)?;
    check(test)?;
    let a = sorted(anchor.iter().map(|&(r, p)| (p, r.ln())).collect());
    let t = sorted(test.iter().map(|&(r, p)| (p, r.ln())).collect());
    let mean = mean_difference(&a, &t, fit, "PSNR")?;
    Ok((mean.exp() - 1.0) * 100.0)
}

/// BD-PSNR of `test` against `anchor`, dB.
pub fn bd_psnr(anchor: &[(f64, f64)], test: &[(f64, f64)], fit: Fit) -> Result<f64, BdError> {
    check(anchor)?;
    check(test)?;
    let a = sorted(anchor.iter().map(|&(r, p)| (r.ln(), p)).collect());
    let t = sorted(test.iter().map(|&(r, p)| (r.ln(), p)).collect());
    mean_difference(&a, &t, fit, "rate")
}

/// The mean of `t(x) - a(x)` over the overlap of the x ranges.
fn mean_difference(a: &[(f64, f64)], t: &[(f64, f64)], fit: Fit, axis: &'static str) -> Result<f64, BdError> {
    let lo = a[0].0.max(t[0].0);
    let hi = a[a.len() - 1].0.min(t[t.len() - 1].0);
    if hi <= lo {
        return Err(BdError::NoOverlap(axis));
    }
    let integral = |c: &[(f64, f64)]| -> Result<f64, BdError> {
        match fit {
            Fit::Cubic => Ok(cubic_integral(c, lo, hi)),
            Fit::Pchip => pchip_integral(c, lo, hi).ok_or(BdError::Duplicate(axis)),
        }
    };
    Ok((integral(t)? - integral(a)?) / (hi - lo))
}

/// Integral over [lo, hi] of the least-squares cubic through `pts`. The
/// abscissae are centred and scaled first, which keeps the normal
/// equations well conditioned.
fn cubic_integral(pts: &[(f64, f64)], lo: f64, hi: f64) -> f64 {
    let n = pts.len() as f64;
    let centre = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let scale = pts
        .iter()
        .map(|p| (p.0 - centre).abs())
        .fold(0.0, f64::max)
        .max(1e-12);
    // Normal equations M c = v for y = c0 + c1 u + c2 u^2 + c3 u^3.
    let mut m = [[0.0; 5]; 4];
    for &(x, y) in pts {
        let u = (x - centre) / scale;
        let powers = [1.0, u, u * u, u * u * u];
        for i in 0..4 {
            for j in 0..4 {
                m[i][j] += powers[i] * powers[j];
            }
            m[i][4] += powers[i] * y;
        }
    }
    let c = solve4(m);
    // The antiderivative in u, times du/dx's inverse.
    let prim = |x: f64| {
        let u = (x - centre) / scale;
        scale * (c[0] * u + c[1] * u * u / 2.0 + c[2] * u.powi(3) / 3.0 + c[3] * u.powi(4) / 4.0)
    };
    prim(hi) - prim(lo)
}

/// Gaussian elimination with partial pivoting of a 4x4 augmented system.
fn solve4(mut m: [[f64; 5]; 4]) -> [f64; 4] {
    for col in 0..4 {
        let pivot = (col..4)
            .max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))
            .unwrap_or(col);
        m.swap(col, pivot);
        let d = m[col][col];
        if d.abs() < 1e-300 {
            continue;
        }
        for row in 0..4 {
            if row != col {
                let f = m[row][col] / d;
                let pivot_row = m[col];
                for (v, p) in m[row][col..].iter_mut().zip(&pivot_row[col..]) {
                    *v -= f * p;
                }
            }
        }
    }
    let mut c = [0.0; 4];
    for i in 0..4 {
        c[i] = if m[i][i].abs() < 1e-300 {
            0.0
        } else {
            m[i][4] / m[i][i]
        };
    }
    c
}

/// Fritsch-Carlson slopes of the pchip interpolant (SciPy's
/// `PchipInterpolator`, including its one-sided end formula).
fn pchip_slopes(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let delta: Vec<f64> = (0..n - 1).map(|k| (y[k + 1] - y[k]) / h[k]).collect();
    let mut d = vec![0.0; n];
    for k in 1..n - 1 {
        if delta[k - 1] * delta[k] > 0.0 {
            let w1 = 2.0 * h[k] + h[k - 1];
            let w2 = h[k] + 2.0 * h[k - 1];
            d[k] = (w1 + w2) / (w1 / delta[k - 1] + w2 / delta[k]);
        }
    }
    let edge = |h0: f64, h1: f64, m0: f64, m1: f64| {
        let d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
        if d.signum() != m0.signum() {
            0.0
        } else if m0.signum() != m1.signum() && d.abs() > 3.0 * m0.abs() {
            3.0 * m0
        } else {
            d
        }
    };
    d[0] = edge(h[0], h[1], delta[0], delta[1]);
    d[n - 1] = edge(h[n - 2], h[n - 3], delta[n - 2], delta[n - 3]);
    d
}

/// Integral over [lo, hi] (inside the points' range) of the pchip
/// interpolant; `None` when two abscissae coincide.
fn pchip_integral(pts: &[(f64, f64)], lo: f64, hi: f64) -> Option<f64> {
    let x: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let y: Vec<f64> = pts.iter().map(|p| p.1).collect();
    if x.windows(2).any(|w| w[1] <= w[0]) {
        return None;
    }
    let d = pchip_slopes(&x, &y);
    let mut total = 0.0;
    for k in 0..x.len() - 1 {
        let (a, b) = (lo.max(x[k]), hi.min(x[k + 1]));
        if b <= a {
            continue;
        }
        let h = x[k + 1] - x[k];
        let delta = (y[k + 1] - y[k]) / h;
        let c2 = (3.0 * delta - 2.0 * d[k] - d[k + 1]) / h;
        let c3 = (d[k] + d[k + 1] - 2.0 * delta) / (h * h);
        let prim = |s: f64| y[k] * s + d[k] * s * s / 2.0 + c2 * s.powi(3) / 3.0 + c3 * s.powi(4) / 4.0;
        total += prim(b - x[k]) - prim(a - x[k]);
    }
    Some(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(r: [f64; 4], p: [f64; 4]) -> Vec<(f64, f64)> {
        r.into_iter().zip(p).collect()
    }

    #[test]
    fn the_four_point_example_gives_the_published_figures() {
        let a = curve([686.76, 309.58, 157.11, 85.95], [40.28, 37.18, 34.24, 31.42]);
        let b = curve([893.34, 407.8, 204.93, 112.75], [40.39, 37.21, 34.17, 31.24]);
        let cubic = bd_rate(&a, &b, Fit::Cubic).unwrap();
        let pchip = bd_rate(&a, &b, Fit::Pchip).unwrap();
        assert!((cubic - 31.397).abs() < 5e-4, "{cubic}");
        assert!((pchip - 31.380).abs() < 5e-4, "{pchip}");
        // BD-PSNR as ../shared/peers/bdrate.py (numpy polyfit, SciPy pchip)
        // gives it: -1.184898 and -1.183472 dB.
        assert!((bd_psnr(&a, &b, Fit::Cubic).unwrap() + 1.184898).abs() < 1e-5);
        assert!((bd_psnr(&a, &b, Fit::Pchip).unwrap() + 1.183472).abs() < 1e-5);
    }

    #[test]
    fn scaled_rates_give_exactly_that_scale_and_a_curve_against_itself_zero() {
        let a = curve([90.0, 170.0, 400.0, 1000.0], [30.1, 32.9, 36.2, 40.0]);
        let b: Vec<(f64, f64)> = a.iter().map(|&(r, p)| (0.8 * r, p)).collect();
        for fit in [Fit::Cubic, Fit::Pchip] {
            assert!((bd_rate(&a, &b, fit).unwrap() + 20.0).abs() < 1e-9);
            assert!(bd_rate(&a, &a, fit).unwrap().abs() < 1e-12);
            assert!(bd_psnr(&a, &a, fit).unwrap().abs() < 1e-12);
            // Less rate for the same PSNR is more PSNR for the same rate.
            assert!(bd_psnr(&a, &b, fit).unwrap() > 0.0);
        }
    }

    #[test]
    fn shifted_psnr_gives_that_shift() {
        let a = curve([100.0, 200.0, 400.0, 800.0], [30.0, 33.5, 36.0, 38.0]);
        let b: Vec<(f64, f64)> = a.iter().map(|&(r, p)| (r, p + 0.5)).collect();
        for fit in [Fit::Cubic, Fit::Pchip] {
            assert!((bd_psnr(&a, &b, fit).unwrap() - 0.5).abs() < 1e-9);
        }
    }

    #[test]
    fn bad_curves_are_errors() {
        let a = curve([100.0, 200.0, 400.0, 800.0], [30.0, 33.0, 36.0, 39.0]);
        let far = curve([100.0, 200.0, 400.0, 800.0], [40.0, 43.0, 46.0, 49.0]);
        assert_eq!(bd_rate(&a, &far, Fit::Cubic), Err(BdError::NoOverlap("PSNR")));
        assert_eq!(bd_rate(&a, &a[..3], Fit::Cubic), Err(BdError::TooFewPoints(3)));
        let zero = curve([0.0, 200.0, 400.0, 800.0], [30.0, 33.0, 36.0, 39.0]);
        assert!(matches!(
            bd_rate(&a, &zero, Fit::Pchip),
            Err(BdError::BadPoint(..))
        ));
        let dup = curve([100.0, 200.0, 400.0, 800.0], [30.0, 33.0, 33.0, 39.0]);
        assert_eq!(bd_rate(&a, &dup, Fit::Pchip), Err(BdError::Duplicate("PSNR")));
    }
}
