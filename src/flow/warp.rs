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

/// Bilinear sample of the row-major `w x h` picture at (x, y), clamped.
#[inline]
pub(crate) fn bilinear_clamped(img: &[f32], w: usize, h: usize, x: f32, y: f32) -> f32 {
    let x = x.clamp(0.0, (w - 1) as f32);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (x - x0 as f32, y - y0 as f32);
    let top = img[y0 * w + x0] + ax * (img[y0 * w + x1] - img[y0 * w + x0]);
    let bot = img[y1 * w + x0] + ax * (img[y1 * w + x1] - img[y1 * w + x0]);
    top + ay * (bot - top)
}

/// Keys' cubic convolution weights (a = -0.5, Catmull-Rom) for the four
/// samples around a point at fraction `t` in [0, 1).
#[inline]
pub(crate) fn cubic_weights(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    ]
}

/// Bicubic (Keys, a = -0.5) sample of `img` at (x, y), coordinates clamped
/// to the picture. Exact on quadratic functions, and sharper than bilinear:
/// it does not smooth sub-pixel shifts the way bilinear does, which would
/// bias flow towards whole pixels.
#[inline]
pub fn sample_bicubic(img: &Array2<f32>, x: f32, y: f32) -> f32 {
    let (h, w) = img.dim();
    let x = x.clamp(0.0, (w - 1) as f32);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (wx, wy) = (cubic_weights(x - x0), cubic_weights(y - y0));
    let (x0, y0) = (x0 as isize, y0 as isize);
    let data = img.as_slice().expect("standard layout");
    let mut acc = 0.0;
    if x0 >= 1 && y0 >= 1 && x0 + 2 < w as isize && y0 + 2 < h as isize {
        // Inside: the four rows' four samples without clamping.
        let (x0, y0) = (x0 as usize - 1, y0 as usize - 1);
        for (j, wyj) in wy.iter().enumerate() {
            let at = (y0 + j) * w + x0;
            let row = &data[at..at + 4];
            let mut r = 0.0;
            for (wxi, v) in wx.iter().zip(row) {
                r += wxi * v;
            }
            acc += wyj * r;
        }
        return acc;
    }
    for (j, wyj) in wy.iter().enumerate() {
        let yy = (y0 + j as isize - 1).clamp(0, h as isize - 1) as usize;
        let row = &data[yy * w..(yy + 1) * w];
        let mut r = 0.0;
        for (i, wxi) in wx.iter().enumerate() {
            let xx = (x0 + i as isize - 1).clamp(0, w as isize - 1) as usize;
            r += wxi * row[xx];
        }
        acc += wyj * r;
    }
    acc
}

/// Backward warp: `out(p) = img(p + flow(p))`, bicubic, edges extended.
pub fn warp_bicubic(img: &Array2<f32>, flow: &Flow) -> Array2<f32> {
    assert_eq!(
        img.dim(),
        (flow.height(), flow.width()),
        "warp: picture and flow sizes differ"
    );
    let img = img.as_standard_layout().to_owned();
    Array2::from_shape_fn(img.dim(), |(y, x)| {
        let (u, v) = flow.get(x, y);
        sample_bicubic(&img, x as f32 + u, y as f32 + v)
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bicubic_is_exact_on_quadratics_and_shifts_by_whole_pixels() {
        let q = |x: f32, y: f32| 0.5 * x * x - 0.25 * x * y + 2.0 * y + 3.0;
        let img = Array2::from_shape_fn((12, 12), |(y, x)| q(x as f32, y as f32));
        for (x, y) in [(4.25, 5.5), (6.75, 3.125), (5.0, 5.0)] {
            assert!((sample_bicubic(&img, x, y) - q(x, y)).abs() < 1e-3, "({x},{y})");
        }
        let flow = Flow::from_fn(12, 12, |_, _| (2.0, -1.0));
        let warped = warp_bicubic(&img, &flow);
        assert_eq!(warped[[5, 4]], img[[4, 6]]);
        // Bilinear and bicubic agree on a linear ramp.
        let ramp = Array2::from_shape_fn((8, 8), |(y, x)| 3.0 * x as f32 + y as f32);
        let half = Flow::from_fn(8, 8, |_, _| (0.5, 0.25));
        assert!((warp_bicubic(&ramp, &half)[[3, 3]] - warp_bilinear(&ramp, &half)[[3, 3]]).abs() < 1e-4);
    }

    #[test]
    fn bicubic_inside_and_at_the_edges_is_the_clamped_sum() {
        // The definition: 4x4 samples around the point, indices clamped.
        let clamped = |img: &Array2<f32>, x: f32, y: f32| {
            let (h, w) = img.dim();
            let (x, y) = (x.clamp(0.0, (w - 1) as f32), y.clamp(0.0, (h - 1) as f32));
            let (wx, wy) = (cubic_weights(x - x.floor()), cubic_weights(y - y.floor()));
            let at = |i: f32, n: usize| (i as isize).clamp(0, n as isize - 1) as usize;
            let mut acc = 0.0;
            for (j, wyj) in wy.iter().enumerate() {
                let mut r = 0.0;
                for (i, wxi) in wx.iter().enumerate() {
                    r += wxi
                        * img[[
                            at(y.floor() + j as f32 - 1.0, h),
                            at(x.floor() + i as f32 - 1.0, w),
                        ]];
                }
                acc += wyj * r;
            }
            acc
        };
        let img = Array2::from_shape_fn((9, 11), |(y, x)| ((x * 37 + y * 91) % 23) as f32);
        for k in 0..400 {
            let (x, y) = (-1.5 + 0.037 * k as f32, -1.25 + 0.029 * (k * 7 % 400) as f32);
            assert_eq!(sample_bicubic(&img, x, y), clamped(&img, x, y), "({x}, {y})");
        }
    }
}
