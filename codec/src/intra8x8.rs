//! Intra prediction of luma in 8x8 blocks, H.264's Intra_8x8 (its clause
//! 8.3.2): the nine directional modes of [`Intra4x4Mode`] on 8x8 blocks,
//! from edge samples smoothed first by a [1 2 1] filter (the 8x8
//! transform's larger blocks show the edges' noise more than 4x4 ones).
//!
//! Edges are the sixteen samples above the block (eight above, eight
//! above right), the eight to its left and the corner. Samples above right
//! that are not decoded yet repeat the last one above, as in H.264.
//!
//! A macroblock coded in 8x8 blocks (FORMAT.md section 9.2) predicts its
//! four blocks in raster order, each from the reconstruction of those
//! before it, and codes their residuals in the 8x8 transform.
//!
//! ```
//! use mocomp_codec::intra4x4::Intra4x4Mode;
//! use mocomp_codec::intra8x8::{predict, Edges8};
//! let e = Edges8 { top: Some([50; 16]), left: Some([90; 8]), top_left: Some(70) };
//! let mut out = [0u8; 64];
//! predict(Intra4x4Mode::Vertical, &e, &mut out);
//! // The first sample above is smoothed with the corner: (70 + 2 * 50 + 50 + 2) >> 2.
//! assert_eq!(out[56..], [55, 50, 50, 50, 50, 50, 50, 50]);
//! predict(Intra4x4Mode::Dc, &e, &mut out);
//! assert_eq!(out, [70; 64]);
//! ```

use crate::consts::MB;
use crate::intra4x4::{block_edges, neighbour_modes, spread8, Intra4x4Mode};
use crate::picture::Plane;

use crate::dsp::ipred::ipred;
pub use crate::dsp::ipred::{Edges8, ModeSource};

/// Which neighbours 8x8 block `q` (raster order in its macroblock) of
/// macroblock (mb_x, mb_y) has in a picture `mb_cols` macroblocks wide:
/// (above, left, above right decoded). Blocks are coded in raster order.
pub fn neighbours(q: usize, mb_x: usize, mb_y: usize, mb_cols: usize) -> (bool, bool, bool) {
    let (i, j) = (q % 2, q / 2);
    let above = j > 0 || mb_y > 0;
    let left = i > 0 || mb_x > 0;
    let above_right = match q {
        0 => mb_y > 0,
        1 => mb_y > 0 && mb_x + 1 < mb_cols,
        // Block 1 is decoded before block 2; nothing right of block 3 is.
        2 => true,
        _ => false,
    };
    (above, left, above_right)
}

/// The modes of the 4x4 blocks left of and above 8x8 block `q`'s top-left
/// 4x4 block, which predict its mode (FORMAT.md section 3.2): in this
/// macroblock (`own`, the 8x8 modes before `q` decided) or in the
/// neighbour macroblocks (as [`neighbour_modes`] takes them).
pub fn neighbour_modes8(
    q: usize,
    own: &[Intra4x4Mode; 4],
    left_mb: Option<&[Intra4x4Mode; 16]>,
    above_mb: Option<&[Intra4x4Mode; 16]>,
) -> (Option<Intra4x4Mode>, Option<Intra4x4Mode>) {
    const TOP_LEFT4: [usize; 4] = [0, 2, 8, 10];
    neighbour_modes(TOP_LEFT4[q], &spread8(own), left_mb, above_mb)
}

/// The edges of 8x8 block `q` of macroblock (mb_x, mb_y): samples outside
/// the macroblock from `recon` (the luma reconstructed so far), inside it
/// from `own` (the macroblock's blocks reconstructed so far, 16x16
/// row-major).
pub fn edges(recon: &Plane, own: &[u8; 256], mb_x: usize, mb_y: usize, q: usize) -> Edges8 {
    let available = neighbours(q, mb_x, mb_y, recon.width() / MB);
    let (top, left, top_left) =
        block_edges::<8, 16>(recon, own, (mb_x, mb_y), (8 * (q % 2), 8 * (q / 2)), available);
    Edges8 { top, left, top_left }
}

