//! Intra prediction of luma in 4x4 blocks (normative, FORMAT.md section
//! 9.1), H.264's Intra_4x4 (its clause 8.3.1): nine directional modes, the
//! blocks in coding order, each predicted from the reconstruction of the
//! blocks before it (its own macroblock's included), and the most probable
//! mode its coding predicts.
//!
//! Edges are the eight samples above the block (four above, four above
//! right), the four to its left and the corner. Samples above right that
//! are not decoded yet repeat the last one above, as in H.264.
//!
//! ```
//! use mocomp_codec::intra4x4::{predict, Edges, Intra4x4Mode};
//! let e = Edges { top: Some([10, 20, 30, 40, 50, 60, 70, 80]), left: Some([1, 2, 3, 4]), top_left: Some(0) };
//! let mut out = [0u8; 16];
//! predict(Intra4x4Mode::Vertical, &e, &mut out);
//! assert_eq!(&out[12..], &[10, 20, 30, 40]);
//! ```

use crate::consts::MB;
use crate::intra::IntraMode;
use crate::picture::Plane;
use crate::transform::Block4;

use crate::dsp::ipred::ipred;
pub use crate::dsp::ipred::{Edges, Intra4x4Mode, ModeSource4};

/// How a macroblock's luma is intra-predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LumaIntra {
    /// As one 16x16 block, in this mode (section 9).
    Whole(IntraMode),
    /// In 4x4 blocks, with these modes (raster order of the blocks).
    Blocks([Intra4x4Mode; 16]),
    /// In 8x8 blocks (section 9.2), with these modes (raster order of the
    /// blocks), the residual in the 8x8 transform.
    Blocks8([Intra4x4Mode; 4]),
}

impl LumaIntra {
    /// The mode of each 4x4 block (raster order) as the blocks of the
    /// macroblocks after it see them: its own in 4x4 blocks, its 8x8
    /// block's in 8x8 blocks, `None` for a 16x16 mode (which they count as
    /// DC).
    pub fn modes4(&self) -> Option<[Intra4x4Mode; 16]> {
        match self {
            LumaIntra::Whole(_) => None,
            LumaIntra::Blocks(modes) => Some(*modes),
            LumaIntra::Blocks8(modes) => Some(spread8(modes)),
        }
    }
}

/// Each 8x8 block's mode on its four 4x4 blocks (raster order).
pub fn spread8(modes: &[Intra4x4Mode; 4]) -> [Intra4x4Mode; 16] {
    std::array::from_fn(|k| modes[(k / 8) * 2 + (k % 4) / 2])
}

/// Raster index (block k covers luma `(4 (k % 4), 4 (k / 4))` onwards) of
/// the blocks in coding order: the 8x8 quadrants in raster order, each
/// quadrant's four blocks in raster order.
pub const CODING_ORDER: [usize; 16] = [0, 1, 4, 5, 2, 3, 6, 7, 8, 9, 12, 13, 10, 11, 14, 15];

/// Position in coding order of each raster block.
const CODING_POSITION: [usize; 16] = {
    let mut p = [0; 16];
    let mut i = 0;
    while i < 16 {
        p[CODING_ORDER[i]] = i;
        i += 1;
    }
    p
};

/// Which neighbours raster block `k` of macroblock (mb_x, mb_y) has in a
/// picture `mb_cols` macroblocks wide: (above, left, above right decoded).
pub fn neighbours(k: usize, mb_x: usize, mb_y: usize, mb_cols: usize) -> (bool, bool, bool) {
    let (i, j) = (k % 4, k / 4);
    let above = j > 0 || mb_y > 0;
    let left = i > 0 || mb_x > 0;
    let above_right = match (i, j) {
        (3, 0) => mb_y > 0 && mb_x + 1 < mb_cols,
        (_, 0) => mb_y > 0,
        (3, _) => false,
        _ => CODING_POSITION[k - 3] < CODING_POSITION[k],
    };
    (above, left, above_right)
}

/// The edges of raster block `k` of macroblock (mb_x, mb_y): samples
/// outside the macroblock from `recon` (the luma reconstructed so far),
/// inside it from `own` (the macroblock's blocks reconstructed so far,
/// 16x16 row-major).
pub fn edges(recon: &Plane, own: &[u8; 256], mb_x: usize, mb_y: usize, k: usize) -> Edges {
    let available = neighbours(k, mb_x, mb_y, recon.width() / MB);
    let (top, left, top_left) =
        block_edges::<4, 8>(recon, own, (mb_x, mb_y), (4 * (k % 4), 4 * (k / 4)), available);
    Edges { top, left, top_left }
}

