//! Rate estimates of the mode decision: the bits of a macroblock's mode and
//! residual as the frame's coders would code them now, priced bin by bin
//! in the contexts' present state (x264's `rdo.c` cabac size functions).
//! The codec gives the binarisation (`replay` of its mode and residual
//! coders, the 4x4 and 8x8 blocks' bins) and the price of one bin
//! (`entropy::Pricer`, the writer's statistics' table); what to price and
//! how fast is the encoder's. Prices are in 1/256 bit.

use crate::codec::entropy::{cost_table, Context, Pricer, BYPASS_COST};
use crate::codec::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::codec::residual::{
    chroma_dc_base, chroma_dc_flag_context, class8_base, code_block, magnitude_bins, BlockClass, MbResidual,
    ResidualCoder, ResidualSyntax, ScanContexts, SCAN4, SCAN8, SCAN_DC, ZIGZAG,
};
use crate::codec::transform::Block4;
use crate::codec::transform8x8::{Block8, ZIGZAG8};

mod trials;
pub use trials::{few_levels, TrialPrices, WholeTrials};

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

/// A rough count of the bits coding `res` takes, from its levels alone:
/// 2 a coded 4x4 block (its flag and the zeros before its last level), 5 a
/// non-zero level (significance, last flag, the first magnitude bin,
/// sign) and 2 for each step of its magnitude above one (16 at most).
/// What the fast mode decision without the 8x8 transform (ultrafast)
/// weighs the coded macroblock against skip with, instead of pricing its
/// bins ([`residual_cost`]): x264 below `--subme 6` takes skip only where
/// nothing is coded. Against the exact price (`benches/pair.py`, the 28
/// sequences' first 60 frames, one run each): ultrafast -0.06 % on the
/// mean (poster_384 -2.3 %, cuts_cif +1.9 %) for 0.945x the wall time in
/// a run that shared the machine with a build (0.961x for a first
/// version alone; `farm-bench` of cockatoo_720p, diver_vga and
/// garden_720p at QP 27-32: 0.96-0.99x, the gain the largest at QP 22);
/// with no residual bits at all +0.01 % for 0.978x (dark_cif -14.0 %,
/// fish_1160 +6.5 %: more coded, and more to write). Not where the 8x8
/// transform is tried, whose choice weighs the two transforms' bits,
/// which the counts do not tell apart: superfast +0.95 % for 0.966x
/// (testsrc2_qcif +15.5 %), veryfast +0.92 % for 1.009x.
// (Inlined into the coder table's kernels: each level's table compiles it
// for its instruction set.)
#[inline(always)]
pub fn residual_estimate(res: &MbResidual) -> f64 {
    let mut sum = Estimate::default();
    for block in res.luma.iter().chain(res.chroma.iter().flatten()) {
        sum.add_block(block.as_flattened());
    }
    for block in res.luma8.iter().flat_map(|b| b.iter()) {
        // An 8x8 block counts as the four 4x4 ones it replaces.
        for quarter in block.as_flattened().chunks_exact(16) {
            sum.add_block(quarter);
        }
    }
    sum.add_block(&res.luma_dc);
    f64::from(2 * sum.blocks + 5 * sum.levels + 2 * sum.magnitude)
}

/// The counts [`residual_estimate`] weighs.
#[derive(Default)]
struct Estimate {
    blocks: u32,
    levels: u32,
    magnitude: u32,
}

