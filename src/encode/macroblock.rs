//! One macroblock: its residual (transform, quantisation, the small-block
//! zeroing H.264's reference encoder does), its rate as the frame's
//! residual coder prices it in its present state, and the rate-distortion
//! cost J = SSD + lambda * bits of each way to code it.

use super::dsp::{coder, CoderDsp};
use super::rate::{self, BlockPricer};
use super::rdo;
use crate::codec::mv::Mv;
use crate::codec::recon::{add_luma8, add_residual, chroma_qp, MbSamples};
use crate::codec::residual::{BlockClass, MbResidual, ResidualCoder, ResidualSyntax};
use crate::codec::syntax::MB;
use crate::codec::transform::{dequantize_chroma_dc, quantize_chroma_dc, quantize_luma_dc, Block4};
use crate::codec::transform8x8::Block8;
use crate::codec::Frame;
use crate::metrics::squared_difference_sum;

/// Quantiser rounding offsets (fractions of a step) where no RDOQ
/// follows ([`rdo::quant_rounding`]).
const ROUND_INTRA: f64 = rdo::quant_rounding(true, false);
const ROUND_INTER: f64 = rdo::quant_rounding(false, false);

/// The source samples of one macroblock.
#[derive(Debug, Clone)]
pub(crate) struct MbSource {
    pub luma: [u8; 256],
    pub chroma: [[u8; 64]; 2],
}

impl MbSource {
    /// Macroblock (mb_x, mb_y) of a coded-size frame.
    pub fn load(frame: &Frame, mb_x: usize, mb_y: usize) -> MbSource {
        let mut s = MbSource {
            luma: [0; 256],
            chroma: [[0; 64]; 2],
        };
        s.load_into(frame, mb_x, mb_y);
        s
    }

    /// [`MbSource::load`] into this record (kept from macroblock to
    /// macroblock: no copy of a returned one).
    pub fn load_into(&mut self, frame: &Frame, mb_x: usize, mb_y: usize) {
        let (x0, y0) = (mb_x * MB, mb_y * MB);
        frame.y().read_block::<MB>(x0, y0, &mut self.luma);
        for p in 0..2 {
            frame
                .plane(p + 1)
                .read_block::<8>(x0 / 2, y0 / 2, &mut self.chroma[p]);
        }
    }

    /// Squared error of a prediction (or reconstruction), luma and chroma.
    pub fn ssd(&self, p: &MbSamples) -> u64 {
        let (luma, chroma) = self.ssd_by_plane(p);
        luma + chroma
    }

    /// [`MbSource::ssd`]'s luma and chroma parts.
    pub fn ssd_by_plane(&self, p: &MbSamples) -> (u64, u64) {
        let d = squared_difference_sum;
        (
            d(&self.luma, &p.luma),
            d(&self.chroma[0], &p.chroma[0]) + d(&self.chroma[1], &p.chroma[1]),
        )
    }
}

/// Asks for the rows of the next four macroblocks in the row of `frame`
/// (a source, a reconstruction being written) to be brought into cache
/// while these are decided (x264's `prefetch_fenc`): a macroblock reads
/// 16 short rows a frame's stride apart, which the processor does not
/// foresee.
#[inline]
pub(crate) fn prefetch_ahead(frame: &Frame, mb_x: usize, mb_y: usize) {
    prefetch_ahead_displaced(frame, mb_x, mb_y, Mv::ZERO);
}

/// [`prefetch_ahead`] for a reference, displaced by `mv` (quarter pels) with
/// the interpolation filter's reach (x264's `prefetch_ref` at the
/// predicted vector): the next macroblocks' predictions mostly read
/// there. Asked at every fourth macroblock, for the two cache lines
/// each row of the next four may straddle: asked at every macroblock,
/// the hints cost 2 % of ultrafast's time at 1080p.
#[inline]
pub(crate) fn prefetch_ahead_displaced(frame: &Frame, mb_x: usize, mb_y: usize, mv: Mv) {
    if mb_x % 4 != 0 {
        return;
    }
    let (x, y) = (
        (mb_x * MB) as isize + (mv.x >> 2) as isize,
        (mb_y * MB) as isize + (mv.y >> 2) as isize,
    );
    let (reach, chroma_reach) = if mv == Mv::ZERO { (0, 0) } else { (3, 1) };
    let four = 4 * MB as isize;
    for at in [x + four - reach, x + 2 * four - 1 + reach] {
        frame.y().prefetch_rows(at, y - reach, MB + 2 * reach as usize);
    }
    for p in 1..3 {
        let (cx, cy) = (x / 2, y / 2 - chroma_reach);
        let rows = MB / 2 + 2 * chroma_reach as usize;
        for at in [cx + four / 2 - chroma_reach, cx + four - 1 + chroma_reach] {
            frame.plane(p).prefetch_rows(at, cy, rows);
        }
    }
}

