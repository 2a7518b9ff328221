//! Motion vector prediction (normative: FORMAT.md section 5; as dav1d's
//! `refmvs.c` and x264's `mvpred.c`, in one place): the median rule of one
//! reference, H.264's rules over references, a partition's directional
//! prediction, a macroblock's and a grid node's prediction from the
//! vectors decoded before it. The encoder predicts with the same
//! functions, so what it prices is what the decoder adds back.

use crate::mv::Mv;
use crate::partition::{Direction, MbVectors, Part, RefMv, Split, WHOLE};

/// The median of three values.
#[inline]
pub(crate) fn median3(a: i32, b: i32, c: i32) -> i32 {
    a.max(b).min(a.min(b).max(c))
}

/// The predicted vector of a block from its neighbours' vectors (`None`
/// where unavailable); see the module documentation.
///
/// ```
/// use mocomp_codec::mv::Mv;
/// use mocomp_codec::mvpred::predict_mv;
/// let (a, b, c) = (Mv::new(4, -8), Mv::new(12, 0), Mv::new(-4, 2));
/// assert_eq!(predict_mv(Some(a), Some(b), Some(c), None), Mv::new(4, 0));
/// assert_eq!(predict_mv(Some(a), None, None, None), a);
/// ```
pub fn predict_mv(left: Option<Mv>, top: Option<Mv>, top_right: Option<Mv>, top_left: Option<Mv>) -> Mv {
    // One reference: the rule of several with every neighbour on it.
    let c = top_right.or(top_left);
    predict_with_references([left, top, c].map(|m| m.map(RefMv::previous)), 0)
}

/// The vectors of the decoded macroblocks (raster order, `done.len()`
/// of them) and of the current one's partitions decoded so far: what a
/// partition's vector prediction reads.
#[derive(Debug, Clone, Copy)]
pub struct VectorNeighbourhood<'a> {
    /// Every macroblock before the current one.
    pub done: &'a [MbVectors],
    /// Macroblocks per row.
    pub mb_cols: usize,
    /// The current macroblock.
    pub mb: (usize, usize),
    /// Its blocks decoded so far.
    pub current: &'a MbVectors,
}

impl VectorNeighbourhood<'_> {
    /// The vector of the 8x8 block at (gx, gy), in 8x8 blocks relative to
    /// the current macroblock's top-left: `None` outside the picture, not
    /// decoded yet, or intra.
    fn at(&self, gx: isize, gy: isize) -> Option<RefMv> {
        if (0..2).contains(&gx) && (0..2).contains(&gy) {
            return self.current[(gy * 2 + gx) as usize];
        }
        let ax = 2 * self.mb.0 as isize + gx;
        let ay = 2 * self.mb.1 as isize + gy;
        if ax < 0 || ay < 0 || ax as usize >= 2 * self.mb_cols {
            return None;
        }
        let (ax, ay) = (ax as usize, ay as usize);
        let index = (ay / 2) * self.mb_cols + ax / 2;
        self.done.get(index)?[(ay % 2) * 2 + ax % 2]
    }

    /// The predicted vector of partition `p` pointing into reference
    /// `ref_idx` (FORMAT.md section 5).
    pub fn predict(&self, p: &Part, ref_idx: u8) -> Mv {
        let (x, y) = (p.x8 as isize, p.y8 as isize);
        let a = self.at(x - 1, y);
        let b = self.at(x, y - 1);
        let c = self
            .at(x + p.w8 as isize, y - 1)
            .or_else(|| self.at(x - 1, y - 1));
        let directional = match p.direction {
            Direction::Median => None,
            Direction::Left => a,
            Direction::Above => b,
            Direction::AboveRight => c,
        };
        match directional {
            Some(n) if n.ref_idx == ref_idx => n.mv,
            _ => predict_with_references([a, b, c], ref_idx),
        }
    }
}

/// Rules 1-3 of FORMAT.md section 5 (H.264 8.4.1.3.1) over A, B and C (D
/// already in C's place): A alone when B and C are unavailable; else the
/// one neighbour with reference `ref_idx` when exactly one has it; else
/// the component-wise median, unavailable neighbours counting as zero.
pub fn predict_with_references([a, b, c]: [Option<RefMv>; 3], ref_idx: u8) -> Mv {
    if let (Some(a), None, None) = (a, b, c) {
        return a.mv;
    }
    // Which neighbours point into `ref_idx`, as bits (no iterator: this
    // runs several times a macroblock, in the decoder too).
    let into = |n: Option<RefMv>, bit: u8| n.filter(|n| n.ref_idx == ref_idx).map_or(0, |_| bit);
    match into(a, 1) | into(b, 2) | into(c, 4) {
        1 => return a.map_or(Mv::ZERO, |n| n.mv),
        2 => return b.map_or(Mv::ZERO, |n| n.mv),
        4 => return c.map_or(Mv::ZERO, |n| n.mv),
        _ => {}
    }
    let [a, b, c] = [a, b, c].map(|n| n.map_or(Mv::ZERO, |n| n.mv));
    Mv::new(median3(a.x, b.x, c.x), median3(a.y, b.y, c.y))
}

