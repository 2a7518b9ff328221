//! A frame's macroblocks decided on a wavefront (x264's and HEVC's
//! wavefront order): rows on several threads at once, each row two
//! macroblocks behind the one above, so that every macroblock finds its
//! left, top-left, top and top-right neighbours decided. The frame is then
//! written in raster order by one range coder.
//!
//! Each worker holds a copy of what a macroblock's analysis reads (the
//! decided vectors, the coders that price it, the reconstruction) and
//! brings in each neighbour of the row above as it is published. The
//! pricing coders of a row start from the contexts the row above had
//! reached after its second macroblock (HEVC's wavefront rule), not from
//! where the previous row ended: every decision then depends only on
//! what came before it on the wavefront, so the stream is the same for
//! any number of threads.

use std::cell::RefCell;
use std::sync::{Mutex, OnceLock};

use super::analyse::{MbAnalysis, MbEnv};
use super::deblock_choice::{filter_row_trying, DeblockEffect, DeblockMeasure, DeblockMeter, StrengthTrial};
use super::macroblock::prefetch_ahead;
use super::partition::SatdCache;
use super::refs_choice::OlderGain;
use super::slice::kind_index;
use crate::codec::deblock::{DeblockStrength, FrameDeblocker, MbEdgeInfo};
use crate::codec::entropy::Context;
use crate::codec::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::codec::mv::Mv;
use crate::codec::partition::{MbVectors, RefMv};
use crate::codec::recon::{write_mb, MbSamples};
use crate::codec::residual::ResidualCoder;
use crate::codec::syntax::{mb_mode, mb_vectors, CodedMb, MbKind, MotionTool, SequenceHeader};
use crate::codec::{Frame, PictureError};
use crate::me::pipeline::wavefront;

/// A decided macroblock, as the rows below and the frame read it.
pub(super) struct Decided {
    pub(super) coded: CodedMb,
    mode: MbMode,
    vectors: MbVectors,
    /// Its reconstruction, for the other workers' rows (none with one
    /// worker, whose own reconstruction holds every macroblock: the copy
    /// of each was a few per cent of ultrafast's time on 720p).
    samples: Option<Box<MbSamples>>,
    /// The prediction's squared luma error (visible part).
    prediction_sse: u64,
    /// What its older references saved ([`super::refs_choice`]).
    older_gain: OlderGain,
}

/// What a frame's decisions keep of each decided macroblock in their
/// residual coder, for the pricing of the macroblocks after it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ResidualTracking {
    /// Its bins adapt the contexts, and its coded blocks are recorded (the
    /// neighbours' flags choose contexts).
    Adapt,
    /// Its coded blocks alone: the contexts stay the frame's first.
    CodedBlocks,
    /// Nothing, where nothing reads it: residual bits estimated from the
    /// levels alone ([`super::macroblock::MbCoder::estimated_rates`]),
    /// whose decisions price no bin of any residual. The same streams;
    /// ultrafast 0.957x, 0.994x and 0.986x the wall time in three runs of
    /// `benches/pair.py` (the 28 sequences' first 60 frames) against
    /// recording the coded blocks.
    Nothing,
}

/// What one macroblock's decision returns beside its best choice (which
/// it leaves in the worker's [`MbAnalysis`]).
pub(super) struct Decision {
    /// Its prediction's squared luma error (visible part).
    pub(super) prediction_sse: u64,
    /// The macroblock's predicted vector, where the analysis found it from
    /// the decided vectors as [`mb_vectors`] does: a skip's own vector, not
    /// predicted again.
    pub(super) mvp: Option<Mv>,
    /// What its older references saved ([`super::refs_choice`]).
    pub(super) older_gain: OlderGain,
}

