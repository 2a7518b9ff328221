//! Resampling a plane through a plane-to-plane map: for each pixel of the
//! output, the map says where it lies in the input, and the input is read
//! there with bicubic interpolation (Catmull-Rom, a = -0.5, as ffmpeg's
//! swscale and vid.stab's bicubic). Pixel centres are at integer
//! coordinates, as everywhere in the toolkit.

use rayon::prelude::*;

use crate::codec::{Frame, Plane};

/// What a pixel reads from outside the input picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Border {
    /// The nearest edge pixel (as OpenCV's `BORDER_REPLICATE`).
    Replicate,
    /// A constant (as `BORDER_CONSTANT`; 0 is black luma, 128 grey chroma).
    Constant(u8),
    /// The output's pixel as it was (as OpenCV's `BORDER_TRANSPARENT`;
    /// vid.stab's `crop=keep` with the previous output there).
    Keep,
}

/// Sub-pixel positions per pixel, and the weights' scale (bits).
const PHASES: usize = 64;
const WEIGHT_BITS: u32 = 10;

/// Catmull-Rom weights of the four taps around a sample at fraction `t`.
fn cubic_weights(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// The weights of every phase in fixed point, each set summing to
/// `1 << WEIGHT_BITS` (the rounding error put on the largest tap).
fn weight_table() -> &'static [[i32; 4]; PHASES] {
    static TABLE: std::sync::OnceLock<[[i32; 4]; PHASES]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|p| {
            let w = cubic_weights(p as f64 / PHASES as f64);
            let mut q = w.map(|v| (v * f64::from(1 << WEIGHT_BITS)).round() as i32);
            let err = (1 << WEIGHT_BITS) - q.iter().sum::<i32>();
            let big = if p < PHASES / 2 { 1 } else { 2 };
            q[big] += err;
            q
        })
    })
}

/// `src` at `(x, y)`, positions rounded to 1/64 pixel (as OpenCV's warps
/// round to 1/32); `None` where `border` says to keep the output.
#[inline]
fn sample(src: &Plane, x: f64, y: f64, border: Border, table: &[[i32; 4]; PHASES]) -> Option<u8> {
    let (w, h) = (src.width() as i64, src.height() as i64);
    if !matches!(border, Border::Replicate)
        && (x < -0.5 || y < -0.5 || x > w as f64 - 0.5 || y > h as f64 - 0.5)
    {
        return match border {
            Border::Constant(c) => Some(c),
            _ => None,
        };
    }
    // Far outside, any position reads the same clamped edge; from -4 on,
    // truncation after the offset is rounding (no libm call).
    let phase = |v: f64, size: i64| {
        ((v.clamp(-4.0, size as f64 + 4.0) + 8.0) * PHASES as f64 + 0.5) as i64 - 8 * PHASES as i64
    };
    let (px, py) = (phase(x, w), phase(y, h));
    let (shift, mask) = (PHASES.trailing_zeros(), PHASES as i64 - 1);
    let (ix, iy) = ((px >> shift) - 1, (py >> shift) - 1);
    let (wx, wy) = (&table[(px & mask) as usize], &table[(py & mask) as usize]);
    let inside = ix >= 0 && iy >= 0 && ix + 3 < w && iy + 3 < h;
    let mut acc = 0i32;
    for (j, &k) in wy.iter().enumerate() {
        let yy = iy + j as i64;
        let row_sum: i32 = if inside {
            let row = &src.row(yy as usize)[ix as usize..ix as usize + 4];
            row.iter().zip(wx).map(|(&p, &c)| i32::from(p) * c).sum()
        } else {
            (0..4)
                .map(|i| i32::from(src.pixel_clamped((ix + i) as isize, yy as isize)) * wx[i as usize])
                .sum()
        };
        acc += row_sum * k;
    }
    let round = 1 << (2 * WEIGHT_BITS - 1);
    Some(((acc + round) >> (2 * WEIGHT_BITS)).clamp(0, 255) as u8)
}

/// A `width` x `height` plane whose pixel `(x, y)` is `src` at
/// `map(x, y)` (a 3x3 matrix, row by row, on homogeneous coordinates);
/// with [`Border::Keep`], 0 where the map leaves the input.
pub fn warp_plane(src: &Plane, width: usize, height: usize, map: &[f64; 9], border: Border) -> Plane {
    let mut out = Plane::new(width, height).expect("the size of an existing plane's output");
    warp_plane_onto(src, &mut out, map, border);
    out
}

