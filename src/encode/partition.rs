//! The motion search of a macroblock's partitions (encoder side, not
//! normative): each partition's vector is the best of a few candidates
//! (the 8x8 blocks' searched vectors under it, the macroblock's, its
//! predicted vector) by SATD + lambda * vector bits against its own
//! predicted vector, then, when refined, walked at full pel by a small
//! diamond and refined by half- and quarter-pel steps. x264 searches each
//! 8x8 partition on its own the same way (its candidates, a full-pel
//! pattern, sub-pel steps), seeds its 16x8 and 8x16 searches from the 8x8
//! ones, and ranks sub-pel candidates on half-pel planes as here.
//!
//! A partition's SATD is the sum of its 8x8 blocks', each kept once
//! computed: the 16x8 and 8x16 searches meet many of the 8x8 search's.

use std::cell::{OnceCell, RefCell};

use crate::codec::mv::{mvd_bits, Mv};
use crate::codec::partition::Part;
use crate::codec::syntax::MB;
use crate::codec::Plane;
use crate::me::halfpel::{block_or_predicted, HalfPel, PhaseWindow};
use crate::me::{nearest_full_pel, Metric};

/// One macroblock's partition search.
pub(crate) struct PartitionSearch<'a> {
    /// The macroblock's source luma, 16x16.
    pub source: &'a [u8; 256],
    /// The (weighted) reference luma, borders extended.
    pub reference: &'a Plane,
    /// Its half-pel planes, where the frame has them.
    pub halfpel: Option<&'a HalfPel>,
    /// The macroblock.
    pub mb: (usize, usize),
    /// Weight of one vector bit against SATD.
    pub sad_lambda: f64,
    /// SATD of (8x8 block, vector) pairs measured so far, keyed by
    /// [`block_key`]; emptied per macroblock.
    pub satd8: &'a RefCell<SatdCache>,
    /// Each 8x8 block's view of `halfpel`, found at its first candidate.
    pub windows: [OnceCell<Option<PhaseWindow<'a>>>; 4],
}

/// SATDs of a macroblock's 8x8 blocks by (block, vector): about half the
/// lookups of a search find one (53 % on birds_720p, medium, QP 27).
/// Direct-mapped, each slot tagged with the
/// macroblock it was filled for, so that emptying it per macroblock is one
/// increment (a hash map's lookups and inserts cost as much as the SATDs
/// they saved). A slot taken by another key is measured again: the same
/// value, so the search is the same.
pub(crate) struct SatdCache {
    slots: Box<[SatdSlot; SATD_SLOTS]>,
    generation: u32,
}

/// A [`SatdCache`] entry: the key, its SATD, and the macroblock it is of.
#[derive(Clone, Copy, Default)]
struct SatdSlot {
    key: u64,
    satd: u32,
    generation: u32,
}

/// The cache's slots (a macroblock's search meets a few dozen keys).
const SATD_SLOTS: usize = 256;

impl Default for SatdCache {
    fn default() -> SatdCache {
        SatdCache {
            slots: Box::new([SatdSlot::default(); SATD_SLOTS]),
            generation: 1,
        }
    }
}

impl SatdCache {
    /// Forgets every entry (a new macroblock).
    pub(crate) fn clear(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            // Slots of 2^32 macroblocks ago would look current.
            *self = SatdCache::default();
        }
    }

    fn slot(key: u64) -> usize {
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - SATD_SLOTS.trailing_zeros())) as usize
    }

    fn get(&self, key: u64) -> Option<u32> {
        let s = &self.slots[Self::slot(key)];
        (s.generation == self.generation && s.key == key).then_some(s.satd)
    }

    fn insert(&mut self, key: u64, satd: u32) {
        let generation = self.generation;
        self.slots[Self::slot(key)] = SatdSlot {
            key,
            satd,
            generation,
        };
    }
}

/// The cache key of 8x8 block `b` with `mv` (components within +-2^14).
fn block_key(b: usize, mv: Mv) -> u64 {
    (b as u64) << 40 | u64::from(mv.x as u32 & 0xf_ffff) << 20 | u64::from(mv.y as u32 & 0xf_ffff)
}

/// A partition's vector and its SATD + lambda * bits.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PartChoice {
    pub mv: Mv,
    pub cost: f64,
}

/// Half- then quarter-pel steps around the best, and the moves each may
/// make.
const REFINE_STEPS: [(i32, usize); 2] = [(2, 1), (1, 1)];

/// The full-pel walk's moves before the sub-pel steps. Candidates alone
/// keep a partition on its neighbours' motion: where a part of the
/// macroblock moves on its own (a hand, an instrument's neck) none of them
/// is near its vector. Against candidates and sub-pel steps alone
/// (`benches/pair.py`, the 28 sequences and four of other kinds, 60
/// frames, one run): medium -0.09 % for 0.996x the wall time (band_qcif
/// -2.2 %, cartoon_cif -1.8 %; fish_1160 +1.6 %); steps across alone,
/// without the diagonals, -0.19 % for 1.004x.
const FULL_PEL_MOVES: usize = 8;

