//! Pictures of motion: vectors drawn over a frame, and flow fields in the
//! Middlebury colour coding.

use crate::codec::Plane;
use crate::flow::Flow;
use crate::me::MotionField;

/// An RGB picture, 3 bytes per pixel, row after row.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rgb {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `3 * width * height` bytes.
    pub data: Vec<u8>,
}

impl Rgb {
    /// A grey picture from a luma plane.
    pub fn from_luma(plane: &Plane) -> Rgb {
        let mut data = Vec::with_capacity(3 * plane.width() * plane.height());
        for row in plane.rows() {
            for &v in row {
                data.extend_from_slice(&[v, v, v]);
            }
        }
        Rgb {
            width: plane.width(),
            height: plane.height(),
            data,
        }
    }

    /// Sets pixel (x, y) if it is inside the picture.
    pub fn put(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let i = 3 * (y as usize * self.width + x as usize);
            self.data[i..i + 3].copy_from_slice(&colour);
        }
    }

    /// Draws a line from (x0, y0) to (x1, y1) (Bresenham), clipped to the picture.
    pub fn line(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64), colour: [u8; 3]) {
        let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
        let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
        let (mut x, mut y, mut err) = (x0, y0, dx + dy);
        loop {
            self.put(x, y, colour);
            if x == x1 && y == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }
}

/// The frame with each block's vector drawn from the block's centre to
/// where it points in the reference (red), the centre marked (yellow).
pub fn draw_field(frame: &Plane, field: &MotionField) -> Rgb {
    let mut img = Rgb::from_luma(frame);
    let half = field.block() as i64 / 2;
    for r in 0..field.rows() {
        for c in 0..field.cols() {
            let (cx, cy) = (
                c as i64 * field.block() as i64 + half,
                r as i64 * field.block() as i64 + half,
            );
            let v = field.vector(c, r);
            let end = (
                cx + (i64::from(v.x) + 2).div_euclid(4),
                cy + (i64::from(v.y) + 2).div_euclid(4),
            );
            img.line((cx, cy), end, [255, 40, 40]);
            img.put(cx, cy, [255, 230, 0]);
        }
    }
    img
}

/// The frame with an arrow every `step` pixels showing the flow there (the
/// mean over the `step x step` cell, drawn from the cell's centre, scaled by
/// `scale`), red with a yellow head; cells without a valid pixel are skipped.
pub fn draw_flow_arrows(frame: &Plane, flow: &Flow, step: usize, scale: f32) -> Rgb {
    assert!(step > 0, "arrow step must be positive");
    let mut img = Rgb::from_luma(frame);
    for cy in (0..flow.height()).step_by(step) {
        for cx in (0..flow.width()).step_by(step) {
            let (mut su, mut sv, mut n) = (0f32, 0f32, 0usize);
            for y in cy..(cy + step).min(flow.height()) {
                for x in cx..(cx + step).min(flow.width()) {
                    if flow.is_valid(x, y) {
                        let (u, v) = flow.get(x, y);
                        su += u;
                        sv += v;
                        n += 1;
                    }
                }
            }
            if n == 0 {
                continue;
            }
            let (u, v) = (scale * su / n as f32, scale * sv / n as f32);
            let (x0, y0) = ((cx + step / 2) as f32, (cy + step / 2) as f32);
            let (x1, y1) = (x0 + u, y0 + v);
            img.line(
                (x0 as i64, y0 as i64),
                (x1.round() as i64, y1.round() as i64),
                [255, 40, 40],
            );
            // Two barbs at +-25 degrees behind the tip.
            let len = (u * u + v * v).sqrt();
            if len >= 2.0 {
                let (dx, dy) = (u / len, v / len);
                let barb = (len * 0.3).clamp(2.0, 6.0);
                for s in [-1.0f32, 1.0] {
                    let (c, sn) = (0.906f32, 0.423 * s);
                    let (bx, by) = (-(dx * c - dy * sn), -(dx * sn + dy * c));
                    img.line(
                        (x1.round() as i64, y1.round() as i64),
                        ((x1 + barb * bx).round() as i64, (y1 + barb * by).round() as i64),
                        [255, 230, 0],
                    );
                }
            }
        }
    }
    img
}