/// [`warp_plane`] into `dst` (its size the output's); with
/// [`Border::Keep`], `dst`'s own pixels stay where the map leaves the
/// input.
pub fn warp_plane_onto(src: &Plane, dst: &mut Plane, map: &[f64; 9], border: Border) {
    let width = dst.width();
    let mut packed = dst.to_packed();
    let table = weight_table();
    packed
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| warp_row(src, row, y, map, border, table));
    for (d, s) in dst.rows_mut().zip(packed.chunks_exact(width)) {
        d.copy_from_slice(s);
    }
    dst.extend_border();
}

fn warp_row(src: &Plane, row: &mut [u8], y: usize, m: &[f64; 9], border: Border, table: &[[i32; 4]; PHASES]) {
    if m[6] == 0.0 && m[7] == 0.0 && m[8] == 1.0 {
        return warp_row_affine(src, row, y, m, border, table);
    }
    let y = y as f64;
    let (bx, by, bw) = (m[1] * y + m[2], m[4] * y + m[5], m[7] * y + m[8]);
    for (x, out) in row.iter_mut().enumerate() {
        let x = x as f64;
        let w = m[6] * x + bw;
        if w.abs() < 1e-12 {
            continue;
        }
        if let Some(v) = sample(src, (m[0] * x + bx) / w, (m[3] * x + by) / w, border, table) {
            *out = v;
        }
    }
}

/// [`warp_row`] for an affine map: positions stepped in fixed point
/// (1/64 pixel with 16 more bits), the 4x4 taps read straight from the
/// plane wherever they all lie inside it.
fn warp_row_affine(
    src: &Plane,
    row: &mut [u8],
    y: usize,
    m: &[f64; 9],
    border: Border,
    table: &[[i32; 4]; PHASES],
) {
    const EXTRA: u32 = 16;
    let scale = (PHASES as f64) * f64::from(1u32 << EXTRA);
    let y = y as f64;
    let (x0, y0) = (m[1] * y + m[2], m[4] * y + m[5]);
    let (w, h) = (src.width() as i64, src.height() as i64);
    // Where every position of the row stays within +-2^40 (a few thousand
    // pixels of a picture), fixed point is exact enough; else the general path.
    let far = |v: f64| v.is_nan() || v.abs() >= 1e6;
    let end = row.len() as f64;
    if [x0, y0, x0 + m[0] * end, y0 + m[3] * end].into_iter().any(far) {
        for (x, out) in row.iter_mut().enumerate() {
            let x = x as f64;
            if let Some(v) = sample(src, m[0] * x + x0, m[3] * x + y0, border, table) {
                *out = v;
            }
        }
        return;
    }
    let (mut fx, mut fy) = ((x0 * scale).round() as i64, (y0 * scale).round() as i64);
    let (dx, dy) = ((m[0] * scale).round() as i64, (m[3] * scale).round() as i64);
    let (shift, mask) = (PHASES.trailing_zeros(), PHASES as i64 - 1);
    let (data, stride) = (src.data(), src.stride() as i64);
    let origin = src.index(0, 0) as i64;
    let half = 1i64 << (EXTRA - 1);
    let round = 1 << (2 * WEIGHT_BITS - 1);
    for (x, out) in row.iter_mut().enumerate() {
        let (px, py) = ((fx + half) >> EXTRA, (fy + half) >> EXTRA);
        let (ix, iy) = ((px >> shift) - 1, (py >> shift) - 1);
        if ix >= 0 && iy >= 0 && ix + 3 < w && iy + 3 < h {
            let (wx, wy) = (&table[(px & mask) as usize], &table[(py & mask) as usize]);
            let at = (origin + iy * stride + ix) as usize;
            // One slice over the 4x4 block: a single bounds check.
            let block = &data[at..at + 3 * stride as usize + 4];
            let tap_row = |j: usize| {
                let r: &[u8; 4] = block[j * stride as usize..][..4].try_into().expect("four taps");
                i32::from(r[0]) * wx[0]
                    + i32::from(r[1]) * wx[1]
                    + i32::from(r[2]) * wx[2]
                    + i32::from(r[3]) * wx[3]
            };
            let acc = tap_row(0) * wy[0] + tap_row(1) * wy[1] + tap_row(2) * wy[2] + tap_row(3) * wy[3];
            *out = ((acc + round) >> (2 * WEIGHT_BITS)).clamp(0, 255) as u8;
        } else {
            let xf = x as f64;
            if let Some(v) = sample(src, m[0] * xf + x0, m[3] * xf + y0, border, table) {
                *out = v;
            }
        }
        fx += dx;
        fy += dy;
    }
}

