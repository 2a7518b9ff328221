//! One frame: rate-distortion mode decision over the macroblocks, in
//! raster order, with reconstruction through the codec's functions.

use std::cell::RefCell;

use super::config::ModeDecision;
use super::intra4x4::{self, IntraBlockSearch};
use super::macroblock::{Coded, MbCoder, MbSource};
use super::motion::{BlockMotion, FrameMotion};
use super::partition::{PartitionSearch, SatdCache};
use crate::codec::deblock::{deblock_frame, MbEdgeInfo};
use crate::codec::intra4x4::LumaIntra;
use crate::codec::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::codec::mv::mvd_bits;
use crate::codec::mv::Mv;
use crate::codec::mvpred::{mv_prediction, mv_prediction_into, walk_partitions};
use crate::codec::partition::{MbVectors, Part, RefMv, Split};
use crate::codec::recon::{
    frame_vectors, predict_inter, predict_inter_blocks, predict_intra, predict_intra_plane, write_mb,
    InterContext, MbSamples,
};
use crate::codec::residual::{MbResidual, ResidualCoder, ResidualSyntax};
use crate::codec::syntax::{
    mb_mode, mb_vectors, vector_syntax, write_frame, BitCounts, CodedMb, EntropyState, FrameHeader,
    FrameSyntax, FrameType, FrameWriter, MbKind, MotionTool, SequenceHeader,
};
use crate::codec::warp::warp_frame;
use crate::codec::weight::Weights;
use crate::codec::{Frame, PictureError};
use crate::me::halfpel::HalfPel;
use crate::me::SQUARE;
use crate::metrics::squared_difference_sum;

/// With the full decision, an inter candidate is coded only when its
/// SATD + rate estimate is within this factor of the best's (x264's 5/4).
const RD_MARGIN: f64 = 1.25;

/// A 16x16 inter candidate of the mode decision.
struct InterCandidate {
    mv: RefMv,
    /// The predicted vector into its reference.
    mvp: Mv,
    satd: u32,
    /// SATD + sqrt(lambda) * (vector and reference index bits).
    estimate: f64,
    pred: MbSamples,
}

/// The length of reference index `ref_idx`'s truncated unary code among
/// `refs` references (the rate estimate of the motion search).
fn reference_bits(ref_idx: u8, refs: u8) -> u32 {
    u32::from(if ref_idx + 1 < refs { ref_idx + 1 } else { ref_idx })
}

/// A coded frame.
pub(crate) struct CodedFrame {
    pub syntax: FrameSyntax,
    /// Its bytes in the stream and their bits per category.
    pub bytes: Vec<u8>,
    pub bits: BitCounts,
    /// The reconstruction at the coded size, borders extended.
    pub recon: Frame,
    /// Squared error of the prediction (before the residual) over the
    /// visible luma.
    pub prediction_sse: u64,
    /// Macroblocks coded as skip, inter, intra.
    pub kinds: [usize; 3],
}

/// The squared luma error of `pred` against `src` over the visible part of
/// macroblock (mb_x, mb_y).
fn visible_luma_sse(src: &MbSource, pred: &MbSamples, mb_x: usize, mb_y: usize, seq: &SequenceHeader) -> u64 {
    let w = (seq.width - mb_x * 16).min(16);
    let h = (seq.height - mb_y * 16).min(16);
    (0..h)
        .map(|r| squared_difference_sum(&src.luma[r * 16..r * 16 + w], &pred.luma[r * 16..r * 16 + w]))
        .sum()
}

/// Luma SATD of a prediction.
fn luma_satd(src: &MbSource, pred: &MbSamples) -> u32 {
    crate::me::Metric::Satd.cost(&src.luma, 16, &pred.luma, 16, 16, 16)
}

fn kind_index(kind: &MbKind) -> usize {
    match kind {
        MbKind::Skip => 0,
        MbKind::Inter { .. } | MbKind::Split { .. } => 1,
        MbKind::Intra { .. } => 2,
    }
}

/// Where decided macroblocks go: written at once, the coders they are
/// priced with being the writer's (the writing adapts them), or only
/// adapted (OBMC, whose residuals are coded again once every vector is
/// decided, and written after that).
enum MbSink {
    Write(Box<FrameWriter>),
    Adapt(Box<(ModeCoder, ResidualCoder)>),
}

impl MbSink {
    fn modes(&self) -> &ModeCoder {
        match self {
            MbSink::Write(w) => w.modes(),
            MbSink::Adapt(c) => &c.0,
        }
    }

    fn residual(&self) -> &ResidualCoder {
        match self {
            MbSink::Write(w) => w.residual(),
            MbSink::Adapt(c) => &c.1,
        }
    }

