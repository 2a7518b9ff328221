//! One frame's macroblocks in raster order (x264's `slice_write`): the I
//! frame's loop, and the P frame's, each macroblock analysed
//! ([`super::analyse`]), reconstructed through the codec's functions and
//! written through a [`FrameWriter`] as it is decided, so that the next is
//! priced from the writer's coders as they stand; OBMC's second pass; the
//! frame deblocked at the end as the decoder does it.

use std::cell::RefCell;

use super::analyse::{intra_against, MbAnalysis, MbEnv};
use super::progress::FrameProgress;
use super::reference::GrowingReference;
use super::wavefront::{self, ResidualTracking, WavefrontFrame};

use super::config::ModeDecision;
use super::deblock_choice::{measured_around, DeblockEffect, DeblockMeasure};
use super::intra4x4::IntraBlockSearch;
use super::macroblock::{prefetch_ahead, MbCoder, MbSource};
use super::motion::{BlockMotion, FrameMotion, LazySearch};
use super::partition::SatdCache;
use super::refs_choice::OlderGain;
use super::{rate, rdo};
use crate::codec::deblock::{DeblockOffsets, DeblockStrength, FrameDeblocker, MbEdgeInfo};
use crate::codec::interp::LumaFilter;
use crate::codec::intra4x4::LumaIntra;
use crate::codec::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::codec::mv::Mv;
use crate::codec::partition::{MbVectors, RefMv};
use crate::codec::recon::{
    frame_vectors, predict_inter_blocks, predict_intra, predict_intra_plane, write_mb, InterContext,
    MbSamples,
};
use crate::codec::residual::{ResidualCoder, ResidualSyntax};
use crate::codec::syntax::{
    mb_mode, mb_vectors, vector_syntax, write_decided_frame, BitCounts, CodedMb, EntropyState, FrameHeader,
    FrameSyntax, FrameType, FrameWriter, MbKind, MotionTool, SequenceHeader,
};
use crate::codec::warp::{warp_frame, MotionGrid};
use crate::codec::weight::Weights;
use crate::codec::{Frame, PictureError, Plane};
use crate::me::halfpel::HalfPel;
use crate::metrics::squared_difference_sum;

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
    /// Each macroblock's vectors (none for intra), as
    /// [`crate::codec::recon::frame_vectors`] gives them.
    pub vectors: Vec<MbVectors>,
    /// Whether `recon` is deblocked already (as it was decided).
    pub deblocked: bool,
    /// What the filter did, where the frame's deblocking is chosen and
    /// it was deblocked ([`super::deblock_choice`]).
    pub deblock_effect: Option<DeblockEffect>,
    /// What its older references saved, where it searched any
    /// ([`super::refs_choice`]).
    pub older_gain: Option<OlderGain>,
}

/// The squared luma error of `pred` against `src` over the visible part of
/// macroblock (mb_x, mb_y).
pub(super) fn visible_luma_sse(
    src: &MbSource,
    pred: &MbSamples,
    mb_x: usize,
    mb_y: usize,
    seq: &SequenceHeader,
) -> u64 {
    let (w, h) = visible_size(mb_x, mb_y, seq);
    if w == 16 {
        // Whole rows: one run of samples (a call a row cost 16 kernel calls
        // a macroblock).
        return squared_difference_sum(&src.luma[..h * 16], &pred.luma[..h * 16]);
    }
    (0..h)
        .map(|r| squared_difference_sum(&src.luma[r * 16..r * 16 + w], &pred.luma[r * 16..r * 16 + w]))
        .sum()
}

/// The columns and rows of macroblock (mb_x, mb_y) inside the picture.
fn visible_size(mb_x: usize, mb_y: usize, seq: &SequenceHeader) -> (usize, usize) {
    ((seq.width - mb_x * 16).min(16), (seq.height - mb_y * 16).min(16))
}

