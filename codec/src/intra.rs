//! Intra prediction of a square block from its reconstructed neighbours
//! (normative), after H.264's Intra_16x16 (8.3.3) and chroma (8.3.4) modes.
//!
//! Neighbours are the row above the block (`top`, as wide as the block), the
//! column to its left (`left`, as tall), and the sample above-left; any of
//! them is unavailable at the picture's top or left edge. Modes:
//!
//! * `Vertical`: every row copies `top` (needs `top`).
//! * `Horizontal`: every column copies `left` (needs `left`).
//! * `Dc`: the rounded mean of the available neighbours, `top` and `left`
//!   together, either alone, or 128 when neither exists.
//! * `Plane`: a least-squares plane through the neighbours (needs `top`,
//!   `left` and the corner), H.264's equations for 16x16 luma, and its
//!   8x8 chroma variant for 8x8 blocks.
//!
//! A mode whose neighbours are missing is an error, not a guess.
//!
//! ```
//! use mocomp_codec::intra::{predict, IntraMode, Neighbours};
//! let top = [10u8; 8];
//! let left = [30u8; 8];
//! let n = Neighbours { top: Some(&top), left: Some(&left), top_left: Some(20) };
//! let mut out = [0u8; 64];
//! predict(IntraMode::Dc, 8, &n, &mut out, 8).unwrap();
//! assert!(out.iter().all(|&v| v == 20));
//! ```

use crate::dsp::ipred::ipred;
pub use crate::dsp::ipred::{IntraMode, Neighbours};

/// Why a block cannot be predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum IntraError {
    /// The mode needs a neighbour the block does not have.
    #[error("intra mode {0:?} needs neighbours that are outside the picture")]
    Unavailable(IntraMode),
}

/// Predicts a `size x size` block (`size` 8 or 16) into `out` (row stride
/// `stride`).
pub fn predict(
    mode: IntraMode,
    size: usize,
    n: &Neighbours<'_>,
    out: &mut [u8],
    stride: usize,
) -> Result<(), IntraError> {
    assert!(size == 8 || size == 16, "intra block size {size}");
    assert!(n.top.is_none_or(|t| t.len() >= size) && n.left.is_none_or(|l| l.len() >= size));
    if !mode.is_available(n) {
        return Err(IntraError::Unavailable(mode));
    }
    // Sizes the compiler knows: rows filled and copied by fixed-size
    // moves, not a memset or memcpy call a row.
    let dsp = ipred();
    if size == 16 {
        (dsp.pred_16x16)(mode, n, out, stride);
    } else {
        (dsp.pred_8x8_chroma)(mode, n, out, stride);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(mode: IntraMode, size: usize, n: &Neighbours<'_>) -> Result<Vec<u8>, IntraError> {
        let mut out = vec![0u8; size * size];
        predict(mode, size, n, &mut out, size)?;
        Ok(out)
    }

    #[test]
    fn vertical_and_horizontal_copy() -> Result<(), IntraError> {
        let top: Vec<u8> = (0..16).map(|i| i * 10).collect();
        let left: Vec<u8> = (0..16).map(|i| 255 - i * 3).collect();
        let n = Neighbours {
            top: Some(&top),
            left: Some(&left),
            top_left: None,
        };
        let v = run(IntraMode::Vertical, 16, &n)?;
        let h = run(IntraMode::Horizontal, 16, &n)?;
        for y in 0..16 {
            for x in 0..16 {
                assert_eq!(v[y * 16 + x], top[x]);
                assert_eq!(h[y * 16 + x], left[y]);
            }
        }
        Ok(())
    }

    #[test]
    fn dc_uses_what_is_available() -> Result<(), IntraError> {
        let top = [10u8; 16];
        let mut left = [0u8; 16];
        left[0] = 16; // mean of left alone is 1
        let both = Neighbours {
            top: Some(&top),
            left: Some(&left),
            top_left: None,
        };
        // (160 + 16 + 16) >> 5 = 6
        assert!(run(IntraMode::Dc, 16, &both)?.iter().all(|&v| v == 6));
        let only_left = Neighbours {
            left: Some(&left),
            ..Default::default()
        };
        assert!(run(IntraMode::Dc, 16, &only_left)?.iter().all(|&v| v == 1));
        let only_top = Neighbours {
            top: Some(&top),
            ..Default::default()
        };
        assert!(run(IntraMode::Dc, 8, &only_top)?.iter().all(|&v| v == 10));
        assert!(run(IntraMode::Dc, 8, &Neighbours::default())?
            .iter()
            .all(|&v| v == 128));
        Ok(())
    }

    #[test]
    fn plane_reproduces_a_linear_ramp() -> Result<(), IntraError> {
        // Neighbours sampled from p(x, y) = 50 + 3x + 2y (the corner is p(-1, -1)):
        // both sizes give b = 96, c = 64 and (1616 + 96x + 64y) >> 5 = 50 + 3x + 2y.
        for size in [16usize, 8] {
            let ramp = |x: i32, y: i32| (50 + 3 * x + 2 * y) as u8;
            let top: Vec<u8> = (0..size as i32).map(|x| ramp(x, -1)).collect();
            let left: Vec<u8> = (0..size as i32).map(|y| ramp(-1, y)).collect();
            let n = Neighbours {
                top: Some(&top),
                left: Some(&left),
                top_left: Some(ramp(-1, -1)),
            };
            let out = run(IntraMode::Plane, size, &n)?;
            for y in 0..size {
                for x in 0..size {
                    let want = ramp(x as i32, y as i32) as i32;
                    let got = out[y * size + x] as i32;
                    assert_eq!(got, want, "{size} ({x},{y})");
                }
            }
        }
        Ok(())
    }

    #[test]
    fn plane_is_clipped() -> Result<(), IntraError> {
        // Slopes of 17 per sample in x and y: the plane overshoots 255 towards
        // the bottom-right when rising, and undershoots 0 there when falling.
        let rising: Vec<u8> = (0..16).map(|i| (i * 17) as u8).collect();
        let falling: Vec<u8> = (0..16).map(|i| 255 - (i * 17) as u8).collect();
        for (edge, corner, clip) in [(&rising, 0u8, 255u8), (&falling, 255, 0)] {
            let n = Neighbours {
                top: Some(edge),
                left: Some(edge),
                top_left: Some(corner),
            };
            let out = run(IntraMode::Plane, 16, &n)?;
            for y in 12..16 {
                for x in 12..16 {
                    assert_eq!(out[y * 16 + x], clip, "({x},{y})");
                }
            }
            // Away from the clipped corner the ramp is intact.
            assert!(out[0] != clip && out[0] != 255 - clip);
        }
        Ok(())
    }

    #[test]
    fn missing_neighbours_are_errors() {
        let top = [1u8; 16];
        let only_top = Neighbours {
            top: Some(&top),
            ..Default::default()
        };
        assert_eq!(
            run(IntraMode::Horizontal, 16, &only_top),
            Err(IntraError::Unavailable(IntraMode::Horizontal))
        );
        assert_eq!(
            run(IntraMode::Plane, 16, &only_top),
            Err(IntraError::Unavailable(IntraMode::Plane))
        );
        assert!(run(IntraMode::Vertical, 16, &Neighbours::default()).is_err());
        assert_eq!(IntraMode::from_code(3), Some(IntraMode::Plane));
        assert_eq!(IntraMode::from_code(4), None);
    }
}
