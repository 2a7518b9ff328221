//! Pictures from and to image files (PNG, and whatever the `image` crate
//! reads), in BT.601.
//!
//! * [`read_luma`] gives full-range luma, `Y = 0.299 R + 0.587 G + 0.114 B`
//!   (what OpenCV's `COLOR_RGB2GRAY` gives, so flow is computed on the same
//!   values as the OpenCV peers); a grey image reads back unchanged.
//! * [`read_frame`] gives a 4:2:0 frame in limited ("TV") range, chroma the
//!   mean of each 2x2 block: what `ffmpeg -i in.png -pix_fmt yuv420p` gives.
//! * [`write_plane`] writes a plane as 8-bit grey; [`write_frame`] converts a
//!   limited-range frame back to RGB; [`write_rgb`] writes RGB bytes.
//!
//! The decoder is given size limits, so an image header claiming a huge
//! picture is refused before it is decoded.

use std::io::BufReader;
use std::path::Path;

use image::{ColorType, ExtendedColorType, ImageEncoder, ImageReader, Limits};

use super::OutputFile;
use crate::codec::picture::{check_size, Frame, PictureError, Plane, MAX_DIMENSION};

/// What can go wrong with an image file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// Opening, reading or writing failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The `image` crate could not decode or encode it.
    #[error(transparent)]
    Image(#[from] image::ImageError),
    /// The picture size is out of range.
    #[error(transparent)]
    Size(#[from] PictureError),
}

fn open_rgb(path: &Path) -> Result<image::RgbImage, ImageError> {
    let file = std::fs::File::open(path)?;
    let mut reader = ImageReader::new(BufReader::new(file)).with_guessed_format()?;
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_DIMENSION as u32);
    limits.max_image_height = Some(MAX_DIMENSION as u32);
    reader.limits(limits);
    let img = reader.decode()?;
    check_size(img.width() as usize, img.height() as usize)?;
    Ok(img.into_rgb8())
}

/// BT.601 luma of an RGB triple, full range, rounded.
#[inline]
fn luma_full(r: u8, g: u8, b: u8) -> u8 {
    // 16-bit fixed point; the weights sum to 65536 so grey maps to itself.
    ((19595 * r as u32 + 38470 * g as u32 + 7471 * b as u32 + 32768) >> 16) as u8
}

/// Full-range BT.601 luma of an image file.
pub fn read_luma(path: &Path) -> Result<Plane, ImageError> {
    let rgb = open_rgb(path)?;
    Ok(luma_from_rgb(
        rgb.width() as usize,
        rgb.height() as usize,
        rgb.as_raw(),
    )?)
}

/// Full-range BT.601 luma of packed RGB bytes (what [`read_luma`] gives
/// for the same pixels).
pub fn luma_from_rgb(width: usize, height: usize, rgb: &[u8]) -> Result<Plane, PictureError> {
    check_size(width, height)?;
    check_rgb_len(width, height, rgb)?;
    let mut plane = Plane::new(width, height)?;
    for (row, src) in plane.rows_mut().zip(rgb.chunks_exact(3 * width)) {
        for (d, px) in row.iter_mut().zip(src.chunks_exact(3)) {
            *d = luma_full(px[0], px[1], px[2]);
        }
    }
    plane.extend_border();
    Ok(plane)
}

/// Limited-range BT.601 Y, Cb, Cr (as floats) of an RGB triple.
#[inline]
fn ycbcr_limited(r: f32, g: f32, b: f32) -> (f32, f32, f32) {
    let y = 0.299 * r + 0.587 * g + 0.114 * b;
    (
        16.0 + y * (219.0 / 255.0),
        128.0 + (b - y) * (224.0 / 255.0 / 1.772),
        128.0 + (r - y) * (224.0 / 255.0 / 1.402),
    )
}

#[inline]
fn to_u8(v: f32) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

/// A limited-range BT.601 4:2:0 frame from an image file.
pub fn read_frame(path: &Path) -> Result<Frame, ImageError> {
    let rgb = open_rgb(path)?;
    Ok(frame_from_rgb(
        rgb.width() as usize,
        rgb.height() as usize,
        rgb.as_raw(),
    )?)
}

fn check_rgb_len(width: usize, height: usize, rgb: &[u8]) -> Result<(), PictureError> {
    if rgb.len() != 3 * width * height {
        return Err(PictureError::DataLength {
            width,
            height,
            expected: 3 * width * height,
            actual: rgb.len(),
        });
    }
    Ok(())
}