pub(super) fn kind_index(kind: &MbKind) -> usize {
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
pub(super) enum MbSink {
    Write(Box<FrameWriter>),
    Adapt(Box<(ModeCoder, ResidualCoder)>),
}

impl MbSink {
    pub(super) fn modes(&self) -> &ModeCoder {
        match self {
            MbSink::Write(w) => w.modes(),
            MbSink::Adapt(c) => &c.0,
        }
    }

    pub(super) fn residual(&self) -> &ResidualCoder {
        match self {
            MbSink::Write(w) => w.residual(),
            MbSink::Adapt(c) => &c.1,
        }
    }

    /// Macroblock (mb_x, mb_y) of a frame `cols` macroblocks wide,
    /// decided (`done`: the vectors of the macroblocks before it).
    pub(super) fn push(
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

/// An I frame: every macroblock intra, modes by SATD, decided on a
/// wavefront; reconstructed into `recon` (coded size, contents all
/// overwritten) and written, `state` updated.
pub(crate) fn code_intra(
    seq: &SequenceHeader,
    coder: &MbCoder,
    src: &Frame,
    deblock: Option<DeblockOffsets>,
    state: &mut EntropyState,
    recon: Frame,
) -> Result<CodedFrame, PictureError> {
    let cols = seq.mb_cols();
    let header = FrameHeader {
        frame_type: FrameType::Intra,
        qp: coder.qp,
        tool: MotionTool::Block,
        refs: 1,
        deblock: deblock.is_some(),
        deblock_offsets: deblock.unwrap_or_default(),
        weights: Weights::NONE,
        luma_filter: LumaFilter::Sharp,
    };
    let (modes, residual) = state.coders(seq, FrameType::Intra);
    let frame = WavefrontFrame {
        seq,
        modes: &modes,
        residual: &residual,
        inter_frame: false,
        syntax: vector_syntax(&header),
        // Half a row: the contexts start untrained in an I frame, and a
        // row priced from the row above's after two macroblocks cost 0.6 %
        // more bits on the development set's mean (30 frames) than raster
        // order; after half a row, 0.25 %, with two workers still busy.
        lead: cols / 2,
        // Untrained at an I frame's start: they adapt.
        tracking: ResidualTracking::Adapt,
        deblock: header
            .deblock
            .then_some((DeblockStrength::of(&header), header.tool)),
        measure: None,
    };
    let decided = frame.decide(recon, &|env, index, mb| {
        let (mb_x, mb_y) = (index % cols, index / cols);
        mb.source.load_into(src, mb_x, mb_y);
        prefetch_ahead(src, mb_x, mb_y);
        // Without a bound, the 16x16 candidate is always coded.
        let (coded, _) = intra_against(
            coder,
            &mb.source,
            env.recon,
            (mb_x, mb_y),
            (env.modes, env.residual),
            None,
            &mut mb.best,
        );
        debug_assert!(coded, "an I frame's macroblock coded as 16x16 intra at least");
        wavefront::Decision {
            prediction_sse: visible_luma_sse(&mb.source, &mb.best.pred, mb_x, mb_y, seq),
            mvp: None,
            older_gain: OlderGain::default(),
        }
    })?;
    let (sum, recon) = wavefront::collect(decided, cols);
    let syntax = FrameSyntax {
        header,
        grid: None,
        mbs: sum.mbs,
    };
    let mut frame = CodedFrame {
        syntax,
        bytes: Vec::new(),
        bits: BitCounts::default(),
        recon,
        prediction_sse: sum.prediction_sse,
        kinds: sum.kinds,
        vectors: sum.vectors,
        deblocked: sum.deblocked,
        deblock_effect: None,
        older_gain: None,
    };
    frame.write_and_finish(seq, state, None, |_| ());
    Ok(frame)
}

impl CodedFrame {
    /// A frame of `syntax` not written yet, over `recon`, nothing counted.
    fn empty(syntax: FrameSyntax, recon: Frame) -> CodedFrame {
        CodedFrame {
            syntax,
            bytes: Vec::new(),
            bits: BitCounts::default(),
            recon,
            prediction_sse: 0,
            kinds: [0; 3],
            vectors: Vec::new(),
            deblocked: false,
            deblock_effect: None,
            older_gain: None,
        }
    }

    /// Writes the frame (its macroblocks decided) and finishes its
    /// reconstruction at once: the range coder on one thread, the
    /// deblocking on others, and `beside` (given the frame's vectors)
    /// after the range coder (work for the next frame that the frame's
    /// threads would otherwise wait on, one after the other).
    fn write_and_finish(
        &mut self,
        seq: &SequenceHeader,
        state: &mut EntropyState,
        measure: Option<DeblockMeasure<'_>>,
        beside: impl FnOnce(&[MbVectors]) + Send,
    ) {
        let ((written, ()), effect) = rayon::join(
            || {
                rayon::join(
                    || write_decided_frame(seq, &self.syntax, &self.vectors, state),
                    || beside(&self.vectors),
                )
            },
            || {
                finish_recon(
                    seq,
                    &self.syntax,
                    &self.vectors,
                    &mut self.recon,
                    (self.deblocked, measure),
                )
            },
        );
        (self.bytes, self.bits) = written;
        self.deblock_effect = self.deblock_effect.or(effect);
    }
}

/// The reconstruction of `syntax` as the decoder's: deblocked when the
/// header says so (after every macroblock, whose intra prediction read the
/// samples before it; the three planes at once) unless `deblocked`
/// already, borders extended; the filter's effect where deblocked here
/// and measured against `measure` (the source's luma).
fn finish_recon(
    seq: &SequenceHeader,
    syntax: &FrameSyntax,
    vectors: &[MbVectors],
    recon: &mut Frame,
    (deblocked, measure): (bool, Option<DeblockMeasure<'_>>),
) -> Option<DeblockEffect> {
    let header = &syntax.header;
    let deblocker = (header.deblock && !deblocked).then(|| {
        debug_assert_eq!(vectors, frame_vectors(seq, syntax));
        let info = MbEdgeInfo::of_frame(syntax, vectors);
        FrameDeblocker::new(
            &info,
            (recon.width(), recon.height()),
            DeblockStrength::of(header),
        )
    });
    let luma = |y: &mut Plane| {
        let effect = match (&deblocker, measure) {
            (Some(d), Some(m)) => Some(measured_around(m, y, d)),
            (Some(d), None) => {
                d.filter(y, 0);
                None
            }
            (None, _) => None,
        };
        y.extend_border();
        effect
    };
    // The chroma planes together: the kernel filters an edge of both at
    // once.
    let chroma = |u: &mut Plane, v: &mut Plane| {
        if let Some(d) = &deblocker {
            d.filter_chroma(u, v);
        }
        u.extend_border();
        v.extend_border();
    };
    let [y, u, v] = recon.planes_mut();
    rayon::join(|| luma(y), || chroma(u, v)).0
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
    /// The filter's offsets, where it is.
    pub deblock_offsets: DeblockOffsets,
    /// Whether, where the filter's effect is measured, it is also tried
    /// at other offsets (where the offsets are chosen).
    pub try_deblock_offsets: bool,
    /// Whether the filter's effect is measured, where deblocked
    /// ([`super::deblock_choice`]).
    pub measure_deblock: bool,
    /// The weights `reference` was weighted with (already applied).
    pub weights: Weights,
    /// The luma interpolation filter of block frames.
    pub luma_filter: LumaFilter,
    /// Inter macroblocks may be split (block frames).
    pub partitions: bool,
    /// Sub-pel RD refinement of 16x16 inter vectors (block frames).
    pub subpel_rd: bool,
    /// Splits within a margin of the 16x16 estimate ([`super::EncoderConfig::split_margin`]).
    pub split_margin: bool,
    /// Splits searched within a margin ([`super::EncoderConfig::split_search_margin`]).
    pub split_search_margin: bool,
    /// Chroma in the 16x16 searches' sub-pel cost ([`super::EncoderConfig::chroma_me`]).
    pub chroma_me: bool,
    /// The decision's residual prices adapt through the frame
    /// ([`super::EncoderConfig::adaptive_pricing`]).
    pub adaptive_pricing: bool,
    /// x264's fast P-skip (see [`super::EncoderConfig::fast_pskip`]).
    pub fast_pskip: bool,
    /// Fast P-skip before the search too ([`super::EncoderConfig::early_pskip`]).
    pub early_pskip: bool,
    /// The contexts block frames are priced from (the stream's two frames
    /// back: see [`super::Encoder`]'s `pricing`).
    pub pricing: &'a EntropyState,
}

/// A P frame's mode decision: one analysis context over the frame, one
/// method per kind of candidate, macroblocks in raster order.
pub(super) struct InterFrameCoder<'a, 'r> {
    pub(super) seq: &'a SequenceHeader,
    pub(super) coder: &'a MbCoder,
    pub(super) src: &'a Frame,
    /// The frame's references, the previous reconstruction first (none
    /// between the rows of a frame decided row by row, whose first
    /// reference grows: [`InterFrameCoder::with_references`]).
    pub(super) references: Vec<&'r Frame>,
    pub(super) tool: MotionTool,
    pub(super) decision: ModeDecision,
    /// Motion analysis' vector per macroblock (zero for grid frames;
    /// empty when the decision searches, `lazy`).
    pub(super) searched: Vec<Mv>,
    /// The search the decision runs per macroblock that needs a vector.
    pub(super) lazy: Option<Box<LazySearch>>,
    /// Whether inter macroblocks may be split (block frames).
    pub(super) partitions: bool,
    /// Sub-pel RD refinement of 16x16 inter vectors (block frames).
    pub(super) subpel_rd: bool,
    /// Splits within a margin of the 16x16 estimate.
    pub(super) split_margin: bool,
    /// Splits searched within a margin of the 16x16 estimate.
    pub(super) split_search_margin: bool,
    /// Chroma in the 16x16 searches' sub-pel cost.
    pub(super) chroma_me: bool,
    /// The decision's residual prices adapt through the frame.
    pub(super) adaptive_pricing: bool,
    /// x264's fast P-skip (see [`super::EncoderConfig::fast_pskip`]).
    pub(super) fast_pskip: bool,
    /// Fast P-skip before the search too ([`super::EncoderConfig::early_pskip`]).
    pub(super) early_pskip: bool,
    /// The deblocking filter's effect measured ([`InterInputs::measure_deblock`]).
    pub(super) measure_deblock: bool,
    /// [`InterInputs::try_deblock_offsets`].
    pub(super) try_deblock_offsets: bool,
    /// A vector per 8x8 block, when motion analysis has one (flows).
    pub(super) blocks: Option<Vec<Mv>>,
    /// The reference's half-pel planes, for the partitions' search.
    pub(super) halfpel: Option<HalfPel>,
    /// The reference warped by the grid, for grid frames.
    pub(super) warped: Option<Frame>,
    /// Which vectors the frame codes.
    pub(super) syntax: VectorSyntax,
    /// The vectors OBMC predicts with: decided ones, searched ones for the
    /// macroblocks not decided yet.
    pub(super) context: Vec<MbVectors>,
    /// The decided vectors, for the vector prediction.
    pub(super) decided: Vec<MbVectors>,
    pub(super) sink: MbSink,
    /// OBMC's second pass prices residuals from the frame's start again.
    pub(super) residual_coder_at_start: Option<ResidualCoder>,
    /// The frame so far: its macroblocks and reconstruction.
    pub(super) frame: CodedFrame,
}

/// A P frame's motion as the coder takes it: block vectors (searched, or
/// to be searched in the decision), or a grid with the reference warped by
/// it and no block vectors.
fn motion_of(
    seq: &SequenceHeader,
    motion: FrameMotion,
    reference: &Frame,
) -> Result<(BlockMotion, Option<MotionGrid>, Option<Frame>), PictureError> {
    match motion {
        FrameMotion::Vectors(v) => Ok((v, None, None)),
        FrameMotion::Grid(g) => {
            let mut out = Frame::new(seq.coded_width(), seq.coded_height())?;
            warp_frame(reference, &g, &mut out);
            let none = BlockMotion {
                mb: vec![Mv::ZERO; seq.mb_cols() * seq.mb_rows()],
                blocks: None,
                halfpel: None,
                lazy: None,
            };
            Ok((none, Some(g), Some(out)))
        }
    }
}

/// The header of a P frame coded at `qp` from `inputs`.
fn inter_header(qp: u8, inputs: &InterInputs<'_>) -> FrameHeader {
    FrameHeader {
        frame_type: FrameType::Inter,
        qp,
        tool: inputs.tool,
        refs: inputs.references.len() as u8,
        deblock: inputs.deblock,
        deblock_offsets: if inputs.deblock {
            inputs.deblock_offsets
        } else {
            DeblockOffsets::ZERO
        },
        weights: inputs.weights,
        // Block frames choose; the others interpolate sharp.
        luma_filter: match inputs.tool {
            MotionTool::Block => inputs.luma_filter,
            _ => LumaFilter::Sharp,
        },
    }
}

impl<'a, 'r> InterFrameCoder<'a, 'r> {
    pub(super) fn new(
        seq: &'a SequenceHeader,
        coder: &'a MbCoder,
        src: &'a Frame,
        inputs: InterInputs<'r>,
        state: &EntropyState,
        recon: Frame,
    ) -> Result<InterFrameCoder<'a, 'r>, PictureError> {
        let n = seq.mb_cols() * seq.mb_rows();
        let header = inter_header(coder.qp, &inputs);
        let (
            BlockMotion {
                mb: searched,
                blocks,
                halfpel,
                lazy,
            },
            grid,
            warped,
        ) = motion_of(seq, inputs.motion, inputs.references[0])?;
        let obmc = inputs.tool == MotionTool::Obmc;
        // Block frames are decided on a wavefront with coders of their own
        // and written once decided ([`super::wavefront`]).
        let sink = if inputs.tool == MotionTool::Block {
            MbSink::Adapt(Box::new(inputs.pricing.coders(seq, FrameType::Inter)))
        } else if obmc {
            MbSink::Adapt(Box::new(state.coders(seq, FrameType::Inter)))
        } else {
            MbSink::Write(Box::new(FrameWriter::new(seq, &header, grid.as_ref(), state)))
        };
        Ok(InterFrameCoder {
            seq,
            coder,
            src,
            references: inputs.references,
            tool: inputs.tool,
            decision: inputs.decision,
            syntax: vector_syntax(&header),
            context: searched.iter().map(|&v| [Some(RefMv::previous(v)); 4]).collect(),
            searched,
            lazy,
            partitions: inputs.partitions && inputs.tool == MotionTool::Block,
            subpel_rd: inputs.subpel_rd,
            split_margin: inputs.split_margin,
            split_search_margin: inputs.split_search_margin,
            chroma_me: inputs.chroma_me,
            adaptive_pricing: inputs.adaptive_pricing,
            fast_pskip: inputs.fast_pskip,
            early_pskip: inputs.early_pskip,
            measure_deblock: inputs.measure_deblock,
            try_deblock_offsets: inputs.try_deblock_offsets,
            halfpel,
            blocks,
            warped,
            decided: Vec::with_capacity(n),
            residual_coder_at_start: obmc.then(|| sink.residual().clone()),
            sink,
            frame: CodedFrame::empty(
                FrameSyntax {
                    header,
                    grid,
                    mbs: Vec::with_capacity(n),
                },
                recon,
            ),
        })
    }

    /// This coder deciding from `references` instead (the same frames: a
    /// growing reference lent for a row, or none between rows).
    pub(super) fn with_references<'s>(self, references: Vec<&'s Frame>) -> InterFrameCoder<'a, 's> {
        InterFrameCoder {
            references,
            seq: self.seq,
            coder: self.coder,
            src: self.src,
            tool: self.tool,
            decision: self.decision,
            searched: self.searched,
            lazy: self.lazy,
            partitions: self.partitions,
            subpel_rd: self.subpel_rd,
            split_margin: self.split_margin,
            split_search_margin: self.split_search_margin,
            chroma_me: self.chroma_me,
            adaptive_pricing: self.adaptive_pricing,
            fast_pskip: self.fast_pskip,
            early_pskip: self.early_pskip,
            measure_deblock: self.measure_deblock,
            try_deblock_offsets: self.try_deblock_offsets,
            blocks: self.blocks,
            halfpel: self.halfpel,
            warped: self.warped,
            syntax: self.syntax,
            context: self.context,
            decided: self.decided,
            sink: self.sink,
            residual_coder_at_start: self.residual_coder_at_start,
            frame: self.frame,
        }
    }

    pub(super) fn inter_context(&self) -> InterContext<'_> {
        InterContext {
            references: &self.references,
            tool: self.tool,
            luma_filter: self.frame.syntax.header.luma_filter,
            vectors: &self.context,
            warped: self.warped.as_ref(),
            mb_cols: self.seq.mb_cols(),
        }
    }

    /// Bits of a mode as the mode coder of `env` prices it.
    pub(super) fn mode_bits(&self, env: &MbEnv<'_>, mb: &MbAnalysis, mode: &MbMode) -> f64 {
        self.mode_bits_at(env, (mb.mb_x, mb.mb_y), mode)
    }

    /// [`Self::mode_bits`] of the macroblock at `at`.
    pub(super) fn mode_bits_at(&self, env: &MbEnv<'_>, at: (usize, usize), mode: &MbMode) -> f64 {
        rdo::bits(rate::mode_cost(env.modes, at, true, self.syntax, mode))
    }

    /// Whether the filter's effect on this frame is measured: deblocked,
    /// and its deblocking chosen.
    fn deblock_measured(&self) -> Option<DeblockMeasure<'a>> {
        (self.measure_deblock && self.frame.syntax.header.deblock).then(|| DeblockMeasure {
            source: self.src.y(),
            try_strengths: self.try_deblock_offsets,
        })
    }

    /// How the frame's macroblocks are decided on a wavefront (block
    /// frames).
    fn wavefront(&self) -> WavefrontFrame<'_> {
        let header = &self.frame.syntax.header;
        WavefrontFrame {
            seq: self.seq,
            modes: self.sink.modes(),
            residual: self.sink.residual(),
            inter_frame: true,
            syntax: self.syntax,
            // HEVC's two: as good as raster order on the development set
            // (-0.1 %), the contexts being trained by the frames before.
            lead: 2,
            tracking: if self.adaptive_pricing {
                ResidualTracking::Adapt
            } else if self.coder.estimated_rates {
                ResidualTracking::Nothing
            } else {
                ResidualTracking::CodedBlocks
            },
            deblock: header
                .deblock
                .then_some((DeblockStrength::of(header), header.tool)),
            measure: self.deblock_measured(),
        }
    }

    /// Macroblock `index` decided from `env` into `mb` (its best choice),
    /// and its prediction's squared luma error.
    fn decide_mb(&self, env: &MbEnv<'_>, index: usize, mb: &mut MbAnalysis) -> wavefront::Decision {
        self.analyse_skip(index, env, mb);
        self.analyse_beyond_skip(mb, env);
        let prediction_sse = match mb.skip_pred() {
            Some(_) if visible_size(mb.mb_x, mb.mb_y, self.seq) == (16, 16) => mb.skip_luma_sse,
            _ => visible_luma_sse(&mb.source, &mb.best.pred, mb.mb_x, mb.mb_y, self.seq),
        };
        wavefront::Decision {
            prediction_sse,
            // (Predicted from the decided vectors only where the frame
            // codes vectors: [`Self::analyse_skip`].)
            mvp: self.syntax.any().then_some(mb.mvp),
            older_gain: mb.older_gain,
        }
    }

    /// The reconstruction, lent to a wavefront's worker (it comes back,
    /// complete or to be written): a macroblock-sized frame holds its
    /// place.
    fn lend_recon(&mut self) -> Result<Frame, PictureError> {
        let mb = crate::codec::consts::MB;
        Ok(std::mem::replace(&mut self.frame.recon, Frame::new(mb, mb)?))
    }

    /// Takes the decided macroblocks into the frame.
    fn take_decided(&mut self, decided: wavefront::DecidedFrame) {
        let sum;
        (sum, self.frame.recon) = wavefront::collect(decided, self.seq.mb_cols());
        self.frame.syntax.mbs = sum.mbs;
        self.frame.prediction_sse = sum.prediction_sse;
        self.frame.kinds = sum.kinds;
        self.frame.vectors = sum.vectors;
        self.frame.deblocked = sum.deblocked;
        self.frame.deblock_effect = sum.deblock_effect;
        self.frame.older_gain = (self.syntax.refs() > 1).then_some(sum.older_gain);
    }

    /// How many macroblock rows of the first reference, from its own on,
    /// a row's decisions read: the search's window
    /// ([`crate::me::FrameSearch::reach_below`]), the half-pel planes'
    /// filter below that, and a macroblock more for the steps of the
    /// partitions and sub-pel refinements around the searched vectors.
    /// Every row without a search.
    fn rows_reach(&self) -> usize {
        const HALFPEL_FILTER: usize = 4;
        let mb = crate::codec::consts::MB;
        match &self.lazy {
            Some(lazy) => (lazy.search.reach_below(mb) + HALFPEL_FILTER + mb).div_ceil(mb),
            None => self.seq.mb_rows(),
        }
    }

    /// Decides every macroblock on a wavefront (block frames) into the
    /// frame.
    fn decide_on_wavefront(&mut self) -> Result<(), PictureError> {
        let recon = self.lend_recon()?;
        let decided = self
            .wavefront()
            .decide(recon, &|env, index, mb| self.decide_mb(env, index, mb))?;
        self.take_decided(decided);
        Ok(())
    }

    /// The analysis environment of the next macroblock in raster order:
    /// the frame's own decisions, coders and reconstruction.
    fn raster_env<'e>(&'e self, satd8: &'e RefCell<SatdCache>) -> MbEnv<'e> {
        MbEnv {
            decided: &self.decided,
            modes: self.sink.modes(),
            residual: self.sink.residual(),
            recon: &self.frame.recon,
            satd8,
        }
    }

    /// Reconstructs and records the decided macroblock (its residual
    /// taken from the record).
    fn commit(&mut self, mb: &mut MbAnalysis) {
        let (mb_x, mb_y) = (mb.mb_x, mb.mb_y);
        let best = &mut mb.best;
        write_mb(best.reconstruction(), &mut self.frame.recon, mb_x, mb_y);
        self.frame.prediction_sse += visible_luma_sse(&mb.source, &best.pred, mb_x, mb_y, self.seq);
        let cols = self.seq.mb_cols();
        let v = mb_vectors(&best.kind, &self.decided, mb_x, mb_y, cols);
        self.frame.kinds[kind_index(&best.kind)] += 1;
        let coded = match best.residual.take() {
            Some(levels) => CodedMb::with_levels(best.kind, levels),
            None => CodedMb::without_residual(best.kind),
        };
        self.sink
            .push(&coded, (mb_x, mb_y, cols), &self.decided, self.syntax);
        self.decided.push(v);
        self.context[mb.index] = v;
        self.frame.syntax.mbs.push(coded);
    }

    /// The coded frame, written; `state` updated; `beside` run with its
    /// vectors and references as it is written.
    pub(super) fn finish(
        self,
        state: &mut EntropyState,
        beside: impl FnOnce(&[MbVectors], &[&Frame]) + Send,
    ) -> Result<CodedFrame, PictureError> {
        let references = &self.references;
        let beside = |vectors: &[MbVectors]| beside(vectors, references);
        let measure = self.deblock_measured();
        let mut frame = self.frame;
        if frame.vectors.is_empty() {
            // Decided in raster order: the frame's own record.
            frame.vectors = self.decided;
        }
        match self.sink {
            MbSink::Write(writer) => {
                (frame.bytes, frame.bits) = writer.finish(state);
                let effect = finish_recon(
                    self.seq,
                    &frame.syntax,
                    &frame.vectors,
                    &mut frame.recon,
                    (frame.deblocked, measure),
                );
                frame.deblock_effect = frame.deblock_effect.or(effect);
                beside(&frame.vectors);
            }
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
                frame.write_and_finish(self.seq, state, measure, beside);
            }
        }
        Ok(frame)
    }
}

