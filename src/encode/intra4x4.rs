//! The encoder's choice of 4x4 intra modes (x264 medium's way): each
//! block in coding order gets the mode of least SATD + sqrt(lambda) *
//! mode bits, then is quantised (RDOQ included) and reconstructed as the
//! decoder will, since the blocks after it are predicted from it. A bound
//! ends the search early when the running cost passes what another
//! candidate already costs.

use super::macroblock::{MbCoder, MbSource};
use crate::codec::intra4x4::{self, most_probable, neighbour_modes, Intra4x4Mode, ModeSource4, CODING_ORDER};
use crate::codec::modes::ModeCoder;
use crate::codec::recon::add_block;
use crate::codec::residual::{BlockClass, ResidualCoder};
use crate::codec::syntax::MB;
use crate::codec::transform::Block4;
use crate::codec::Frame;
use crate::me::dsp::pixel;

/// The luma of a macroblock coded in 4x4 blocks.
pub(crate) struct Intra4x4Luma {
    pub modes: [Intra4x4Mode; 16],
    /// Each block's prediction (from the reconstruction of those before).
    pub pred: [u8; 256],
    /// The levels each block was reconstructed with (as
    /// [`MbCoder::code`] quantises them against `pred`).
    pub levels: [Block4; 16],
    /// SATD + sqrt(lambda) * mode bits, summed over the blocks.
    pub estimate: f64,
}

/// What the search of one macroblock reads.
pub(crate) struct IntraBlockSearch<'a> {
    pub coder: &'a MbCoder,
    /// The picture reconstructed so far.
    pub recon: &'a Frame,
    pub at: (usize, usize),
    /// The 4x4 modes left of and above the macroblock, and the prices of
    /// a most probable mode and of another (1/256 bit), as the mode coder
    /// before it has them ([`IntraBlockSearch::pricing`]).
    pub around: [Option<[Intra4x4Mode; 16]>; 2],
    pub mode_bits: (u32, u32),
    /// The residual coder before this macroblock (RDOQ's prices).
    pub residual: &'a ResidualCoder,
}

/// What [`IntraBlockSearch`] needs of the mode coder before macroblock
/// (mb_x, mb_y).
pub(crate) fn pricing(
    modes: &ModeCoder,
    (mb_x, mb_y): (usize, usize),
) -> ([Option<[Intra4x4Mode; 16]>; 2], (u32, u32)) {
    (modes.modes4_around(mb_x, mb_y), super::rate::mode4_costs(modes))
}

impl IntraBlockSearch<'_> {
    /// sqrt(lambda) * the bits of a block's mode: `[other, most
    /// probable]`, indexed by whether it is the most probable (found once
    /// a macroblock, not once a candidate).
    pub fn mode_costs(&self) -> [f64; 2] {
        let (probable_bits, other_bits) = self.mode_bits;
        [other_bits, probable_bits].map(|bits| self.coder.lambda.sqrt() * f64::from(bits) / 256.0)
    }

    /// The modes (`fixed`, or each block's best), their prediction and
    /// estimate; `None` as soon as the estimate reaches `bound`.
    pub fn run(
        &self,
        src: &MbSource,
        fixed: Option<&[Intra4x4Mode; 16]>,
        bound: f64,
    ) -> Option<Intra4x4Luma> {
        let (mb_x, mb_y) = self.at;
        let cols = self.recon.width() / MB;
        let around = &self.around;
        let rate = self
            .coder
            .rdoq
            .then(|| super::rate::block_pricer(self.residual, BlockClass::luma(true)));
        let mut out = Intra4x4Luma {
            modes: [Intra4x4Mode::Dc; 16],
            pred: [0; 256],
            levels: [[[0; 4]; 4]; 16],
            estimate: 0.0,
        };
        let mut own = [0u8; 256];
        let mode_costs = self.mode_costs();
        for k in CODING_ORDER {
            let (bx, by) = (4 * (k % 4), 4 * (k / 4));
            let edges = intra4x4::edges(self.recon.y(), &own, mb_x, mb_y, k);
            let (l, a) = neighbour_modes(k, &out.modes, around[0].as_ref(), around[1].as_ref());
            let probable = most_probable(l, a);
            let (above, left, _) = intra4x4::neighbours(k, mb_x, mb_y, cols);
            let mut candidates = [Intra4x4Mode::Dc; 9];
            let mut n = 0;
            for m in Intra4x4Mode::ALL {
                if fixed.is_none_or(|f| f[k] == m) && m.is_available(above, left) {
                    candidates[n] = m;
                    n += 1;
                }
            }
            // The modes gathered from one source of the edges.
            let source = ModeSource4::new(&edges);
            let satds = block_satds(&src.luma, (bx, by), &source, &candidates[..n]);
            let mut best = (f64::INFINITY, Intra4x4Mode::Dc);
            for i in 0..n {
                let cost = f64::from(satds[i]) + mode_costs[usize::from(candidates[i] == probable)];
                if cost < best.0 {
                    best = (cost, candidates[i]);
                }
            }
            let (cost, mode) = best;
            let mut block = [0u8; 16];
            source.predict(mode, &mut block);
            out.estimate += cost;
            if out.estimate >= bound {
                return None;
            }
            out.modes[k] = mode;
            for r in 0..4 {
                let i = (by + r) * MB + bx;
                out.pred[i..i + 4].copy_from_slice(&block[4 * r..4 * r + 4]);
                own[i..i + 4].copy_from_slice(&block[4 * r..4 * r + 4]);
            }
            let levels = &mut out.levels[by + bx / 4];
            *levels = self
                .coder
                .intra_luma_levels(src, &out.pred, (bx / 4, by / 4), rate.as_ref());
            add_block(levels, self.coder.qp, &mut own, MB, (bx, by));
        }
        Some(out)
    }
}

/// The SATD against the source's 4x4 block at (bx, by) of each mode's
/// prediction: gathered two at a time side by side, measured four at a
/// time (the last one or two as a pair).
fn block_satds(
    src: &[u8; 256],
    (bx, by): (usize, usize),
    source: &ModeSource4,
    modes: &[Intra4x4Mode],
) -> [u32; 9] {
    let (pair, quad) = (pixel().satd_4x4_pair, pixel().satd_4x4_quad);
    let predict_pair = crate::codec::dsp::ipred::ipred().pred_4x4_pair;
    // The source block twice side by side, predictions likewise.
    let mut doubled = [0u8; 32];
    for r in 0..4 {
        let row = &src[(by + r) * MB + bx..][..4];
        doubled[8 * r..8 * r + 4].copy_from_slice(row);
        doubled[8 * r + 4..8 * r + 8].copy_from_slice(row);
    }
    let mut out = [0u32; 9];
    let n = modes.len();
    let mut i = 0;
    while i + 4 <= n {
        let mut two_pairs = [[0u8; 32]; 2];
        predict_pair(source, modes[i], modes[i + 1], &mut two_pairs[0]);
        predict_pair(source, modes[i + 2], modes[i + 3], &mut two_pairs[1]);
        out[i..i + 4].copy_from_slice(&quad(&doubled, &two_pairs));
        i += 4;
    }
    while i < n {
        let j = (i + 1).min(n - 1);
        let mut two = [0u8; 32];
        predict_pair(source, modes[i], modes[j], &mut two);
        let [a, b] = pair(&doubled, &two);
        out[i] = a;
        out[j] = b;
        i += 2;
    }
    out
}
