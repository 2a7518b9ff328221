//! Macroblock partitions (normative, FORMAT.md sections 3.2 and 5): an
//! inter macroblock of a block-motion frame is one 16x16 block or is split
//! into two 16x8, two 8x16 or four 8x8 partitions, each with its own
//! vector, predicted as H.264 predicts them (8.4.1.3, one reference).
//!
//! Vectors are kept per 8x8 block ([`MbVectors`]), each with the index of
//! the reference it points into: what the vector prediction, the motion
//! compensation and the deblocking filter read.

use crate::mv::Mv;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_vectors_spread_each_partition() {
        let m = [1, 2, 3, 4].map(|x| RefMv::new(Mv::new(x, 0), x as u8));
        assert_eq!(Split::Horizontal.block_vectors(&m), [m[0], m[0], m[1], m[1]]);
        assert_eq!(Split::Vertical.block_vectors(&m), [m[0], m[1], m[0], m[1]]);
        assert_eq!(Split::Quad.block_vectors(&m), m);
    }
}