    /// Macroblock (mb_x, mb_y) of a frame `cols` macroblocks wide,
    /// decided (`done`: the vectors of the macroblocks before it).
    fn push(
        &mut self,
        mb: &CodedMb,
        (mb_x, mb_y, cols): (usize, usize, usize),
        done: &[MbVectors],
        syntax: VectorSyntax,
    ) {
        match self {
            MbSink::Write(w) => w.push(mb),
            MbSink::Adapt(c) => {
                let (modes, residual_coder) = &mut **c;
                let mode = mb_mode(&mb.kind, done, (mb_x, mb_y, cols), syntax);
                modes.commit(mb_x, mb_y, true, syntax, &mode);
                if mb.kind != MbKind::Skip {
                    residual_coder.commit(mb_x, mb_y, mb.kind.residual_syntax(), mb.residual());
                }
            }
        }
    }
}

/// An I frame: every macroblock intra, modes by SATD; reconstructed into
/// `recon` (coded size, contents all overwritten) and written, `state`
/// updated.
pub(crate) fn code_intra(
    seq: &SequenceHeader,
    coder: &MbCoder,
    src: &Frame,
    deblock: bool,
    state: &mut EntropyState,
    mut recon: Frame,
) -> Result<CodedFrame, PictureError> {
    let cols = seq.mb_cols();
    let header = FrameHeader {
        frame_type: FrameType::Intra,
        qp: coder.qp,
        tool: MotionTool::Block,
        refs: 1,
        deblock,
        weights: Weights::NONE,
    };
    let mut writer = FrameWriter::new(seq, &header, None, state);
    let mut mbs = Vec::with_capacity(cols * seq.mb_rows());
    let mut prediction_sse = 0;
    for i in 0..cols * seq.mb_rows() {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let s = MbSource::load(src, mb_x, mb_y);
        let best = best_intra(
            coder,
            &s,
            &recon,
            (mb_x, mb_y),
            (writer.modes(), writer.residual()),
            None,
        );
        let Some(Choice {
            kind,
            pred,
            residual: Some(residual),
            samples,
            ..
        }) = best
        else {
            unreachable!("without a bound, intra always has a choice");
        };
        write_mb(&samples, &mut recon, mb_x, mb_y);
        prediction_sse += visible_luma_sse(&s, &pred, mb_x, mb_y, seq);
        let mb = CodedMb::with_levels(kind, residual);
        writer.push(&mb);
        mbs.push(mb);
    }
    let (bytes, bits) = writer.finish(state);
    let mut frame = CodedFrame {
        syntax: FrameSyntax {
            header,
            grid: None,
            mbs,
        },
        bytes,
        bits,
        recon,
        prediction_sse,
        kinds: [0, 0, cols * seq.mb_rows()],
    };
    frame.finish_recon(seq);
    Ok(frame)
}

/// The best intra choice of macroblock `at` by SSD + lambda * bits: the
/// 16x16 luma mode of least SATD, and the 8x8 and 4x4 modes of
/// [`IntraBlockSearch`], each with the chroma mode of least SAD.
/// `coders` are the frame's as they stand before the macroblock. With
/// `bound` (an inter estimate, SATD + sqrt(lambda) * bits), each luma
/// candidate is coded only when its estimate is below it; `None` when
/// none is.
fn best_intra(
    coder: &MbCoder,
    s: &MbSource,
    recon: &Frame,
    at: (usize, usize),
    (modes, residual_coder): (&ModeCoder, &ResidualCoder),
    bound: Option<(u32, f64)>,
) -> Option<Choice> {
    let mut pred = MbSamples::default();
    let (luma, satd) = coder.best_intra_luma(s, recon, at, &mut pred);
    let whole = bound.is_none_or(|(inter_satd, _)| satd < inter_satd);
    // In P frames, where inter mostly wins, blocks are searched only when
    // 16x16 intra is within 1.25 times inter's SATD (as x264's fast-intra
    // threshold; its 2 times at medium measured 0.1 % better on the
    // development set's mean against x264 medium, for 15 % more time; 1
    // time, 0.8 % worse).
    let hopeless = bound.is_some_and(|(inter_satd, _)| 4 * u64::from(satd) > 5 * u64::from(inter_satd));
    let search = (!hopeless).then(|| {
        let (around, mode_bits) = intra4x4::pricing(modes, at);
        IntraBlockSearch {
            coder,
            recon,
            at,
            around,
            mode_bits,
            residual: residual_coder,
        }
    });
    let estimate_bound = bound.map_or(f64::INFINITY, |b| b.1);
    // 8x8 blocks, where inter mostly wins, only where 16x16 intra is no
    // worse than inter by SATD: within 1.25 times, as 4x4 blocks, bought
    // 0.4 % more on the development set's mean for 5 % more of medium's
    // instructions on pan_cif.
    let blocks8_worth = bound.is_none_or(|(inter_satd, _)| satd <= inter_satd);
    let blocks8 = search
        .as_ref()
        .filter(|_| coder.intra8x8 && blocks8_worth)
        .and_then(|search| search.run8(s, None, estimate_bound));
    let blocks4 = search
        .as_ref()
        .filter(|_| coder.intra4x4)
        .and_then(|search| search.run(s, None, estimate_bound));
    if !whole && blocks8.is_none() && blocks4.is_none() {
        return None;
    }
    let chroma = coder.best_intra_chroma(s, recon, at, &mut pred);
    let inter_frame = bound.is_some();
    let choice = |luma: LumaIntra, pred: MbSamples, c: Coded| {
        let mode = MbMode::Intra { luma, chroma };
        let mode_bits = f64::from(modes.cost(at.0, at.1, inter_frame, VectorSyntax::None, &mode)) / 256.0;
        Choice {
            cost: coder.cost(c.ssd, c.bits + mode_bits),
            residual_cost: coder.cost(c.ssd, c.bits),
            kind: MbKind::Intra { luma, chroma },
            pred,
            residual: Some(c.residual),
            samples: c.samples,
        }
    };
    let code4 = |pred: &MbSamples| coder.code(s, pred, true, residual_coder, at.0, at.1);
    let mut candidates = Vec::with_capacity(3);
    if whole {
        candidates.push(choice(LumaIntra::Whole(luma), pred.clone(), code4(&pred)));
    }
    if let Some(b) = blocks8 {
        let pred8 = MbSamples {
            luma: b.pred,
            ..pred.clone()
        };
        let coded = coder.code_intra8x8(s, &pred8, b.levels, residual_coder, at);
        candidates.push(choice(LumaIntra::Blocks8(b.modes), pred8, coded));
    }
    if let Some(b) = blocks4 {
        let pred4 = MbSamples { luma: b.pred, ..pred };
        let coded = code4(&pred4);
        candidates.push(choice(LumaIntra::Blocks(b.modes), pred4, coded));
    }
    candidates.into_iter().min_by(|a, b| a.cost.total_cmp(&b.cost))
}

