//! The prices of RDOQ's trials in constant time each. RDOQ visits a
//! block's non-zero levels from the last in scan order to the first, and
//! tries each one step lower against the block as it stands: the levels
//! above it decided, those below it as quantised. Priced whole, a trial
//! costs a pass over every level (an 8x8 block with 30 levels, 30 passes
//! of 30); here the levels above are one sum kept as they are decided, and
//! those below one sum per state their contexts may start from, found
//! once. The same integer prices are added, so every trial costs exactly
//! what [`ScanPrices::cost`] gives for its block.

use super::{Block8Pricer, BlockPricer, LevelState, ScanLevels, ScanPrices};

/// What RDOQ's trials cost: the block with the position under trial
/// changed (positions are tried from the last non-zero one down, the
/// highest undecided one each time), and each position decided.
pub trait TrialPrices {
    /// The bits (1/256) of the block with `level` at position `i`.
    fn cost_with(&mut self, i: usize, level: i32) -> u32;
    /// Position `i` decided at `level`; the next trial is below it.
    fn keep(&mut self, i: usize, level: i32);
}

/// Whether a block with the non-zero levels of `mask` is priced whole
/// trial by trial ([`WholeTrials`]) rather than by a [`Descent`]: up to
/// four levels, a few passes over them cost less than the descent's table
/// takes to fill (medium's instructions, callgrind: cockatoo_720p at QP 27,
/// 10 frames, 2.936 G against 2.955 G with every block a descent;
/// birds_720p's I frame at QP 22 1.442 G against 1.441 G).
pub fn few_levels(mask: u64) -> bool {
    mask.count_ones() <= 4
}

/// A pricer of whole blocks in scan order.
pub trait ScanCost<const N: usize> {
    /// The bits (1/256) of the block whose levels in scan order are `scan`.
    fn scan_cost(&self, scan: &ScanLevels<N>) -> u32;
}

impl ScanCost<16> for BlockPricer {
    #[inline(always)]
    fn scan_cost(&self, scan: &ScanLevels<16>) -> u32 {
        BlockPricer::scan_cost(self, scan)
    }
}

impl ScanCost<64> for Block8Pricer {
    #[inline(always)]
    fn scan_cost(&self, scan: &ScanLevels<64>) -> u32 {
        Block8Pricer::scan_cost(self, scan)
    }
}

/// Trials priced as whole blocks: the block as it stands, changed at the
/// position under trial and priced from every level.
#[derive(Debug, Clone)]
pub struct WholeTrials<'p, P, const N: usize> {
    pricer: &'p P,
    scan: ScanLevels<N>,
}

impl<'p, P: ScanCost<N>, const N: usize> WholeTrials<'p, P, N> {
    /// The trials of `scan`'s levels priced by `pricer`.
    pub fn new(pricer: &'p P, scan: ScanLevels<N>) -> Self {
        WholeTrials { pricer, scan }
    }
}

impl<P: ScanCost<N>, const N: usize> TrialPrices for WholeTrials<'_, P, N> {
    #[inline(always)]
    fn cost_with(&mut self, i: usize, level: i32) -> u32 {
        let kept = self.scan.levels[i];
        self.scan.set(i, level);
        let cost = self.pricer.scan_cost(&self.scan);
        self.scan.set(i, kept);
        cost
    }

    #[inline(always)]
    fn keep(&mut self, i: usize, level: i32) {
        self.scan.set(i, level);
    }
}

/// A block's trials priced as they descend: the levels decided one sum
/// and a state, those below one sum per state.
#[derive(Debug, Clone)]
struct Descent<'p, const N: usize> {
    prices: &'p ScanPrices<N>,
    /// The non-zero positions: decided at and above the cursor, as given
    /// below it.
    mask: u64,
    /// The flags those add ([`ScanPrices::flag_of`], wrapping).
    flags: u32,
    /// The level bins of the positions decided, and the state after them.
    decided: u32,
    state: LevelState,
    /// `below[j][s]`: the level bins of the `j` lowest non-zero levels as
    /// given, coded from state `s`.
    below: [[u32; LevelState::COUNT]; N],
    /// How many of the given non-zero positions are still to be decided.
    undecided: usize,
}

