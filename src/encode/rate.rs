//! Rate estimates of the mode decision: the bits of a macroblock's mode and
//! residual as the frame's coders would code them now, priced bin by bin
//! in the contexts' present state (x264's `rdo.c` cabac size functions).
//! The codec gives the binarisation (`replay` of its mode and residual
//! coders, the 4x4 and 8x8 blocks' bins) and the price of one bin
//! (`entropy::Pricer`, the writer's statistics' table); what to price and
//! how fast is the encoder's. Prices are in 1/256 bit.

use crate::codec::entropy::{cost_table, Bins, Pricer, BYPASS_COST};
use crate::codec::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::codec::residual::{
    class8_base, code_block, code_block8, BlockClass, MbResidual, ResidualCoder, ResidualSyntax,
    CLASS8_CONTEXTS, CLASS_CONTEXTS,
};
use crate::codec::transform::Block4;
use crate::codec::transform8x8::Block8;

/// The bits of coding `mode` as macroblock (mb_x, mb_y) now
/// (`inter_frame`: a P frame; `vectors`: which vectors the frame codes).
pub fn mode_cost(
    modes: &ModeCoder,
    at: (usize, usize),
    inter_frame: bool,
    vectors: VectorSyntax,
    mode: &MbMode,
) -> u32 {
    let mut p = Pricer::new(modes.contexts(), 0);
    modes.replay(&mut p, at, inter_frame, vectors, mode);
    p.cost
}

/// The bits of the flag saying macroblock (mb_x, mb_y) of a P frame is not
/// skipped: what every choice but skip spends at least.
pub fn not_skipped_cost(modes: &ModeCoder, (mb_x, mb_y): (usize, usize)) -> u32 {
    modes.contexts()[modes.skip_context(mb_x, mb_y)].cost(false)
}

/// The bits of a 4x4 or 8x8 intra mode that is the most probable one and
/// of one that is not (its three bins taken at their mean price).
pub fn mode4_costs(modes: &ModeCoder) -> (u32, u32) {
    let (flag, rest) = ModeCoder::MODE4_CONTEXTS;
    let (flag, rest) = (&modes.contexts()[flag], &modes.contexts()[rest]);
    (
        flag.cost(true),
        flag.cost(false) + 3 * (rest.cost(false) + rest.cost(true)) / 2,
    )
}

/// The bits of coding `res` as macroblock (mb_x, mb_y) now (the contexts
/// not adapted within the macroblock).
pub fn residual_cost(
    coder: &ResidualCoder,
    (mb_x, mb_y): (usize, usize),
    syntax: ResidualSyntax,
    res: &MbResidual,
) -> u32 {
    let mut p = Pricer::new(coder.contexts(), 0);
    coder.replay(&mut p, mb_x, mb_y, syntax, res);
    p.cost
}

fn is_zero<const N: usize>(block: &[[i32; N]; N]) -> bool {
    block.as_flattened().iter().all(|&v| v == 0)
}

/// What coding `block` adds over an all-zero block in its place (0 for an
/// all-zero block): its levels and the change of its coded flag, priced
/// with one coded neighbour (for per-block decisions).
pub fn block_cost(coder: &ResidualCoder, class: BlockClass, block: &Block4) -> u32 {
    if is_zero(block) {
        return 0;
    }
    let flag = &coder.contexts()[class.coded_flag_context(1)];
    let mut p = Pricer::new(coder.contexts(), flag.cost(true));
    code_block(&mut p, class.first_context(), block);
    p.cost.saturating_sub(flag.cost(false))
}

/// [`block_cost`] for one block class with the prices of its contexts'
/// bins looked up once: what pricing many trial blocks against the same
/// state needs (RDOQ).
#[derive(Debug, Clone)]
pub struct BlockPricer {
    /// Price of a 0 and of a 1 in each of the class's contexts.
    costs: [[u32; 2]; CLASS_CONTEXTS],
    cls: usize,
    /// The coded flag's prices (0, 1) with one coded neighbour.
    flag: (u32, u32),
}

/// The [`BlockPricer`] of `class` in `coder`'s present state.
pub fn block_pricer(coder: &ResidualCoder, class: BlockClass) -> BlockPricer {
    let cls = class.first_context();
    let table = cost_table();
    let costs: [[u32; 2]; CLASS_CONTEXTS] =
        std::array::from_fn(|k| coder.contexts()[cls + k].costs_in(table));
    let [flag0, flag1] = costs[class.coded_flag_context(1) - cls];
    BlockPricer {
        costs,
        cls,
        flag: (flag0, flag1),
    }
}

impl BlockPricer {
    /// What [`block_cost`] gives for `block` in the state the pricer was
    /// made from.
    pub fn block_cost(&self, block: &Block4) -> u32 {
        if is_zero(block) {
            return 0;
        }
        let mut p = TablePricer {
            costs: &self.costs,
            first: self.cls,
            cost: self.flag.1,
        };
        code_block(&mut p, self.cls, block);
        p.cost.saturating_sub(self.flag.0)
    }
}