/// A P frame predicted as `inputs` say, reconstructed into `recon` (coded
/// size, contents all overwritten) and written, `state` updated; `beside`
/// runs with the frame's decided vectors and its references while the
/// frame is written.
pub(crate) fn code_inter(
    seq: &SequenceHeader,
    coder: &MbCoder,
    src: &Frame,
    inputs: InterInputs<'_>,
    (state, recon): (&mut EntropyState, Frame),
    beside: impl FnOnce(&[MbVectors], &[&Frame]) + Send,
) -> Result<CodedFrame, PictureError> {
    let mut frame_coder = InterFrameCoder::new(seq, coder, src, inputs, state, recon)?;
    if frame_coder.tool == MotionTool::Block {
        frame_coder.decide_on_wavefront()?;
    } else {
        // OBMC prices with its neighbours' searched vectors until they are
        // decided, and grid frames are cheap to decide: raster order.
        let satd8 = RefCell::default();
        let mut mb = MbAnalysis::empty();
        for index in 0..seq.mb_cols() * seq.mb_rows() {
            let env = frame_coder.raster_env(&satd8);
            frame_coder.analyse_skip(index, &env, &mut mb);
            frame_coder.analyse_beyond_skip(&mut mb, &env);
            frame_coder.commit(&mut mb);
        }
    }
    frame_coder.finish(state, beside)
}