/// Walks the partitions of a split macroblock in coding order: `step(k,
/// predict)` gives partition k's motion, `predict(ref_idx)` being its
/// predicted vector into reference `ref_idx` (which reads the partitions
/// before it), `None` to stop.
pub fn walk_partitions(
    split: Split,
    done: &[MbVectors],
    (mb_x, mb_y, mb_cols): (usize, usize, usize),
    mut step: impl FnMut(usize, &dyn Fn(u8) -> Mv) -> Option<RefMv>,
) -> Option<()> {
    let mut current: MbVectors = [None; 4];
    for (k, p) in split.parts().iter().enumerate() {
        let n = VectorNeighbourhood {
            done,
            mb_cols,
            mb: (mb_x, mb_y),
            current: &current,
        };
        let mv = step(k, &|ref_idx| n.predict(p, ref_idx))?;
        for b in p.blocks() {
            current[b] = Some(mv);
        }
    }
    Some(())
}

/// The predicted vector of the element at (col, row) of a grid `cols`
/// wide, from the elements before it in raster order: `at(c, r)` is an
/// element's vector, `None` when it has none (section 5 of FORMAT.md).
pub fn predict_in_grid(cols: usize, col: usize, row: usize, at: impl Fn(usize, usize) -> Option<Mv>) -> Mv {
    let left = if col > 0 { at(col - 1, row) } else { None };
    let top = if row > 0 { at(col, row - 1) } else { None };
    let top_right = if row > 0 && col + 1 < cols {
        at(col + 1, row - 1)
    } else {
        None
    };
    let top_left = if row > 0 && col > 0 {
        at(col - 1, row - 1)
    } else {
        None
    };
    predict_mv(left, top, top_right, top_left)
}

/// The predicted vector of macroblock (mb_x, mb_y) as one 16x16 block
/// into reference 0 (skip's vector), from the vectors of the macroblocks
/// before it in raster order.
pub fn mv_prediction(done: &[MbVectors], mb_x: usize, mb_y: usize, mb_cols: usize) -> Mv {
    mv_prediction_into(done, (mb_x, mb_y, mb_cols), 0)
}