/// What the frame is decided with: its size and syntax, and the coders it
/// starts with.
pub(super) struct WavefrontFrame<'a> {
    pub(super) seq: &'a SequenceHeader,
    pub(super) modes: &'a ModeCoder,
    pub(super) residual: &'a ResidualCoder,
    pub(super) inter_frame: bool,
    pub(super) syntax: VectorSyntax,
    /// How many macroblocks of the row above a row's pricing contexts have
    /// seen (at least 2).
    pub(super) lead: usize,
    /// What the decision's residual coder keeps of each decided
    /// macroblock.
    pub(super) tracking: ResidualTracking,
    /// The deblocking of the frame (its QP and motion tool), if any: one
    /// worker deblocks each row as soon as the row below is decided,
    /// while the rows are in its caches (several workers leave it to the
    /// frame's end, [`DecidedFrame::deblocked`]).
    pub(super) deblock: Option<(DeblockStrength, MotionTool)>,
    /// The source (luma) the filter's effect is measured against, where
    /// the frame's deblocking is chosen ([`super::deblock_choice`]).
    pub(super) measure: Option<DeblockMeasure<'a>>,
}

/// The pricing contexts a row starts from.
struct RowStart {
    modes: Vec<Context>,
    residual: Vec<Context>,
}

/// What the workers share of a frame being decided: the decided
/// macroblocks and each row's starting contexts.
struct FrameRows<'f> {
    decided: &'f [OnceLock<Decided>],
    starts: &'f [OnceLock<RowStart>],
    /// The first row's.
    first: &'f RowStart,
}

/// One worker's copy of the frame's state, current where its rows read it.
struct Worker {
    decided: Vec<MbVectors>,
    modes: ModeCoder,
    residual: ResidualCoder,
    recon: Frame,
    satd8: RefCell<SatdCache>,
    /// The record each macroblock's analysis is made in (one a worker).
    analysis: Box<MbAnalysis>,
    /// The row the worker decided last: when that is the row above, its
    /// state already holds the neighbours there (one worker: every row).
    last_row: Option<usize>,
    /// The rows its reconstruction holds whole: those it decided, and
    /// those above them (brought in macroblock by macroblock).
    held: Vec<bool>,
    /// Its reconstruction's deblocking row by row (one worker only).
    deblocking: Option<RowDeblocking>,
}

/// One worker's deblocking of its reconstruction as rows are decided.
struct RowDeblocking {
    deblocker: FrameDeblocker,
    tool: MotionTool,
    /// The records of the row decided last, and the buffer of the next.
    above: Vec<MbEdgeInfo>,
    row: Vec<MbEdgeInfo>,
    /// The filter's effect so far, where measured, and the strengths
    /// tried beside the frame's.
    meter: Option<(DeblockMeter, Option<StrengthTrial>)>,
}

impl RowDeblocking {
    fn effect(&self) -> Option<DeblockEffect> {
        self.meter.as_ref().map(|(meter, trial)| DeblockEffect {
            tried: trial.as_ref().map_or([0; 3], StrengthTrial::tried),
            ..meter.effect()
        })
    }
}

impl Worker {
    /// Row `r` decided to its end: the row above was brought in whole by
    /// then (or was the worker's own).
    fn finish_row(&mut self, r: usize) {
        self.last_row = Some(r);
        self.held[r] = true;
        if r > 0 {
            self.held[r - 1] = true;
        }
    }
}

/// The worker whose reconstruction holds the most rows whole.
fn fullest(mut workers: Vec<Worker>) -> Option<Worker> {
    let rows_held = |w: &Worker| w.held.iter().filter(|&&h| h).count();
    let best = (0..workers.len()).max_by_key(|&i| rows_held(&workers[i]))?;
    Some(workers.swap_remove(best))
}

/// A frame's decided macroblocks (raster order), and the reconstruction
/// of the worker that holds the most rows whole (one worker holds them
/// all; two taking turns, every row but maybe the last).
pub(super) struct DecidedFrame {
    mbs: Vec<OnceLock<Decided>>,
    recon: Frame,
    /// The rows `recon` holds whole: the others are written from `mbs`.
    held: Vec<bool>,
    /// Whether `recon` is deblocked already (one worker did every row).
    pub(super) deblocked: bool,
    /// What the filter did, where deblocked already and measured.
    pub(super) deblock_effect: Option<DeblockEffect>,
}