/// Where a block P frame decided row by row ([`decide_inter_rows`]) takes
/// its references from and publishes its own rows: the previous
/// reconstruction's published rows, the reference it grows into, the
/// older references; where its final rows go.
pub(crate) struct RowReferences<'f> {
    pub from: &'f FrameProgress,
    pub growing: &'f mut GrowingReference,
    pub older: &'f [&'f Frame],
    pub publish: &'f FrameProgress,
}

/// A frame thread's weights before the reference's rows they are measured
/// on are in: the frame's rows are decided as if it weighed nothing (and
/// not published) until they are, then the weights are measured. None,
/// the rows stand; any, they are decided again, weighted
/// ([`RowsDecided::Weigh`]). The same stream as waiting for the rows
/// first, without the wait (most frames weigh nothing).
pub(crate) struct UnmeasuredWeights<'f> {
    /// The reference's macroblock rows the weights are measured on.
    pub rows: usize,
    /// The weights measured on the reference (its rows to `rows` in).
    pub measure: &'f dyn Fn(&Frame) -> Weights,
}

/// What [`decide_inter_rows`] ends with.
pub(crate) enum RowsDecided<'a> {
    /// The frame decided, to be written once its references are lent
    /// again ([`InterFrameCoder::with_references`]).
    Decided(Box<InterFrameCoder<'a, 'static>>),
    /// The weights measured once their rows came in, which the rows
    /// decided before did not weigh by: to decide again with them, into
    /// the reconstruction's buffer given back.
    Weigh(Weights, Frame),
}