/// A residual with its rate and the reconstruction it gives.
#[derive(Debug, Clone)]
pub(crate) struct Coded {
    /// On the heap: candidates move it around until one is written.
    pub residual: Box<MbResidual>,
    /// Bits of the coded block pattern, flags and levels (the residual
    /// coder's estimate).
    pub bits: f64,
    /// Squared error of the reconstruction.
    pub ssd: u64,
    /// The reconstructed macroblock.
    pub samples: MbSamples,
}

impl Coded {
    /// `residual` reconstructed as `samples`, measured against `src` and
    /// priced by the frame's `residual_coder` for macroblock `at`.
    fn priced(
        src: &MbSource,
        residual: Box<MbResidual>,
        samples: MbSamples,
        (residual_coder, syntax): (&ResidualCoder, ResidualSyntax),
        (mb_x, mb_y): (usize, usize),
    ) -> Coded {
        Coded {
            bits: rdo::bits(rate::residual_cost(
                residual_coder,
                (mb_x, mb_y),
                syntax,
                &residual,
            )),
            ssd: src.ssd(&samples),
            residual,
            samples,
        }
    }
}

/// The per-frame constants of macroblock coding.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MbCoder {
    pub qp: u8,
    /// Weight of one bit against squared error.
    pub lambda: f64,
    /// Rate-distortion optimised quantisation (see [`super::dsp::rdoq_4x4`]).
    pub rdoq: bool,
    /// Intra luma may be coded in 4x4 blocks.
    pub intra4x4: bool,
    /// Intra luma may be coded in 8x8 blocks.
    pub intra8x8: bool,
    /// Inter luma may be coded in the 8x8 transform.
    pub transform_8x8: bool,
    /// Coded macroblocks' residual bits estimated from their levels
    /// ([`rate::residual_estimate`]) instead of priced bin by bin: the
    /// fast mode decision's without the 8x8 transform (ultrafast's).
    pub estimated_rates: bool,
    /// The kernels (the CPU level's when the coder was made).
    pub dsp: &'static CoderDsp,
}

impl MbCoder {
    pub fn new(qp: u8, lambda_scale: f64, rdoq: bool) -> MbCoder {
        MbCoder {
            qp,
            lambda: rdo::lambda(qp, lambda_scale),
            rdoq,
            intra4x4: true,
            intra8x8: true,
            transform_8x8: true,
            estimated_rates: false,
            dsp: coder(),
        }
    }

    /// This coder with residual bits estimated or priced
    /// ([`MbCoder::estimated_rates`]).
    pub fn estimated_rates(self, on: bool) -> MbCoder {
        MbCoder {
            estimated_rates: on,
            ..self
        }
    }

    /// This coder with RDOQ on or off.
    pub fn rdoq(self, on: bool) -> MbCoder {
        MbCoder { rdoq: on, ..self }
    }

    /// This coder with 4x4 intra on or off.
    pub fn intra4x4(self, on: bool) -> MbCoder {
        MbCoder { intra4x4: on, ..self }
    }

    /// This coder with 8x8 intra on or off.
    pub fn intra8x8(self, on: bool) -> MbCoder {
        MbCoder { intra8x8: on, ..self }
    }

    /// This coder with the inter 8x8 transform on or off.
    pub fn transform_8x8(self, on: bool) -> MbCoder {
        MbCoder {
            transform_8x8: on,
            ..self
        }
    }

    /// Transforms and quantises `src - pred`, reconstructs the macroblock
    /// (through the codec, as the decoder will) and measures it, the rate
    /// priced by `residual_coder` (the frame's, as it stands before
    /// macroblock (mb_x, mb_y)).
    pub fn code(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        self.code_body(src, pred, intra, residual_coder, mb_x, mb_y)
    }

    /// Whether an inter macroblock predicted by `pred` would code no level:
    /// its luma zero after quantisation and decimation, and each chroma
    /// plane's levels cheap enough to be dropped, as [`MbCoder::code`]
    /// leaves them without RDOQ. x264's `macroblock_probe_pskip`: what
    /// skipping `pred` loses is then only what the decimation drops (and,
    /// under RDOQ, whose levels start from a rounding nearer the middle, a
    /// level the dead zone drops and RDOQ would keep).
    pub fn codes_nothing(&self, src: &MbSource, pred: &MbSamples) -> bool {
        // Quadrant by quadrant, out at the first that settles it (x264's
        // probe): the zeroing keeps a quadrant that costs 4 or more, and
        // the macroblock's luma when those kept cost 6 or more.
        let mut kept = 0;
        for q in 0..4 {
            let levels = (self.dsp.quadrant_levels)(&src.luma, &pred.luma, q, self.qp, ROUND_INTER);
            let cost = (self.dsp.decimate_score)(&levels);
            if cost >= 4 {
                kept += cost;
                if kept >= 6 {
                    return false;
                }
            }
        }
        let cqp = chroma_qp(self.qp);
        (0..2).all(|p| {
            let (mut diffs, mut levels) = ([[[0i32; 4]; 4]; 4], [[[0i32; 4]; 4]; 4]);
            (self.dsp.quantize_blocks)(
                &src.chroma[p],
                &pred.chroma[p],
                8,
                cqp,
                ROUND_INTER,
                &mut diffs,
                &mut levels,
            );
            (self.dsp.decimate_score)(&levels) < 4
        })
    }

