//! Dense motion from a coded grid (normative when a frame uses it): how a
//! dense optical flow becomes a predictor.
//!
//! A [`MotionGrid`] holds quarter-pel vectors at nodes every `spacing`
//! pixels (4, 8 or 16): node (i, j) sits on luma pixel (i * spacing,
//! j * spacing), and there is one more node than cells in each direction so
//! that every pixel lies inside a cell. A luma pixel's motion is the
//! bilinear interpolation of its cell's four nodes, in integers and rounded
//! to quarter-pel:
//!
//! `m = floor((sum of (S - fx or fx)(S - fy or fy) v + S^2 / 2) / S^2)`,
//!
//! with `S` the spacing and (fx, fy) the pixel's offset in its cell. The
//! pixel is then predicted exactly as a 1x1 block with vector `m` by the
//! block predictors of [`interp`](crate::interp) (8-tap luma); chroma sample
//! (cx, cy) takes the motion of luma pixel (2cx, 2cy) as its eighth-pel
//! vector. A constant grid therefore predicts exactly what block motion
//! compensation with that vector does.
//!
//! ```
//! use mocomp_codec::mv::Mv;
//! use mocomp_codec::warp::MotionGrid;
//! let mut g = MotionGrid::new(33, 17, 16).unwrap();
//! assert_eq!((g.cols(), g.rows()), (4, 3));
//! g.set(1, 0, Mv::new(16, 0));
//! // Half way between nodes 0 (zero) and 1 (16): 8.
//! assert_eq!(g.pixel_motion(8, 0), Mv::new(8, 0));
//! assert_eq!(g.pixel_motion(16, 0), Mv::new(16, 0));
//! ```

use crate::interp::{predict_chroma, predict_luma, LumaFilter, MAX_BLOCK};
use crate::mv::Mv;
use crate::picture::{check_size, Frame, PictureError, Plane};

pub use crate::consts::SPACINGS;

/// Quarter-pel vectors on a regular grid of nodes over a picture.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MotionGrid {
    spacing: usize,
    cols: usize,
    rows: usize,
    vectors: Vec<Mv>,
}

/// Why a grid cannot be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GridError {
    /// Spacing other than 4, 8 or 16.
    #[error("motion grid spacing {0} is not 4, 8 or 16")]
    Spacing(usize),
    /// Bad picture size.
    #[error(transparent)]
    Size(#[from] PictureError),
}

impl MotionGrid {
    /// A zero grid for a `width x height` picture.
    pub fn new(width: usize, height: usize, spacing: usize) -> Result<MotionGrid, GridError> {
        check_size(width, height)?;
        if !SPACINGS.contains(&spacing) {
            return Err(GridError::Spacing(spacing));
        }
        let (cols, rows) = ((width - 1) / spacing + 2, (height - 1) / spacing + 2);
        Ok(MotionGrid {
            spacing,
            cols,
            rows,
            vectors: vec![Mv::ZERO; cols * rows],
        })
    }

    /// Node spacing in luma pixels.
    pub fn spacing(&self) -> usize {
        self.spacing
    }

    /// Nodes per row.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Rows of nodes.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The vector at node (col, row).
    pub fn get(&self, col: usize, row: usize) -> Mv {
        self.vectors[row * self.cols + col]
    }

    /// Sets the vector at node (col, row).
    pub fn set(&mut self, col: usize, row: usize, mv: Mv) {
        self.vectors[row * self.cols + col] = mv;
    }

    /// All node vectors, row after row.
    pub fn vectors(&self) -> &[Mv] {
        &self.vectors
    }

