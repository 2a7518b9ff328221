//! One frame: rate-distortion mode decision over the macroblocks, in
//! raster order, with reconstruction through the codec's functions.

use super::config::ModeDecision;
use super::macroblock::{MbCoder, MbSource};
use super::motion::FrameMotion;
use crate::codec::modes::{MbMode, ModeCoder};
use crate::codec::mv::mvd_bits;
use crate::codec::mv::Mv;
use crate::codec::recon::{predict_inter, predict_intra, write_mb, InterContext, MbSamples};
use crate::codec::residual::{MbResidual, ResidualCoder};
use crate::codec::syntax::{
    mb_mode, mb_vector, mv_prediction, write_frame, BitCounts, CodedMb, EntropyState, FrameHeader,
    FrameSyntax, FrameType, FrameWriter, MbKind, MotionTool, SequenceHeader,
};
use crate::codec::warp::warp_frame;
use crate::codec::{Frame, PictureError};
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
        MbKind::Inter { .. } => 1,
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

    /// Macroblock (mb_x, mb_y), decided (`mvp`: its predicted vector).
    fn push(&mut self, mb: &CodedMb, (mb_x, mb_y): (usize, usize), mvp: Mv, uses_mvs: bool) {
        match self {
            MbSink::Write(w) => w.push(mb),
            MbSink::Adapt(c) => {
                let (modes, residual_coder) = &mut **c;
                modes.commit(mb_x, mb_y, true, uses_mvs, &mb_mode(&mb.kind, mvp, uses_mvs));
                if mb.kind != MbKind::Skip {
                    let intra = matches!(mb.kind, MbKind::Intra { .. });
                    residual_coder.commit(mb_x, mb_y, intra, mb.residual());
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
    state: &mut EntropyState,
    mut recon: Frame,
) -> Result<CodedFrame, PictureError> {
    let cols = seq.mb_cols();
    let header = FrameHeader {
        frame_type: FrameType::Intra,
        qp: coder.qp,
        tool: MotionTool::Block,
    };
    let mut writer = FrameWriter::new(seq, &header, None, state);
    let mut mbs = Vec::with_capacity(cols * seq.mb_rows());
    let mut prediction_sse = 0;
    for i in 0..cols * seq.mb_rows() {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let s = MbSource::load(src, mb_x, mb_y);
        let mut pred = MbSamples::default();
        let (luma, _) = coder.best_intra_luma(&s, &recon, (mb_x, mb_y), &mut pred);
        let chroma = coder.best_intra_chroma(&s, &recon, (mb_x, mb_y), &mut pred);
        let coded = coder.code(&s, &pred, true, writer.residual(), mb_x, mb_y);
        write_mb(&coded.samples, &mut recon, mb_x, mb_y);
        prediction_sse += visible_luma_sse(&s, &pred, mb_x, mb_y, seq);
        let mb = CodedMb::with_levels(MbKind::Intra { luma, chroma }, coded.residual);
        writer.push(&mb);
        mbs.push(mb);
    }
    recon.extend_borders();
    let (bytes, bits) = writer.finish(state);
    Ok(CodedFrame {
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
    })
}

/// One way to code a macroblock, with its cost.
struct Choice {
    cost: f64,
    kind: MbKind,
    pred: MbSamples,
    residual: Option<Box<MbResidual>>,
    /// The reconstruction it gives.
    samples: MbSamples,
}

/// A P frame predicted from `reference` with `motion` and `tool`,
/// reconstructed into `recon` (coded size, contents all overwritten).
#[allow(clippy::too_many_arguments)]
pub(crate) fn code_inter(
    seq: &SequenceHeader,
    coder: &MbCoder,
    src: &Frame,
    reference: &Frame,
    motion: FrameMotion,
    tool: MotionTool,
    decision: ModeDecision,
    state: &mut EntropyState,
    mut recon: Frame,
) -> Result<CodedFrame, PictureError> {
    let (cols, n) = (seq.mb_cols(), seq.mb_cols() * seq.mb_rows());
    let (w, h) = (seq.coded_width(), seq.coded_height());
    let (searched, grid, warped) = match motion {
        FrameMotion::Vectors(v) => (v, None, None),
        FrameMotion::Grid(g) => {
            let mut out = Frame::new(w, h)?;
            warp_frame(reference, &g, &mut out);
            (vec![Mv::ZERO; n], Some(g), Some(out))
        }
    };
    let uses_mvs = grid.is_none();
    // OBMC predicts a block from its neighbours' vectors too: the ones not
    // decided yet are taken as searched.
    let mut context: Vec<Option<Mv>> = searched.iter().copied().map(Some).collect();
    let mut decided: Vec<Option<Mv>> = Vec::with_capacity(n);
    let mut mbs = Vec::with_capacity(n);
    let mut prediction_sse = 0;
    let mut kinds = [0; 3];
    let header = FrameHeader {
        frame_type: FrameType::Inter,
        qp: coder.qp,
        tool,
    };
    let mut sink = if tool == MotionTool::Obmc {
        MbSink::Adapt(Box::new(state.coders(seq, FrameType::Inter)))
    } else {
        MbSink::Write(Box::new(FrameWriter::new(seq, &header, grid.as_ref(), state)))
    };
    // OBMC's second pass prices residuals from the frame's start again.
    let residual_coder_at_start = (tool == MotionTool::Obmc).then(|| sink.residual().clone());
    // Bits of a mode as the frame's mode coder prices it now.
    let mode_bits = |modes: &ModeCoder, mb_x, mb_y, mode: &MbMode| {
        f64::from(modes.cost(mb_x, mb_y, true, uses_mvs, mode)) / 256.0
    };
    for i in 0..n {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let s = MbSource::load(src, mb_x, mb_y);
        let mvp = if uses_mvs {
            mv_prediction(&decided, mb_x, mb_y, cols)
        } else {
            Mv::ZERO
        };
        let ctx = InterContext {
            reference,
            tool,
            vectors: &context,
            warped: warped.as_ref(),
            mb_cols: cols,
        };
        let skip_pred = predict_inter(&ctx, mb_x, mb_y, mvp);
        let mut best = Choice {
            cost: coder.cost(
                s.ssd(&skip_pred),
                mode_bits(sink.modes(), mb_x, mb_y, &MbMode::Skip),
            ),
            kind: MbKind::Skip,
            pred: skip_pred.clone(),
            residual: None,
            samples: skip_pred.clone(),
        };
        // Every other choice spends at least the flag saying it is not
        // skipped: when skip costs no more, nothing can beat it.
        let not_skipped = f64::from(sink.modes().not_skipped_cost(mb_x, mb_y)) / 256.0;
        let exhaustive = best.cost > coder.cost(0, not_skipped);
        let searched_mv = (uses_mvs && searched[i] != mvp).then_some(searched[i]);
        let mut candidates = Vec::with_capacity(2);
        for mv in std::iter::once(mvp).chain(searched_mv).filter(|_| exhaustive) {
            let pred = if mv == mvp {
                skip_pred.clone()
            } else {
                predict_inter(&ctx, mb_x, mb_y, mv)
            };
            let satd = luma_satd(&s, &pred);
            candidates.push((mv, pred, satd));
        }
        let inter_satd = candidates.iter().map(|c| c.2).min().unwrap_or(u32::MAX);
        if decision == ModeDecision::Fast && candidates.len() == 2 {
            // The lower SATD + sqrt(lambda) * vector bits is coded alone.
            let sad_lambda = coder.lambda.sqrt();
            let estimate = |(mv, _, satd): &(Mv, MbSamples, u32)| {
                f64::from(*satd) + sad_lambda * f64::from(mvd_bits(*mv, mvp))
            };
            if estimate(&candidates[1]) < estimate(&candidates[0]) {
                candidates.swap(0, 1);
            }
            candidates.truncate(1);
        }
        for (mv, pred, _) in candidates {
            let coded = coder.code(&s, &pred, false, sink.residual(), mb_x, mb_y);
            let mode = MbMode::Inter { mvd: mv - mvp };
            let bits = mode_bits(sink.modes(), mb_x, mb_y, &mode) + coded.bits;
            let cost = coder.cost(coded.ssd, bits);
            if cost < best.cost {
                best = Choice {
                    cost,
                    kind: MbKind::Inter { mv },
                    pred,
                    residual: Some(coded.residual),
                    samples: coded.samples,
                };
            }
        }
        // Intra is coded only when its luma SATD is below inter's (as the
        // H.264 reference encoder's fast modes); its chroma mode is looked
        // for only then.
        let mut pred = MbSamples::default();
        let luma = exhaustive
            .then(|| coder.best_intra_luma(&s, &recon, (mb_x, mb_y), &mut pred))
            .filter(|&(_, satd)| satd < inter_satd);
        if let Some((luma, _)) = luma {
            let chroma = coder.best_intra_chroma(&s, &recon, (mb_x, mb_y), &mut pred);
            let coded = coder.code(&s, &pred, true, sink.residual(), mb_x, mb_y);
            let mode = MbMode::Intra { luma, chroma };
            let bits = mode_bits(sink.modes(), mb_x, mb_y, &mode) + coded.bits;
            let cost = coder.cost(coded.ssd, bits);
            if cost < best.cost {
                best = Choice {
                    cost,
                    kind: MbKind::Intra { luma, chroma },
                    pred,
                    residual: Some(coded.residual),
                    samples: coded.samples,
                };
            }
        }
        write_mb(&best.samples, &mut recon, mb_x, mb_y);
        prediction_sse += visible_luma_sse(&s, &best.pred, mb_x, mb_y, seq);
        let v = mb_vector(&best.kind, &decided, mb_x, mb_y, cols);
        decided.push(v);
        context[i] = v;
        kinds[kind_index(&best.kind)] += 1;
        let mb = match best.residual {
            Some(levels) => CodedMb::with_levels(best.kind, levels),
            None => CodedMb::without_residual(best.kind),
        };
        sink.push(&mb, (mb_x, mb_y), mvp, uses_mvs);
        mbs.push(mb);
    }
    let mut frame = CodedFrame {
        syntax: FrameSyntax { header, grid, mbs },
        bytes: Vec::new(),
        bits: BitCounts::default(),
        recon,
        prediction_sse,
        kinds,
    };
    match sink {
        MbSink::Write(writer) => (frame.bytes, frame.bits) = writer.finish(state),
        MbSink::Adapt(_) => {
            // Decisions saw neighbours' searched vectors; code the residuals
            // again against the final prediction, which uses the decided
            // ones, then write the frame.
            if let Some(residual_coder) = residual_coder_at_start {
                recode(seq, coder, src, reference, residual_coder, &mut frame)?;
            }
            (frame.bytes, frame.bits) = write_frame(seq, &frame.syntax, state);
        }
    }
    frame.recon.extend_borders();
    Ok(frame)
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
        reference,
        tool: frame.syntax.header.tool,
        vectors: &vectors,
        warped: None,
        mb_cols: cols,
    };
    for (i, mb) in frame.syntax.mbs.iter_mut().enumerate() {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let s = MbSource::load(src, mb_x, mb_y);
        let (pred, intra) = match mb.kind {
            MbKind::Intra { luma, chroma } => (predict_intra(&recon, mb_x, mb_y, luma, chroma), true),
            _ => (
                predict_inter(&ctx, mb_x, mb_y, vectors[i].unwrap_or_default()),
                false,
            ),
        };
        frame.prediction_sse += visible_luma_sse(&s, &pred, mb_x, mb_y, seq);
        if mb.kind == MbKind::Skip {
            write_mb(&pred, &mut recon, mb_x, mb_y);
        } else {
            let coded = coder.code(&s, &pred, intra, &residual_coder, mb_x, mb_y);
            write_mb(&coded.samples, &mut recon, mb_x, mb_y);
            residual_coder.commit(mb_x, mb_y, intra, &coded.residual);
            *mb = CodedMb::with_levels(mb.kind, coded.residual);
        }
    }
    frame.recon = recon;
    Ok(())
}