/// The `T = 2 N` samples above the `N x N` block at (bx, by) of macroblock
/// (mb_x, mb_y) (the `N`-th repeated past it without `above_right`), the
/// `N` to its left and the one above-left, each where available: inside
/// the macroblock from `own` (16x16 row-major), outside from `recon`.
/// Read as slices of the two sources, not sample by sample: a block
/// search gathers the edges of every block it tries.
pub(crate) fn block_edges<const N: usize, const T: usize>(
    recon: &Plane,
    own: &[u8; 256],
    (mb_x, mb_y): (usize, usize),
    (bx, by): (usize, usize),
    (above, left, above_right): (bool, bool, bool),
) -> (Option<[u8; T]>, Option<[u8; N]>, Option<u8>) {
    let (mx, my) = (mb_x * MB, mb_y * MB);
    let top = above.then(|| {
        let row = if by > 0 {
            &own[(by - 1) * MB + bx..]
        } else {
            &recon.row(my - 1)[mx + bx..]
        };
        let mut t = [row[N - 1]; T];
        let n = if above_right { T } else { N };
        t[..n].copy_from_slice(&row[..n]);
        t
    });
    let left_col = left.then(|| {
        std::array::from_fn(|r| {
            if bx > 0 {
                own[(by + r) * MB + bx - 1]
            } else {
                recon.row(my + by + r)[mx - 1]
            }
        })
    });
    let top_left = (above && left).then(|| match (bx > 0, by > 0) {
        (true, true) => own[(by - 1) * MB + bx - 1],
        _ => recon.row(my + by - 1)[mx + bx - 1],
    });
    (top, left_col, top_left)
}

/// Sample (x, y) relative to macroblock (mb_x, mb_y) (-1 is left of or
/// above it) as intra prediction reads it: the macroblock's `own` samples
/// (16x16 row-major) inside it, `recon`'s outside.
#[cfg(test)]
pub(crate) fn mb_sampler<'a>(
    recon: &'a Plane,
    own: &'a [u8; 256],
    mb_x: usize,
    mb_y: usize,
) -> impl Fn(isize, isize) -> u8 + 'a {
    let (mx, my) = ((mb_x * MB) as isize, (mb_y * MB) as isize);
    move |x, y| {
        if x >= 0 && y >= 0 && x < MB as isize {
            own[y as usize * MB + x as usize]
        } else {
            recon.get((mx + x) as usize, (my + y) as usize)
        }
    }
}

/// Predicts a 4x4 block in `mode` into `out` (row-major). The mode must be
/// available with these edges ([`Intra4x4Mode::is_available`]); panics
/// otherwise.
pub fn predict(mode: Intra4x4Mode, e: &Edges, out: &mut [u8; 16]) {
    let (needs_top, needs_left) = mode.needs();
    assert!(
        (e.top.is_some() || !needs_top)
            && (e.left.is_some() || !needs_left)
            && (e.top_left.is_some() || !(needs_top && needs_left)),
        "4x4 intra mode {mode:?} without its neighbours"
    );
    (ipred().pred_4x4)(mode, e, out);
}

/// The most probable mode of a block from the modes of the blocks left of
/// and above it (`None` outside the picture; DC for a block of a
/// macroblock not coded in 4x4 blocks): the lower of the two, DC when
/// either is outside.
pub fn most_probable(left: Option<Intra4x4Mode>, above: Option<Intra4x4Mode>) -> Intra4x4Mode {
    match (left, above) {
        (Some(a), Some(b)) => a.min(b),
        _ => Intra4x4Mode::Dc,
    }
}

/// The modes of the blocks left of and above raster block `k` of a
/// macroblock whose own blocks have `own` modes (those before `k` in coding
/// order decided), given the neighbour macroblocks' modes (`None` outside
/// the picture; all DC when not coded in 4x4 blocks).
pub fn neighbour_modes(
    k: usize,
    own: &[Intra4x4Mode; 16],
    left_mb: Option<&[Intra4x4Mode; 16]>,
    above_mb: Option<&[Intra4x4Mode; 16]>,
) -> (Option<Intra4x4Mode>, Option<Intra4x4Mode>) {
    let (i, j) = (k % 4, k / 4);
    let left = if i > 0 {
        Some(own[k - 1])
    } else {
        left_mb.map(|m| m[k + 3])
    };
    let above = if j > 0 {
        Some(own[k - 4])
    } else {
        above_mb.map(|m| m[12 + i])
    };
    (left, above)
}