impl WavefrontFrame<'_> {
    /// Every macroblock decided by `decide(env, index)` on the current
    /// rayon pool's threads; `recon` (coded size, any content) is one
    /// worker's reconstruction, so that one worker allocates none.
    pub(super) fn decide(
        &self,
        recon: Frame,
        decide: &(dyn Fn(&MbEnv<'_>, usize, &mut MbAnalysis) -> Decision + Sync),
    ) -> Result<DecidedFrame, PictureError> {
        let (cols, rows) = (self.seq.mb_cols(), self.seq.mb_rows());
        let decided: Vec<OnceLock<Decided>> = (0..cols * rows).map(|_| OnceLock::new()).collect();
        let starts: Vec<OnceLock<RowStart>> = (0..rows).map(|_| OnceLock::new()).collect();
        let first = RowStart {
            modes: self.modes.contexts().to_vec(),
            residual: self.residual.contexts().to_vec(),
        };
        // The workers' reconstructions, made before the rows start (an
        // allocation that fails is an error, not a panic on a worker). A
        // macroblock's analysis reads only what its worker wrote before
        // it, so `recon`'s old content is never seen.
        let recons = (1..rayon::current_num_threads().min(rows).max(1))
            .map(|_| Frame::new(self.seq.coded_width(), self.seq.coded_height()))
            .chain([Ok(recon)])
            .collect::<Result<Vec<_>, _>>()?;
        let shared = recons.len() > 1;
        let recons = Mutex::new(recons);
        let new_worker = || self.new_worker(&recons, shared);
        let rows_of = FrameRows {
            decided: &decided,
            starts: &starts,
            first: &first,
        };
        let workers = wavefront(cols, rows, self.lead(), &new_worker, &|w: &mut Worker, c, r| {
            self.step(w, &rows_of, decide, (c, r), shared);
        });
        let (recon, held, deblocked, deblock_effect) = match fullest(workers) {
            Some(w) => {
                let effect = w.deblocking.as_ref().and_then(RowDeblocking::effect);
                (w.recon, w.held, w.deblocking.is_some(), effect)
            }
            // No worker took a row (a frame has one at least).
            None => (
                recons
                    .into_inner()
                    .ok()
                    .and_then(|mut r| r.pop())
                    .expect("the reconstruction given"),
                vec![false; rows],
                false,
                None,
            ),
        };
        Ok(DecidedFrame {
            mbs: decided,
            recon,
            held,
            deblocked,
            deblock_effect,
        })
    }

    /// How many macroblocks of the row above a row waits for.
    fn lead(&self) -> usize {
        let cols = self.seq.mb_cols();
        self.lead.clamp(2.min(cols), cols)
    }

    /// Macroblock (c, r) on worker `w`: its row's pricing contexts set at
    /// the row's start, the neighbours above brought in, decided and
    /// published; the row deblocked behind it at its end (one worker).
    fn step(
        &self,
        w: &mut Worker,
        frame: &FrameRows<'_>,
        decide: &(dyn Fn(&MbEnv<'_>, usize, &mut MbAnalysis) -> Decision + Sync),
        (c, r): (usize, usize),
        shared: bool,
    ) {
        let cols = self.seq.mb_cols();
        if c == 0 {
            let start = if r == 0 {
                frame.first
            } else {
                frame.starts[r - 1].get().expect("row above started")
            };
            w.modes.set_contexts(&start.modes);
            w.residual.set_contexts(&start.residual);
        }
        let above_is_own = r > 0 && w.last_row == Some(r - 1);
        if c + 1 == cols {
            w.finish_row(r);
        }
        if r > 0 && !above_is_own {
            self.bring_in_above(w, frame.decided, (c, r));
        }
        // The record this macroblock's decision is stored in two on is in
        // no cache (one a macroblock, a frame's worth apart): storing it
        // stalled on its first line.
        if let Some(ahead) = frame.decided.get(r * cols + c + 2) {
            crate::codec::cpu::prefetch(ahead);
        }
        // And the reconstruction's rows the next macroblocks are written
        // into (a frame's worth of stores a frame).
        prefetch_ahead(&w.recon, c, r);
        // Decided into its place (moved there from a local, the record was
        // copied twice a macroblock).
        frame.decided[r * cols + c].get_or_init(|| self.commit(w, decide, (c, r), shared));
        if c + 1 == self.lead() {
            let start = RowStart {
                modes: w.modes.contexts().to_vec(),
                residual: w.residual.contexts().to_vec(),
            };
            let _ = frame.starts[r].set(start);
        }
        if c + 1 == cols {
            self.deblock_behind(w, &frame.decided[r * cols..(r + 1) * cols], r);
        }
    }

    /// A worker's state: the frame's first coders, one of `recons`, and
    /// the deblocking of its rows where it is the only worker.
    fn new_worker(&self, recons: &Mutex<Vec<Frame>>, shared: bool) -> Worker {
        let (cols, rows) = (self.seq.mb_cols(), self.seq.mb_rows());
        Worker {
            decided: vec![[None; 4]; cols * rows],
            modes: self.modes.clone(),
            residual: self.residual.clone(),
            recon: recons
                .lock()
                .ok()
                .and_then(|mut r| r.pop())
                .expect("a reconstruction per worker"),
            satd8: RefCell::default(),
            analysis: Box::new(MbAnalysis::empty()),
            last_row: None,
            held: vec![false; rows],
            deblocking: self.deblock.filter(|_| !shared).map(|(strength, tool)| {
                let size = (self.seq.coded_width(), self.seq.coded_height());
                RowDeblocking {
                    deblocker: FrameDeblocker::progressive(size, strength),
                    tool,
                    above: Vec::with_capacity(cols),
                    row: Vec::with_capacity(cols),
                    meter: self.measure.map(|m| {
                        let trial = m.try_strengths.then(|| StrengthTrial::like(m.source));
                        (DeblockMeter::default(), trial)
                    }),
                }
            }),
        }
    }

    /// Macroblock (c, r) decided from the worker's state, and committed to
    /// it; its reconstruction kept when other workers will read it
    /// (`shared`).
    fn commit(
        &self,
        w: &mut Worker,
        decide: &(dyn Fn(&MbEnv<'_>, usize, &mut MbAnalysis) -> Decision + Sync),
        (c, r): (usize, usize),
        shared: bool,
    ) -> Decided {
        let cols = self.seq.mb_cols();
        let index = r * cols + c;
        let env = MbEnv {
            decided: &w.decided[..index],
            modes: &w.modes,
            residual: &w.residual,
            recon: &w.recon,
            satd8: &w.satd8,
        };
        // The analysis record is the worker's, kept from macroblock to
        // macroblock: the decision is read where it was made (returned,
        // the 850-byte choice was copied a macroblock; the record below is
        // built where it is returned).
        let decision = decide(&env, index, &mut w.analysis);
        let best = &mut w.analysis.best;
        let done = &w.decided[..index];
        let vectors = match (&best.kind, decision.mvp) {
            (MbKind::Skip, Some(mvp)) => [Some(RefMv::previous(mvp)); 4],
            (kind, _) => mb_vectors(kind, done, c, r, cols),
        };
        let mode = mb_mode(&best.kind, done, (c, r, cols), self.syntax);
        write_mb(best.reconstruction(), &mut w.recon, c, r);
        w.decided[index] = vectors;
        w.modes.commit(c, r, self.inter_frame, self.syntax, &mode);
        let coded = match best.residual.take() {
            Some(levels) if !levels.is_empty() => CodedMb::with_levels(best.kind, levels),
            levels => {
                // A record with no level stays the worker's, for the next
                // trial to code into (a new one is a zeroed allocation).
                let trial = &mut w.analysis.trial.residual;
                if trial.is_none() {
                    *trial = levels;
                }
                CodedMb::without_residual(best.kind)
            }
        };
        if coded.kind != MbKind::Skip {
            let syntax = coded.kind.residual_syntax();
            match self.tracking {
                ResidualTracking::Adapt => w.residual.commit(c, r, syntax, coded.residual()),
                ResidualTracking::CodedBlocks => w.residual.record(c, r, syntax, coded.residual()),
                ResidualTracking::Nothing => {}
            }
        }
        Decided {
            prediction_sse: decision.prediction_sse,
            older_gain: decision.older_gain,
            // (Not `shared.then(..)`: its closure took the samples, a copy
            // a macroblock with one worker too.)
            samples: if shared {
                Some(Box::new(best.reconstruction().clone()))
            } else {
                None
            },
            coded,
            mode,
            vectors,
        }
    }

    /// The neighbours in the row above that macroblock (c, r) reads and
    /// the worker has not brought in yet.
    fn bring_in_above(&self, w: &mut Worker, decided: &[OnceLock<Decided>], (c, r): (usize, usize)) {
        let cols = self.seq.mb_cols();
        for x in (if c == 0 { 0 } else { c + 1 })..(c + 2).min(cols) {
            let above = decided[(r - 1) * cols + x].get().expect("wavefront order");
            self.bring_in(w, above, x, r - 1);
        }
    }

    /// Row `r` decided (its macroblocks `row`): the row above deblocked
    /// (the rows below read nothing of it before the filter: intra reads
    /// only the row above), and the last row too at the frame's end. A
    /// row's filter reads and changes no row below it
    /// ([`FrameDeblocker::filter_rows`]).
    fn deblock_behind(&self, w: &mut Worker, row: &[OnceLock<Decided>], r: usize) {
        let Some(d) = &mut w.deblocking else {
            return;
        };
        d.row.clear();
        d.row.extend(row.iter().map(|m| {
            let m = m.get().expect("the row decided");
            MbEdgeInfo::of_coded(&m.coded, d.tool, m.vectors)
        }));
        d.deblocker.set_row(r, &d.row, (r > 0).then_some(&d.above[..]));
        std::mem::swap(&mut d.above, &mut d.row);
        let last = r + 1 == self.seq.mb_rows();
        let rows = r.saturating_sub(1)..if last { r + 1 } else { r };
        let [y, u, v] = w.recon.planes_mut();
        // Final once filtered: the rows above the last filtered (whose
        // last three lines change with the row below), all at the end.
        let settled = if last {
            rows.end
        } else {
            rows.end.saturating_sub(1)
        };
        let meter = d.meter.as_mut().zip(self.measure);
        if let Some(((meter, trial), m)) = meter {
            meter.before(m.source, y, rows.clone());
            for k in rows.clone() {
                filter_row_trying(&d.deblocker, y, k, trial.as_mut().map(|t| (m.source, t)));
            }
            meter.after(m.source, y, settled);
        } else {
            d.deblocker.filter_rows(y, 0, rows.clone());
        }
        d.deblocker.filter_chroma_rows(u, v, rows);
    }

    /// Records macroblock (x, y), decided by another row, in the worker's
    /// state as a neighbour (a worker's coders adapt only to its own row).
    fn bring_in(&self, w: &mut Worker, d: &Decided, x: usize, y: usize) {
        w.decided[y * self.seq.mb_cols() + x] = d.vectors;
        let samples = d.samples.as_ref().expect("kept with several workers");
        write_mb(samples, &mut w.recon, x, y);
        w.modes.record(x, y, &d.mode);
        if d.coded.kind != MbKind::Skip && self.tracking != ResidualTracking::Nothing {
            w.residual
                .record(x, y, d.coded.kind.residual_syntax(), d.coded.residual());
        }
    }
}

/// A frame decided a row at a time by one worker on the calling thread, in
/// raster order: the same decisions as [`WavefrontFrame::decide`]'s on any
/// number of threads. Between rows the caller may change what the rows
/// after read (a frame thread brings in the reference's rows as the frame
/// before finishes them).
pub(super) struct RowByRow {
    decided: Vec<OnceLock<Decided>>,
    starts: Vec<OnceLock<RowStart>>,
    first: RowStart,
    worker: Worker,
    /// Rows decided.
    done: usize,
}

impl WavefrontFrame<'_> {
    /// The frame's rows, none decided yet, to be reconstructed into
    /// `recon` (coded size, any content).
    pub(super) fn row_by_row(&self, recon: Frame) -> RowByRow {
        let (cols, rows) = (self.seq.mb_cols(), self.seq.mb_rows());
        RowByRow {
            decided: (0..cols * rows).map(|_| OnceLock::new()).collect(),
            starts: (0..rows).map(|_| OnceLock::new()).collect(),
            first: RowStart {
                modes: self.modes.contexts().to_vec(),
                residual: self.residual.contexts().to_vec(),
            },
            worker: self.new_worker(&Mutex::new(vec![recon]), false),
            done: 0,
        }
    }

    /// Decides the next row of `rows` by `decide(env, index)`.
    pub(super) fn decide_row(
        &self,
        rows: &mut RowByRow,
        decide: &(dyn Fn(&MbEnv<'_>, usize, &mut MbAnalysis) -> Decision + Sync),
    ) {
        let r = rows.done;
        assert!(r < self.seq.mb_rows(), "a row beyond the frame");
        let frame = FrameRows {
            decided: &rows.decided,
            starts: &rows.starts,
            first: &rows.first,
        };
        for c in 0..self.seq.mb_cols() {
            self.step(&mut rows.worker, &frame, decide, (c, r), false);
        }
        rows.done += 1;
    }
}

impl RowByRow {
    /// How many macroblock rows of the reconstruction are final: written
    /// and, where the frame is deblocked, filtered (a row's filter changes
    /// the three lines above it, so a row is final once the row below it
    /// is filtered: two rows behind the decisions, all at the end).
    pub(super) fn final_rows(&self) -> usize {
        let rows = self.worker.held.len();
        if self.worker.deblocking.is_none() || self.done == rows {
            self.done
        } else {
            self.done.saturating_sub(2)
        }
    }

    /// The reconstruction so far: final to [`RowByRow::final_rows`],
    /// borders not extended.
    pub(super) fn recon(&self) -> &Frame {
        &self.worker.recon
    }

    /// The decided macroblocks' vectors (raster order; the rows not
    /// decided yet hold none).
    pub(super) fn vectors(&self) -> &[MbVectors] {
        &self.worker.decided
    }

    /// The reconstruction's buffer back, its rows given up (a frame
    /// decided again from its first row).
    pub(super) fn into_recon(self) -> Frame {
        self.worker.recon
    }

    /// The decided frame; panics unless every row is decided.
    pub(super) fn finish(self) -> DecidedFrame {
        assert_eq!(self.done, self.worker.held.len(), "every row decided");
        DecidedFrame {
            mbs: self.decided,
            deblocked: self.worker.deblocking.is_some(),
            deblock_effect: self.worker.deblocking.as_ref().and_then(RowDeblocking::effect),
            recon: self.worker.recon,
            held: self.worker.held,
        }
    }
}

/// What the decided macroblocks make of a frame: its reconstruction
/// (before deblocking) is written, its prediction error and kinds counted.
pub(super) struct FrameSummary {
    pub(super) mbs: Vec<CodedMb>,
    pub(super) prediction_sse: u64,
    pub(super) kinds: [usize; 3],
    pub(super) vectors: Vec<MbVectors>,
    /// Whether the reconstruction is deblocked already.
    pub(super) deblocked: bool,
    /// What the filter did, where deblocked already and measured.
    pub(super) deblock_effect: Option<DeblockEffect>,
    /// What the older references saved, summed.
    pub(super) older_gain: OlderGain,
}

/// The frame's reconstruction (every macroblock of `decided` written into
/// it), and the sums of its macroblocks.
pub(super) fn collect(decided: DecidedFrame, cols: usize) -> (FrameSummary, Frame) {
    let mut out = FrameSummary {
        mbs: Vec::with_capacity(decided.mbs.len()),
        prediction_sse: 0,
        kinds: [0; 3],
        vectors: Vec::with_capacity(decided.mbs.len()),
        deblocked: decided.deblocked,
        deblock_effect: decided.deblock_effect,
        older_gain: OlderGain::default(),
    };
    let mut recon = decided.recon;
    for (i, d) in decided.mbs.into_iter().enumerate() {
        let d = d.into_inner().expect("every macroblock decided");
        if !decided.held[i / cols] {
            let samples = d.samples.as_ref().expect("kept with several workers");
            write_mb(samples, &mut recon, i % cols, i / cols);
        }
        out.prediction_sse += d.prediction_sse;
        out.older_gain = out.older_gain.plus(d.older_gain);
        out.kinds[kind_index(&d.coded.kind)] += 1;
        out.vectors.push(d.vectors);
        out.mbs.push(d.coded);
    }
    (out, recon)
}
