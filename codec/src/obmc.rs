//! Overlapped block motion compensation (normative when a frame enables it).
//!
//! Each block of size `B` (16 luma, 8 chroma) has a window of `2B` samples
//! per axis, centred on it, reaching `B/2` into each neighbour. The 1-D
//! window is a raised cosine in integers, `w[n] ~ 64 sin^2(pi (n + 1/2) / 2B)`,
//! built so that the windows of two neighbouring blocks sum to exactly 64
//! at every sample; the 2-D weight is `wx * wy`, so the four windows that
//! overlap at any pixel sum to exactly 4096.
//!
//! A pixel in a quadrant of its block is predicted from four vectors: its
//! block's own, the horizontal neighbour's on that side, the vertical
//! neighbour's, and the diagonal neighbour's, each through the ordinary
//! block predictors of [`interp`](crate::interp), then
//! `(sum of weight * prediction + 2048) >> 12`. A neighbour outside the
//! picture or without a vector (intra) lends the block's own vector.
//!
//! ```
//! use mocomp_codec::obmc::window;
//! let w = window(16);
//! assert_eq!(w.len(), 32);
//! assert!((0..16).all(|n| w[n] + w[n + 16] == 64));
//! ```

use crate::interp::{predict_chroma, predict_luma, LumaFilter};
use crate::mv::Mv;
use crate::picture::Plane;

/// Window for 16-sample blocks: `w[n] = round(64 sin^2(pi (n + 1/2) / 32))`
/// for n < 8, the rest from `w[15 - n] = 64 - w[n]` and
/// `w[n + 16] = 64 - w[n]`. Constants, so that no decoder depends on a
/// maths library's `sin` (a test recomputes them).
const WINDOW_16: [i32; 32] = [
    0, 1, 4, 7, 12, 17, 23, 29, 35, 41, 47, 52, 57, 60, 63, 64, 64, 63, 60, 57, 52, 47, 41, 35, 29, 23, 17,
    12, 7, 4, 1, 0,
];

/// Window for 8-sample blocks, built the same way.
const WINDOW_8: [i32; 16] = [1, 5, 14, 26, 38, 50, 59, 63, 63, 59, 50, 38, 26, 14, 5, 1];

/// The 1-D window for blocks of `size` samples (8 or 16): `2 * size`
/// integer weights, symmetric, with `w[n] + w[n + size] == 64`.
pub fn window(size: usize) -> &'static [i32] {
    match size {
        8 => &WINDOW_8,
        16 => &WINDOW_16,
        _ => {
            assert!(size == 8 || size == 16, "OBMC block size {size}");
            &[]
        }
    }
}

/// The vectors around a block, `None` where there is none (outside the
/// picture or intra): `[row][col]` with the block itself at `[1][1]`.
pub type Neighbourhood = [[Option<Mv>; 3]; 3];