    /// The levels of intra luma block (bx, by) (in blocks) of `src -
    /// pred`, as [`MbCoder::code`] quantises them (RDOQ priced by `rate`
    /// when given): what a 4x4 intra search reconstructs each block from.
    pub fn intra_luma_levels(
        &self,
        src: &MbSource,
        pred: &[u8; 256],
        at: (usize, usize),
        rate: Option<&BlockPricer>,
    ) -> Block4 {
        let rounding = rdo::quant_rounding(true, rate.is_some());
        let (diff, mut levels) = (self.dsp.quantize_4x4)(&src.luma, pred, MB, at, self.qp, rounding);
        if let Some(rate) = rate {
            (self.dsp.rdoq_4x4)(&diff, &mut levels, self.qp, self.lambda, rate);
        }
        levels
    }

    fn code_body(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        let mut residual = Box::<MbResidual>::default();
        let mut diffs = [[[0i32; 4]; 4]; 16];
        self.levels_into((src, pred), intra, residual_coder, &mut residual, &mut diffs);
        let syntax = ResidualSyntax::of_4x4(intra);
        self.reconstructed(src, pred, residual, (residual_coder, syntax), (mb_x, mb_y))
    }

    /// A macroblock whose levels are all decided (an intra one's luma by a
    /// block search or [`MbCoder::intra16x16_luma`], its chroma by
    /// [`MbCoder::intra_chroma_levels`]), reconstructed over `pred`,
    /// measured and priced as `syntax` codes it.
    pub fn reconstructed(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual: Box<MbResidual>,
        coder_syntax: (&ResidualCoder, ResidualSyntax),
        at: (usize, usize),
    ) -> Coded {
        // Built in place: reconstructed by value and moved in, the
        // samples were copied three times a coded candidate.
        let mut coded = Coded {
            residual,
            bits: 0.0,
            ssd: 0,
            samples: pred.clone(),
        };
        (coded.bits, coded.ssd) =
            self.reconstruct_in_place(src, &coded.residual, &mut coded.samples, coder_syntax, at);
        coded
    }

    /// `residual` added to the prediction in `samples` (as the decoder
    /// adds it), and its bits and the reconstruction's squared error
    /// against `src`, priced as [`MbCoder::reconstructed`] prices them.
    pub fn reconstruct_in_place(
        &self,
        src: &MbSource,
        residual: &MbResidual,
        samples: &mut MbSamples,
        (residual_coder, syntax): (&ResidualCoder, ResidualSyntax),
        at: (usize, usize),
    ) -> (f64, u64) {
        add_residual(samples, residual, self.qp);
        let bits = if self.estimated_rates {
            (self.dsp.residual_estimate)(residual)
        } else {
            rdo::bits(rate::residual_cost(residual_coder, at, syntax, residual))
        };
        (bits, src.ssd(samples))
    }

    /// The levels [`MbCoder::code`] codes `src - pred` with (4x4
    /// transforms) into `residual` (a record reused from candidate to
    /// candidate: every field written; a new one was a zeroed allocation),
    /// with `diffs` as the luma's scratch.
    pub fn levels_into(
        &self,
        (src, pred): (&MbSource, &MbSamples),
        intra: bool,
        residual_coder: &ResidualCoder,
        residual: &mut MbResidual,
        diffs: &mut [Block4; 16],
    ) {
        self.luma_levels_into(src, pred, intra, residual_coder, (&mut residual.luma, diffs));
        (residual.luma8, residual.luma_dc) = (None, [0; 16]);
        self.code_chroma(src, pred, intra, residual_coder, &mut residual.chroma);
    }

    /// The luma levels of `src - pred` in 4x4 transforms into `luma`, the
    /// differences into `diffs` (both written whole).
    fn luma_levels_into(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        (luma, diffs): (&mut [Block4; 16], &mut [Block4; 16]),
    ) {
        let rounding = rdo::quant_rounding(intra, self.rdoq);
        (self.dsp.quantize_blocks)(&src.luma, &pred.luma, MB, self.qp, rounding, diffs, luma);
        // Inter blocks are zeroed below where their levels cost little.
        // RDOQ only lowers levels, and lowering never raises that cost, so
        // what the rule zeroes before RDOQ it zeroes after it too: it is
        // applied first, and RDOQ spends no work on those blocks.
        if !intra {
            (self.dsp.decimate_luma)(luma);
        }
        // (Pricers are made only for levels left to lower.)
        let coded = |blocks: &[Block4]| blocks.iter().any(|b| b.as_flattened().iter().any(|&v| v != 0));
        if self.rdoq && coded(luma) {
            let rate = rate::block_pricer(residual_coder, BlockClass::luma(intra));
            for (block, diff) in luma.iter_mut().zip(diffs.iter()) {
                (self.dsp.rdoq_4x4)(diff, block, self.qp, self.lambda, &rate);
            }
            if !intra {
                (self.dsp.decimate_luma)(luma);
            }
        }
    }