/// A limited-range BT.601 4:2:0 frame from packed RGB bytes; chroma is the
/// mean over each 2x2 block (edge pixels repeated for odd sizes).
pub fn frame_from_rgb(width: usize, height: usize, rgb: &[u8]) -> Result<Frame, PictureError> {
    check_size(width, height)?;
    check_rgb_len(width, height, rgb)?;
    let mut frame = Frame::new(width, height)?;
    let px = |x: usize, y: usize| {
        let i = 3 * (y.min(height - 1) * width + x.min(width - 1));
        ycbcr_limited(rgb[i] as f32, rgb[i + 1] as f32, rgb[i + 2] as f32)
    };
    for (y, row) in frame.plane_mut(0).rows_mut().enumerate() {
        for (x, d) in row.iter_mut().enumerate() {
            *d = to_u8(px(x, y).0);
        }
    }
    let (cw, ch) = Frame::chroma_size(width, height);
    for cy in 0..ch {
        for cx in 0..cw {
            let (mut cb, mut cr) = (0.0, 0.0);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (_, b, r) = px(2 * cx + dx, 2 * cy + dy);
                cb += b;
                cr += r;
            }
            frame.plane_mut(1).set(cx, cy, to_u8(cb / 4.0));
            frame.plane_mut(2).set(cx, cy, to_u8(cr / 4.0));
        }
    }
    frame.extend_borders();
    Ok(frame)
}

/// Packed RGB bytes of a limited-range BT.601 4:2:0 frame (chroma repeated
/// over its 2x2 block).
pub fn frame_to_rgb(frame: &Frame) -> Vec<u8> {
    let (w, h) = (frame.width(), frame.height());
    let mut out = Vec::with_capacity(3 * w * h);
    for y in 0..h {
        let (ly, cb, cr) = (frame.y().row(y), frame.u().row(y / 2), frame.v().row(y / 2));
        for x in 0..w {
            let yf = (ly[x] as f32 - 16.0) * (255.0 / 219.0);
            let b = (cb[x / 2] as f32 - 128.0) * (255.0 / 224.0);
            let r = (cr[x / 2] as f32 - 128.0) * (255.0 / 224.0);
            out.push(to_u8(yf + 1.402 * r));
            out.push(to_u8(yf - 0.344_136 * b - 0.714_136 * r));
            out.push(to_u8(yf + 1.772 * b));
        }
    }
    out
}

fn write_png(
    path: &Path,
    width: usize,
    height: usize,
    bytes: &[u8],
    color: ColorType,
) -> Result<(), ImageError> {
    check_size(width, height)?;
    let mut out = OutputFile::create(path)?;
    image::codecs::png::PngEncoder::new(&mut out).write_image(
        bytes,
        width as u32,
        height as u32,
        ExtendedColorType::from(color),
    )?;
    out.commit()?;
    Ok(())
}

/// Writes a plane as an 8-bit grey PNG.
pub fn write_plane(path: &Path, plane: &Plane) -> Result<(), ImageError> {
    write_png(
        path,
        plane.width(),
        plane.height(),
        &plane.to_packed(),
        ColorType::L8,
    )
}

/// Writes a limited-range 4:2:0 frame as an RGB PNG.
pub fn write_frame(path: &Path, frame: &Frame) -> Result<(), ImageError> {
    write_png(
        path,
        frame.width(),
        frame.height(),
        &frame_to_rgb(frame),
        ColorType::Rgb8,
    )
}

/// Writes packed RGB bytes (`3 * width * height`) as a PNG.
pub fn write_rgb(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<(), ImageError> {
    check_rgb_len(width, height, rgb)?;
    write_png(path, width, height, rgb, ColorType::Rgb8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_is_its_own_luma() {
        for v in 0..=255u8 {
            assert_eq!(luma_full(v, v, v), v);
        }
    }

    #[test]
    fn primaries_have_bt601_luma() {
        assert_eq!(luma_full(255, 0, 0), 76); // 0.299 * 255 = 76.2
        assert_eq!(luma_full(0, 255, 0), 150); // 0.587 * 255 = 149.7
        assert_eq!(luma_full(0, 0, 255), 29); // 0.114 * 255 = 29.1
    }

    #[test]
    fn limited_range_levels() {
        let white = ycbcr_limited(255.0, 255.0, 255.0);
        let black = ycbcr_limited(0.0, 0.0, 0.0);
        assert_eq!((to_u8(white.0), to_u8(white.1), to_u8(white.2)), (235, 128, 128));
        assert_eq!((to_u8(black.0), to_u8(black.1), to_u8(black.2)), (16, 128, 128));
        // Saturated blue has the largest Cb: 240.
        assert_eq!(to_u8(ycbcr_limited(0.0, 0.0, 255.0).1), 240);
    }

    #[test]
    fn rgb_round_trip_is_close() -> Result<(), PictureError> {
        let (w, h) = (6, 4);
        // Flat 2x2 blocks, so chroma subsampling loses nothing.
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w / 2, i / w / 2);
                [
                    (40 + 60 * x) as u8,
                    (200 - 50 * y) as u8,
                    (90 + 30 * x + 20 * y) as u8,
                ]
            })
            .collect();
        let back = frame_to_rgb(&frame_from_rgb(w, h, &rgb)?);
        for (a, b) in rgb.iter().zip(&back) {
            assert!((*a as i32 - *b as i32).abs() <= 2, "{a} vs {b}");
        }
        Ok(())
    }
}