impl Estimate {
    #[inline(always)]
    fn add_block(&mut self, levels: &[i32]) {
        let (mut count, mut magnitude) = (0, 0);
        for &v in levels {
            let a = v.unsigned_abs();
            count += u32::from(a != 0);
            magnitude += a.saturating_sub(1).min(16);
        }
        self.blocks += u32::from(count != 0);
        self.levels += count;
        self.magnitude += magnitude;
    }
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

/// The prices of one block class's bins, laid out by scan position, so
/// that a block is priced from its non-zero levels alone: the significance
/// bins of a run of zeros are one prefix sum, each non-zero level adds its
/// own significance and last flags, then its magnitude. Gives exactly
/// what replaying [`code_block`] / [`code_block8`] bin by bin gives (the
/// same integer prices added in another order); RDOQ prices every trial
/// block this way.
#[derive(Debug, Clone)]
struct ScanPrices<const N: usize> {
    /// `zero_run[n]`: the significance bins of positions `0..n`, all zero.
    zero_run: [u32; N],
    /// What a non-zero level at a position adds over a zero there: its
    /// significance as one, and its last flag as zero (wrapping: it may
    /// be less).
    nonzero: [u32; N],
    /// What the last flag costs more as one than as zero, per position.
    last_gain: [u32; N],
    /// By [`LevelState`]: a level of 1 (its "> 1" bin and sign), a level
    /// above 1 before its magnitude bins, and a magnitude bin of one and
    /// of zero.
    one: [u32; LevelState::COUNT],
    big: [u32; LevelState::COUNT],
    abs_one: [u32; LevelState::COUNT],
    abs_zero: [u32; LevelState::COUNT],
}

impl<const N: usize> ScanPrices<N> {
    /// The prices of the class whose first context is `cls` in `contexts`
    /// present state, laid out as `scan` says.
    fn new(contexts: &[Context], cls: usize, scan: &ScanContexts<N>) -> ScanPrices<N> {
        let table = cost_table();
        let price = |ctx: usize| contexts[cls + ctx].costs_in(table);
        let mut zero_run = [0u32; N];
        let (mut nonzero, mut last_gain) = ([0u32; N], [0u32; N]);
        for i in 0..N - 1 {
            let (sig, last) = (price(scan.sig[i]), price(scan.last[i]));
            zero_run[i + 1] = zero_run[i] + sig[0];
            nonzero[i] = (sig[1] + last[0]).wrapping_sub(sig[0]);
            last_gain[i] = last[1].wrapping_sub(last[0]);
        }
        let gt1: [[u32; 2]; 5] = std::array::from_fn(|k| price(scan.gt1 + k));
        let abs: [[u32; 2]; 5] = std::array::from_fn(|k| price(scan.abs + k));
        let (first, magnitude) = (LevelState::FIRST, LevelState::MAGNITUDE);
        ScanPrices {
            zero_run,
            nonzero,
            last_gain,
            one: std::array::from_fn(|s| gt1[first[s]][0] + BYPASS_COST),
            big: std::array::from_fn(|s| gt1[first[s]][1] + BYPASS_COST),
            abs_one: std::array::from_fn(|s| abs[magnitude[s]][1]),
            abs_zero: std::array::from_fn(|s| abs[magnitude[s]][0]),
        }
    }

    /// The bins of a block whose scan position `i` holds `level(i)`,
    /// non-zero exactly at the bits of `mask` (not empty).
    #[inline]
    fn cost(&self, mask: u64, level: impl Fn(usize) -> i32) -> u32 {
        let last = 63 - mask.leading_zeros() as usize;
        let mut cost = self.last_at(last);
        // (The final position has no flags.)
        let mut flagged = mask & !(1 << (N - 1));
        while flagged != 0 {
            cost = cost.wrapping_add(self.nonzero[flagged.trailing_zeros() as usize]);
            flagged &= flagged - 1;
        }
        // The levels in reverse scan order.
        let mut state = LevelState::START;
        let mut rest = mask;
        while rest != 0 {
            let i = 63 - rest.leading_zeros() as usize;
            rest &= !(1 << i);
            let a = level(i).unsigned_abs();
            cost = cost.wrapping_add(self.level_cost(a, state));
            state = state.after(a);
        }
        cost
    }

    /// The significance and last flags of the positions up to the last
    /// non-zero one, `last`, all as zeros but its own (the final position
    /// has none), before [`ScanPrices::flag_of`] each non-zero one.
    #[inline(always)]
    fn last_at(&self, last: usize) -> u32 {
        if last < N - 1 {
            self.zero_run[last + 1].wrapping_add(self.last_gain[last])
        } else {
            self.zero_run[N - 1]
        }
    }

    /// What a non-zero level at position `i` adds to the flags (wrapping:
    /// it may be less).
    #[inline(always)]
    fn flag_of(&self, i: usize) -> u32 {
        if i < N - 1 {
            self.nonzero[i]
        } else {
            0
        }
    }

    /// The bins of a level of magnitude `a` (not 0) coded in `state`.
    #[inline(always)]
    fn level_cost(&self, a: u32, state: LevelState) -> u32 {
        let s = usize::from(state.0);
        if a > 1 {
            let (ones, zero, bypass) = magnitude_bins(a - 2);
            self.big[s] + ones * self.abs_one[s] + u32::from(zero) * self.abs_zero[s] + bypass * BYPASS_COST
        } else {
            self.one[s]
        }
    }