impl CodedFrame {
    /// The reconstruction as the decoder's: deblocked when the header says
    /// so (after every macroblock, whose intra prediction read the samples
    /// before it), borders extended.
    fn finish_recon(&mut self, seq: &SequenceHeader) {
        let header = &self.syntax.header;
        if header.deblock {
            let vectors = frame_vectors(seq, &self.syntax);
            let info = MbEdgeInfo::of_frame(&self.syntax, &vectors);
            deblock_frame(&mut self.recon, &info, header.qp);
        }
        self.recon.extend_borders();
    }
}

/// One way to code a macroblock, with its cost.
struct Choice {
    cost: f64,
    /// The part of `cost` the residual accounts for (its SSD + lambda *
    /// bits; 0 for skip).
    residual_cost: f64,
    kind: MbKind,
    pred: MbSamples,
    residual: Option<Box<MbResidual>>,
    /// The reconstruction it gives.
    samples: MbSamples,
}

/// What a P frame is predicted from and how.
pub(crate) struct InterInputs<'a> {
    /// The references (coded size): the previous reconstruction (weighted)
    /// first, then older ones (block frames).
    pub references: Vec<&'a Frame>,
    pub motion: FrameMotion,
    pub tool: MotionTool,
    pub decision: ModeDecision,
    /// Whether the frame is deblocked.
    pub deblock: bool,
    /// The weights `reference` was weighted with (already applied).
    pub weights: Weights,
    /// Inter macroblocks may be split (block frames).
    pub partitions: bool,
    /// Sub-pel RD refinement of 16x16 inter vectors (block frames).
    pub subpel_rd: bool,
}

/// One macroblock under analysis: its source, its predicted vector and the
/// best choice so far (x264's per-macroblock analysis context).
struct MbAnalysis {
    index: usize,
    mb_x: usize,
    mb_y: usize,
    source: MbSource,
    mvp: Mv,
    /// The skip prediction (also the inter prediction with vector `mvp`).
    skip_pred: MbSamples,
    best: Choice,
    /// Whether any choice but skip can win (see [`InterFrameCoder::analyse_skip`]).
    exhaustive: bool,
    /// The lowest luma SATD of the inter candidates, for intra's early out.
    inter_satd: u32,
    /// The lowest SATD + sqrt(lambda) * vector bits of the 16x16 inter
    /// candidates, which a split must beat to be coded.
    inter_estimate: f64,
}

impl MbAnalysis {
    /// Keeps `choice` if it costs less than the best so far.
    fn consider(&mut self, choice: Choice) {
        if choice.cost < self.best.cost {
            self.best = choice;
        }
    }
}