/// The decisions of [`code_inter`] for a block P frame whose search the
/// decision runs ([`super::motion::MotionAnalyser::analyse_growing`]),
/// decided a row at a time on this thread, as a frame thread decides it:
/// before each row, the first reference is brought in as far as the row's
/// searches reach (waiting for the rows to be published;
/// `inputs.references` is replaced), and after it the rows final are
/// published. The same decisions as on a wavefront from the whole
/// reference; the frame is written by [`InterFrameCoder::finish`] (once
/// the frame before is: its contexts go on into this one's).
pub(crate) fn decide_inter_rows<'a>(
    (seq, coder, src): (&'a SequenceHeader, &'a MbCoder, &'a Frame),
    inputs: InterInputs<'_>,
    refs: RowReferences<'_>,
    mut unmeasured: Option<UnmeasuredWeights<'_>>,
    recon: Frame,
) -> Result<RowsDecided<'a>, PictureError> {
    let RowReferences {
        from,
        growing,
        older,
        publish,
    } = refs;
    let first = InterInputs {
        references: std::iter::once(growing.frame())
            .chain(older.iter().copied())
            .collect(),
        ..inputs
    };
    // Block frames are priced from `inputs.pricing`, not the state.
    let unused = EntropyState::new();
    let mut frame_coder =
        InterFrameCoder::new(seq, coder, src, first, &unused, recon)?.with_references(Vec::new());
    let reach = frame_coder.rows_reach();
    let recon = frame_coder.lend_recon()?;
    let mut rows = frame_coder.wavefront().row_by_row(recon);
    let mut prior_rows = 0;
    for r in 0..seq.mb_rows() {
        // Never fewer rows than before (the weights may have taken more).
        let mut upto = (r + reach).min(seq.mb_rows()).max(prior_rows);
        if let Some(weights) = &unmeasured {
            // Measured once their rows are in (waiting for them only where
            // this row needs them too).
            if upto >= weights.rows || from.rows() >= weights.rows {
                upto = upto.max(weights.rows);
            }
        }
        let mut lazy = frame_coder.lazy.as_deref_mut();
        // Only the copies hold the frame before's lock.
        from.with_rows(upto, |f, prior| {
            growing.copy_in(f, upto);
            if let (Some(lazy), Some(prior)) = (lazy.as_deref_mut(), prior) {
                lazy.bring_in_prior(prior, prior_rows..upto);
            }
        });
        prior_rows = upto;
        if let Some(weights) = unmeasured.take_if(|w| upto >= w.rows) {
            let measured = (weights.measure)(growing.plain());
            if measured.any() {
                return Ok(RowsDecided::Weigh(measured, rows.into_recon()));
            }
            publish.publish(rows.recon(), rows.vectors(), rows.final_rows());
        }
        growing.settle(lazy.and_then(|l| l.search.planes_mut()), upto);
        let row_coder = frame_coder.with_references(
            std::iter::once(growing.frame())
                .chain(older.iter().copied())
                .collect(),
        );
        row_coder
            .wavefront()
            .decide_row(&mut rows, &|env, index, mb| row_coder.decide_mb(env, index, mb));
        frame_coder = row_coder.with_references(Vec::new());
        if unmeasured.is_none() {
            publish.publish(rows.recon(), rows.vectors(), rows.final_rows());
        }
    }
    debug_assert!(unmeasured.is_none(), "the weights' rows are among the frame's");
    frame_coder.take_decided(rows.finish());
    Ok(RowsDecided::Decided(Box::new(
        frame_coder.with_references(Vec::new()),
    )))
}

