//! A block P frame's work from its reference's first rows to its bytes,
//! which runs on a thread of its own while the frame before it finishes
//! (x264's frame threads), or inline on one thread: the same work, so the
//! same stream. It waits on the frame before for what it reads of it: the
//! reference's rows as they are published ([`FrameProgress`]) and, to
//! write, the stream's state once that frame is written.

use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;

use super::config::{EncoderConfig, FilterChoice};
use super::encoder::{report, FrameStart};
use super::filter::FilterChooser;
use super::macroblock::MbCoder;
use super::motion::FrameMotion;
use super::progress::FrameProgress;
use super::reference::GrowingReference;
use super::slice::{self, CodedFrame};
use super::{EncodeError, EncodedFrame};
use crate::codec::consts::MB;
use crate::codec::interp::LumaFilter;
use crate::codec::syntax::{EntropyState, MotionTool, SequenceHeader};
use crate::codec::Frame;

/// The stream's state after a frame is written, which the next frame's
/// writing goes on from: the entropy contexts and what the luma filter
/// chooser has learnt.
#[derive(Clone)]
pub(super) struct Written {
    pub entropy: EntropyState,
    pub filter: FilterChooser,
}

/// What stays the same from frame to frame.
#[derive(Clone, Copy)]
pub(super) struct Sequence {
    pub seq: SequenceHeader,
    pub config: EncoderConfig,
    pub coder: MbCoder,
}

/// Everything a block P frame decided row by row needs, owned.
pub(super) struct RowFrame {
    pub sequence: Sequence,
    pub frame: FrameStart,
    /// The picture where it is measured against and is not `src`, and
    /// the buffer its visible reconstruction goes into.
    pub source: Option<Frame>,
    pub output: Option<Frame>,
    /// The source (coded size).
    pub src: Frame,
    /// The buffer to reconstruct into and weigh the reference into (coded
    /// size, any content).
    pub recon: Frame,
    pub weighted: Option<Frame>,
    /// The frame before, as its rows come in (or finished).
    pub reference: GrowingReference,
    /// Motion analysis made ready ([`super::motion::MotionAnalyser::analyse_growing`])
    /// and the time it took, ms.
    pub motion: FrameMotion,
    pub me_ms: f64,
    /// The frame before's rows, and this one's, as they become final.
    pub from: Arc<FrameProgress>,
    pub publish: Arc<FrameProgress>,
    /// The older references (complete).
    pub older: Vec<Arc<Frame>>,
    /// The contexts two frames back, which the decisions are priced from.
    pub pricing: EntropyState,
    pub luma_filter: LumaFilter,
    /// The state after the frame before is written, and where this
    /// frame's goes.
    pub before: Receiver<Written>,
    pub after: Sender<Written>,
}

/// A [`RowFrame`] done: the frame as reported and as coded (its bytes
/// taken), and its buffers back.
pub(super) struct RowFrameDone {
    pub frame: FrameStart,
    pub encoded: EncodedFrame,
    pub coded: CodedFrame,
    pub src: Frame,
    pub plain: Option<Frame>,
    pub weighted: Option<Frame>,
    pub from: Arc<FrameProgress>,
    pub older: Vec<Arc<Frame>>,
    /// The stream's state before the frame was written and after.
    pub before: EntropyState,
    pub after: Written,
}

/// Marks a frame's rows published, whatever they hold, unless it is
/// disarmed: a frame that fails or panics keeps no one waiting.
struct AbandonUnlessDone<'p>(&'p FrameProgress, bool);

impl Drop for AbandonUnlessDone<'_> {
    fn drop(&mut self) {
        if !self.1 {
            self.0.abandon();
        }
    }
}

impl RowFrame {
    /// Decides the frame row by row (after its weights, measured on the
    /// reference's top half), then, once the frame before is written,
    /// writes it.
    pub(super) fn run(self) -> Result<RowFrameDone, EncodeError> {
        let publish = Arc::clone(&self.publish);
        let mut guard = AbandonUnlessDone(&publish, false);
        let done = self.decide_and_write();
        guard.1 = done.is_ok();
        done
    }