    /// [`ScanPrices::level_cost`] of a level of magnitude `a` in each
    /// state, beside `then`'s cost of what follows it from the state
    /// after it: the bins of `a` and the levels after, from each state.
    /// (Written out, the magnitude's bins found once for the eight states:
    /// through `level_cost` birds_720p's I frame at QP 22 took 1.59 G
    /// instructions against 1.44 G.)
    #[inline(always)]
    fn level_then(&self, a: u32, then: &[u32; LevelState::COUNT]) -> [u32; LevelState::COUNT] {
        if a > 1 {
            let (ones, zero, bypass) = magnitude_bins(a - 2);
            let (zero, bypass) = (u32::from(zero), bypass * BYPASS_COST);
            std::array::from_fn(|s| {
                let own = self.big[s] + ones * self.abs_one[s] + zero * self.abs_zero[s] + bypass;
                own.wrapping_add(then[LevelState::AFTER_BIG[s]])
            })
        } else {
            std::array::from_fn(|s| self.one[s].wrapping_add(then[LevelState::AFTER_ONE[s]]))
        }
    }
}

/// What the level bins' contexts depend on after some of a block's levels
/// in reverse scan order (the residual syntax's `level_contexts`): the
/// count of levels equal to 1 (up to 3) while none is above 1, then the
/// count of those above 1 (up to 4). Eight states, 0-3 and 4-7.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct LevelState(u8);

impl LevelState {
    const START: LevelState = LevelState(0);
    const COUNT: usize = 8;
    /// The state after a level of 1, and after one above 1, by state: a
    /// 1 counts while none is above 1 (up to 3), a level above 1 counts
    /// from then on (up to 4).
    const AFTER_ONE: [usize; 8] = [1, 2, 3, 3, 4, 5, 6, 7];
    const AFTER_BIG: [usize; 8] = [4, 4, 4, 4, 5, 6, 7, 7];
    /// The contexts of the next level's first bin and of its magnitude,
    /// by state.
    const FIRST: [usize; 8] = [1, 2, 3, 4, 0, 0, 0, 0];
    const MAGNITUDE: [usize; 8] = [0, 0, 0, 0, 1, 2, 3, 4];

    /// The state after a level of magnitude `a` (not 0).
    #[inline(always)]
    fn after(self, a: u32) -> LevelState {
        let s = usize::from(self.0);
        LevelState(if a > 1 {
            Self::AFTER_BIG[s]
        } else {
            Self::AFTER_ONE[s]
        } as u8)
    }
}

/// Bit `k` set where scan position `k` of `flat` (in raster order, `scan`
/// its zig-zag) is non-zero.
#[inline]
fn scan_mask(flat: &[i32], scan: &[usize]) -> u64 {
    scan.iter()
        .enumerate()
        .fold(0, |m, (k, &r)| m | u64::from(flat[r] != 0) << k)
}

/// A block's levels in scan order with the mask of the non-zero ones:
/// what RDOQ changes a level at a time and prices after each change,
/// without gathering the block again.
#[derive(Debug, Clone, Copy)]
pub struct ScanLevels<const N: usize> {
    /// The level at each scan position.
    pub levels: [i32; N],
    /// Bit `k` set where `levels[k]` is non-zero.
    pub mask: u64,
}

impl<const N: usize> ScanLevels<N> {
    /// The levels of `flat` (raster order) along `zigzag`.
    #[inline]
    pub fn gather(flat: &[i32], zigzag: &[usize; N]) -> ScanLevels<N> {
        ScanLevels {
            levels: std::array::from_fn(|k| flat[zigzag[k]]),
            mask: scan_mask(flat, zigzag),
        }
    }