/// A P frame's mode decision: one analysis context over the frame, one
/// method per kind of candidate, macroblocks in raster order.
struct InterFrameCoder<'a> {
    seq: &'a SequenceHeader,
    coder: &'a MbCoder,
    src: &'a Frame,
    /// The frame's references, the previous reconstruction first.
    references: Vec<&'a Frame>,
    tool: MotionTool,
    decision: ModeDecision,
    /// Motion analysis' vector per macroblock (zero for grid frames).
    searched: Vec<Mv>,
    /// Whether inter macroblocks may be split (block frames).
    partitions: bool,
    /// Sub-pel RD refinement of 16x16 inter vectors (block frames).
    subpel_rd: bool,
    /// A vector per 8x8 block, when motion analysis has one (flows).
    blocks: Option<Vec<Mv>>,
    /// Motion analysis' vectors per macroblock into each older reference.
    older: Vec<Vec<Mv>>,
    /// The reference's half-pel planes, for the partitions' search.
    halfpel: Option<HalfPel>,
    /// The partition search's cache (kept: emptied, not reallocated).
    satd8: RefCell<SatdCache>,
    /// The reference warped by the grid, for grid frames.
    warped: Option<Frame>,
    /// Which vectors the frame codes.
    syntax: VectorSyntax,
    /// The vectors OBMC predicts with: decided ones, searched ones for the
    /// macroblocks not decided yet.
    context: Vec<MbVectors>,
    /// The decided vectors, for the vector prediction.
    decided: Vec<MbVectors>,
    sink: MbSink,
    /// OBMC's second pass prices residuals from the frame's start again.
    residual_coder_at_start: Option<ResidualCoder>,
    /// The frame so far: its macroblocks and reconstruction.
    frame: CodedFrame,
}