    fn decide_and_write(self) -> Result<RowFrameDone, EncodeError> {
        let RowFrame {
            sequence,
            frame,
            source,
            output,
            src,
            recon,
            weighted,
            reference,
            motion,
            me_ms,
            from,
            publish,
            older,
            pricing,
            luma_filter,
            before,
            after,
        } = self;
        let Sequence { seq, config, coder } = &sequence;
        let index = frame.index;
        let mut growing = reference;
        let top = super::encoder::weight_rows(seq) / MB;
        from.with_rows(top, |f, _| growing.copy_in(f, top));
        growing.settle(None);
        let weights = super::encoder::weights_of(config, seq, &src, growing.plain());
        let mut spare_weighted = weighted;
        if weights.any() {
            let buffer = match spare_weighted.take() {
                Some(f) => f,
                None => Frame::new(seq.coded_width(), seq.coded_height())?,
            };
            growing.weigh(weights, buffer);
        }
        let older_frames: Vec<&Frame> = older.iter().map(|f| &**f).collect();
        let inputs = super::encoder::inter_inputs(
            config,
            &pricing,
            motion,
            MotionTool::Block,
            (weights, luma_filter),
        );
        let refs = slice::RowReferences {
            from: &from,
            growing: &mut growing,
            older: &older_frames,
            publish: &publish,
        };
        let decided = slice::decide_inter_rows((seq, coder, &src), inputs, refs, recon)?;
        let mut written = before
            .recv()
            .map_err(|_| EncodeError::Config("the frame before this one failed".into()))?;
        let entropy_before = written.entropy.clone();
        let learn = config.luma_filter == FilterChoice::Auto;
        let mut coded = decided.finish(
            &mut written.entropy,
            super::encoder::learner(&mut written.filter, learn, &src, index),
        )?;
        // No one listens where the next frame is not a frame thread's.
        let _ = after.send(written.clone());
        drop(older_frames);
        let (plain, weighted) = growing.into_frames();
        // Measured here, off the thread that starts the frames.
        let measured = source.as_ref().unwrap_or(&src);
        let encoded = report((seq, config, output), &frame, measured, (&mut coded, me_ms))?;
        Ok(RowFrameDone {
            frame,
            encoded,
            coded,
            src,
            plain,
            weighted: weighted.or(spare_weighted),
            from,
            older,
            before: entropy_before,
            after: written,
        })
    }
}

/// The threads frames in flight run on: two pools of one thread each,
/// taken in turn. A frame's own parallel steps (rayon's joins in its
/// weights and writing) stay on its thread, so no frame ever waits for a
/// pool whose threads wait for frames (an encoder called from a pool's
/// thread waits there for its frames).
pub(super) struct FrameThreads {
    pools: [rayon::ThreadPool; 2],
}

/// A frame on its thread.
pub(super) struct InFlight(Receiver<std::thread::Result<Result<RowFrameDone, EncodeError>>>);

impl FrameThreads {
    pub(super) fn new() -> Result<FrameThreads, EncodeError> {
        let pool = |slot: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .thread_name(move |_| format!("mocomp frame thread {slot}"))
                .build()
                .map_err(|e| EncodeError::Config(format!("starting a frame thread: {e}")))
        };
        Ok(FrameThreads {
            pools: [pool(0)?, pool(1)?],
        })
    }

    /// Starts frame `index`'s `job` on its thread (the other frame in
    /// flight, `index - 1`, is on the other).
    pub(super) fn start(&self, index: usize, job: RowFrame) -> InFlight {
        let (done, outcome) = std::sync::mpsc::channel();
        self.pools[index % 2].spawn(move || {
            let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job.run()));
            // The encoder waits for it unless it was dropped.
            let _ = done.send(run);
        });
        InFlight(outcome)
    }
}

impl InFlight {
    /// Waits for the frame and drops its outcome, a panic too.
    pub(super) fn abandon(self) {
        let _ = self.0.recv();
    }

    /// The frame's outcome, once done (its panic goes on here).
    pub(super) fn wait(self) -> Result<RowFrameDone, EncodeError> {
        match self.0.recv() {
            Ok(Ok(done)) => done,
            Ok(Err(panic)) => std::panic::resume_unwind(panic),
            Err(_) => Err(EncodeError::Config("a frame thread stopped".into())),
        }
    }
}