    /// Sets scan position `k` to `v`.
    #[inline]
    pub fn set(&mut self, k: usize, v: i32) {
        self.levels[k] = v;
        self.mask = self.mask & !(1 << k) | u64::from(v != 0) << k;
    }
}

/// [`block_cost`] for one block class with the prices of its contexts'
/// bins looked up once: what pricing many trial blocks against the same
/// state needs (RDOQ).
#[derive(Debug, Clone)]
pub struct BlockPricer {
    prices: ScanPrices<16>,
    /// The coded flag's prices (0, 1) with one coded neighbour.
    flag: (u32, u32),
}

/// The [`BlockPricer`] of `class` in `coder`'s present state.
pub fn block_pricer(coder: &ResidualCoder, class: BlockClass) -> BlockPricer {
    let flag = coder.contexts()[class.coded_flag_context(1)].costs_in(cost_table());
    BlockPricer {
        prices: ScanPrices::new(coder.contexts(), class.first_context(), &SCAN4),
        flag: (flag[0], flag[1]),
    }
}

/// The [`BlockPricer`] of the chroma blocks' AC levels of intra (`true`)
/// or inter macroblocks in `coder`'s present state.
pub fn chroma_ac_pricer(coder: &ResidualCoder, intra: bool) -> BlockPricer {
    ac_pricer(coder, BlockClass::chroma(intra))
}

/// The [`BlockPricer`] of an intra 16x16 macroblock's luma blocks' AC
/// levels in `coder`'s present state.
pub fn luma_ac_pricer(coder: &ResidualCoder) -> BlockPricer {
    ac_pricer(coder, BlockClass::luma_ac16())
}

/// The [`BlockPricer`] of `class`'s blocks whose position 0 holds a DC
/// level coded apart (or none): no bin of the scan's first position is
/// priced.
fn ac_pricer(coder: &ResidualCoder, class: BlockClass) -> BlockPricer {
    let mut pricer = block_pricer(coder, class);
    let first = pricer.prices.zero_run[1];
    for run in &mut pricer.prices.zero_run[1..] {
        *run -= first;
    }
    pricer
}

/// The prices of a chroma plane's DC levels (its coded flag and its
/// 4-position block) in intra or inter macroblocks.
#[derive(Debug, Clone)]
pub struct ChromaDcPricer {
    prices: ScanPrices<4>,
    /// Per plane (Cb, Cr), the coded flag's prices (0, 1).
    flag: [[u32; 2]; 2],
    /// A chroma block's AC coded flag's prices (0, 1), one coded
    /// neighbour.
    ac_flag: [u32; 2],
}

/// The [`ChromaDcPricer`] of intra (`true`) or inter macroblocks in
/// `coder`'s present state.
pub fn chroma_dc_pricer(coder: &ResidualCoder, intra: bool) -> ChromaDcPricer {
    let contexts = coder.contexts();
    let base = chroma_dc_base(intra);
    let table = cost_table();
    ChromaDcPricer {
        prices: ScanPrices::new(contexts, base, &SCAN_DC),
        flag: std::array::from_fn(|p| contexts[chroma_dc_flag_context(intra, p)].costs_in(table)),
        ac_flag: contexts[BlockClass::chroma(intra).coded_flag_context(1)].costs_in(table),
    }
}

impl ChromaDcPricer {
    /// The prices (1/256 bit) of a chroma block's AC coded flag of 0 and
    /// of 1, with one coded neighbour.
    pub fn ac_flag_prices(&self) -> (u32, u32) {
        (self.ac_flag[0], self.ac_flag[1])
    }

    /// The bits (1/256) of plane `p`'s DC `levels` (block order).
    pub fn cost(&self, p: usize, levels: &[i32; 4]) -> u32 {
        let mask = (0..4).filter(|&k| levels[k] != 0).fold(0u64, |m, k| m | 1 << k);
        if mask == 0 {
            return self.flag[p][0];
        }
        self.flag[p][1] + self.prices.cost(mask, |k| levels[k])
    }
}

impl BlockPricer {
    /// What [`block_cost`] gives for `block` in the state the pricer was
    /// made from.
    pub fn block_cost(&self, block: &Block4) -> u32 {
        self.scan_cost(&ScanLevels::gather(block.as_flattened(), &ZIGZAG))
    }

    /// [`BlockPricer::block_cost`] of the block whose levels in scan
    /// order are `scan`.
    #[inline]
    pub fn scan_cost(&self, scan: &ScanLevels<16>) -> u32 {
        if scan.mask == 0 {
            return 0;
        }
        let levels = self.prices.cost(scan.mask, |i| scan.levels[i]);
        (self.flag.1 + levels).saturating_sub(self.flag.0)
    }
}

/// The prices of the 8x8 luma blocks' bins of intra or inter macroblocks.
#[derive(Debug, Clone)]
pub struct Block8Pricer {
    prices: ScanPrices<64>,
}

/// The [`Block8Pricer`] of intra (`true`) or inter macroblocks in
/// `coder`'s present state.
pub fn block8_pricer(coder: &ResidualCoder, intra: bool) -> Block8Pricer {
    Block8Pricer {
        prices: ScanPrices::new(coder.contexts(), class8_base(intra), &SCAN8),
    }
}

impl Block8Pricer {
    /// The bits of `block`'s levels (0 for an all-zero block; its pattern
    /// bit is the caller's).
    pub fn block_cost(&self, block: &Block8) -> u32 {
        self.scan_cost(&ScanLevels::gather(block.as_flattened(), &ZIGZAG8))
    }