    /// The quarter-pel motion of luma pixel (x, y) (inside the picture the
    /// grid was made for).
    pub fn pixel_motion(&self, x: usize, y: usize) -> Mv {
        let s = self.spacing as i64;
        let (i, j) = (x / self.spacing, y / self.spacing);
        let (fx, fy) = ((x % self.spacing) as i64, (y % self.spacing) as i64);
        let weights = [(s - fx) * (s - fy), fx * (s - fy), (s - fx) * fy, fx * fy];
        let nodes = [
            self.get(i, j),
            self.get(i + 1, j),
            self.get(i, j + 1),
            self.get(i + 1, j + 1),
        ];
        let shift = 2 * self.spacing.trailing_zeros();
        let round = 1i64 << (shift - 1);
        let axis = |f: fn(&Mv) -> i32| {
            let sum: i64 = weights.iter().zip(&nodes).map(|(w, v)| w * i64::from(f(v))).sum();
            ((sum + round) >> shift) as i32
        };
        Mv::new(axis(|v| v.x), axis(|v| v.y))
    }
}

/// Predicts every plane of `out` from `reference` warped by `grid`. Both
/// frames have the grid's picture size.
pub fn warp_frame(reference: &Frame, grid: &MotionGrid, out: &mut Frame) {
    assert!(
        reference.width() == out.width() && reference.height() == out.height(),
        "warp_frame: frame sizes differ"
    );
    let (w, h) = (out.width(), out.height());
    // Luma: runs of pixels with equal motion go through the block predictor together.
    let mut motion = vec![Mv::ZERO; w];
    for y in 0..h {
        for (x, m) in motion.iter_mut().enumerate() {
            *m = grid.pixel_motion(x, y);
        }
        let row = out.plane_mut(0).row_mut(y);
        for_runs(&motion, longest_run(reference.y()), |start, len, mv| {
            // Grid frames interpolate with the sharp filter (FORMAT.md
            // section 3).
            predict_luma(
                LumaFilter::Sharp,
                reference.y(),
                start as isize,
                y as isize,
                mv.x,
                mv.y,
                len,
                1,
                &mut row[start..start + len],
                len,
            );
        });
    }
    let (cw, ch) = Frame::chroma_size(w, h);
    for cy in 0..ch {
        motion.truncate(cw);
        for (cx, m) in motion.iter_mut().enumerate() {
            *m = grid.pixel_motion(2 * cx, 2 * cy);
        }
        for p in 1..3 {
            let row = out.plane_mut(p).row_mut(cy);
            for_runs(&motion, longest_run(reference.plane(p)), |start, len, mv| {
                predict_chroma(
                    reference.plane(p),
                    start as isize,
                    cy as isize,
                    mv.x,
                    mv.y,
                    len,
                    1,
                    &mut row[start..start + len],
                    len,
                );
            });
        }
        motion.resize(w, Mv::ZERO);
    }
    out.extend_borders();
}

/// The longest block the predictors take from `plane`: they need a border
/// of the block's size plus 8 (a chroma plane's default border is 48).
fn longest_run(plane: &Plane) -> usize {
    MAX_BLOCK.min(plane.pad().saturating_sub(8)).max(1)
}