impl<'p, const N: usize> Descent<'p, N> {
    #[inline(always)]
    fn new(prices: &'p ScanPrices<N>, scan: &ScanLevels<N>) -> Self {
        let mut below = [[0u32; LevelState::COUNT]; N];
        let count = scan.mask.count_ones() as usize;
        let mut rest = scan.mask;
        // The levels from the first up: each row codes one more level
        // ahead of the row before (the topmost is never needed).
        for j in 1..count {
            let i = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            below[j] = prices.level_then(scan.levels[i].unsigned_abs(), &below[j - 1]);
        }
        let mut flags = 0u32;
        let mut rest = scan.mask;
        while rest != 0 {
            flags = flags.wrapping_add(prices.flag_of(rest.trailing_zeros() as usize));
            rest &= rest - 1;
        }
        Descent {
            prices,
            mask: scan.mask,
            flags,
            decided: 0,
            state: LevelState::START,
            below,
            undecided: count,
        }
    }

    /// [`ScanPrices::cost`] of the block with `level` at position `i`, the
    /// highest undecided non-zero one (`None` where no level is left).
    fn cost_with(&self, i: usize, level: i32) -> Option<u32> {
        debug_assert!(
            self.undecided > 0 && self.mask >> i & 1 == 1,
            "a level at {i} to try"
        );
        let below = &self.below[self.undecided - 1];
        let a = level.unsigned_abs();
        let (mask, flags, levels) = if a == 0 {
            let levels = self.decided.wrapping_add(below[usize::from(self.state.0)]);
            (
                self.mask & !(1 << i),
                self.flags.wrapping_sub(self.prices.flag_of(i)),
                levels,
            )
        } else {
            let own = self.prices.level_cost(a, self.state);
            let levels = self
                .decided
                .wrapping_add(own)
                .wrapping_add(below[usize::from(self.state.after(a).0)]);
            (self.mask, self.flags, levels)
        };
        if mask == 0 {
            return None;
        }
        let last = 63 - mask.leading_zeros() as usize;
        Some(self.prices.last_at(last).wrapping_add(flags).wrapping_add(levels))
    }

    /// Position `i` (the highest undecided non-zero one) decided at
    /// `level`.
    fn keep(&mut self, i: usize, level: i32) {
        let a = level.unsigned_abs();
        if a == 0 {
            self.mask &= !(1 << i);
            self.flags = self.flags.wrapping_sub(self.prices.flag_of(i));
        } else {
            self.decided = self.decided.wrapping_add(self.prices.level_cost(a, self.state));
            self.state = self.state.after(a);
        }
        self.undecided -= 1;
    }
}

/// RDOQ's trials of a 4x4 block as a [`Descent`]
/// ([`BlockPricer::trials`]).
#[derive(Debug, Clone)]
pub struct BlockTrials<'p> {
    levels: Descent<'p, 16>,
    flag: (u32, u32),
}

impl BlockPricer {
    /// The trials of `scan`'s levels as a descent, priced as
    /// [`BlockPricer::scan_cost`] prices the blocks they make.
    #[inline(always)]
    pub fn trials(&self, scan: &ScanLevels<16>) -> BlockTrials<'_> {
        BlockTrials {
            levels: Descent::new(&self.prices, scan),
            flag: self.flag,
        }
    }
}

impl TrialPrices for BlockTrials<'_> {
    #[inline(always)]
    fn cost_with(&mut self, i: usize, level: i32) -> u32 {
        self.levels.cost_with(i, level).map_or(0, |levels| {
            self.flag.1.wrapping_add(levels).saturating_sub(self.flag.0)
        })
    }

    #[inline(always)]
    fn keep(&mut self, i: usize, level: i32) {
        self.levels.keep(i, level);
    }
}

/// RDOQ's trials of an 8x8 block as a [`Descent`]
/// ([`Block8Pricer::trials`]).
#[derive(Debug, Clone)]
pub struct Block8Trials<'p>(Descent<'p, 64>);

impl Block8Pricer {
    /// The trials of `scan`'s levels, priced as
    /// [`Block8Pricer::scan_cost`] prices the blocks they make.
    #[inline(always)]
    pub fn trials(&self, scan: &ScanLevels<64>) -> Block8Trials<'_> {
        Block8Trials(Descent::new(&self.prices, scan))
    }
}