/// The luma prediction of an intra macroblock's blocks in the modes
/// decided, each block predicted from the reconstruction of those before
/// it (and the 8x8 blocks' levels, found on the way); nothing for whole
/// 16x16 intra, which the caller predicts.
fn intra_as_decided(
    search: &IntraBlockSearch<'_>,
    s: &MbSource,
    luma: &LumaIntra,
) -> (MbSamples, Option<Box<[crate::codec::transform8x8::Block8; 4]>>) {
    let mut pred = MbSamples::default();
    let mut luma8 = None;
    match luma {
        LumaIntra::Whole(_) => {}
        LumaIntra::Blocks(modes) => {
            if let Some(b) = search.run(s, Some(modes), f64::INFINITY) {
                pred.luma = b.pred;
            }
        }
        LumaIntra::Blocks8(modes) => {
            if let Some(b) = search.run8(s, Some(modes), f64::INFINITY) {
                (pred.luma, luma8) = (b.pred, b.levels);
            }
        }
    }
    (pred, luma8)
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
        luma_filter: frame.syntax.header.luma_filter,
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
        let (pred, luma8) = match mb.kind {
            MbKind::Intra { luma, chroma } => {
                let (mut pred, luma8) = intra_as_decided(&search, &s, &luma);
                if let LumaIntra::Whole(luma) = luma {
                    pred = predict_intra(&recon, mb_x, mb_y, luma, chroma);
                }
                for p in 0..2 {
                    predict_intra_plane(&recon, p + 1, mb_x, mb_y, chroma, &mut pred.chroma[p]);
                }
                (pred, luma8)
            }
            _ => {
                let vectors = vectors[i].map(Option::unwrap_or_default);
                (predict_inter_blocks(&ctx, mb_x, mb_y, &vectors), None)
            }
        };
        frame.prediction_sse += visible_luma_sse(&s, &pred, mb_x, mb_y, seq);
        if mb.kind == MbKind::Skip {
            write_mb(&pred, &mut recon, mb_x, mb_y);
        } else {
            let coded = match mb.kind.residual_syntax() {
                ResidualSyntax::Intra => coder.code(&s, &pred, true, &residual_coder, mb_x, mb_y),
                ResidualSyntax::Intra16x16 => coder.code_intra16x16(&s, &pred, &residual_coder, (mb_x, mb_y)),
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