/// The prices of the 8x8 luma blocks' bins of intra or inter macroblocks.
#[derive(Debug, Clone)]
pub struct Block8Pricer {
    costs: [[u32; 2]; CLASS8_CONTEXTS],
    cls: usize,
}

/// The [`Block8Pricer`] of intra (`true`) or inter macroblocks in
/// `coder`'s present state.
pub fn block8_pricer(coder: &ResidualCoder, intra: bool) -> Block8Pricer {
    let cls = class8_base(intra);
    let table = cost_table();
    Block8Pricer {
        costs: std::array::from_fn(|k| coder.contexts()[cls + k].costs_in(table)),
        cls,
    }
}

impl Block8Pricer {
    /// The bits of `block`'s levels (0 for an all-zero block; its pattern
    /// bit is the caller's).
    pub fn block_cost(&self, block: &Block8) -> u32 {
        if is_zero(block) {
            return 0;
        }
        let mut p = TablePricer {
            costs: &self.costs,
            first: self.cls,
            cost: 0,
        };
        code_block8(&mut p, self.cls, block);
        p.cost
    }
}

/// Prices bins from a table of one class's bin prices (`first`: the
/// class's first context).
struct TablePricer<'a> {
    costs: &'a [[u32; 2]],
    first: usize,
    cost: u32,
}

impl Bins for TablePricer<'_> {
    #[inline]
    fn bin(&mut self, ctx: usize, bit: bool) {
        self.cost += self.costs[ctx - self.first][usize::from(bit)];
    }
    fn bypass(&mut self, _: bool) {
        self.cost += BYPASS_COST;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: u32) -> impl FnMut(u32) -> i32 {
        let mut seed = seed;
        move |n: u32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            ((seed >> 16) % n) as i32
        }
    }

    #[test]
    fn the_block_pricer_prices_as_block_cost() {
        let mut next = lcg(5);
        let mut coder = ResidualCoder::new(4, 4);
        for round in 0..200 {
            // Sparse blocks with small levels, some large ones past the
            // unary part.
            let mut res = MbResidual::default();
            for b in res.luma.iter_mut().chain(res.chroma.iter_mut().flatten()) {
                for v in b.as_flattened_mut() {
                    *v = match next(10) {
                        0 => next(5) - 2,
                        1 => next(61) - 30,
                        _ => 0,
                    };
                }
            }
            let intra = round % 3 == 0;
            for class in [BlockClass::luma(intra), BlockClass::chroma(intra)] {
                let pricer = block_pricer(&coder, class);
                let blocks: Vec<&Block4> = if class == BlockClass::chroma(intra) {
                    res.chroma.iter().flatten().collect()
                } else {
                    res.luma.iter().collect()
                };
                for b in blocks {
                    assert_eq!(pricer.block_cost(b), block_cost(&coder, class, b));
                }
            }
            // Adapt, so that later rounds price other states.
            coder.commit(round % 4, round / 4 % 4, ResidualSyntax::of_4x4(intra), &res);
        }
    }

    #[test]
    fn the_8x8_pricer_prices_the_blocks_bins() {
        let mut next = lcg(77);
        let coder = ResidualCoder::new(1, 1);
        for intra in [false, true] {
            let pricer = block8_pricer(&coder, intra);
            for _ in 0..50 {
                let mut b8: Block8 = [[0; 8]; 8];
                for v in b8.as_flattened_mut() {
                    *v = if next(6) == 0 { next(9) - 4 } else { 0 };
                }
                b8[0][0] = 2;
                let mut p = Pricer::new(coder.contexts(), 0);
                code_block8(&mut p, class8_base(intra), &b8);
                assert_eq!(pricer.block_cost(&b8), p.cost);
            }
        }
    }

    #[test]
    fn a_macroblock_prices_as_its_coder_writes_it() {
        // In a fresh state the first macroblock's price is the writer's
        // own count of the bins it writes.
        use crate::codec::entropy::RangeEncoder;
        let mut next = lcg(11);
        let mut res = MbResidual::default();
        for v in res.luma.iter_mut().flat_map(|b| b.as_flattened_mut().iter_mut()) {
            *v = if next(4) == 0 { next(7) - 3 } else { 0 };
        }
        let priced = residual_cost(&ResidualCoder::new(2, 2), (0, 0), ResidualSyntax::Inter, &res);
        let written =
            ResidualCoder::new(2, 2).write(&mut RangeEncoder::new(), 0, 0, ResidualSyntax::Inter, &res);
        assert!(priced > 0);
        // The writer adapts as it goes; the first bin of each context
        // agrees, later ones are estimates: within a tenth.
        assert!(
            (priced as f64 - written as f64).abs() <= 0.1 * written as f64,
            "{priced} vs {written}"
        );
    }
}