    /// An intra 16x16 macroblock predicted by `pred`: its luma's DC
    /// levels apart ([`MbCoder::intra16x16_luma`]), its chroma as
    /// [`MbCoder::code`] codes it.
    pub fn code_intra16x16(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Coded {
        let mut residual = self.intra16x16_luma(src, pred, residual_coder);
        self.code_chroma(src, pred, true, residual_coder, &mut residual.chroma);
        self.reconstructed(
            src,
            pred,
            residual,
            (residual_coder, ResidualSyntax::Intra16x16),
            at,
        )
    }

    /// The luma levels of an intra 16x16 macroblock predicted by `pred`
    /// (chroma left empty): its sixteen blocks' AC levels (RDOQ priced
    /// as they are coded, without position 0), and the DC levels of the
    /// 4x4 Hadamard transform of their DC coefficients (H.264's
    /// Intra16x16: a smooth area's level of brightness costs a few DC
    /// levels, not one in every block).
    pub fn intra16x16_luma(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual_coder: &ResidualCoder,
    ) -> Box<MbResidual> {
        let mut residual = Box::<MbResidual>::default();
        self.intra16x16_luma_into(src, pred, residual_coder, &mut residual);
        residual
    }

    /// [`MbCoder::intra16x16_luma`] into `residual`'s luma (a reused
    /// record: its luma, DC and 8x8 levels all written, its chroma left).
    pub fn intra16x16_luma_into(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual_coder: &ResidualCoder,
        residual: &mut MbResidual,
    ) {
        let mut diffs = [[[0i32; 4]; 4]; 16];
        (self.dsp.quantize_blocks)(
            &src.luma,
            &pred.luma,
            MB,
            self.qp,
            rdo::quant_rounding(true, self.rdoq),
            &mut diffs,
            &mut residual.luma,
        );
        residual.luma8 = None;
        for b in residual.luma.iter_mut() {
            b[0][0] = 0;
        }
        let coded = residual
            .luma
            .iter()
            .any(|b| b.as_flattened().iter().any(|&v| v != 0));
        if self.rdoq && coded {
            // The residual keeps its DC, which no AC basis function
            // correlates with: the AC choices see it as a constant.
            let rate = rate::luma_ac_pricer(residual_coder);
            for (block, diff) in residual.luma.iter_mut().zip(&diffs) {
                (self.dsp.rdoq_4x4)(diff, block, self.qp, self.lambda, &rate);
            }
        }
        // A block's DC coefficient is the sum of its residual.
        let sums = diffs.each_ref().map(|d| d.as_flattened().iter().sum());
        // Quantised as they are: weighing each DC level by rate and
        // distortion, as the chroma's are, changed nothing on the 28
        // sequences (medium +0.05 %).
        residual.luma_dc = quantize_luma_dc(sums, self.qp, ROUND_INTRA);
    }

    /// The chroma levels of an intra macroblock predicted by `pred`, as
    /// [`MbCoder::code`] quantises them: the same for every luma choice
    /// of the macroblock.
    pub fn intra_chroma_levels(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual_coder: &ResidualCoder,
    ) -> [[Block4; 4]; 2] {
        let mut chroma = [[[[0; 4]; 4]; 4]; 2];
        self.code_chroma(src, pred, true, residual_coder, &mut chroma);
        chroma
    }

    /// An intra macroblock coded in 8x8 blocks: `pred` (each luma block
    /// predicted from the reconstruction of those before it with `luma8`,
    /// the levels the search chose), the chroma coded as [`MbCoder::code`]
    /// codes it.
    pub fn code_intra8x8(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        luma8: Option<Box<[Block8; 4]>>,
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Coded {
        let residual = Box::new(MbResidual {
            luma8,
            chroma: self.intra_chroma_levels(src, pred, residual_coder),
            ..MbResidual::default()
        });
        self.reconstructed(
            src,
            pred,
            residual,
            (residual_coder, ResidualSyntax::Intra8x8),
            at,
        )
    }

    /// The chroma levels of `src - pred` into `chroma`, as
    /// [`MbCoder::code`] quantises them: per plane, the AC levels of its
    /// four blocks ([`MbCoder::chroma_ac`]), then its DC levels in the
    /// blocks' position 0 (FORMAT.md section 10.1): the plane zeroed in an
    /// inter macroblock where its levels are few and all of them ±1 (as
    /// x264 zeroes chroma, the DC levels scored as first positions), else
    /// each DC level weighed by rate and distortion ([`ChromaDcTrial`]).
    #[inline(always)]
    fn code_chroma(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        chroma: &mut [[Block4; 4]; 2],
    ) {
        let cqp = chroma_qp(self.qp);
        // Chroma keeps the dead zones under RDOQ too: rounded as luma, it
        // bought chroma's quality with luma's bits (encoder.md, "RDOQ from
        // levels rounded nearer the middle").
        let rounding = rdo::quant_rounding(intra, false);
        let (mut ac_rate, mut dc_rate) = (None, None);
        for (p, blocks) in chroma.iter_mut().enumerate() {
            let mut diffs = [[[0i32; 4]; 4]; 4];
            (self.dsp.quantize_blocks)(
                &src.chroma[p],
                &pred.chroma[p],
                8,
                cqp,
                rounding,
                &mut diffs,
                blocks,
            );
            self.chroma_ac(blocks, &diffs, intra, (&mut ac_rate, residual_coder));
            // A block's DC coefficient is the sum of its residual.
            let sums = diffs.each_ref().map(|d| d.as_flattened().iter().sum());
            let mut levels = quantize_chroma_dc(sums, cqp, rounding);
            let dc_score = |l: &[i32; 4]| -> u32 {
                l.iter()
                    .map(|v| match v.unsigned_abs() {
                        0 => 0,
                        1 => 3,
                        _ => 999,
                    })
                    .sum()
            };
            if !intra && dc_score(&levels) + (self.dsp.decimate_score)(blocks) < CHROMA_DECIMATE_BELOW {
                *blocks = [[[0; 4]; 4]; 4];
                levels = [0; 4];
            }
            if levels != [0; 4] {
                let trial = ChromaDcTrial {
                    sums,
                    qp: cqp,
                    rate: dc_rate.get_or_insert_with(|| rate::chroma_dc_pricer(residual_coder, intra)),
                    has_ac: blocks.iter().any(|b| b.as_flattened().iter().any(|&v| v != 0)),
                };
                levels = trial.choose(p, levels, self.lambda);
            }
            for (b, level) in blocks.iter_mut().zip(levels) {
                b[0][0] = level;
            }
        }
    }

    /// A chroma plane's AC levels (`blocks` as quantised, their position 0
    /// cleared here): zeroed in an inter macroblock where few and small
    /// (x264's chroma AC decimation), else weighed by RDOQ priced by
    /// `ac_rate`.
    #[inline(always)]
    fn chroma_ac(
        &self,
        blocks: &mut [Block4; 4],
        residuals: &[Block4; 4],
        intra: bool,
        (rate, coder): (&mut Option<BlockPricer>, &ResidualCoder),
    ) {
        for b in blocks.iter_mut() {
            b[0][0] = 0;
        }
        let cheap = |blocks: &[Block4; 4]| (self.dsp.decimate_score)(blocks) < CHROMA_DECIMATE_BELOW;
        let coded = |blocks: &[Block4; 4]| blocks.iter().any(|b| b.as_flattened().iter().any(|&v| v != 0));
        if !intra && cheap(blocks) {
            *blocks = [[[0; 4]; 4]; 4];
        } else if self.rdoq && coded(blocks) {
            // The residual keeps its DC, which no AC basis function
            // correlates with: the AC choices see it as a constant.
            let rate = rate.get_or_insert_with(|| rate::chroma_ac_pricer(coder, intra));
            for (block, residual) in blocks.iter_mut().zip(residuals) {
                (self.dsp.rdoq_4x4)(residual, block, chroma_qp(self.qp), self.lambda, rate);
            }
            if !intra && cheap(blocks) {
                *blocks = [[[0; 4]; 4]; 4];
            }
        }
    }

    /// An inter macroblock's `residual` and reconstructed `samples` (as
    /// [`MbCoder::code`] codes them, in 4x4 transforms) with its luma in
    /// the 8x8 transform instead, when this coder allows it, the 4x4
    /// transforms left luma levels and the 8x8 one leaves some: the chroma
    /// kept, the rate priced as [`MbCoder::code`] prices it. Whichever
    /// costs less is the caller's to keep (x264 decides the transform size
    /// once the mode is decided).
    ///
    /// Trying it where the 4x4 transforms left no luma levels too gained
    /// 0.2 % more on the development set's mean (-0.8 % against -0.6 %,
    /// BD-rate against no 8x8 transform) for twice the time (+11 % against
    /// +6 % of the medium preset's on pan_cif).
    pub fn luma8_alternative(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        (residual, samples): (&MbResidual, &MbSamples),
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Option<Coded> {
        if !self.transform_8x8 || residual.cbp() & 15 == 0 {
            return None;
        }
        let rate = self.rdoq.then(|| rate::block8_pricer(residual_coder, false));
        let luma8 = (self.dsp.inter_luma8)(&src.luma, &pred.luma, self.qp, self.lambda, rate.as_ref())?;
        // The chroma as coded already: only the luma is reconstructed.
        let mut samples = samples.clone();
        samples.luma = pred.luma;
        add_luma8(&luma8, self.qp, &mut samples.luma);
        let mut residual = Box::new(residual.clone());
        residual.luma = Default::default();
        residual.luma8 = Some(luma8);
        Some(Coded::priced(
            src,
            residual,
            samples,
            (residual_coder, ResidualSyntax::Inter),
            at,
        ))
    }

    /// [`MbCoder::code`] of an inter macroblock, then the cheaper of it and
    /// its [`MbCoder::luma8_alternative`].
    pub fn code_inter(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        let coded = self.code(src, pred, false, residual_coder, mb_x, mb_y);
        let coded4 = (&*coded.residual, &coded.samples);
        match self.luma8_alternative(src, pred, coded4, residual_coder, (mb_x, mb_y)) {
            Some(c8)
                if rdo::cost(self.lambda, c8.ssd, c8.bits)
                    < rdo::cost(self.lambda, coded.ssd, coded.bits) =>
            {
                c8
            }
            _ => coded,
        }
    }
}

/// An inter macroblock's chroma plane whose levels score below this
/// (the decimation score of `encode::dsp`) is zeroed: x264's threshold for
/// chroma AC (`i_decimate_score < 7`). Against 4 (the luma's, as chroma had
/// before its DC levels), on the 28 sequences (`benches/pair.py`, one
/// run): medium -0.44 % BD-rate on luma, +0.14 % on 6:1:1 YUV PSNR;
/// ultrafast -0.72 % on luma.
const CHROMA_DECIMATE_BELOW: u32 = 7;

/// A chroma plane's DC levels weighed by rate and distortion, its AC
/// levels decided (x264 and JM zero small chroma DC levels of inter
/// macroblocks by rules; this weighs each as RDOQ weighs AC levels).
struct ChromaDcTrial<'a> {
    /// Each block's DC coefficient (the sum of its residual).
    sums: [i32; 4],
    qp: u8,
    rate: &'a rate::ChromaDcPricer,
    /// Whether the plane has AC levels (else its DC levels alone code it).
    has_ac: bool,
}

impl ChromaDcTrial<'_> {
    /// What DC `levels` add to the plane's squared error over none. A DC
    /// coefficient `d` moves every sample of its block by about `d / 64`
    /// (the AC levels' samples sum to about zero), so the block's error
    /// changes by `16 (d / 64)^2 - 2 (d / 64) s` for its residual's sum
    /// `s` (the transform's rounding left out: this only chooses).
    fn error(&self, levels: [i32; 4]) -> f64 {
        let dc = dequantize_chroma_dc(levels, self.qp);
        dc.iter()
            .zip(self.sums)
            .map(|(&d, s)| {
                let shift = f64::from(d) / 64.0;
                16.0 * shift * shift - 2.0 * shift * f64::from(s)
            })
            .sum()
    }

    /// The bits of plane `p`'s DC `levels`: with no AC levels, a plane of
    /// DC levels also codes its pattern bit (about a bit) and four AC
    /// flags of 0.
    fn bits(&self, p: usize, levels: &[i32; 4]) -> f64 {
        let mut cost = self.rate.cost(p, levels);
        if !self.has_ac && *levels != [0; 4] {
            cost += 256 + 4 * self.rate.ac_flag_prices().0;
        }
        f64::from(cost) / 256.0
    }

    /// The DC levels of plane `p` that cost least, from `levels` (the
    /// quantiser's): each lowered toward zero in turn where that pays,
    /// then all of them against none.
    fn choose(&self, p: usize, mut levels: [i32; 4], lambda: f64) -> [i32; 4] {
        let cost = |l: &[i32; 4]| self.error(*l) + lambda * self.bits(p, l);
        let mut best = cost(&levels);
        for k in (0..4).rev() {
            if levels[k] == 0 {
                continue;
            }
            let mut lowered = levels;
            lowered[k] -= lowered[k].signum();
            let c = cost(&lowered);
            if c < best {
                (levels, best) = (lowered, c);
            }
        }
        if levels != [0; 4] && cost(&[0; 4]) <= best {
            levels = [0; 4];
        }
        levels
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::recon::reconstruct_samples;
    use proptest::prelude::*;

    /// A textured macroblock.
    fn source() -> MbSource {
        let mut s = MbSource {
            luma: [0; 256],
            chroma: [[0; 64]; 2],
        };
        for (i, v) in s.luma.iter_mut().enumerate() {
            *v = (100 + (i * 37) % 61) as u8;
        }
        for (p, plane) in s.chroma.iter_mut().enumerate() {
            for (i, v) in plane.iter_mut().enumerate() {
                *v = (120 + (i * (13 + p)) % 17) as u8;
            }
        }
        s
    }

    /// `s` as a prediction, each sample moved by `noise` (cycled), luma
    /// and chroma.
    fn perturbed(s: &MbSource, noise: &[i8]) -> MbSamples {
        let mv = |v: u8, k: usize| (i16::from(v) + i16::from(noise[k % noise.len()])).clamp(0, 255) as u8;
        let mut p = MbSamples::default();
        for (k, (o, &v)) in p.luma.iter_mut().zip(&s.luma).enumerate() {
            *o = mv(v, k);
        }
        for c in 0..2 {
            for (k, (o, &v)) in p.chroma[c].iter_mut().zip(&s.chroma[c]).enumerate() {
                *o = mv(v, k + 256 + 64 * c);
            }
        }
        p
    }

    #[test]
    fn a_prediction_off_by_much_codes_something_and_an_exact_one_nothing() {
        let coder = MbCoder::new(28, 1.4, true);
        let s = source();
        assert!(coder.codes_nothing(&s, &perturbed(&s, &[0])));
        // One 4x4 luma block off by 30: levels the decimation keeps.
        let mut off = perturbed(&s, &[0]);
        for r in 0..4 {
            for c in 0..4 {
                off.luma[r * 16 + c] += 30;
            }
        }
        assert!(!coder.codes_nothing(&s, &off));
        // The chroma alone off.
        let mut off = perturbed(&s, &[0]);
        off.chroma[1].iter_mut().for_each(|v| *v += 30);
        assert!(!coder.codes_nothing(&s, &off));
    }

    /// A plane whose blocks are constant residuals `means` (block order):
    /// its residual sums and the quantiser's DC levels at `qp`.
    fn dc_plane(means: [i32; 4], qp: u8) -> ([i32; 4], [i32; 4]) {
        let sums = means.map(|m| 16 * m);
        (sums, quantize_chroma_dc(sums, qp, ROUND_INTER))
    }

    /// The squared error of the plane rebuilt from DC `levels` against
    /// constant blocks `means`, through the decoder's reconstruction.
    fn rebuilt_error(means: [i32; 4], levels: [i32; 4], qp: u8) -> i64 {
        let mut blocks = [[[0; 4]; 4]; 4];
        for (b, l) in blocks.iter_mut().zip(levels) {
            b[0][0] = l;
        }
        let mut out = [128u8; 64];
        crate::codec::recon::add_chroma_plane(&blocks, qp, &mut out);
        (0..64)
            .map(|i| i64::from(i32::from(out[i]) - 128 - means[(i / 32) * 2 + (i % 8) / 4]).pow(2))
            .sum()
    }

    #[test]
    fn an_intra16x16_macroblock_codes_block_means_as_dc_levels() {
        // Sixteen blocks, each flat at its own level over a flat
        // prediction: the DC levels carry them, no AC level is left, the
        // reconstruction is each block's level within the quantiser's
        // reach, and it costs fewer bits than each block's own DC level.
        let qp = 22;
        let coder = MbCoder::new(qp, 1.3, true);
        let means: [i32; 16] = std::array::from_fn(|k| [23, -17, 40, 5][k % 4] + [0, 11, -30, 8][k / 4]);
        let pred = MbSamples {
            luma: [128; 256],
            ..MbSamples::default()
        };
        let mut src = MbSource {
            luma: [0; 256],
            chroma: [[128; 64]; 2],
        };
        for (i, v) in src.luma.iter_mut().enumerate() {
            let k = (i / 64) * 4 + (i % 16) / 4;
            *v = (128 + means[k]) as u8;
        }
        let residual_coder = ResidualCoder::new(1, 1);
        let dc16 = coder.intra16x16_luma(&src, &pred, &residual_coder);
        assert!(dc16.luma.iter().all(|b| b.as_flattened().iter().all(|&v| v == 0)));
        assert_ne!(dc16.luma_dc, [0; 16]);
        let samples = reconstruct_samples(&pred, &dc16, qp);
        let step = crate::codec::transform::qstep(qp);
        let errors: Vec<f64> = (0..256)
            .map(|i| f64::from(i32::from(samples.luma[i]) - i32::from(src.luma[i])).abs())
            .collect();
        assert!(errors.iter().all(|&e| e <= 2.0 * step + 1.0), "{errors:?}");
        assert!(errors.iter().sum::<f64>() / 256.0 <= step / 2.0 + 1.0);
        // The same luma in 4x4 blocks (its chroma left out, as dc16's).
        let mut blocks = coder.code(&src, &pred, true, &residual_coder, 0, 0).residual;
        blocks.chroma = Default::default();
        let price = |syntax, res: &MbResidual| rate::residual_cost(&residual_coder, (0, 0), syntax, res);
        assert!(price(ResidualSyntax::Intra16x16, &dc16) < price(ResidualSyntax::Intra, &blocks));
    }

    #[test]
    fn the_chroma_dc_trial_weighs_error_against_bits() {
        let coder = ResidualCoder::new(1, 1);
        let rate = rate::chroma_dc_pricer(&coder, false);
        let qp = 26;
        let (sums, levels) = dc_plane([9, 7, -6, 8], qp);
        assert_ne!(levels, [0; 4]);
        let trial = ChromaDcTrial {
            sums,
            qp,
            rate: &rate,
            has_ac: false,
        };
        // Bits free: nothing is lowered that rebuilds the plane better.
        let free = trial.choose(0, levels, 0.0);
        assert!(rebuilt_error([9, 7, -6, 8], free, qp) <= rebuilt_error([9, 7, -6, 8], levels, qp));
        assert!(rebuilt_error([9, 7, -6, 8], free, qp) < rebuilt_error([9, 7, -6, 8], [0; 4], qp) / 4);
        // Bits dear: none of it.
        assert_eq!(trial.choose(0, levels, 1e9), [0; 4]);
        // The estimate of the error follows the reconstruction's: between
        // the quantiser's levels and none, the same change within the
        // transform's rounding (half a sample a sample at most).
        let estimated = trial.error(levels) - trial.error([0; 4]);
        let rebuilt = rebuilt_error([9, 7, -6, 8], levels, qp) - rebuilt_error([9, 7, -6, 8], [0; 4], qp);
        let sum_abs: i32 = [9, 7, -6, 8].iter().map(|m: &i32| m.abs()).sum();
        assert!(
            (estimated - rebuilt as f64).abs() <= 16.0 * f64::from(sum_abs) + 64.0,
            "estimated {estimated}, rebuilt {rebuilt}"
        );
    }

    proptest! {
        /// What the probe says codes nothing, the coder without RDOQ codes
        /// as the prediction itself: skipping it loses nothing the inter
        /// macroblock would have coded. (Under RDOQ, whose levels start
        /// from a rounding nearer the middle, it may.)
        #[test]
        fn what_codes_nothing_is_coded_as_its_prediction(
            noise in prop::collection::vec(-6i8..=6, 1..40),
            qp in 18u8..40,
        ) {
            let coder = MbCoder::new(qp, 1.4, false);
            let s = source();
            let pred = perturbed(&s, &noise);
            if coder.codes_nothing(&s, &pred) {
                let coded = coder.code(&s, &pred, false, &ResidualCoder::new(1, 1), 0, 0);
                prop_assert!(coded.residual.is_empty());
                prop_assert_eq!(coded.samples.luma, pred.luma);
                prop_assert_eq!(coded.samples.chroma, pred.chroma);
            }
        }

        /// A reused record coded into (every level, the 8x8 blocks and the
        /// luma DC levels left over from another macroblock) holds what a
        /// fresh one does, and reconstructs and prices the same.
        #[test]
        fn levels_written_into_a_used_record_are_a_fresh_records(
            noise in prop::collection::vec(-40i8..=40, 1..40),
            qp in 10u8..45,
            rdoq in any::<bool>(),
            intra in any::<bool>(),
            junk in -99i32..99,
        ) {
            let coder = MbCoder::new(qp, 1.4, rdoq);
            let residual_coder = ResidualCoder::new(1, 1);
            let s = source();
            let pred = perturbed(&s, &noise);
            let mut used = MbResidual {
                luma: [[[junk; 4]; 4]; 16],
                chroma: [[[[junk; 4]; 4]; 4]; 2],
                luma8: Some(Box::new([[[junk; 8]; 8]; 4])),
                luma_dc: [junk; 16],
            };
            let mut diffs = [[[junk; 4]; 4]; 16];
            // An intra 16x16 macroblock's luma (its chroma is the caller's).
            let mut used16 = used.clone();
            coder.intra16x16_luma_into(&s, &pred, &residual_coder, &mut used16);
            let fresh16 = coder.intra16x16_luma(&s, &pred, &residual_coder);
            prop_assert_eq!(
                (used16.luma, used16.luma_dc, &used16.luma8),
                (fresh16.luma, fresh16.luma_dc, &fresh16.luma8)
            );
            coder.levels_into((&s, &pred), intra, &residual_coder, &mut used, &mut diffs);
            let coded = coder.code(&s, &pred, intra, &residual_coder, 0, 0);
            prop_assert_eq!(&used, &*coded.residual);
            let syntax = ResidualSyntax::of_4x4(intra);
            let mut samples = pred.clone();
            let (bits, ssd) = coder.reconstruct_in_place(&s, &used, &mut samples, (&residual_coder, syntax), (0, 0));
            prop_assert_eq!(samples.luma, coded.samples.luma);
            prop_assert_eq!(samples.chroma, coded.samples.chroma);
            prop_assert_eq!((bits, ssd), (coded.bits, coded.ssd));
        }
    }
}