/// OBMC prediction of one block: the block of `size x size` (16 for luma,
/// 8 for chroma) at (x, y) of `reference`'s plane, with `own` its vector and
/// `around` its neighbours'. `chroma` selects the eighth-pel chroma
/// predictor. Writes `out` (row stride `stride`).
#[allow(clippy::too_many_arguments)]
pub fn predict_block(
    reference: &Plane,
    chroma: bool,
    x: isize,
    y: isize,
    size: usize,
    own: Mv,
    around: &Neighbourhood,
    out: &mut [u8],
    stride: usize,
) {
    let w = window(size);
    let half = size / 2;
    let mv_at = |row: usize, col: usize| around[row][col].unwrap_or(own);
    let mut preds = [[0u8; 8 * 8]; 4];
    for qy in 0..2 {
        for qx in 0..2 {
            // The neighbours on this quadrant's sides: column 0 or 2, row 0 or 2.
            let (hc, vr) = (2 * qx, 2 * qy);
            let vectors = [own, mv_at(1, hc), mv_at(vr, 1), mv_at(vr, hc)];
            let (px, py) = (x + (qx * half) as isize, y + (qy * half) as isize);
            for (k, mv) in vectors.iter().enumerate() {
                if chroma {
                    predict_chroma(reference, px, py, mv.x, mv.y, half, half, &mut preds[k], half);
                } else {
                    // OBMC frames interpolate with the sharp filter (FORMAT.md section 3).
                    predict_luma(
                        LumaFilter::Sharp,
                        reference,
                        px,
                        py,
                        mv.x,
                        mv.y,
                        half,
                        half,
                        &mut preds[k],
                        half,
                    );
                }
            }
            for v in 0..half {
                for u in 0..half {
                    // Position in the own window, and in the neighbour's.
                    let (ou, ov) = (qx * half + u + half, qy * half + v + half);
                    let nu = if qx == 0 { ou + size } else { ou - size };
                    let nv = if qy == 0 { ov + size } else { ov - size };
                    let weights = [w[ou] * w[ov], w[nu] * w[ov], w[ou] * w[nv], w[nu] * w[nv]];
                    let i = v * half + u;
                    let sum: i32 = (0..4).map(|k| weights[k] * i32::from(preds[k][i])).sum();
                    out[(qy * half + v) * stride + qx * half + u] = ((sum + 2048) >> 12) as u8;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::picture::PictureError;

    fn noise(w: usize, h: usize) -> Result<Plane, PictureError> {
        Plane::from_fn(w, h, |x, y| (((x * 2_654_435_761) ^ (y * 40_503)) >> 3) as u8)
    }

    #[test]
    fn windows_follow_the_raised_cosine() -> Result<(), PictureError> {
        for size in [8usize, 16] {
            let len = 2 * size;
            let mut w = vec![0i32; len];
            for n in 0..size / 2 {
                let t = std::f64::consts::PI * (n as f64 + 0.5) / len as f64;
                w[n] = (64.0 * t.sin().powi(2)).round() as i32;
                w[size - 1 - n] = 64 - w[n];
            }
            for n in 0..size {
                w[n + size] = 64 - w[n];
            }
            assert_eq!(window(size), &w[..]);
        }
        Ok(())
    }

    #[test]
    fn windows_are_symmetric_and_rise_smoothly() -> Result<(), PictureError> {
        for size in [8, 16] {
            let w = window(size);
            for n in 0..2 * size {
                assert_eq!(w[n], w[2 * size - 1 - n], "symmetry at {n}");
                assert!((0..=64).contains(&w[n]));
            }
            assert!(w[..size].windows(2).all(|p| p[0] <= p[1]), "{w:?}");
        }
        Ok(())
    }

    #[test]
    fn the_four_weights_sum_to_the_unit_at_every_pixel() -> Result<(), PictureError> {
        for size in [8usize, 16] {
            let w = window(size);
            let half = size / 2;
            for y in 0..size {
                for x in 0..size {
                    let (ou, ov) = (x + half, y + half);
                    let nu = if x < half { ou + size } else { ou - size };
                    let nv = if y < half { ov + size } else { ov - size };
                    let total = w[ou] * w[ov] + w[nu] * w[ov] + w[ou] * w[nv] + w[nu] * w[nv];
                    assert_eq!(total, 4096, "size {size} at ({x},{y})");
                }
            }
        }
        Ok(())
    }

    #[test]
    fn equal_vectors_give_plain_motion_compensation() -> Result<(), PictureError> {
        let p = noise(64, 48)?;
        let mv = Mv::new(5, -7);
        let around = [[Some(mv); 3]; 3];
        let (mut obmc, mut plain) = ([0u8; 256], [0u8; 256]);
        predict_block(&p, false, 16, 16, 16, mv, &around, &mut obmc, 16);
        predict_luma(LumaFilter::Sharp, &p, 16, 16, mv.x, mv.y, 16, 16, &mut plain, 16);
        assert_eq!(obmc, plain);
        // Missing neighbours lend the block's own vector.
        let alone = [[None; 3]; 3];
        predict_block(&p, true, 4, 4, 8, mv, &alone, &mut obmc[..64], 8);
        predict_chroma(&p, 4, 4, mv.x, mv.y, 8, 8, &mut plain[..64], 8);
        assert_eq!(obmc[..64], plain[..64]);
        Ok(())
    }

    #[test]
    fn a_neighbours_vector_blends_in_towards_its_side() -> Result<(), PictureError> {
        // Flat picture halves: predictions with the two vectors differ by a
        // constant, so the blend shows the weights directly.
        let p = Plane::from_fn(96, 64, |x, _| if x < 48 { 0 } else { 200 })?;
        let own = Mv::full_pel(-24, 0); // reads x 8..24: 0
        let right = Mv::full_pel(24, 0); // reads x 56..72: 200
        let mut around = [[None; 3]; 3];
        around[1][2] = Some(right);
        let mut out = [0u8; 256];
        predict_block(&p, false, 32, 16, 16, own, &around, &mut out, 16);
        let w = window(16);
        for x in 0..16 {
            // Row 5 sits at index 13 of the vertical window. Left half: the
            // own vector only. Right half: the right neighbour weighs
            // w[x - 8] * w[13]; the missing upper and diagonal neighbours
            // lend the own vector.
            let want = if x < 8 {
                0
            } else {
                (200 * w[x - 8] * w[13] + 2048) >> 12
            };
            assert_eq!(i32::from(out[5 * 16 + x]), want, "x {x}");
        }
        assert!(out[15] > out[12] && out[12] > out[8]);
        Ok(())
    }
}
