//! Forward-backward consistency: where following the forward flow and then
//! the backward flow does not come back to the start, the motion is
//! unreliable, most often because the pixel is occluded in the other frame.

use ndarray::Array2;

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
    // Borrowed as they are when in standard layout (always, in practice).
    let fields = [forward.u(), forward.v(), backward.u(), backward.v()].map(|a| a.as_standard_layout());
    let [fu, fv, bu, bv] = [0, 1, 2, 3].map(|k| fields[k].as_slice().expect("standard layout"));
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (fu[y * w + x], fv[y * w + x]);
            let (qx, qy) = (x as f32 + u, y as f32 + v);
            // Also false for NaN: a flow with no value is unreliable.
            let inside = qx >= 0.0 && qy >= 0.0 && qx <= (w - 1) as f32 && qy <= (h - 1) as f32;
            out.push(
                !inside || {
                    let (ub, vb) = bilinear_pair(bu, bv, w, h, qx, qy);
                    let (du, dv) = (u + ub, v + vb);
                    du * du + dv * dv > 0.01 * (u * u + v * v + ub * ub + vb * vb) + 0.5
                },
            );
        }
    }
    Array2::from_shape_vec((h, w), out).expect("w * h values")
}

/// Both components of a flow sampled bilinearly at (x, y), which lies in
/// the picture: the weights found once.
#[inline]
fn bilinear_pair(u: &[f32], v: &[f32], w: usize, h: usize, x: f32, y: f32) -> (f32, f32) {
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (x - x0 as f32, y - y0 as f32);
    let (i00, i01, i10, i11) = (y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1);
    let lerp = |p: &[f32]| {
        let top = p[i00] + ax * (p[i01] - p[i00]);
        let bottom = p[i10] + ax * (p[i11] - p[i10]);
        top + ay * (bottom - top)
    };
    (lerp(u), lerp(v))
}