    /// [`Block8Pricer::block_cost`] of the block whose levels in scan
    /// order are `scan`.
    #[inline]
    pub fn scan_cost(&self, scan: &ScanLevels<64>) -> u32 {
        if scan.mask == 0 {
            return 0;
        }
        self.prices.cost(scan.mask, |i| scan.levels[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::residual::{chroma_dc_levels, code_block8, code_block_ac, code_chroma_dc};

    fn lcg(seed: u32) -> impl FnMut(u32) -> i32 {
        let mut seed = seed;
        move |n: u32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            ((seed >> 16) % n) as i32
        }
    }

    /// Sparse levels, one in `odds` non-zero: small ones, some past the
    /// unary part.
    fn sparse_levels<'b>(
        blocks: impl Iterator<Item = &'b mut Block4>,
        next: &mut impl FnMut(u32) -> i32,
        odds: u32,
    ) {
        for v in blocks.flat_map(|b| b.as_flattened_mut()) {
            *v = match next(odds) {
                0 => next(5) - 2,
                1 => next(61) - 30,
                _ => 0,
            };
        }
    }

    #[test]
    fn the_block_pricer_prices_as_block_cost() {
        let mut next = lcg(5);
        let mut coder = ResidualCoder::new(4, 4);
        for round in 0..200 {
            let mut res = MbResidual::default();
            sparse_levels(
                res.luma.iter_mut().chain(res.chroma.iter_mut().flatten()),
                &mut next,
                10,
            );
            let intra = round % 3 == 0;
            for class in [BlockClass::luma(intra), BlockClass::chroma(intra)] {
                let pricer = block_pricer(&coder, class);
                let blocks: Vec<&Block4> = if class == BlockClass::chroma(intra) {
                    res.chroma.iter().flatten().collect()
                } else {
                    res.luma.iter().collect()
                };
                for b in blocks {
                    let want = block_cost(&coder, class, b);
                    assert_eq!(pricer.block_cost(b), want);
                    assert_eq!(
                        pricer.scan_cost(&ScanLevels::gather(b.as_flattened(), &ZIGZAG)),
                        want
                    );
                }
            }
            // Adapt, so that later rounds price other states.
            coder.commit(round % 4, round / 4 % 4, ResidualSyntax::of_4x4(intra), &res);
        }
    }

    #[test]
    fn the_chroma_pricers_price_as_the_bins_coded() {
        let mut next = lcg(11);
        let mut coder = ResidualCoder::new(4, 4);
        for round in 0..200 {
            let mut res = MbResidual::default();
            sparse_levels(res.chroma.iter_mut().flatten(), &mut next, 8);
            let intra = round % 3 == 0;
            let (ac, dc) = (chroma_ac_pricer(&coder, intra), chroma_dc_pricer(&coder, intra));
            let class = BlockClass::chroma(intra);
            let flag = &coder.contexts()[class.coded_flag_context(1)];
            for (p, plane) in res.chroma.iter().enumerate() {
                let levels = chroma_dc_levels(plane);
                let mut bins = Pricer::new(coder.contexts(), 0);
                code_chroma_dc(&mut bins, intra, p, &levels);
                assert_eq!(dc.cost(p, &levels), bins.cost, "DC {levels:?}");
                for b in plane {
                    let mut only_ac = *b;
                    only_ac[0][0] = 0;
                    let want = if is_zero(&only_ac) {
                        0
                    } else {
                        let mut bins = Pricer::new(coder.contexts(), flag.cost(true));
                        code_block_ac(&mut bins, class.first_context(), &only_ac);
                        bins.cost.saturating_sub(flag.cost(false))
                    };
                    assert_eq!(ac.block_cost(&only_ac), want, "AC {only_ac:?}");
                }
            }
            coder.commit(round % 4, round / 4 % 4, ResidualSyntax::of_4x4(intra), &res);
        }
    }

    /// A random 8x8 block: sparse or dense, small levels and some past
    /// the unary part, the final scan position sometimes set.
    fn random_block8(next: &mut impl FnMut(u32) -> i32) -> Block8 {
        let density = 1 + next(8) as u32;
        let mut b8: Block8 = [[0; 8]; 8];
        for v in b8.as_flattened_mut() {
            if next(density) == 0 {
                *v = match next(12) {
                    0 => next(401) - 200,
                    1..=3 => next(31) - 15,
                    _ => next(5) - 2,
                };
            }
        }
        if next(4) == 0 {
            b8[7][7] = next(7) - 3;
        }
        b8
    }

    #[test]
    fn the_8x8_pricer_prices_the_blocks_bins() {
        let mut next = lcg(77);
        let mut coder = ResidualCoder::new(4, 4);
        for round in 0..120 {
            let intra = round % 2 == 0;
            let pricer = block8_pricer(&coder, intra);
            let blocks: [Block8; 4] = std::array::from_fn(|_| random_block8(&mut next));
            for b8 in &blocks {
                let mut p = Pricer::new(coder.contexts(), 0);
                if b8.as_flattened().iter().any(|&v| v != 0) {
                    code_block8(&mut p, class8_base(intra), b8);
                }
                assert_eq!(pricer.block_cost(b8), p.cost, "round {round}: {b8:?}");
                let scan = ScanLevels::gather(b8.as_flattened(), &ZIGZAG8);
                assert_eq!(pricer.scan_cost(&scan), p.cost);
            }
            // Adapt the 8x8 contexts, so that later rounds price other
            // states.
            let res = MbResidual {
                luma8: Some(Box::new(blocks)),
                ..MbResidual::default()
            };
            let syntax = if intra {
                ResidualSyntax::Intra8x8
            } else {
                ResidualSyntax::Inter
            };
            coder.commit(round % 4, round / 4 % 4, syntax, &res);
        }
    }

    #[test]
    fn level_states_give_the_contexts_of_the_levels_counted() {
        // Every run of up to 10 levels of 1 and above 1 (as bits), the
        // counts kept whole beside the eight states.
        for len in 0..=10u32 {
            for run in 0..1u32 << len {
                let (mut eq1, mut gt1, mut state) = (0, 0, LevelState::START);
                for k in 0..len {
                    let big = run >> k & 1 == 1;
                    state = state.after(if big { 2 } else { 1 });
                    if big {
                        gt1 += 1;
                    } else {
                        eq1 += 1;
                    }
                    let s = usize::from(state.0);
                    let want = crate::codec::residual::level_contexts(eq1, gt1);
                    assert_eq!(
                        (LevelState::FIRST[s], LevelState::MAGNITUDE[s]),
                        want,
                        "{eq1} {gt1}"
                    );
                }
            }
        }
    }

    #[test]
    fn scan_levels_follow_their_changes() {
        // Levels set one at a time, to zero and back, hold the same
        // levels and mask as gathering the changed block.
        let mut next = lcg(3);
        let mut b8 = random_block8(&mut next);
        let mut scan = ScanLevels::gather(b8.as_flattened(), &ZIGZAG8);
        for _ in 0..500 {
            let k = next(64) as usize;
            let v = if next(2) == 0 { 0 } else { next(9) - 4 };
            scan.set(k, v);
            let raster = ZIGZAG8[k];
            b8[raster / 8][raster % 8] = v;
            let want = ScanLevels::gather(b8.as_flattened(), &ZIGZAG8);
            assert_eq!((scan.levels, scan.mask), (want.levels, want.mask));
        }
    }

    #[test]
    fn the_estimate_follows_the_price() {
        // From dense levels to sparse ones, the estimate stays within a
        // factor of the bins' price (fresh contexts), and grows with the
        // levels: the fast decision weighs it against skip.
        assert_eq!(residual_estimate(&MbResidual::default()), 0.0);
        let mut next = lcg(5);
        let mut last = f64::INFINITY;
        for odds in [2, 3, 6, 12, 40] {
            let mut res = MbResidual::default();
            sparse_levels(
                res.luma.iter_mut().chain(res.chroma.iter_mut().flatten()),
                &mut next,
                odds,
            );
            let estimate = residual_estimate(&res);
            let price = residual_cost(&ResidualCoder::new(2, 2), (0, 0), ResidualSyntax::Inter, &res);
            let priced = crate::encode::rdo::bits(price);
            // (1.1 to 1.6 when written: the magnitude steps of levels
            // past the unary part cost less than 2 bits each.)
            let ratio = estimate / priced;
            assert!(
                (0.5..=2.0).contains(&ratio),
                "odds {odds}: {estimate} vs {priced}"
            );
            assert!(estimate < last, "sparser levels, fewer bits");
            last = estimate;
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
