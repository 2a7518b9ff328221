//! Pictures of motion: vectors drawn over a frame.

use crate::codec::Plane;
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

#[cfg(test)]
mod tests {
    use super::*;

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