impl TrialPrices for Block8Trials<'_> {
    #[inline(always)]
    fn cost_with(&mut self, i: usize, level: i32) -> u32 {
        self.0.cost_with(i, level).unwrap_or(0)
    }

    #[inline(always)]
    fn keep(&mut self, i: usize, level: i32) {
        self.0.keep(i, level);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{block8_pricer, block_pricer};
    use super::*;
    use crate::codec::residual::{BlockClass, MbResidual, ResidualCoder, ResidualSyntax};
    use proptest::prelude::*;

    /// A coder whose contexts were moved away from their start by coding
    /// `warm` macroblocks' luma (4x4, intra or inter by turns), so that the
    /// prices differ by context.
    fn warmed(warm: &[[i32; 16]]) -> ResidualCoder {
        let mut coder = ResidualCoder::new(4, 4);
        for (round, levels) in warm.iter().enumerate() {
            let mut res = MbResidual::default();
            for (b, block) in res.luma.iter_mut().enumerate() {
                for (k, v) in block.as_flattened_mut().iter_mut().enumerate() {
                    *v = levels[(k + b) % 16];
                }
            }
            let syntax = ResidualSyntax::of_4x4(round % 2 == 0);
            coder.commit(round % 4, round / 4 % 4, syntax, &res);
        }
        coder
    }

    /// Every trial of a descent over `levels` (scan order; each position
    /// lowered by `steps[k]` toward zero, then kept lowered where
    /// `keeps[k]`) priced by the trials `make` gives as `pricer` prices the
    /// whole block.
    fn descend<const N: usize, T: TrialPrices>(
        levels: [i32; N],
        (steps, keeps): (&[i32], &[bool]),
        pricer: &impl ScanCost<N>,
        make: impl FnOnce(&ScanLevels<N>) -> T,
    ) -> Result<(), TestCaseError> {
        let mut scan = ScanLevels { levels, mask: 0 };
        for (k, &v) in levels.iter().enumerate() {
            scan.set(k, v);
        }
        let mut trials = make(&scan);
        let mut untried = scan.mask;
        let mut n = 0;
        while untried != 0 {
            let i = 63 - untried.leading_zeros() as usize;
            untried &= !(1 << i);
            let v = scan.levels[i];
            let step = steps[n % steps.len()].min(v.abs());
            let tried = v - v.signum() * step;
            let mut changed = scan;
            changed.set(i, tried);
            let (got, want) = (trials.cost_with(i, tried), pricer.scan_cost(&changed));
            prop_assert_eq!(got, want, "position {} level {} -> {}", i, v, tried);
            let kept = if keeps[n % keeps.len()] { tried } else { v };
            scan.set(i, kept);
            trials.keep(i, kept);
            n += 1;
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn a_4x4_trial_costs_what_its_whole_block_costs(
            levels in prop::array::uniform16(-20i32..=20),
            sparse in prop::array::uniform16(0u8..3),
            warm in prop::collection::vec(prop::array::uniform16(-3i32..=3), 0..12),
            steps in prop::collection::vec(0i32..3, 1..8),
            keeps in prop::collection::vec(any::<bool>(), 1..8),
        ) {
            // Most positions zero, as quantised blocks are.
            let levels: [i32; 16] = std::array::from_fn(|k| if sparse[k] == 0 { levels[k] } else { 0 });
            let coder = warmed(&warm);
            let pricer = block_pricer(&coder, BlockClass::luma(true));
            descend(levels, (&steps, &keeps), &pricer, |scan| pricer.trials(scan))?;
            descend(levels, (&steps, &keeps), &pricer, |scan| WholeTrials::new(&pricer, *scan))?;
        }

        #[test]
        fn an_8x8_trial_costs_what_its_whole_block_costs(
            levels in prop::collection::vec(-40i32..=40, 64),
            sparse in prop::collection::vec(0u8..4, 64),
            warm in prop::collection::vec(prop::array::uniform16(-3i32..=3), 0..12),
            intra in any::<bool>(),
            steps in prop::collection::vec(0i32..3, 1..8),
            keeps in prop::collection::vec(any::<bool>(), 1..8),
        ) {
            let levels: [i32; 64] = std::array::from_fn(|k| if sparse[k] == 0 { levels[k] } else { 0 });
            let coder = warmed(&warm);
            let pricer = block8_pricer(&coder, intra);
            descend(levels, (&steps, &keeps), &pricer, |scan| pricer.trials(scan))?;
            descend(levels, (&steps, &keeps), &pricer, |scan| WholeTrials::new(&pricer, *scan))?;
        }
    }
}