/// The Middlebury colour wheel (Baker et al., "A Database and Evaluation
/// Methodology for Optical Flow"): 55 hues, red to yellow (15), yellow to
/// green (6), green to cyan (4), cyan to blue (11), blue to magenta (13),
/// magenta to red (6).
fn colour_wheel() -> Vec<[f32; 3]> {
    let mut wheel = Vec::with_capacity(55);
    // Integer steps, as the reference C++ (`255 * i / RY` on ints).
    let ramp = |i: usize, n: usize| (255 * i / n) as f32;
    (0..15).for_each(|i| wheel.push([255.0, ramp(i, 15), 0.0]));
    (0..6).for_each(|i| wheel.push([255.0 - ramp(i, 6), 255.0, 0.0]));
    (0..4).for_each(|i| wheel.push([0.0, 255.0, ramp(i, 4)]));
    (0..11).for_each(|i| wheel.push([0.0, 255.0 - ramp(i, 11), 255.0]));
    (0..13).for_each(|i| wheel.push([ramp(i, 13), 0.0, 255.0]));
    (0..6).for_each(|i| wheel.push([255.0, 0.0, 255.0 - ramp(i, 6)]));
    wheel
}

/// The colour of a motion (u, v) already divided by the normalising radius:
/// hue from the direction, saturation from the length (white at rest, full
/// colour at length 1, darkened beyond), as Middlebury's `computeColor`.
pub fn flow_colour(wheel: &[[f32; 3]], u: f32, v: f32) -> [u8; 3] {
    // Double precision, as the reference code: floor(255 col) sits on
    // integer boundaries for some directions.
    let (u, v) = (f64::from(u), f64::from(v));
    let n = wheel.len();
    let rad = (u * u + v * v).sqrt();
    let a = (-v).atan2(-u) / std::f64::consts::PI;
    let fk = (a + 1.0) / 2.0 * (n - 1) as f64;
    let k0 = (fk.floor() as usize).min(n - 1);
    let k1 = (k0 + 1) % n;
    let f = fk - k0 as f64;
    let mut out = [0u8; 3];
    for c in 0..3 {
        let col = (1.0 - f) * f64::from(wheel[k0][c]) / 255.0 + f * f64::from(wheel[k1][c]) / 255.0;
        let col = if rad <= 1.0 {
            1.0 - rad * (1.0 - col)
        } else {
            col * 0.75
        };
        out[c] = (255.0 * col).floor().clamp(0.0, 255.0) as u8;
    }
    out
}

/// A flow in the Middlebury colour coding, normalised by `max_radius` or,
/// when `None`, by the largest motion among valid pixels. Invalid pixels
/// are black.
pub fn flow_to_rgb(flow: &Flow, max_radius: Option<f32>) -> Rgb {
    let wheel = colour_wheel();
    let norm = max_radius
        .unwrap_or_else(|| flow.max_magnitude())
        .max(f32::EPSILON);
    let (w, h) = (flow.width(), flow.height());
    let mut data = Vec::with_capacity(3 * w * h);
    for y in 0..h {
        for x in 0..w {
            if flow.is_valid(x, y) {
                let (u, v) = flow.get(x, y);
                data.extend_from_slice(&flow_colour(&wheel, u / norm, v / norm));
            } else {
                data.extend_from_slice(&[0, 0, 0]);
            }
        }
    }
    Rgb {
        width: w,
        height: h,
        data,
    }
}

/// Mode colours of the stream overlay, as ffmpeg's `codecview` and
/// analysers use them: skip green, inter blue, intra 16x16 red, intra 8x8
/// magenta, intra 4x4 orange.
fn mode_colour(kind: &str, partition: &str) -> [u8; 3] {
    match (kind, partition) {
        ("skip", _) => [40, 200, 60],
        ("intra", "4x4") => [255, 150, 0],
        ("intra", "8x8") => [220, 40, 200],
        ("intra", _) => [230, 30, 30],
        _ => [40, 110, 255],
    }
}

