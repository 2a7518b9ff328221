//! Errors of an estimated flow against ground truth.

use serde::Serialize;

use crate::flow::Flow;

/// Flow errors over the pixels where the ground truth is valid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FlowErrors {
    /// Mean end-point error: mean of `|w_est - w_gt|`, in pixels.
    pub epe: f64,
    /// Mean Middlebury angular error in degrees: the angle between
    /// `(u, v, 1)` and `(u_gt, v_gt, 1)`.
    pub ae: f64,
    /// Percentage of pixels with end-point error above 1 px.
    pub r1: f64,
    /// Percentage of pixels with end-point error above 3 px.
    pub r3: f64,
    /// Number of pixels measured (valid in the ground truth).
    pub pixels: usize,
}

/// Errors of `est` against `gt` over the pixels valid in `gt` (the
/// estimate's own mask is not used: every estimate is judged on the same
/// pixels). `None` when `gt` has no valid pixel. Panics if sizes differ.
///
/// ```
/// use mocomp::flow::Flow;
/// use mocomp::metrics::flow_errors;
/// let gt = Flow::from_fn(4, 4, |_, _| (1.0, 0.0));
/// let est = Flow::from_fn(4, 4, |_, _| (1.0, 2.0));
/// let e = flow_errors(&est, &gt).unwrap();
/// assert_eq!((e.epe, e.r1, e.r3), (2.0, 100.0, 0.0));
/// ```
pub fn flow_errors(est: &Flow, gt: &Flow) -> Option<FlowErrors> {
    assert!(
        est.width() == gt.width() && est.height() == gt.height(),
        "flow_errors: {}x{} estimate against {}x{} ground truth",
        est.width(),
        est.height(),
        gt.width(),
        gt.height()
    );
    let (mut epe, mut ae, mut over1, mut over3, mut n) = (0.0f64, 0.0f64, 0usize, 0usize, 0usize);
    ndarray::Zip::from(est.u())
        .and(est.v())
        .and(gt.u())
        .and(gt.v())
        .and(gt.valid())
        .for_each(|&u, &v, &ug, &vg, &ok| {
            if !ok {
                return;
            }
            let (u, v, ug, vg) = (u as f64, v as f64, ug as f64, vg as f64);
            let e = (u - ug).hypot(v - vg);
            let cos = (u * ug + v * vg + 1.0) / ((u * u + v * v + 1.0) * (ug * ug + vg * vg + 1.0)).sqrt();
            epe += e;
            ae += cos.clamp(-1.0, 1.0).acos().to_degrees();
            over1 += usize::from(e > 1.0);
            over3 += usize::from(e > 3.0);
            n += 1;
        });
    (n > 0).then(|| {
        let nf = n as f64;
        FlowErrors {
            epe: epe / nf,
            ae: ae / nf,
            r1: 100.0 * over1 as f64 / nf,
            r3: 100.0 * over3 as f64 / nf,
            pixels: n,
        }
    })
}