/// The edges smoothed by [1 2 1] along them (H.264 8.3.2.2.1), each end
/// weighted [1 3] where its outer neighbour is missing.
pub fn filtered(e: &Edges8) -> Edges8 {
    let f3 = |a: u8, b: u8, c: u8| ((u16::from(a) + 2 * u16::from(b) + u16::from(c) + 2) >> 2) as u8;
    let f_end = |inner: u8, end: u8| ((u16::from(inner) + 3 * u16::from(end) + 2) >> 2) as u8;
    let top = e.top.map(|t| {
        std::array::from_fn(|x| match x {
            0 => e.top_left.map_or(f_end(t[1], t[0]), |c| f3(c, t[0], t[1])),
            15 => f_end(t[14], t[15]),
            _ => f3(t[x - 1], t[x], t[x + 1]),
        })
    });
    let left = e.left.map(|l| {
        std::array::from_fn(|y| match y {
            0 => e.top_left.map_or(f_end(l[1], l[0]), |c| f3(c, l[0], l[1])),
            7 => f_end(l[6], l[7]),
            _ => f3(l[y - 1], l[y], l[y + 1]),
        })
    });
    // The corner exists only with both edges.
    let top_left = match (e.top, e.left, e.top_left) {
        (Some(t), Some(l), Some(c)) => Some(f3(t[0], c, l[0])),
        _ => None,
    };
    Edges8 { top, left, top_left }
}

/// Predicts an 8x8 block in `mode` into `out` (row-major) from its
/// unfiltered edges `e`. The mode must be available with these edges
/// ([`Intra4x4Mode::is_available`]); panics otherwise.
pub fn predict(mode: Intra4x4Mode, e: &Edges8, out: &mut [u8; 64]) {
    let (needs_top, needs_left) = mode.needs();
    assert!(
        (e.top.is_some() || !needs_top)
            && (e.left.is_some() || !needs_left)
            && (e.top_left.is_some() || !(needs_top && needs_left)),
        "8x8 intra mode {mode:?} without its neighbours"
    );
    predict_filtered(mode, &filtered(e), out);
}

/// The luma prediction of a macroblock coded in 8x8 blocks: each block, in
/// raster order, predicted in its mode from the reconstruction before it:
/// `recon` (the picture so far) outside the macroblock, inside it the
/// blocks before, each its prediction plus its levels (`add` adds block
/// `q`'s levels to a 16x16 buffer, as reconstruction does). The
/// macroblock's reconstruction is this prediction plus the same levels.
/// The modes must have their neighbours ([`neighbours`]); panics otherwise.
pub fn predict_mb(
    recon: &Plane,
    (mb_x, mb_y): (usize, usize),
    modes: &[Intra4x4Mode; 4],
    mut add: impl FnMut(usize, &mut [u8; 256]),
) -> [u8; 256] {
    let mut own = [0u8; 256];
    let mut pred = [0u8; 256];
    for (q, &mode) in modes.iter().enumerate() {
        let mut block = [0u8; 64];
        predict(mode, &edges(recon, &own, mb_x, mb_y, q), &mut block);
        place(&block, q, &mut own);
        place(&block, q, &mut pred);
        add(q, &mut own);
    }
    pred
}

/// Copies an 8x8 block into quadrant `q` of a 16x16 one.
pub fn place(block: &[u8; 64], q: usize, out: &mut [u8; 256]) {
    let (bx, by) = (8 * (q % 2), 8 * (q / 2));
    for (r, row) in block.chunks_exact(8).enumerate() {
        let i = (by + r) * MB + bx;
        out[i..i + 8].copy_from_slice(row);
    }
}