/// The decoded picture in grey, each macroblock tinted with its mode's
/// colour (a quarter of it), partition edges drawn in it, and each 8x8
/// block's vector drawn from the block's centre (red, to where it points
/// in the reference, x1) for inter and skip macroblocks.
pub fn draw_stream_overlay(frame: &crate::analyze::FrameAnalysis) -> Rgb {
    let mut img = Rgb::from_luma(frame.picture.y());
    for m in &frame.mbs {
        let colour = mode_colour(m.kind, m.partition);
        let (x0, y0) = (16 * m.mb_x, 16 * m.mb_y);
        for y in y0..(y0 + 16).min(img.height) {
            for x in x0..(x0 + 16).min(img.width) {
                let i = 3 * (y * img.width + x);
                for (v, c) in img.data[i..i + 3].iter_mut().zip(colour) {
                    *v = ((u16::from(*v) * 3 + u16::from(c)) / 4) as u8;
                }
            }
        }
        let (x0, y0) = (x0 as i64, y0 as i64);
        img.line((x0, y0), (x0 + 15, y0), colour);
        img.line((x0, y0), (x0, y0 + 15), colour);
        match m.partition {
            "16x8" => img.line((x0, y0 + 8), (x0 + 15, y0 + 8), colour),
            "8x16" => img.line((x0 + 8, y0), (x0 + 8, y0 + 15), colour),
            "8x8" => {
                img.line((x0, y0 + 8), (x0 + 15, y0 + 8), colour);
                img.line((x0 + 8, y0), (x0 + 8, y0 + 15), colour);
            }
            _ => {}
        }
        for (k, v) in m.vectors.iter().enumerate() {
            let Some((vx, vy)) = *v else { continue };
            let (cx, cy) = (x0 + 4 + 8 * (k as i64 % 2), y0 + 4 + 8 * (k as i64 / 2));
            img.line(
                (cx, cy),
                (cx + i64::from(vx) / 4, cy + i64::from(vy) / 4),
                [255, 40, 40],
            );
            img.put(cx, cy, [255, 230, 0]);
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compass_directions_have_the_middlebury_colours() {
        // Expected values from an independent implementation of the same
        // code: the `flow_vis` Python package 0.1, `flow_uv_to_colors` at
        // length 0.9 (y points down, so north is v < 0).
        let want: [(&str, f32, f32, [u8; 3]); 8] = [
            ("E", 1.0, 0.0, [255, 25, 25]),
            ("NE", 1.0, -1.0, [223, 25, 255]),
            ("N", 0.0, -1.0, [104, 25, 255]),
            ("NW", -1.0, -1.0, [25, 72, 255]),
            ("W", -1.0, 0.0, [25, 213, 255]),
            ("SW", -1.0, 1.0, [54, 255, 25]),
            ("S", 0.0, 1.0, [255, 232, 25]),
            ("SE", 1.0, 1.0, [255, 128, 25]),
        ];
        let wheel = colour_wheel();
        assert_eq!(wheel.len(), 55);
        for (name, dx, dy, rgb) in want {
            let n = 0.9 / f32::hypot(dx, dy);
            assert_eq!(flow_colour(&wheel, dx * n, dy * n), rgb, "{name}");
        }
        // No motion is white; beyond the normalising radius colours darken.
        assert_eq!(flow_colour(&wheel, 0.0, 0.0), [255, 255, 255]);
        assert_eq!(flow_colour(&wheel, 2.0, 0.0), [191, 0, 0]);
    }

    #[test]
    fn flow_pictures_normalise_by_the_largest_motion() {
        let flow = Flow::from_fn(2, 1, |x, _| (if x == 0 { 4.0 } else { 2.0 }, 0.0));
        let img = flow_to_rgb(&flow, None);
        // The largest motion is at full saturation: pure red.
        assert_eq!(&img.data[0..3], &[255, 0, 0]);
        assert_eq!(&img.data[3..6], &flow_colour(&colour_wheel(), 0.5, 0.0));
    }

    #[test]
    fn arrows_point_along_the_flow() {
        let frame = Plane::filled(32, 32, 0).unwrap();
        let flow = Flow::from_fn(32, 32, |_, _| (6.0, 0.0));
        let img = draw_flow_arrows(&frame, &flow, 16, 1.0);
        let red =
            |x: usize, y: usize| img.data[3 * (y * 32 + x)] == 255 && img.data[3 * (y * 32 + x) + 1] == 40;
        // From the first cell's centre (8, 8) six pixels to the right.
        assert!((8..14).all(|x| red(x, 8)));
        assert!(!red(7, 8) && !red(8, 9));
    }

    #[test]
    fn lines_cover_their_end_points_and_clip() {
        let mut img = Rgb::from_luma(&Plane::filled(10, 6, 0).unwrap());
        img.line((1, 1), (8, 4), [255, 0, 0]);
        assert_eq!(&img.data[3 * (10 + 1)..3 * (10 + 1) + 3], &[255, 0, 0]);
        assert_eq!(&img.data[3 * (4 * 10 + 8)..3 * (4 * 10 + 8) + 3], &[255, 0, 0]);
        let lit = img.data.chunks(3).filter(|p| p[0] == 255).count();
        assert_eq!(lit, 8, "one pixel per column of a shallow line");
        img.line((-5, -5), (20, 20), [0, 255, 0]); // clipped, no panic
    }
}
