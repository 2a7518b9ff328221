//! Forward-backward consistency: where following the forward flow and then
//! the backward flow does not come back to the start, the motion is
//! unreliable, most often because the pixel is occluded in the other frame.

use ndarray::Array2;

use super::warp::sample_bilinear;
use super::Flow;

/// The test of Sundaram, Brox and Keutzer (2010): pixel p is inconsistent
/// when `|w_f(p) + w_b(q)|^2 > 0.01 (|w_f(p)|^2 + |w_b(q)|^2) + 0.5`, with
/// `q = p + w_f(p)` and `w_b(q)` sampled bilinearly, or when q lies outside
/// the picture. Returns `true` where the forward flow is unreliable.
///
/// ```
/// use mocomp::flow::{consistency::inconsistent, Flow};
/// let fwd = Flow::from_fn(8, 8, |_, _| (1.0, 0.0));
/// let bwd = Flow::from_fn(8, 8, |_, _| (-1.0, 0.0));
/// let mask = inconsistent(&fwd, &bwd);
/// assert!(!mask[[4, 3]]); // consistent
/// assert!(mask[[4, 7]]); // moves out of the picture
/// ```
pub fn inconsistent(forward: &Flow, backward: &Flow) -> Array2<bool> {
    assert!(
        forward.width() == backward.width() && forward.height() == backward.height(),
        "forward and backward flows differ in size"
    );
    let (w, h) = (forward.width(), forward.height());
    let (bu, bv) = (backward.u(), backward.v());
    Array2::from_shape_fn((h, w), |(y, x)| {
        let (u, v) = forward.get(x, y);
        let (qx, qy) = (x as f32 + u, y as f32 + v);
        if qx < 0.0 || qy < 0.0 || qx > (w - 1) as f32 || qy > (h - 1) as f32 {
            return true;
        }
        let (ub, vb) = (sample_bilinear(bu, qx, qy), sample_bilinear(bv, qx, qy));
        let (du, dv) = (u + ub, v + vb);
        du * du + dv * dv > 0.01 * (u * u + v * v + ub * ub + vb * vb) + 0.5
    })
}