/// The luma prediction of a macroblock coded in 4x4 blocks: each block, in
/// coding order, predicted in its mode from the reconstruction before it:
/// `recon` (the picture so far) outside the macroblock, inside it the
/// blocks before, each its prediction plus its levels (`add` adds one
/// block's levels to a 16x16 buffer at a block position, as
/// reconstruction does). The macroblock's reconstruction is this
/// prediction plus the same levels.
pub fn predict_mb(
    recon: &Plane,
    (mb_x, mb_y): (usize, usize),
    modes: &[Intra4x4Mode; 16],
    levels: &[Block4; 16],
    add: impl Fn(&Block4, &mut [u8; 256], (usize, usize)),
) -> [u8; 256] {
    let mut own = [0u8; 256];
    let mut pred = [0u8; 256];
    for &k in &CODING_ORDER {
        let mut block = [0u8; 16];
        predict(modes[k], &edges(recon, &own, mb_x, mb_y, k), &mut block);
        let (bx, by) = (4 * (k % 4), 4 * (k / 4));
        for r in 0..4 {
            let i = (by + r) * MB + bx;
            own[i..i + 4].copy_from_slice(&block[r * 4..r * 4 + 4]);
            pred[i..i + 4].copy_from_slice(&block[r * 4..r * 4 + 4]);
        }
        add(&levels[k], &mut own, (bx, by));
    }
    pred
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`edges`] written sample by sample through [`mb_sampler`].
    fn edges_sampled(recon: &Plane, own: &[u8; 256], mb_x: usize, mb_y: usize, k: usize) -> Edges {
        let (above, left, above_right) = neighbours(k, mb_x, mb_y, recon.width() / MB);
        let at = mb_sampler(recon, own, mb_x, mb_y);
        let (bx, by) = (4 * (k % 4) as isize, 4 * (k / 4) as isize);
        let top = above.then(|| {
            std::array::from_fn(|c| {
                let c = c as isize;
                at(bx + if c < 4 || above_right { c } else { 3 }, by - 1)
            })
        });
        Edges {
            top,
            left: left.then(|| [0, 1, 2, 3].map(|r| at(bx - 1, by + r))),
            top_left: (above && left).then(|| at(bx - 1, by - 1)),
        }
    }

    #[test]
    fn edges_read_as_slices_are_the_samples_beside_the_block() {
        let recon = Plane::from_fn(48, 48, |x, y| ((x * 37 + y * 101) % 251) as u8).unwrap();
        let own: [u8; 256] = std::array::from_fn(|i| (i * 7 % 253) as u8);
        for (mb_x, mb_y) in [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1), (0, 2), (2, 2)] {
            for k in 0..16 {
                assert_eq!(
                    edges(&recon, &own, mb_x, mb_y, k),
                    edges_sampled(&recon, &own, mb_x, mb_y, k),
                    "block {k} of macroblock ({mb_x}, {mb_y})"
                );
            }
        }
    }

    fn edges_of(top: [u8; 8], left: [u8; 4], corner: u8) -> Edges {
        Edges {
            top: Some(top),
            left: Some(left),
            top_left: Some(corner),
        }
    }

    #[test]
    fn hand_computed_predictions() {
        // Above: A..H = 10, 20, ..., 80; left: I..L = 1, 2, 3, 4; corner M = 0.
        let e = edges_of([10, 20, 30, 40, 50, 60, 70, 80], [1, 2, 3, 4], 0);
        let mut out = [0u8; 16];
        predict(Intra4x4Mode::Horizontal, &e, &mut out);
        assert_eq!(out, [1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4]);
        predict(Intra4x4Mode::Dc, &e, &mut out);
        assert!(out.iter().all(|&v| v == 14)); // (100 + 10 + 4) >> 3
                                               // Down-left: (A + 2B + C + 2) >> 2 = 20 at (0, 0); (G + 3H + 2) >> 2 = 78 at (3, 3).
        predict(Intra4x4Mode::DiagonalDownLeft, &e, &mut out);
        assert_eq!((out[0], out[1], out[5], out[15]), (20, 30, 40, 78));
        // Down-right: (A + 2M + I + 2) >> 2 on the diagonal; (M + 2A + B + 2) >> 2 right of it.
        predict(Intra4x4Mode::DiagonalDownRight, &e, &mut out);
        assert_eq!((out[0], out[1], out[4], out[15]), (3, 10, 1, 3));
        // Vertical-left: (A + B + 1) >> 1 in row 0, (A + 2B + C + 2) >> 2 in row 1.
        predict(Intra4x4Mode::VerticalLeft, &e, &mut out);
        assert_eq!((out[0], out[4], out[8], out[15]), (15, 20, 25, 60));
        // Horizontal-up: past the bottom of the column, L.
        predict(Intra4x4Mode::HorizontalUp, &e, &mut out);
        assert_eq!((out[0], out[1], out[2], out[11], out[15]), (2, 2, 3, 4, 4));
        // Vertical-right: (M + A + 1) >> 1 at (0, 0); (I + 2M + A + 2) >> 2 at (0, 1).
        predict(Intra4x4Mode::VerticalRight, &e, &mut out);
        assert_eq!((out[0], out[4], out[8]), (5, 3, 1));
        // Horizontal-down: (M + I + 1) >> 1 at (0, 0); (I + 2M + A + 2) >> 2 at
        // (1, 0); (B + 2A + M + 2) >> 2 at (2, 0).
        predict(Intra4x4Mode::HorizontalDown, &e, &mut out);
        assert_eq!((out[0], out[1], out[2], out[3]), (1, 3, 10, 20));
    }

    #[test]
    fn a_picture_constant_along_a_direction_is_continued_exactly() {
        // Samples that change linearly across a direction and not along it
        // are continued exactly by that direction's mode (the filters
        // average linear runs to their middle value); `skip` is where the
        // mode's definition departs from the direction.
        let check = |s: &dyn Fn(i32, i32) -> u8, mode: Intra4x4Mode, skip: (i32, i32)| {
            let e = Edges {
                top: Some([0, 1, 2, 3, 4, 5, 6, 7].map(|x| s(x, -1))),
                left: Some([0, 1, 2, 3].map(|y| s(-1, y))),
                top_left: Some(s(-1, -1)),
            };
            let mut out = [0u8; 16];
            predict(mode, &e, &mut out);
            for y in 0..4 {
                for x in (0..4).filter(|&x| (x, y) != skip) {
                    assert_eq!(out[(y * 4 + x) as usize], s(x, y), "{mode:?} at ({x}, {y})");
                }
            }
        };
        let none = (-9, -9);
        check(
            &|x, _| [5, 9, 200, 31, 77, 0, 0, 0, 0][(x + 1) as usize],
            Intra4x4Mode::Vertical,
            none,
        );
        check(&|_, y| (y * 50 + 7) as u8, Intra4x4Mode::Horizontal, none);
        check(
            &|x, y| (20 + 10 * (x + y)) as u8,
            Intra4x4Mode::DiagonalDownLeft,
            (3, 3),
        );
        check(
            &|x, y| (100 + 10 * (x - y)) as u8,
            Intra4x4Mode::DiagonalDownRight,
            none,
        );
        check(&|_, _| 77, Intra4x4Mode::Dc, none);
    }

    #[test]
    fn coding_order_and_above_right_availability() {
        // Quadrants in raster order, blocks in raster order inside them.
        assert_eq!(CODING_ORDER[..4], [0, 1, 4, 5]);
        // Inside a macroblock away from the picture's edges, as H.264's
        // Figure 6-10: no above-right for raster blocks 5, 7, 11, 13, 15
        // (decoded after it, or in the next macroblock).
        let missing: Vec<usize> = (0..16).filter(|&k| !neighbours(k, 1, 1, 3).2).collect();
        assert_eq!(missing, vec![5, 7, 11, 13, 15]);
        // The last macroblock of a row has no above-right for block 3.
        assert!(!neighbours(3, 2, 1, 3).2);
        // The top row has nothing above.
        assert_eq!(neighbours(1, 1, 0, 3), (false, true, false));
        assert_eq!(neighbours(0, 0, 1, 3), (true, false, true));
    }

    #[test]
    fn most_probable_is_the_lower_mode_or_dc() {
        use Intra4x4Mode::*;
        assert_eq!(
            most_probable(Some(HorizontalUp), Some(VerticalRight)),
            VerticalRight
        );
        assert_eq!(most_probable(None, Some(Vertical)), Dc);
        assert_eq!(most_probable(Some(Vertical), None), Dc);
        let own = [HorizontalDown; 16];
        let left = [Vertical; 16];
        // Block 0 looks into the left macroblock's block 3 and the one above's 12.
        assert_eq!(
            neighbour_modes(0, &own, Some(&left), None),
            (Some(Vertical), None)
        );
        assert_eq!(
            neighbour_modes(5, &own, None, None),
            (Some(HorizontalDown), Some(HorizontalDown))
        );
    }
}
