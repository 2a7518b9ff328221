//! Sampling and warping float fields by a flow.

use ndarray::Array2;

use super::Flow;

/// Bilinear sample of `img` at (x, y), coordinates clamped to the picture
/// (the edge pixels extend outwards).
#[inline]
pub fn sample_bilinear(img: &Array2<f32>, x: f32, y: f32) -> f32 {
    let (h, w) = img.dim();
    let x = x.clamp(0.0, (w - 1) as f32);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let top = img[[y0, x0]] + fx * (img[[y0, x1]] - img[[y0, x0]]);
    let bottom = img[[y1, x0]] + fx * (img[[y1, x1]] - img[[y1, x0]]);
    top + fy * (bottom - top)
}

/// Backward warp: `out(p) = img(p + flow(p))`, bilinear, edges extended.
///
/// With `flow` the forward flow from frame 1 to frame 2 and `img` frame 2,
/// the result approximates frame 1: frame 2 "warped back" by the flow.
///
/// ```
/// use mocomp::flow::{warp::warp_bilinear, Flow};
/// let img = ndarray::Array2::from_shape_fn((4, 6), |(_, x)| x as f32 * 10.0);
/// let shifted = warp_bilinear(&img, &Flow::from_fn(6, 4, |_, _| (1.5, 0.0)));
/// assert_eq!(shifted[[2, 1]], 25.0);
/// ```
pub fn warp_bilinear(img: &Array2<f32>, flow: &Flow) -> Array2<f32> {
    assert_eq!(
        img.dim(),
        (flow.height(), flow.width()),
        "warp: picture and flow sizes differ"
    );
    Array2::from_shape_fn(img.dim(), |(y, x)| {
        let (u, v) = flow.get(x, y);
        sample_bilinear(img, x as f32 + u, y as f32 + v)
    })
}