/// The map of a 4:2:0 chroma plane for the luma map `m`: chroma sample
/// `(x, y)` sits at luma `(2x + 0.5, 2y + 0.5)` (between its four luma
/// samples, as JPEG and MPEG-1 site it).
pub fn chroma_map(m: &[f64; 9]) -> [f64; 9] {
    let to_luma = [2.0, 0.0, 0.5, 0.0, 2.0, 0.5, 0.0, 0.0, 1.0];
    let to_chroma = [0.5, 0.0, -0.25, 0.0, 0.5, -0.25, 0.0, 0.0, 1.0];
    mul(&to_chroma, &mul(m, &to_luma))
}

fn mul(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    std::array::from_fn(|i| (0..3).map(|k| a[i / 3 * 3 + k] * b[k * 3 + i % 3]).sum())
}

/// A `w` x `h` frame (4:2:0) read from `src` through the luma map `map`
/// (chroma through [`chroma_map`]); outside the input,
/// `Border::Constant` gives that luma and neutral chroma.
pub fn warp_frame(src: &Frame, w: usize, h: usize, map: &[f64; 9], border: Border) -> Frame {
    let (cw, ch) = Frame::chroma_size(w, h);
    let cmap = chroma_map(map);
    let chroma_border = match border {
        Border::Constant(_) => Border::Constant(128),
        b => b,
    };
    let y = warp_plane(src.y(), w, h, map, border);
    let u = warp_plane(src.u(), cw, ch, &cmap, chroma_border);
    let v = warp_plane(src.v(), cw, ch, &cmap, chroma_border);
    Frame::from_planes(y, u, v).expect("planes of one frame's sizes")
}

/// [`warp_frame`] into `dst` (the output's size); with [`Border::Keep`],
/// `dst`'s pixels stay where the map leaves the input.
pub fn warp_frame_onto(src: &Frame, dst: &mut Frame, map: &[f64; 9], border: Border) {
    let cmap = chroma_map(map);
    let chroma_border = match border {
        Border::Constant(_) => Border::Constant(128),
        b => b,
    };
    warp_plane_onto(src.y(), dst.plane_mut(0), map, border);
    warp_plane_onto(src.u(), dst.plane_mut(1), &cmap, chroma_border);
    warp_plane_onto(src.v(), dst.plane_mut(2), &cmap, chroma_border);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Plane {
        Plane::from_fn(w, h, |x, y| (x * 3 + y * 2) as u8).unwrap()
    }

    #[test]
    fn identity_and_integer_shift_are_exact() {
        let src = ramp(40, 30);
        let id = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(
            warp_plane(&src, 40, 30, &id, Border::Replicate).to_packed(),
            src.to_packed()
        );
        let shift = [1.0, 0.0, 3.0, 0.0, 1.0, -2.0, 0.0, 0.0, 1.0];
        let out = warp_plane(&src, 40, 30, &shift, Border::Constant(7));
        for y in 0..30 {
            for x in 0..40 {
                let (sx, sy) = (x as isize + 3, y as isize - 2);
                let want = if sx < 40 && sy >= 0 { src.at(sx, sy) } else { 7 };
                assert_eq!(out.get(x, y), want, "({x}, {y})");
            }
        }
    }

    #[test]
    fn half_pixel_shift_of_a_ramp_is_its_midpoint() {
        // Cubic interpolation reproduces a linear ramp exactly.
        let src = ramp(40, 30);
        let half = [1.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let out = warp_plane(&src, 40, 30, &half, Border::Replicate);
        for y in 2..28 {
            for x in 2..36 {
                let want = (f64::from(src.get(x, y)) + f64::from(src.get(x + 1, y))) / 2.0;
                assert!((f64::from(out.get(x, y)) - want).abs() <= 0.5, "({x}, {y})");
            }
        }
    }

    #[test]
    fn chroma_map_of_a_luma_shift_is_half_the_shift() {
        let m = chroma_map(&[1.0, 0.0, 4.0, 0.0, 1.0, -6.0, 0.0, 0.0, 1.0]);
        let want = [1.0, 0.0, 2.0, 0.0, 1.0, -3.0, 0.0, 0.0, 1.0];
        assert!(m.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12), "{m:?}");
    }
}