impl<'a> InterFrameCoder<'a> {
    fn new(
        seq: &'a SequenceHeader,
        coder: &'a MbCoder,
        src: &'a Frame,
        inputs: InterInputs<'a>,
        state: &EntropyState,
        recon: Frame,
    ) -> Result<InterFrameCoder<'a>, PictureError> {
        let n = seq.mb_cols() * seq.mb_rows();
        let (
            BlockMotion {
                mb: searched,
                blocks,
                halfpel,
                older,
            },
            grid,
            warped,
        ) = match inputs.motion {
            FrameMotion::Vectors(v) => (v, None, None),
            FrameMotion::Grid(g) => {
                let mut out = Frame::new(seq.coded_width(), seq.coded_height())?;
                warp_frame(inputs.references[0], &g, &mut out);
                let none = BlockMotion {
                    mb: vec![Mv::ZERO; n],
                    blocks: None,
                    halfpel: None,
                    older: Vec::new(),
                };
                (none, Some(g), Some(out))
            }
        };
        let header = FrameHeader {
            frame_type: FrameType::Inter,
            qp: coder.qp,
            tool: inputs.tool,
            refs: inputs.references.len() as u8,
            deblock: inputs.deblock,
            weights: inputs.weights,
        };
        let obmc = inputs.tool == MotionTool::Obmc;
        let sink = if obmc {
            MbSink::Adapt(Box::new(state.coders(seq, FrameType::Inter)))
        } else {
            MbSink::Write(Box::new(FrameWriter::new(seq, &header, grid.as_ref(), state)))
        };
        Ok(InterFrameCoder {
            seq,
            coder,
            src,
            references: inputs.references,
            older,
            tool: inputs.tool,
            decision: inputs.decision,
            syntax: vector_syntax(&header),
            context: searched.iter().map(|&v| [Some(RefMv::previous(v)); 4]).collect(),
            searched,
            partitions: inputs.partitions && inputs.tool == MotionTool::Block,
            subpel_rd: inputs.subpel_rd,
            halfpel,
            blocks,
            satd8: RefCell::default(),
            warped,
            decided: Vec::with_capacity(n),
            residual_coder_at_start: obmc.then(|| sink.residual().clone()),
            sink,
            frame: CodedFrame {
                syntax: FrameSyntax {
                    header,
                    grid,
                    mbs: Vec::with_capacity(n),
                },
                bytes: Vec::new(),
                bits: BitCounts::default(),
                recon,
                prediction_sse: 0,
                kinds: [0; 3],
            },
        })
    }

    fn inter_context(&self) -> InterContext<'_> {
        InterContext {
            references: &self.references,
            tool: self.tool,
            vectors: &self.context,
            warped: self.warped.as_ref(),
            mb_cols: self.seq.mb_cols(),
        }
    }

    /// Bits of a mode as the frame's mode coder prices it now.
    fn mode_bits(&self, mb: &MbAnalysis, mode: &MbMode) -> f64 {
        f64::from(self.sink.modes().cost(mb.mb_x, mb.mb_y, true, self.syntax, mode)) / 256.0
    }

    /// Macroblock `index`, decided: skip first, then inter and intra when
    /// they can win.
    fn analyse(&self, index: usize) -> MbAnalysis {
        let mut mb = self.analyse_skip(index);
        if mb.exhaustive {
            self.analyse_inter(&mut mb);
            self.analyse_split(&mut mb);
            self.analyse_intra(&mut mb);
            self.analyse_subpel_rd(&mut mb);
            self.analyse_transform(&mut mb);
        }
        mb
    }

    /// Sub-pel RD refinement (x264's `--subme 8`): when a 16x16 inter
    /// vector won, its eight quarter-pel neighbours are estimated (SATD +
    /// sqrt(lambda) * vector bits), and the two of lowest estimate within
    /// [`RD_MARGIN`] of the winner's are coded and weighed by RD.
    fn analyse_subpel_rd(&self, mb: &mut MbAnalysis) {
        let MbKind::Inter { mv } = mb.best.kind else {
            return;
        };
        if !self.subpel_rd || self.tool != MotionTool::Block {
            return;
        }
        let at = (mb.mb_x, mb.mb_y, self.seq.mb_cols());
        let mvp = mv_prediction_into(&self.decided, at, mv.ref_idx);
        let winner = self.inter_candidate(mb, mv, mvp, mb.best.pred.clone()).estimate;
        // The eight quarter-pel steps around it.
        let mut candidates: Vec<InterCandidate> = SQUARE
            .iter()
            .map(|&(dx, dy)| Mv::new(mv.mv.x + dx, mv.mv.y + dy))
            .filter(|m| m.in_range())
            .map(|m| {
                let m = RefMv::new(m, mv.ref_idx);
                let pred = predict_inter(&self.inter_context(), mb.mb_x, mb.mb_y, m);
                self.inter_candidate(mb, m, mvp, pred)
            })
            .filter(|c| c.estimate <= RD_MARGIN * winner)
            .collect();
        candidates.sort_by(|a, b| a.estimate.total_cmp(&b.estimate));
        for c in candidates.into_iter().take(2) {
            let mode = MbMode::Inter {
                mvd: c.mv.mv - c.mvp,
                ref_idx: c.mv.ref_idx,
            };
            let choice = self.coded_choice(mb, MbKind::Inter { mv: c.mv }, &mode, c.pred);
            mb.consider(choice);
        }
    }

    /// An inter choice's luma in the 8x8 transform, kept when it costs
    /// less than in 4x4 ones.
    fn analyse_transform(&self, mb: &mut MbAnalysis) {
        let best = &mut mb.best;
        let (MbKind::Inter { .. } | MbKind::Split { .. }, Some(residual)) = (&best.kind, &best.residual)
        else {
            return;
        };
        let at = (mb.mb_x, mb.mb_y);
        let Some(c8) = self.coder.luma8_alternative(
            &mb.source,
            &best.pred,
            (residual, &best.samples),
            self.sink.residual(),
            at,
        ) else {
            return;
        };
        let cost8 = self.coder.cost(c8.ssd, c8.bits);
        if cost8 < best.residual_cost {
            best.cost += cost8 - best.residual_cost;
            best.residual_cost = cost8;
            best.residual = Some(c8.residual);
            best.samples = c8.samples;
        }
    }

    /// The analysis context of macroblock `index` with skip as its best.
    fn analyse_skip(&self, index: usize) -> MbAnalysis {
        let cols = self.seq.mb_cols();
        let (mb_x, mb_y) = (index % cols, index / cols);
        let source = MbSource::load(self.src, mb_x, mb_y);
        let mvp = if self.syntax.any() {
            mv_prediction(&self.decided, mb_x, mb_y, cols)
        } else {
            Mv::ZERO
        };
        let skip_pred = predict_inter(&self.inter_context(), mb_x, mb_y, RefMv::previous(mvp));
        let mut mb = MbAnalysis {
            index,
            mb_x,
            mb_y,
            mvp,
            best: Choice {
                cost: 0.0,
                residual_cost: 0.0,
                kind: MbKind::Skip,
                pred: skip_pred.clone(),
                residual: None,
                samples: skip_pred.clone(),
            },
            source,
            skip_pred,
            exhaustive: false,
            inter_satd: u32::MAX,
            inter_estimate: f64::INFINITY,
        };
        mb.best.cost = self
            .coder
            .cost(mb.source.ssd(&mb.skip_pred), self.mode_bits(&mb, &MbMode::Skip));
        // Every other choice spends at least the flag saying it is not
        // skipped: when skip costs no more, nothing can beat it.
        let not_skipped = f64::from(self.sink.modes().not_skipped_cost(mb_x, mb_y)) / 256.0;
        mb.exhaustive = mb.best.cost > self.coder.cost(0, not_skipped);
        mb
    }

    /// Inter with the predicted vector and with the searched one, and
    /// with each older reference's searched vector (with
    /// [`ModeDecision::Fast`], only the one of lowest SATD + rate
    /// estimate; with the full decision, those within [`RD_MARGIN`] of it).
    fn analyse_inter(&self, mb: &mut MbAnalysis) {
        let searched = self.searched[mb.index];
        let searched_mv = (self.syntax.any() && searched != mb.mvp).then_some(searched);
        let mut candidates = Vec::with_capacity(1 + usize::from(self.syntax.refs()));
        for mv in std::iter::once(mb.mvp).chain(searched_mv) {
            let pred = if mv == mb.mvp {
                mb.skip_pred.clone()
            } else {
                predict_inter(&self.inter_context(), mb.mb_x, mb.mb_y, RefMv::previous(mv))
            };
            candidates.push(self.inter_candidate(mb, RefMv::previous(mv), mb.mvp, pred));
        }
        for ref_idx in 1..self.syntax.refs() {
            candidates.push(self.older_reference_candidate(mb, ref_idx));
        }
        mb.inter_satd = candidates.iter().map(|c| c.satd).min().unwrap_or(u32::MAX);
        mb.inter_estimate = candidates
            .iter()
            .map(|c| c.estimate)
            .fold(f64::INFINITY, f64::min);
        if self.decision == ModeDecision::Fast {
            // The lowest SATD + sqrt(lambda) * vector bits is coded alone.
            candidates.sort_by(|a, b| a.estimate.total_cmp(&b.estimate));
            candidates.truncate(1);
        } else {
            // Only the candidates whose estimate is within a quarter of
            // the best are coded (x264's threshold for RD mode decision):
            // as good on the development set's mean, 2 % fewer
            // instructions on pan_cif (callgrind).
            candidates.retain(|c| c.estimate <= RD_MARGIN * mb.inter_estimate);
        }
        for c in candidates {
            let mode = MbMode::Inter {
                mvd: c.mv.mv - c.mvp,
                ref_idx: c.mv.ref_idx,
            };
            let choice = self.coded_choice(mb, MbKind::Inter { mv: c.mv }, &mode, c.pred);
            mb.consider(choice);
        }
    }

    /// A 16x16 inter candidate with its SATD and its estimate, SATD +
    /// sqrt(lambda) * (vector and reference index bits).
    fn inter_candidate(&self, mb: &MbAnalysis, mv: RefMv, mvp: Mv, pred: MbSamples) -> InterCandidate {
        let satd = luma_satd(&mb.source, &pred);
        let bits = mvd_bits(mv.mv, mvp) + reference_bits(mv.ref_idx, self.syntax.refs());
        InterCandidate {
            mv,
            mvp,
            estimate: f64::from(satd) + self.coder.lambda.sqrt() * f64::from(bits),
            satd,
            pred,
        }
    }

    /// The 16x16 candidate into older reference `ref_idx`, with motion
    /// analysis' vector.
    fn older_reference_candidate(&self, mb: &MbAnalysis, ref_idx: u8) -> InterCandidate {
        let at = (mb.mb_x, mb.mb_y, self.seq.mb_cols());
        let mvp = mv_prediction_into(&self.decided, at, ref_idx);
        let mv = RefMv::new(self.older[usize::from(ref_idx) - 1][mb.index], ref_idx);
        let pred = predict_inter(&self.inter_context(), mb.mb_x, mb.mb_y, mv);
        self.inter_candidate(mb, mv, mvp, pred)
    }

    /// The macroblock split into partitions (block frames): the 8x8 split
    /// first, then, when it beats the 16x16 estimate, 16x8 and 8x16 seeded
    /// with its vectors (as x264); the best of them by SATD + lambda *
    /// bits is coded and considered.
    fn analyse_split(&self, mb: &mut MbAnalysis) {
        if !self.partitions {
            return;
        }
        let search = PartitionSearch {
            source: &mb.source.luma,
            reference: self.references[0].y(),
            halfpel: self.halfpel.as_ref(),
            mb: (mb.mb_x, mb.mb_y),
            sad_lambda: self.coder.lambda.sqrt(),
            satd8: &self.satd8,
        };
        self.satd8.borrow_mut().clear();
        // The candidates alone first: when they do not beat the 16x16
        // estimate, the refinement (most of the work) is not done (a
        // margin of 10 % for what it could still find: 0.2 % better on the
        // development set's mean, 15 % slower).
        let rough = self.search_split(mb, &search, Split::Quad, None, false);
        if rough.0 >= mb.inter_estimate {
            return;
        }
        let quad = self.search_split(mb, &search, Split::Quad, None, true);
        if quad.0 >= mb.inter_estimate {
            return;
        }
        let best = [Split::Horizontal, Split::Vertical]
            .map(|split| self.search_split(mb, &search, split, Some(&quad.2), true))
            .into_iter()
            .fold(quad, |a, b| if b.0 < a.0 { b } else { a });
        let (_, split, mvs) = best;
        let kind = MbKind::Split {
            split,
            mvs: mvs.map(RefMv::previous),
        };
        let at = (mb.mb_x, mb.mb_y, self.seq.mb_cols());
        let mode = mb_mode(&kind, &self.decided, at, self.syntax);
        let pred = predict_inter_blocks(
            &self.inter_context(),
            mb.mb_x,
            mb.mb_y,
            &split.block_vectors(&mvs.map(RefMv::previous)),
        );
        let choice = self.coded_choice(mb, kind, &mode, pred);
        mb.consider(choice);
    }

    /// The vectors of `split`'s partitions, each searched against its
    /// predicted vector (which reads the partitions before it), with their
    /// total SATD + lambda * bits (the split's own bits included).
    /// Candidates: the 8x8 vectors under the partition, the macroblock's,
    /// and `quad`'s (the 8x8 split's decided vectors) when given.
    fn search_split(
        &self,
        mb: &MbAnalysis,
        search: &PartitionSearch<'_>,
        split: Split,
        quad: Option<&[Mv; 4]>,
        refine: bool,
    ) -> (f64, Split, [Mv; 4]) {
        let (mut mvs, mut total) = ([Mv::ZERO; 4], 0.0);
        let mut candidates = Vec::with_capacity(16);
        walk_partitions(
            split,
            &self.decided,
            (mb.mb_x, mb.mb_y, self.seq.mb_cols()),
            |k, predict| {
                let mvp = predict(0);
                let p = &split.parts()[k];
                self.partition_candidates(mb, p, quad, &mut candidates);
                let best = search.best(p, &candidates, mvp, refine);
                mvs[k] = best.mv;
                total += best.cost;
                Some(RefMv::previous(best.mv))
            },
        );
        // The split's own flags, over a 16x16 macroblock's.
        let flags = self.mode_bits(
            mb,
            &MbMode::Split {
                split,
                mvds: [Mv::ZERO; 4],
                refs: [0; 4],
            },
        ) - self.mode_bits(
            mb,
            &MbMode::Inter {
                mvd: Mv::ZERO,
                ref_idx: 0,
            },
        );
        (total + search.sad_lambda * flags.max(0.0), split, mvs)
    }

    /// The candidate vectors of partition `p` of `mb` into `out` (emptied
    /// first): the macroblock's searched vector, and per 8x8 block of the
    /// partition the flow's vector (flow predictors), `quad`'s and the
    /// searched vectors of the macroblocks the block touches (a block on
    /// a motion edge moves with one of them).
    fn partition_candidates(&self, mb: &MbAnalysis, p: &Part, quad: Option<&[Mv; 4]>, out: &mut Vec<Mv>) {
        let (cols, rows) = (self.seq.mb_cols(), self.seq.mb_rows());
        out.clear();
        out.push(self.searched[mb.index]);
        for b in p.blocks() {
            if let Some(blocks) = &self.blocks {
                out.push(blocks[(2 * mb.mb_y + b / 2) * 2 * cols + 2 * mb.mb_x + b % 2]);
            }
            if let Some(q) = quad {
                out.push(q[b]);
            }
            let (dx, dy) = (2 * (b % 2) as isize - 1, 2 * (b / 2) as isize - 1);
            for (ox, oy) in [(dx, 0), (0, dy), (dx, dy)] {
                let (x, y) = (mb.mb_x as isize + ox, mb.mb_y as isize + oy);
                if x >= 0 && y >= 0 && (x as usize) < cols && (y as usize) < rows {
                    out.push(self.searched[y as usize * cols + x as usize]);
                }
            }
        }
    }

    /// Intra, each luma candidate coded only when its estimate is below
    /// inter's (the 16x16 SATD below inter's SATD, as the H.264 reference
    /// encoder's fast modes; the 4x4 search's below inter's SATD + vector
    /// cost, where it stops early).
    fn analyse_intra(&self, mb: &mut MbAnalysis) {
        let bound = (mb.inter_satd, mb.inter_estimate);
        let coders = (self.sink.modes(), self.sink.residual());
        let at = (mb.mb_x, mb.mb_y);
        if let Some(choice) = best_intra(self.coder, &mb.source, &self.frame.recon, at, coders, Some(bound)) {
            mb.consider(choice);
        }
    }

    /// `pred` with its residual coded, priced as `mode`.
    fn coded_choice(&self, mb: &MbAnalysis, kind: MbKind, mode: &MbMode, pred: MbSamples) -> Choice {
        let intra = matches!(kind, MbKind::Intra { .. });
        let coded = self
            .coder
            .code(&mb.source, &pred, intra, self.sink.residual(), mb.mb_x, mb.mb_y);
        let bits = self.mode_bits(mb, mode) + coded.bits;
        Choice {
            cost: self.coder.cost(coded.ssd, bits),
            residual_cost: self.coder.cost(coded.ssd, coded.bits),
            kind,
            pred,
            residual: Some(coded.residual),
            samples: coded.samples,
        }
    }

    /// Reconstructs and records the decided macroblock.
    fn commit(&mut self, mb: MbAnalysis) {
        let (mb_x, mb_y) = (mb.mb_x, mb.mb_y);
        let best = mb.best;
        write_mb(&best.samples, &mut self.frame.recon, mb_x, mb_y);
        self.frame.prediction_sse += visible_luma_sse(&mb.source, &best.pred, mb_x, mb_y, self.seq);
        let cols = self.seq.mb_cols();
        let v = mb_vectors(&best.kind, &self.decided, mb_x, mb_y, cols);
        self.frame.kinds[kind_index(&best.kind)] += 1;
        let coded = match best.residual {
            Some(levels) => CodedMb::with_levels(best.kind, levels),
            None => CodedMb::without_residual(best.kind),
        };
        self.sink
            .push(&coded, (mb_x, mb_y, cols), &self.decided, self.syntax);
        self.decided.push(v);
        self.context[mb.index] = v;
        self.frame.syntax.mbs.push(coded);
    }

    /// The coded frame, written; `state` updated.
    fn finish(self, state: &mut EntropyState) -> Result<CodedFrame, PictureError> {
        let mut frame = self.frame;
        match self.sink {
            MbSink::Write(writer) => (frame.bytes, frame.bits) = writer.finish(state),
            MbSink::Adapt(_) => {
                // Decisions saw neighbours' searched vectors; code the
                // residuals again against the final prediction, which uses
                // the decided ones, then write the frame.
                if let Some(residual_coder) = self.residual_coder_at_start {
                    recode(
                        self.seq,
                        self.coder,
                        self.src,
                        self.references[0],
                        residual_coder,
                        &mut frame,
                    )?;
                }
                (frame.bytes, frame.bits) = write_frame(self.seq, &frame.syntax, state);
            }
        }
        frame.finish_recon(self.seq);
        Ok(frame)
    }
}