/// [`predict`] from edges already [`filtered`] (the mode's neighbours
/// present, as [`predict`] asks; missing ones read as 0), by the intra
/// kernels of the CPU level in force.
pub fn predict_filtered(mode: Intra4x4Mode, e: &Edges8, out: &mut [u8; 64]) {
    (ipred().pred_8x8)(mode, e, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_read_as_slices_are_the_samples_beside_the_block() {
        let recon = Plane::from_fn(48, 48, |x, y| ((x * 37 + y * 101) % 251) as u8).unwrap();
        let own: [u8; 256] = std::array::from_fn(|i| (i * 7 % 253) as u8);
        for (mb_x, mb_y) in [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1), (0, 2), (2, 2)] {
            let at = crate::intra4x4::mb_sampler(&recon, &own, mb_x, mb_y);
            for q in 0..4 {
                let (above, left, above_right) = neighbours(q, mb_x, mb_y, 3);
                let (bx, by) = (8 * (q % 2) as isize, 8 * (q / 2) as isize);
                let top = above.then(|| {
                    std::array::from_fn(|c| {
                        at(bx + if c < 8 || above_right { c } else { 7 } as isize, by - 1)
                    })
                });
                let sampled = Edges8 {
                    top,
                    left: left.then(|| std::array::from_fn(|r| at(bx - 1, by + r as isize))),
                    top_left: (above && left).then(|| at(bx - 1, by - 1)),
                };
                assert_eq!(
                    edges(&recon, &own, mb_x, mb_y, q),
                    sampled,
                    "block {q} of ({mb_x}, {mb_y})"
                );
            }
        }
    }

    /// The modes written sample by sample, as FORMAT.md section 9.2 gives
    /// them: what the gather tables must equal.
    fn by_formula(mode: Intra4x4Mode, e: &Edges8) -> [u8; 64] {
        use Intra4x4Mode::*;
        let mut line = [0i32; 25];
        if let Some(l) = e.left {
            for (y, &v) in l.iter().enumerate() {
                line[7 - y] = i32::from(v);
            }
        }
        line[8] = i32::from(e.top_left.unwrap_or(0));
        if let Some(t) = e.top {
            for (x, &v) in t.iter().enumerate() {
                line[9 + x] = i32::from(v);
            }
        }
        let t = |x: i32| line[(9 + x) as usize];
        let l = |y: i32| line[(7 - y) as usize];
        let f3 = |a: i32, b: i32, c: i32| (a + 2 * b + c + 2) >> 2;
        let f2 = |a: i32, b: i32| (a + b + 1) >> 1;
        std::array::from_fn(|i| {
            let (x, y) = ((i % 8) as i32, (i / 8) as i32);
            let v = match mode {
                Vertical => t(x),
                Horizontal => l(y),
                Dc => i32::from(crate::dsp::ipred::dc8(e)),
                DiagonalDownLeft => match (x, y) {
                    (7, 7) => (t(14) + 3 * t(15) + 2) >> 2,
                    _ => f3(t(x + y), t(x + y + 1), t(x + y + 2)),
                },
                DiagonalDownRight => match x - y {
                    d if d > 0 => f3(t(d - 2), t(d - 1), t(d)),
                    d if d < 0 => f3(l(-d - 2), l(-d - 1), l(-d)),
                    _ => f3(t(0), t(-1), l(0)),
                },
                VerticalRight => match 2 * x - y {
                    z if z >= 0 && z % 2 == 0 => f2(t(x - (y >> 1) - 1), t(x - (y >> 1))),
                    z if z > 0 => f3(t(x - (y >> 1) - 2), t(x - (y >> 1) - 1), t(x - (y >> 1))),
                    -1 => f3(l(0), l(-1), t(0)),
                    _ => f3(l(y - 2 * x - 1), l(y - 2 * x - 2), l(y - 2 * x - 3)),
                },
                HorizontalDown => match 2 * y - x {
                    z if z >= 0 && z % 2 == 0 => f2(l(y - (x >> 1) - 1), l(y - (x >> 1))),
                    z if z > 0 => f3(l(y - (x >> 1) - 2), l(y - (x >> 1) - 1), l(y - (x >> 1))),
                    -1 => f3(l(0), l(-1), t(0)),
                    _ => f3(t(x - 2 * y - 1), t(x - 2 * y - 2), t(x - 2 * y - 3)),
                },
                VerticalLeft => match y % 2 {
                    0 => f2(t(x + (y >> 1)), t(x + (y >> 1) + 1)),
                    _ => f3(t(x + (y >> 1)), t(x + (y >> 1) + 1), t(x + (y >> 1) + 2)),
                },
                HorizontalUp => match x + 2 * y {
                    z if z < 13 && z % 2 == 0 => f2(l(y + (x >> 1)), l(y + (x >> 1) + 1)),
                    z if z < 13 => f3(l(y + (x >> 1)), l(y + (x >> 1) + 1), l(y + (x >> 1) + 2)),
                    13 => (l(6) + 3 * l(7) + 2) >> 2,
                    _ => l(7),
                },
            };
            v as u8
        })
    }

    #[test]
    fn the_gather_tables_equal_the_formulas() {
        let mut seed = 5u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16) as u8
        };
        for round in 0..200 {
            let e = Edges8 {
                top: Some(std::array::from_fn(|_| next())),
                left: Some(std::array::from_fn(|_| next())),
                top_left: Some(next()),
            };
            // Some rounds without an edge, as at the picture's borders.
            let e = match round % 4 {
                1 => Edges8 {
                    left: None,
                    top_left: None,
                    ..e
                },
                2 => Edges8 {
                    top: None,
                    top_left: None,
                    ..e
                },
                _ => e,
            };
            let (above, left) = (e.top.is_some(), e.left.is_some());
            for mode in Intra4x4Mode::ALL
                .into_iter()
                .filter(|m| m.is_available(above, left))
            {
                let mut out = [0u8; 64];
                predict(mode, &e, &mut out);
                assert_eq!(out, by_formula(mode, &filtered(&e)), "{mode:?} round {round}");
            }
        }
    }

    /// The edges of the 8x8 block at (8, 8) of the picture `f` (all
    /// neighbours decoded).
    fn edges_of(f: &dyn Fn(i32, i32) -> u8) -> (Edges8, [u8; 64]) {
        let e = Edges8 {
            top: Some(std::array::from_fn(|x| f(8 + x as i32, 7))),
            left: Some(std::array::from_fn(|y| f(7, 8 + y as i32))),
            top_left: Some(f(7, 7)),
        };
        (
            e,
            std::array::from_fn(|i| f(8 + (i % 8) as i32, 8 + (i / 8) as i32)),
        )
    }

    fn mean_abs_error(mode: Intra4x4Mode, e: &Edges8, truth: &[u8; 64]) -> f64 {
        let mut out = [0u8; 64];
        predict(mode, e, &mut out);
        out.iter()
            .zip(truth)
            .map(|(&a, &b)| f64::from(a.abs_diff(b)))
            .sum::<f64>()
            / 64.0
    }

    #[test]
    fn each_direction_predicts_a_picture_oriented_along_it() {
        // Pictures constant along each mode's direction, varying across it
        // (a smooth non-linear profile): the mode predicts the block to
        // within rounding, and far better than DC.
        use Intra4x4Mode::*;
        let profile = |s: i32| (128.0 + 60.0 * (f64::from(s) * 0.2).sin()).round() as u8;
        type Along = fn(i32, i32) -> i32;
        let oriented: [(Intra4x4Mode, Along); 8] = [
            (Vertical, |x, _| x),
            (Horizontal, |_, y| y),
            (DiagonalDownLeft, |x, y| x + y),
            (DiagonalDownRight, |x, y| x - y),
            (VerticalRight, |x, y| 2 * x - y),
            (HorizontalDown, |x, y| 2 * y - x),
            (VerticalLeft, |x, y| 2 * x + y),
            (HorizontalUp, |x, y| x + 2 * y),
        ];
        for (mode, along) in oriented {
            let (e, truth) = edges_of(&|x, y| profile(along(x, y)));
            let err = mean_abs_error(mode, &e, &truth);
            let dc = mean_abs_error(Dc, &e, &truth);
            // The [1 2 1] smoothing of the edges costs a level or two on
            // this profile, and horizontal-up holds the last left sample
            // where the block reaches past the edge (4.5 levels on the
            // mean); directions across the profile cost 11-70.
            assert!(
                err < 5.0 && err < dc / 4.0,
                "{mode:?}: {err:.2} against DC {dc:.2}"
            );
            for other in Intra4x4Mode::ALL.into_iter().filter(|&m| m != mode) {
                let o = mean_abs_error(other, &e, &truth);
                assert!(err <= o, "{mode:?} {err:.2} beaten by {other:?} {o:.2}");
            }
        }
    }

    #[test]
    fn linear_ramps_along_the_diagonals_are_exact() {
        // [1 2 1] keeps a linear ramp, and the diagonal modes follow it.
        let (e, truth) = edges_of(&|x, y| (40 + 3 * (x + y)) as u8);
        let mut out = [0u8; 64];
        predict(Intra4x4Mode::DiagonalDownLeft, &e, &mut out);
        // All but the samples read from the last edge sample (x + y >= 13),
        // whose end weighting is not linear.
        for i in (0..64).filter(|i| i % 8 + i / 8 < 13) {
            assert_eq!(out[i], truth[i], "sample {i}");
        }
        let (e, truth) = edges_of(&|x, y| (120 + 5 * (x - y)) as u8);
        predict(Intra4x4Mode::DiagonalDownRight, &e, &mut out);
        assert_eq!(out, truth);
    }

    #[test]
    fn flat_edges_give_flat_blocks_in_every_mode() {
        let e = Edges8 {
            top: Some([77; 16]),
            left: Some([77; 8]),
            top_left: Some(77),
        };
        for mode in Intra4x4Mode::ALL {
            let mut out = [0u8; 64];
            predict(mode, &e, &mut out);
            assert_eq!(out, [77; 64], "{mode:?}");
        }
    }

    #[test]
    fn the_filter_weights_missing_ends_and_dc_uses_what_exists() {
        let e = Edges8 {
            top: Some(std::array::from_fn(|x| (x * 16) as u8)),
            left: None,
            top_left: None,
        };
        let f = filtered(&e);
        let t = f.top.unwrap();
        // No corner: (3 * 0 + 16 + 2) >> 2; inside [1 2 1]; the end (14 * 16 + 3 * 15 * 16 + 2) >> 2.
        assert_eq!((t[0], t[1], t[7], t[15]), (4, 16, 112, 236));
        assert_eq!((f.left, f.top_left), (None, None));
        let mut out = [0u8; 64];
        predict(Intra4x4Mode::Dc, &e, &mut out);
        // The mean of the filtered eight above: (4 + 16 + ... + 112 + 4) >> 3.
        let want = (t[..8].iter().map(|&v| u32::from(v)).sum::<u32>() + 4) >> 3;
        assert_eq!(out, [want as u8; 64]);
        predict(Intra4x4Mode::Dc, &Edges8::default(), &mut out);
        assert_eq!(out, [128; 64]);
    }

    #[test]
    fn neighbours_follow_the_coding_order() {
        // Top-left macroblock: nothing outside; block 3 sees blocks 0-2.
        assert_eq!(neighbours(0, 0, 0, 4), (false, false, false));
        assert_eq!(neighbours(1, 0, 0, 4), (false, true, false));
        assert_eq!(neighbours(2, 0, 0, 4), (true, false, true));
        assert_eq!(neighbours(3, 0, 0, 4), (true, true, false));
        // Block 1 reads above right from the next macroblock of the row
        // above, absent at the right edge.
        assert_eq!(neighbours(1, 2, 1, 4), (true, true, true));
        assert_eq!(neighbours(1, 3, 1, 4), (true, true, false));
    }

    #[test]
    fn edges_read_the_picture_outside_and_the_macroblock_inside() {
        let recon = Plane::from_fn(32, 32, |x, y| (x + 2 * y) as u8).unwrap();
        let own = std::array::from_fn(|i| 200 + (i % 16) as u8 / 4);
        // Block 3 of macroblock (1, 1): everything from its own samples.
        let e = edges(&recon, &own, 1, 1, 3);
        assert_eq!(e.top.unwrap()[..8], own[7 * 16 + 8..7 * 16 + 16]);
        // Nothing right of block 3 is decoded: the last above repeats.
        assert_eq!(e.top.unwrap()[8..], [own[7 * 16 + 15]; 8]);
        assert_eq!(e.left.unwrap(), std::array::from_fn(|r| own[(8 + r) * 16 + 7]));
        // Block 0 of macroblock (1, 1) from the picture.
        let e = edges(&recon, &own, 1, 1, 0);
        assert_eq!(e.top.unwrap(), std::array::from_fn(|c| (16 + c + 2 * 15) as u8));
        assert_eq!(e.top_left, Some((15 + 2 * 15) as u8));
    }
}
