//! The encoder's choice of 8x8 intra modes, as of 4x4 ones: each block in
//! raster order gets the mode of least SATD + sqrt(lambda) * mode bits
//! among the nine, then is quantised in the 8x8 transform (RDOQ included)
//! and reconstructed as the decoder will, since the blocks after it are
//! predicted from it. The same bound as the 4x4 search ends it early.

use super::intra4x4::IntraBlockSearch;
use super::macroblock::MbSource;
use crate::codec::intra4x4::{most_probable, Intra4x4Mode};
use crate::codec::intra8x8::{self, place, ModeSource};
use crate::codec::recon::add_block8;
use crate::codec::syntax::MB;
use crate::codec::transform8x8::Block8;
use crate::me::Metric;

/// The luma of a macroblock coded in 8x8 blocks.
pub(crate) struct Intra8x8Luma {
    pub modes: [Intra4x4Mode; 4],
    /// Each block's prediction (from the reconstruction of those before).
    pub pred: [u8; 256],
    /// The levels each block was reconstructed with; `None` when all are 0.
    pub levels: Option<Box<[Block8; 4]>>,
    /// SATD + sqrt(lambda) * mode bits, summed over the blocks.
    pub estimate: f64,
}

impl IntraBlockSearch<'_> {
    /// The 8x8 modes (`fixed`, or each block's best), their prediction,
    /// levels and estimate; `None` as soon as the estimate reaches `bound`.
    pub fn run8(
        &self,
        src: &MbSource,
        fixed: Option<&[Intra4x4Mode; 4]>,
        bound: f64,
    ) -> Option<Intra8x8Luma> {
        let (mb_x, mb_y) = self.at;
        let cols = self.recon.width() / MB;
        let rate = self
            .coder
            .rdoq
            .then(|| super::rate::block8_pricer(self.residual, true));
        let mut out = Intra8x8Luma {
            modes: [Intra4x4Mode::Dc; 4],
            pred: [0; 256],
            levels: None,
            estimate: 0.0,
        };
        let mut levels = Box::new([[[0; 8]; 8]; 4]);
        let mut own = [0u8; 256];
        let mode_costs = self.mode_costs();
        let predict = crate::codec::dsp::ipred::ipred().pred_8x8_gather;
        for q in 0..4 {
            let edges = intra8x8::filtered(&intra8x8::edges(self.recon.y(), &own, mb_x, mb_y, q));
            let modes = ModeSource::new(&edges);
            let (l, a) =
                intra8x8::neighbour_modes8(q, &out.modes, self.around[0].as_ref(), self.around[1].as_ref());
            let probable = most_probable(l, a);
            let (above, left, _) = intra8x8::neighbours(q, mb_x, mb_y, cols);
            let source = &src.luma[8 * (q / 2) * MB + 8 * (q % 2)..];
            let mut best = (f64::INFINITY, Intra4x4Mode::Dc, [0u8; 64]);
            let mut block = [0u8; 64];
            for m in Intra4x4Mode::ALL {
                if fixed.is_some_and(|f| f[q] != m) || !m.is_available(above, left) {
                    continue;
                }
                predict(&modes, m, &mut block);
                let satd = Metric::Satd.cost(source, MB, &block, 8, 8, 8);
                let cost = f64::from(satd) + mode_costs[usize::from(m == probable)];
                if cost < best.0 {
                    best = (cost, m, block);
                }
            }
            let (cost, mode, block) = best;
            out.estimate += cost;
            if out.estimate >= bound {
                return None;
            }
            out.modes[q] = mode;
            place(&block, q, &mut out.pred);
            place(&block, q, &mut own);
            let qp_lambda = (self.coder.qp, self.coder.lambda);
            levels[q] = (self.coder.dsp.intra_block8)(&src.luma, &out.pred, q, qp_lambda, rate.as_ref());
            add_block8(&levels[q], self.coder.qp, &mut own, ((q % 2) * 8, (q / 2) * 8));
        }
        let any = levels.as_flattened().as_flattened().iter().any(|&v| v != 0);
        out.levels = any.then_some(levels);
        Some(out)
    }
}