/// A P frame predicted as `inputs` say, reconstructed into `recon` (coded
/// size, contents all overwritten) and written, `state` updated.
pub(crate) fn code_inter(
    seq: &SequenceHeader,
    coder: &MbCoder,
    src: &Frame,
    inputs: InterInputs<'_>,
    state: &mut EntropyState,
    recon: Frame,
) -> Result<CodedFrame, PictureError> {
    let mut frame_coder = InterFrameCoder::new(seq, coder, src, inputs, state, recon)?;
    for index in 0..seq.mb_cols() * seq.mb_rows() {
        let mb = frame_coder.analyse(index);
        frame_coder.commit(mb);
    }
    frame_coder.finish(state)
}

/// Codes every macroblock's residual again, keeping the decisions, against
/// the prediction the decoder will form.
fn recode(
    seq: &SequenceHeader,
    coder: &MbCoder,
    src: &Frame,
    reference: &Frame,
    mut residual_coder: ResidualCoder,
    frame: &mut CodedFrame,
) -> Result<(), PictureError> {
    let cols = seq.mb_cols();
    let vectors = crate::codec::recon::frame_vectors(seq, &frame.syntax);
    let mut recon = Frame::new(seq.coded_width(), seq.coded_height())?;
    frame.prediction_sse = 0;
    let ctx = InterContext {
        references: &[reference],
        tool: frame.syntax.header.tool,
        vectors: &vectors,
        warped: None,
        mb_cols: cols,
    };
    for (i, mb) in frame.syntax.mbs.iter_mut().enumerate() {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let s = MbSource::load(src, mb_x, mb_y);
        // Block intra modes are kept, each block predicted from the new
        // reconstruction of those before it.
        let search = IntraBlockSearch {
            coder,
            recon: &recon,
            at: (mb_x, mb_y),
            around: [None, None],
            mode_bits: (0, 0),
            residual: &residual_coder,
        };
        let mut pred = MbSamples::default();
        let mut luma8 = None;
        match mb.kind {
            MbKind::Intra {
                luma: LumaIntra::Whole(luma),
                chroma,
            } => pred = predict_intra(&recon, mb_x, mb_y, luma, chroma),
            MbKind::Intra {
                luma: LumaIntra::Blocks(modes),
                ..
            } => {
                if let Some(b) = search.run(&s, Some(&modes), f64::INFINITY) {
                    pred.luma = b.pred;
                }
            }
            MbKind::Intra {
                luma: LumaIntra::Blocks8(modes),
                ..
            } => {
                if let Some(b) = search.run8(&s, Some(&modes), f64::INFINITY) {
                    (pred.luma, luma8) = (b.pred, b.levels);
                }
            }
            _ => pred = predict_inter_blocks(&ctx, mb_x, mb_y, &vectors[i].map(Option::unwrap_or_default)),
        }
        if let MbKind::Intra { chroma, .. } = mb.kind {
            for p in 0..2 {
                predict_intra_plane(&recon, p + 1, mb_x, mb_y, chroma, &mut pred.chroma[p]);
            }
        }
        frame.prediction_sse += visible_luma_sse(&s, &pred, mb_x, mb_y, seq);
        if mb.kind == MbKind::Skip {
            write_mb(&pred, &mut recon, mb_x, mb_y);
        } else {
            let coded = match mb.kind.residual_syntax() {
                ResidualSyntax::Intra => coder.code(&s, &pred, true, &residual_coder, mb_x, mb_y),
                ResidualSyntax::Intra8x8 => {
                    coder.code_intra8x8(&s, &pred, luma8, &residual_coder, (mb_x, mb_y))
                }
                ResidualSyntax::Inter => coder.code_inter(&s, &pred, &residual_coder, mb_x, mb_y),
            };
            write_mb(&coded.samples, &mut recon, mb_x, mb_y);
            residual_coder.commit(mb_x, mb_y, mb.kind.residual_syntax(), &coded.residual);
            *mb = CodedMb::with_levels(mb.kind, coded.residual);
        }
    }
    frame.recon = recon;
    Ok(())
}