/// Calls `f(start, len, mv)` for each run of equal vectors (at most `longest`
/// long).
fn for_runs(motion: &[Mv], longest: usize, mut f: impl FnMut(usize, usize, Mv)) {
    let mut start = 0;
    while start < motion.len() {
        let mv = motion[start];
        let mut end = start + 1;
        while end < motion.len() && motion[end] == mv && end - start < longest {
            end += 1;
        }
        f(start, end - start, mv);
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Noise in a frame with the default borders (96 luma, 48 chroma), as
    /// the decoder's reference has.
    fn noise_frame(w: usize, h: usize) -> Result<Frame, PictureError> {
        let mut f = Frame::new(w, h)?;
        for (p, plane) in f.planes_mut().iter_mut().enumerate() {
            for y in 0..plane.height() {
                for x in 0..plane.width() {
                    plane.set(x, y, (((x * 2_654_435_761) ^ (y * 40_503) ^ (p + 1)) >> 5) as u8);
                }
            }
        }
        f.extend_borders();
        Ok(f)
    }

    #[test]
    fn grid_sizes_cover_the_picture() -> Result<(), GridError> {
        for (w, h, s, cols, rows) in [
            (1, 1, 4, 2, 2),
            (16, 16, 16, 2, 2),
            (17, 16, 16, 3, 2),
            (352, 288, 8, 45, 37),
        ] {
            let g = MotionGrid::new(w, h, s)?;
            assert_eq!((g.cols(), g.rows()), (cols, rows), "{w}x{h}/{s}");
            assert!((g.cols() - 1) * s >= w - 1 && (g.rows() - 1) * s >= h - 1);
        }
        assert_eq!(MotionGrid::new(8, 8, 5), Err(GridError::Spacing(5)));
        assert!(MotionGrid::new(0, 8, 4).is_err());
        Ok(())
    }

    #[test]
    fn pixel_motion_is_exact_at_nodes_and_linear_between() -> Result<(), GridError> {
        let mut g = MotionGrid::new(64, 64, 8)?;
        // A linear field v = (4i - 2j, 3j) on the nodes.
        for j in 0..g.rows() {
            for i in 0..g.cols() {
                g.set(i, j, Mv::new(4 * i as i32 - 2 * j as i32, 3 * j as i32));
            }
        }
        for y in 0..64 {
            for x in 0..64 {
                // Bilinear interpolation of a linear field is the field itself:
                // (4x - 2y) / 8 and 3y / 8 quarter-pel, rounded half up.
                let want = |num: i64| ((num + 4).div_euclid(8)) as i32;
                let m = g.pixel_motion(x, y);
                assert_eq!(
                    m,
                    Mv::new(want(4 * x as i64 - 2 * y as i64), want(3 * y as i64)),
                    "({x},{y})"
                );
            }
        }
        Ok(())
    }

    #[test]
    fn a_constant_grid_equals_block_motion_compensation() -> Result<(), GridError> {
        // Wide enough for runs of equal chroma vectors longer than the
        // chroma border allows in one block (88 > 48 - 8).
        let (w, h) = (176, 40);
        let reference = noise_frame(w, h)?;
        for spacing in SPACINGS {
            for mv in [Mv::new(0, 0), Mv::new(5, -3), Mv::new(-13, 22), Mv::new(400, -7)] {
                let mut grid = MotionGrid::new(w, h, spacing)?;
                for j in 0..grid.rows() {
                    for i in 0..grid.cols() {
                        grid.set(i, j, mv);
                    }
                }
                let mut warped = Frame::new(w, h)?;
                warp_frame(&reference, &grid, &mut warped);
                let mut block = Frame::new(w, h)?;
                for by in (0..h).step_by(8) {
                    for bx in (0..w).step_by(16) {
                        let mut buf = [0u8; 16 * 8];
                        predict_luma(
                            LumaFilter::Sharp,
                            reference.y(),
                            bx as isize,
                            by as isize,
                            mv.x,
                            mv.y,
                            16,
                            8,
                            &mut buf,
                            16,
                        );
                        for r in 0..8 {
                            block.plane_mut(0).row_mut(by + r)[bx..bx + 16]
                                .copy_from_slice(&buf[r * 16..r * 16 + 16]);
                        }
                        for p in 1..3 {
                            predict_chroma(
                                reference.plane(p),
                                bx as isize / 2,
                                by as isize / 2,
                                mv.x,
                                mv.y,
                                8,
                                4,
                                &mut buf,
                                8,
                            );
                            for r in 0..4 {
                                block.plane_mut(p).row_mut(by / 2 + r)[bx / 2..bx / 2 + 8]
                                    .copy_from_slice(&buf[r * 8..r * 8 + 8]);
                            }
                        }
                    }
                }
                assert_eq!(warped, block, "spacing {spacing}, mv {mv:?}");
            }
        }
        Ok(())
    }

    #[test]
    fn odd_sizes_and_wild_vectors_do_not_fail() -> Result<(), GridError> {
        let reference = noise_frame(7, 5)?;
        let mut grid = MotionGrid::new(7, 5, 4)?;
        grid.set(0, 0, Mv::new(crate::mv::MV_LIMIT, -crate::mv::MV_LIMIT));
        grid.set(2, 1, Mv::new(-crate::mv::MV_LIMIT, 3));
        let mut out = Frame::new(7, 5)?;
        warp_frame(&reference, &grid, &mut out);
        Ok(())
    }
}