/// [`mv_prediction`] into reference `ref_idx`.
pub fn mv_prediction_into(
    done: &[MbVectors],
    (mb_x, mb_y, mb_cols): (usize, usize, usize),
    ref_idx: u8,
) -> Mv {
    VectorNeighbourhood {
        done,
        mb_cols,
        mb: (mb_x, mb_y),
        current: &[None; 4],
    }
    .predict(&WHOLE, ref_idx)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rules 1-3 over every mix of missing neighbours and neighbours into
    /// references 0 and 1, against the rules written as FORMAT.md words
    /// them.
    #[test]
    fn the_reference_rules_pick_as_written() {
        let options = |mv: Mv| {
            [
                None,
                Some(RefMv { mv, ref_idx: 0 }),
                Some(RefMv { mv, ref_idx: 1 }),
            ]
        };
        let (va, vb, vc) = (Mv::new(4, -8), Mv::new(12, 0), Mv::new(-4, 2));
        for a in options(va) {
            for b in options(vb) {
                for c in options(vc) {
                    for ref_idx in [0, 1] {
                        let same: Vec<RefMv> = [a, b, c]
                            .into_iter()
                            .flatten()
                            .filter(|n| n.ref_idx == ref_idx)
                            .collect();
                        let want = match (a, b, c) {
                            (Some(a), None, None) => a.mv,
                            _ if same.len() == 1 => same[0].mv,
                            _ => {
                                let [a, b, c] = [a, b, c].map(|n| n.map_or(Mv::ZERO, |n| n.mv));
                                Mv::new(median3(a.x, b.x, c.x), median3(a.y, b.y, c.y))
                            }
                        };
                        assert_eq!(
                            predict_with_references([a, b, c], ref_idx),
                            want,
                            "{a:?} {b:?} {c:?} into {ref_idx}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn median_of_three() {
        for (a, b, c, m) in [
            (1, 2, 3, 2),
            (3, 1, 2, 2),
            (2, 3, 1, 2),
            (5, 5, 1, 5),
            (-4, 7, 0, 0),
        ] {
            assert_eq!(median3(a, b, c), m);
        }
    }

    #[test]
    fn prediction_rules() {
        let (a, b, c, d) = (Mv::new(4, 4), Mv::new(8, -4), Mv::new(-12, 0), Mv::new(100, 100));
        // All available: component-wise median.
        assert_eq!(predict_mv(Some(a), Some(b), Some(c), Some(d)), Mv::new(4, 0));
        // C unavailable: D takes its place.
        assert_eq!(predict_mv(Some(a), Some(b), None, Some(d)), Mv::new(8, 4));
        // Top row of the picture: only A.
        assert_eq!(predict_mv(Some(a), None, None, None), a);
        // Exactly one available: that one.
        assert_eq!(predict_mv(None, Some(b), None, None), b);
        assert_eq!(predict_mv(None, None, Some(c), None), c);
        // Two available: median with a zero.
        assert_eq!(predict_mv(None, Some(b), Some(c), None), Mv::new(0, 0));
        // None available: zero.
        assert_eq!(predict_mv(None, None, None, None), Mv::ZERO);
    }

    fn mv(x: i32) -> Option<RefMv> {
        Some(RefMv::previous(Mv::new(x, -x)))
    }

    fn into(x: i32, ref_idx: u8) -> Option<RefMv> {
        Some(RefMv::new(Mv::new(x, -x), ref_idx))
    }

    #[test]
    fn the_whole_macroblock_is_predicted_as_before_from_its_neighbours() {
        // 3 columns; macroblocks 0, 1, 2 (row 0) and 3 (row 1) decoded.
        let done = [[mv(4); 4], [mv(8); 4], [mv(12); 4], [mv(16); 4]];
        let n = VectorNeighbourhood {
            done: &done,
            mb_cols: 3,
            mb: (1, 1),
            current: &[None; 4],
        };
        // A = 16, B = 8, C = 12: the median.
        assert_eq!(n.predict(&WHOLE, 0), Mv::new(12, -12));
        let plain = |m: Option<RefMv>| m.map(|m| m.mv);
        assert_eq!(
            n.predict(&WHOLE, 0),
            predict_mv(plain(mv(16)), plain(mv(8)), plain(mv(12)), plain(mv(4)))
        );
    }

    #[test]
    fn partitions_read_their_own_blocks_and_the_directional_neighbours() {
        // Left macroblock's right column differs from its left one.
        let done = [[mv(1), mv(2), mv(3), mv(4)], [mv(5), mv(6), mv(7), mv(8)]];
        fn above<'a>(done: &'a [MbVectors], current: &'a MbVectors) -> VectorNeighbourhood<'a> {
            VectorNeighbourhood {
                done,
                mb_cols: 2,
                mb: (0, 1),
                current,
            }
        }
        // 16x8 top at (0, 1): B (block 2 of the macroblock above) directly.
        let empty = [None; 4];
        assert_eq!(
            above(&done, &empty).predict(&Split::Horizontal.parts()[0], 0),
            Mv::new(3, -3)
        );
        // 16x8 bottom: A outside the picture, so the median rule over B =
        // its own top partition, C not decoded, D outside: only B.
        let top = [mv(9), mv(9), None, None];
        assert_eq!(
            above(&done, &top).predict(&Split::Horizontal.parts()[1], 0),
            Mv::new(9, -9)
        );
        // 8x16 right: C = the above-right macroblock's block 2.
        let wide = VectorNeighbourhood {
            done: &[[mv(1); 4], [mv(2); 4], [mv(3); 4], [mv(4); 4]],
            mb_cols: 3,
            mb: (1, 1),
            current: &[mv(20), None, mv(20), None],
        };
        assert_eq!(wide.predict(&Split::Vertical.parts()[1], 0), Mv::new(3, -3));
        // 8x8 block 3: C (the right macroblock) not decoded, D = block 0.
        let quad = VectorNeighbourhood {
            current: &[mv(40), mv(41), mv(42), None],
            ..wide
        };
        // A = 42, B = 41, D = 40: median 41.
        assert_eq!(quad.predict(&Split::Quad.parts()[3], 0), Mv::new(41, -41));
    }

    #[test]
    fn the_one_neighbour_on_the_same_reference_predicts_alone() {
        // A on reference 1, B and C on reference 0 (H.264 8.4.1.3.1).
        let done = [
            [into(8, 0); 4],
            [into(12, 0); 4],
            [into(16, 0); 4],
            [into(4, 1); 4],
        ];
        let n = VectorNeighbourhood {
            done: &done,
            mb_cols: 3,
            mb: (1, 1),
            current: &[None; 4],
        };
        assert_eq!(n.predict(&WHOLE, 1), Mv::new(4, -4));
        // Two on reference 0: the median of all three, whatever their references.
        assert_eq!(n.predict(&WHOLE, 0), Mv::new(12, -12));
        // None on reference 2: the median too.
        assert_eq!(n.predict(&WHOLE, 2), Mv::new(12, -12));
        // A alone (B and C outside the picture): A, whatever its reference.
        let first_row = VectorNeighbourhood {
            done: &done[..1],
            mb: (1, 0),
            ..n
        };
        assert_eq!(first_row.predict(&WHOLE, 3), Mv::new(8, -8));
    }

    #[test]
    fn a_directional_neighbour_on_another_reference_falls_back_to_the_median_rule() {
        // 16x8 top: B is on reference 1; predicting into reference 0, the
        // median of A, B, C (A and C on reference 0 too: median).
        let done = [
            [into(2, 0); 4],
            [into(6, 1); 4],
            [into(10, 0); 4],
            [into(20, 0); 4],
        ];
        let n = VectorNeighbourhood {
            done: &done,
            mb_cols: 3,
            mb: (1, 1),
            current: &[None; 4],
        };
        assert_eq!(n.predict(&Split::Horizontal.parts()[0], 1), Mv::new(6, -6));
        // Into 0: A = 20 and C = 10 on reference 0, B = 6 on 1: median 10.
        assert_eq!(n.predict(&Split::Horizontal.parts()[0], 0), Mv::new(10, -10));
    }
}
