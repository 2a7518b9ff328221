//! Macroblock partitions (normative, FORMAT.md sections 3.2 and 5): an
//! inter macroblock of a block-motion frame is one 16x16 block or is split
//! into two 16x8, two 8x16 or four 8x8 partitions, each with its own
//! vector, predicted as H.264 predicts them (8.4.1.3, one reference).
//!
//! Vectors are kept per 8x8 block ([`MbVectors`]), each with the index of
//! the reference it points into: what the vector prediction, the motion
//! compensation and the deblocking filter read.

use crate::mv::{median3, Mv};

/// A block's motion: a vector into reference `ref_idx` of the frame's
/// list (0: the previous frame; FORMAT.md section 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct RefMv {
    /// Quarter-pel.
    pub mv: Mv,
    /// Index in the frame's reference list.
    pub ref_idx: u8,
}

impl RefMv {
    /// `mv` into the previous frame (reference 0).
    pub const fn previous(mv: Mv) -> RefMv {
        RefMv { mv, ref_idx: 0 }
    }

    /// `mv` into reference `ref_idx`.
    pub const fn new(mv: Mv, ref_idx: u8) -> RefMv {
        RefMv { mv, ref_idx }
    }
}

/// The motion of each 8x8 block of a macroblock, in raster order (`None`
/// for intra macroblocks, and for blocks not decoded yet).
pub type MbVectors = [Option<RefMv>; 4];

/// How an inter macroblock is split.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Split {
    /// Two 16x8 partitions: top, bottom.
    Horizontal,
    /// Two 8x16 partitions: left, right.
    Vertical,
    /// Four 8x8 partitions in raster order.
    Quad,
}

/// Which neighbour a partition's vector is taken from when it has one
/// (H.264's directional prediction of 16x8 and 8x16 partitions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// The median rule alone.
    Median,
    /// A, the block left of the partition's top-left sample.
    Left,
    /// B, the block above it.
    Above,
    /// C, the block above and right of the top-right sample (D in its place
    /// when it has no vector).
    AboveRight,
}

/// A partition of a macroblock, in 8x8 blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Part {
    /// Top-left 8x8 block (0 or 1 each).
    pub x8: usize,
    /// Top-left 8x8 block row.
    pub y8: usize,
    /// Width in 8x8 blocks (1 or 2).
    pub w8: usize,
    /// Height in 8x8 blocks.
    pub h8: usize,
    /// Its directional prediction.
    pub direction: Direction,
}

const fn part(x8: usize, y8: usize, w8: usize, h8: usize, direction: Direction) -> Part {
    Part {
        x8,
        y8,
        w8,
        h8,
        direction,
    }
}

/// The whole macroblock as one partition.
pub const WHOLE: Part = part(0, 0, 2, 2, Direction::Median);

const HORIZONTAL: [Part; 2] = [
    part(0, 0, 2, 1, Direction::Above),
    part(0, 1, 2, 1, Direction::Left),
];
const VERTICAL: [Part; 2] = [
    part(0, 0, 1, 2, Direction::Left),
    part(1, 0, 1, 2, Direction::AboveRight),
];
const QUAD: [Part; 4] = [
    part(0, 0, 1, 1, Direction::Median),
    part(1, 0, 1, 1, Direction::Median),
    part(0, 1, 1, 1, Direction::Median),
    part(1, 1, 1, 1, Direction::Median),
];

impl Split {
    /// Every split, in the order of their codes.
    pub const ALL: [Split; 3] = [Split::Horizontal, Split::Vertical, Split::Quad];

    /// Its partitions, in coding order.
    pub fn parts(self) -> &'static [Part] {
        match self {
            Split::Horizontal => &HORIZONTAL,
            Split::Vertical => &VERTICAL,
            Split::Quad => &QUAD,
        }
    }

    /// Per 8x8 block, the motion of its partition (`mvs`, in coding order;
    /// entries past its partitions ignored).
    pub fn block_vectors(self, mvs: &[RefMv; 4]) -> [RefMv; 4] {
        let mut out = [RefMv::default(); 4];
        for (p, &mv) in self.parts().iter().zip(mvs) {
            for_blocks(p, |b| out[b] = mv);
        }
        out
    }
}

impl Part {
    /// Its 8x8 blocks' raster indices within the macroblock.
    pub fn blocks(&self) -> impl Iterator<Item = usize> + '_ {
        (self.y8..self.y8 + self.h8).flat_map(move |y| (self.x8..self.x8 + self.w8).map(move |x| y * 2 + x))
    }

    /// Luma rectangle within the macroblock: (x, y, width, height).
    pub fn luma_rect(&self) -> (usize, usize, usize, usize) {
        (8 * self.x8, 8 * self.y8, 8 * self.w8, 8 * self.h8)
    }
}

fn for_blocks(p: &Part, mut f: impl FnMut(usize)) {
    for b in p.blocks() {
        f(b);
    }
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
    let mut same = [a, b, c].into_iter().flatten().filter(|n| n.ref_idx == ref_idx);
    if let (Some(one), None) = (same.next(), same.next()) {
        return one.mv;
    }
    let [a, b, c] = [a, b, c].map(|n| n.map_or(Mv::ZERO, |n| n.mv));
    Mv::new(median3(a.x, b.x, c.x), median3(a.y, b.y, c.y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mv::predict_mv;

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
        assert_eq!(above(&done, &empty).predict(&HORIZONTAL[0], 0), Mv::new(3, -3));
        // 16x8 bottom: A outside the picture, so the median rule over B =
        // its own top partition, C not decoded, D outside: only B.
        let top = [mv(9), mv(9), None, None];
        assert_eq!(above(&done, &top).predict(&HORIZONTAL[1], 0), Mv::new(9, -9));
        // 8x16 right: C = the above-right macroblock's block 2.
        let wide = VectorNeighbourhood {
            done: &[[mv(1); 4], [mv(2); 4], [mv(3); 4], [mv(4); 4]],
            mb_cols: 3,
            mb: (1, 1),
            current: &[mv(20), None, mv(20), None],
        };
        assert_eq!(wide.predict(&VERTICAL[1], 0), Mv::new(3, -3));
        // 8x8 block 3: C (the right macroblock) not decoded, D = block 0.
        let quad = VectorNeighbourhood {
            current: &[mv(40), mv(41), mv(42), None],
            ..wide
        };
        // A = 42, B = 41, D = 40: median 41.
        assert_eq!(quad.predict(&QUAD[3], 0), Mv::new(41, -41));
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
        assert_eq!(n.predict(&HORIZONTAL[0], 1), Mv::new(6, -6));
        // Into 0: A = 20 and C = 10 on reference 0, B = 6 on 1: median 10.
        assert_eq!(n.predict(&HORIZONTAL[0], 0), Mv::new(10, -10));
    }

    #[test]
    fn block_vectors_spread_each_partition() {
        let m = [1, 2, 3, 4].map(|x| RefMv::new(Mv::new(x, 0), x as u8));
        assert_eq!(Split::Horizontal.block_vectors(&m), [m[0], m[0], m[1], m[1]]);
        assert_eq!(Split::Vertical.block_vectors(&m), [m[0], m[1], m[0], m[1]]);
        assert_eq!(Split::Quad.block_vectors(&m), m);
    }
}