/// How far above the 16x16 estimate a split of candidates alone may come
/// and still be searched (then coded where the search makes it beat the
/// estimate), where [`crate::encode::EncoderConfig::split_search_margin`]
/// says so: candidates alone miss the motion the walk finds. With the
/// walk, against neither (the same kind of run): slow -0.81 % for 1.034x
/// (band_qcif -6.9 %, static_noise_cif -2.9 %, testsrc2_qcif -2.6 %;
/// fish_1160 +1.1 %); with steps across alone, medium -1.05 % for 1.062x
/// (band_qcif -6.4 %, testsrc2_qcif and cartoon_cif -3.0 %), and every
/// split searched, medium -1.10 % for 1.149x. Slower keeps its own 5/4
/// (`analyse_split`).
pub(crate) const ROUGH_SPLIT_MARGIN: f64 = 1.1;

/// A diamond at each step, walked until its centre is best (x264's
/// sub-pel refinement of partitions at its medium settings).
const DIRECTIONS: [(i32, i32); 4] = [(0, -1), (-1, 0), (1, 0), (0, 1)];
/// The four diagonal steps, where the full-pel walk's steps across stop.
const DIAGONALS: [(i32, i32); 4] = [(-1, -1), (1, -1), (-1, 1), (1, 1)];

impl PartitionSearch<'_> {
    /// SATD of 8x8 block `b` of the macroblock (raster order) with `mv`:
    /// on the half-pel planes when they reach, else the codec's filter.
    fn block_satd(&self, b: usize, mv: Mv) -> u32 {
        let key = block_key(b, mv);
        if let Some(satd) = self.satd8.borrow().get(key) {
            return satd;
        }
        let (bx, by) = (8 * (b % 2), 8 * (b / 2));
        let x = (self.mb.0 * MB + bx) as isize;
        let y = (self.mb.1 * MB + by) as isize;
        let mut pred = [0u8; 64];
        let window = self.windows[b]
            .get_or_init(|| self.halfpel.and_then(|h| h.window(self.reference, (x, y), 8)))
            .as_ref();
        let (samples, stride) = match window {
            Some(w) if w.holds(mv) => w.block(mv, &mut pred),
            _ => block_or_predicted(self.halfpel, self.reference, (x, y), mv, 8, &mut pred),
        };
        let satd = Metric::Satd.cost(&self.source[by * MB + bx..], MB, samples, stride, 8, 8);
        self.satd8.borrow_mut().insert(key, satd);
        satd
    }

    /// SATD + lambda * bits of partition `p` with vector `mv` predicted by
    /// `mvp`.
    fn cost(&self, p: &Part, mv: Mv, mvp: Mv) -> f64 {
        let satd: u32 = p.blocks().map(|b| self.block_satd(b, mv)).sum();
        f64::from(satd) + self.sad_lambda * f64::from(mvd_bits(mv, mvp))
    }

    /// The best vector of partition `p` among `candidates` and `mvp`,
    /// refined when `refine` says so.
    pub fn best(&self, p: &Part, candidates: &[Mv], mvp: Mv, refine: bool) -> PartChoice {
        let mut best = PartChoice {
            mv: mvp,
            cost: self.cost(p, mvp, mvp),
        };
        for (i, &mv) in candidates.iter().enumerate() {
            if mv == mvp || candidates[..i].contains(&mv) {
                continue;
            }
            let cost = self.cost(p, mv, mvp);
            if cost < best.cost {
                best = PartChoice { mv, cost };
            }
        }
        if !refine {
            return best;
        }
        best = self.full_pel_walk(p, mvp, best);
        for &(step, moves) in &REFINE_STEPS {
            for _ in 0..moves {
                let centre = best.mv;
                best = self.around(p, mvp, best, (centre, step), &DIRECTIONS);
                if best.mv == centre {
                    break;
                }
            }
        }
        best
    }

    /// `best` walked at full pel: from its nearest full-pel position, the
    /// four neighbours a pel away, the diagonal ones where those are no
    /// better, again around the best while one of them is (at most
    /// [`FULL_PEL_MOVES`] times).
    fn full_pel_walk(&self, p: &Part, mvp: Mv, mut best: PartChoice) -> PartChoice {
        let nearest = |mv: Mv| {
            let (x, y) = nearest_full_pel(mv);
            Mv::full_pel(x, y)
        };
        let rounded = nearest(best.mv);
        if rounded != best.mv && rounded.in_range() {
            let cost = self.cost(p, rounded, mvp);
            if cost < best.cost {
                best = PartChoice { mv: rounded, cost };
            }
        }
        let mut centre = nearest(best.mv);
        for _ in 0..FULL_PEL_MOVES {
            let before = best.mv;
            best = self.around(p, mvp, best, (centre, 4), &DIRECTIONS);
            if best.mv == before {
                // Smooth content leaves a valley along a diagonal (the
                // block's mean error cancels there), where no step across
                // lowers the cost.
                best = self.around(p, mvp, best, (centre, 4), &DIAGONALS);
                if best.mv == before {
                    break;
                }
            }
            centre = best.mv;
        }
        best
    }

    /// `best` or the best of `steps` (in units of `step` quarter pels)
    /// around `centre`.
    fn around(
        &self,
        p: &Part,
        mvp: Mv,
        mut best: PartChoice,
        (centre, step): (Mv, i32),
        steps: &[(i32, i32)],
    ) -> PartChoice {
        for &(dx, dy) in steps {
            let mv = Mv::new(centre.x + step * dx, centre.y + step * dy);
            if !mv.in_range() {
                continue;
            }
            let cost = self.cost(p, mv, mvp);
            if cost < best.cost {
                best = PartChoice { mv, cost };
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::partition::Split;

    /// A `size` x `size` plane of `texture`, borders extended.
    fn textured(size: usize, texture: impl Fn(isize, isize) -> u8) -> Plane {
        let mut plane = Plane::with_padding(size, size, 32).unwrap();
        for y in 0..size {
            for x in 0..size {
                plane.set(x, y, texture(x as isize, y as isize));
            }
        }
        plane.extend_border();
        plane
    }

    /// The search of macroblock (1, 1) of `source` in `reference`, one bit
    /// weighing one unit of SATD, no half-pel planes.
    fn search_of<'a>(
        source: &'a [u8; 256],
        reference: &'a Plane,
        cache: &'a RefCell<SatdCache>,
    ) -> PartitionSearch<'a> {
        PartitionSearch {
            source,
            reference,
            halfpel: None,
            mb: (1, 1),
            sad_lambda: 1.0,
            satd8: cache,
            windows: Default::default(),
        }
    }

    #[test]
    fn each_half_finds_its_own_shift() {
        // Reference: a texture. Source macroblock (1, 1): its top half is
        // the reference moved by (+3, 0) pixels, its bottom half by (0, -2).
        let reference = textured(48, |x, y| ((x * 37 + y * 91 + (x * y) % 13) % 251) as u8);
        let mut source = [0u8; 256];
        for y in 0..16 {
            for x in 0..16 {
                let (sx, sy) = (16 + x as isize, 16 + y as isize);
                source[y * 16 + x] = if y < 8 {
                    reference.at(sx + 3, sy)
                } else {
                    reference.at(sx, sy - 2)
                };
            }
        }
        let cache = RefCell::default();
        let search = search_of(&source, &reference, &cache);
        let parts = Split::Horizontal.parts();
        // Candidates half a pel off each true vector: the refinement lands
        // on it, with zero SATD; without refinement they stay.
        let top = search.best(&parts[0], &[Mv::new(14, 0)], Mv::ZERO, true);
        let bottom = search.best(&parts[1], &[Mv::new(0, -10)], Mv::ZERO, true);
        let rough = search.best(&parts[1], &[Mv::new(0, -10)], Mv::new(0, -10), false);
        assert_eq!(rough.mv, Mv::new(0, -10));
        assert_eq!(top.mv, Mv::full_pel(3, 0));
        assert_eq!(bottom.mv, Mv::full_pel(0, -2));
        // The costs are the vector bits alone.
        assert_eq!(top.cost, f64::from(mvd_bits(top.mv, Mv::ZERO)));
    }

    #[test]
    fn the_walk_finds_motion_no_candidate_is_near() {
        // A smooth texture (no minimum within a few pels but the true one),
        // the source macroblock (1, 1) the reference moved by (-3, +2)
        // pixels: sample (x, y) of the source is (x + 3, y - 2) of the
        // reference, the vector (3, -2) pels.
        let reference = textured(64, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 50.0 * (x / 5.0).sin() + 40.0 * (y / 6.0).cos()).round() as u8
        });
        let mut source = [0u8; 256];
        for y in 0..16 {
            for x in 0..16 {
                source[y * 16 + x] = reference.at(16 + x as isize + 3, 16 + y as isize - 2);
            }
        }
        let cache = RefCell::default();
        let search = search_of(&source, &reference, &cache);
        let truth = Mv::full_pel(3, -2);
        for (k, part) in Split::Quad.parts().iter().enumerate() {
            // No candidate but the predicted vector, zero: the walk goes
            // the five pels to the vector; candidates alone stay at zero.
            let walked = search.best(part, &[], Mv::ZERO, true);
            assert_eq!(walked.mv, truth, "block {k}");
            let rough = search.best(part, &[], Mv::ZERO, false);
            assert_eq!(rough.mv, Mv::ZERO, "block {k}");
        }
    }
}
