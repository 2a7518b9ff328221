//! A block P frame's work from its reference's first rows to its bytes,
//! which runs on a thread of its own while the frame before it finishes
//! (x264's frame threads), or inline on one thread: the same work, so the
//! same stream. It waits on the frame before for what it reads of it: the
//! reference's rows as they are published ([`FrameProgress`]) and, to
//! write, the stream's state once that frame is written.

use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;

use super::config::{EncoderConfig, FilterChoice};
use super::deblock_choice::DeblockChooser;
use super::encoder::{report, Chosen, FrameStart};
use super::filter::FilterChooser;
use super::macroblock::MbCoder;
use super::motion::{FrameMotion, MotionAnalyser};
use super::progress::FrameProgress;
use super::reference::GrowingReference;
use super::slice::{self, CodedFrame, InterFrameCoder, RowsDecided};
use super::{EncodeError, EncodedFrame};
use crate::codec::consts::MB;
use crate::codec::mv::Mv;
use crate::codec::syntax::{EntropyState, MotionTool, SequenceHeader};
use crate::codec::weight::Weights;
use crate::codec::Frame;

/// The stream's state after a frame is written, which the next frame's
/// writing goes on from: the entropy contexts and what the luma filter
/// and deblocking choosers have learnt.
#[derive(Clone)]
pub(super) struct Written {
    pub entropy: EntropyState,
    pub filter: FilterChooser,
    pub deblock: DeblockChooser,
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
    pub chosen: Chosen,
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
    /// Decides the frame row by row (its weights measured on the
    /// reference's top half: [`RowsJob::decide`]), then, once the frame
    /// before is written, writes it.
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
            chosen,
            before,
            after,
        } = self;
        let Sequence { seq, config, .. } = &sequence;
        let index = frame.index;
        let mut growing = reference;
        let mut spare_weighted = weighted;
        let older_frames: Vec<&Frame> = older.iter().map(|f| &**f).collect();
        let rows = RowsJob {
            sequence: &sequence,
            src: &src,
            camera: frame.camera,
            from: &from,
            older: &older_frames,
            publish: &publish,
            pricing: &pricing,
            chosen,
        };
        let decided = rows
            .decide(&mut growing, motion, recon, &mut spare_weighted)?
            .with_references(
                std::iter::once(growing.frame())
                    .chain(older_frames.iter().copied())
                    .collect(),
            );
        let mut written = before
            .recv()
            .map_err(|_| EncodeError::Config("the frame before this one failed".into()))?;
        let entropy_before = written.entropy.clone();
        let learn = config.luma_filter == FilterChoice::Auto;
        let mut coded = decided.finish(
            &mut written.entropy,
            super::encoder::learner(&mut written.filter, learn, &src, index),
        )?;
        written.deblock.learn(coded.deblock_effect);
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

/// What deciding a frame's rows reads, apart from its reference, its
/// search and the buffer it reconstructs into.
struct RowsJob<'j> {
    sequence: &'j Sequence,
    src: &'j Frame,
    camera: Mv,
    from: &'j FrameProgress,
    older: &'j [&'j Frame],
    publish: &'j FrameProgress,
    pricing: &'j EntropyState,
    chosen: Chosen,
}

impl<'j> RowsJob<'j> {
    /// The frame's rows decided, weighted as measured on the reference's
    /// top half: measured first where the frame before has those rows
    /// (one thread: always); else once they come in, the rows before them
    /// decided as if unweighted ([`slice::UnmeasuredWeights`]) and again,
    /// weighted, where the weights are not none. A weighted reference
    /// is weighed into `spare_weighted`'s buffer where it holds one.
    fn decide(
        &self,
        growing: &mut GrowingReference,
        motion: FrameMotion,
        recon: Frame,
        spare_weighted: &mut Option<Frame>,
    ) -> Result<InterFrameCoder<'j, 'static>, EncodeError> {
        let Sequence { seq, config, .. } = self.sequence;
        let top = super::encoder::weight_rows(seq) / MB;
        let measure = |plain: &Frame| super::encoder::weights_of(config, seq, self.src, plain);
        let mut weighted_buffer = || match spare_weighted.take() {
            Some(f) => Ok(f),
            None => Frame::new(seq.coded_width(), seq.coded_height()),
        };
        if self.from.rows() < top {
            let unmeasured = slice::UnmeasuredWeights {
                rows: top,
                measure: &measure,
            };
            let (weights, recon) =
                match self.decide_with(growing, motion, Weights::NONE, Some(unmeasured), recon)? {
                    RowsDecided::Decided(decided) => return Ok(*decided),
                    RowsDecided::Weigh(weights, recon) => (weights, recon),
                };
            // Decided again from the top, weighted: a new search (its
            // half-pel planes are the weighted luma's).
            let motion = MotionAnalyser::of_config(config)
                .analyse_growing(growing.plain(), self.older, self.camera, self.from.has_prior())
                .ok_or_else(|| EncodeError::Config("a frame's search changed kind".into()))?;
            growing.reweigh(weights, weighted_buffer()?);
            return self.decided(growing, motion, weights, recon);
        }
        self.from.with_rows(top, |f, _| growing.copy_in(f, top));
        growing.settle(None, top);
        let weights = measure(growing.plain());
        if weights.any() {
            growing.weigh(weights, weighted_buffer()?);
        }
        self.decided(growing, motion, weights, recon)
    }

    /// [`slice::decide_inter_rows`] of the frame weighted by `weights`,
    /// or, where `unmeasured`, as if unweighted until they are measured.
    fn decide_with(
        &self,
        growing: &mut GrowingReference,
        motion: FrameMotion,
        weights: Weights,
        unmeasured: Option<slice::UnmeasuredWeights<'_>>,
        recon: Frame,
    ) -> Result<RowsDecided<'j>, EncodeError> {
        let Sequence { seq, config, coder } = self.sequence;
        let inputs = super::encoder::inter_inputs(
            config,
            self.pricing,
            motion,
            MotionTool::Block,
            (weights, self.chosen),
        );
        let refs = slice::RowReferences {
            from: self.from,
            growing,
            older: self.older,
            publish: self.publish,
        };
        Ok(slice::decide_inter_rows(
            (seq, coder, self.src),
            inputs,
            refs,
            unmeasured,
            recon,
        )?)
    }

    /// [`RowsJob::decide_with`] where the weights are known.
    fn decided(
        &self,
        growing: &mut GrowingReference,
        motion: FrameMotion,
        weights: Weights,
        recon: Frame,
    ) -> Result<InterFrameCoder<'j, 'static>, EncodeError> {
        match self.decide_with(growing, motion, weights, None, recon)? {
            RowsDecided::Decided(decided) => Ok(*decided),
            RowsDecided::Weigh(..) => Err(EncodeError::Config("weights measured twice".into())),
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::interp::LumaFilter;
    use crate::codec::partition::MbVectors;
    use crate::encode::{Encoder, EncoderConfig, EncoderPreset};
    use crate::synth::{Motion, SceneSpec, Synth};

    const SIZE: (usize, usize) = (320, 176);

    /// Frames 0 and 1 of a scene moving by (2.25, -1.5) a frame, its light
    /// up by `brightness` a frame, borders extended.
    fn frames(brightness: f64) -> [Frame; 2] {
        let spec = SceneSpec::new("rising", SIZE.0, SIZE.1, 2)
            .seed(5)
            .camera(Motion::translation(2.25, -1.5))
            .brightness(brightness);
        let synth = Synth::new(spec).unwrap();
        [0, 1].map(|t| {
            let mut f = synth.frame(t);
            f.extend_borders();
            f
        })
    }

    /// `src` decided and written from `reference` as on a frame thread, the
    /// frame before publishing its rows all before (`behind` false) or
    /// a row at a time after the frame starts, so that its rows are
    /// decided before its weights are measured.
    fn coded(src: &Frame, reference: &Frame, behind: bool) -> CodedFrame {
        let (w, h) = SIZE;
        let config = EncoderConfig::new().qp(30).preset(EncoderPreset::Medium);
        let sequence = Encoder::new(w, h, (25, 1), config).unwrap().frame_sequence();
        let buffer = || Frame::new(w, h).unwrap();
        let (from, publish) = (
            FrameProgress::new(SIZE, Some(buffer()), false),
            FrameProgress::new(SIZE, Some(buffer()), false),
        );
        let mut growing = GrowingReference::new(buffer());
        let motion = MotionAnalyser::of_config(&config)
            .analyse_growing(growing.plain(), &[], Mv::ZERO, false)
            .expect("a search that takes its reference as it grows");
        let pricing = EntropyState::new();
        let job = RowsJob {
            sequence: &sequence,
            src,
            camera: Mv::ZERO,
            from: &from,
            older: &[],
            publish: &publish,
            pricing: &pricing,
            chosen: Chosen {
                luma_filter: LumaFilter::default(),
                deblock: true,
                deblock_offsets: crate::codec::deblock::DeblockOffsets::ZERO,
                older_refs: 0,
            },
        };
        let no_vectors: Vec<MbVectors> = vec![[None; 4]; (w / MB) * (h / MB)];
        let decide = || job.decide(&mut growing, motion, buffer(), &mut None).unwrap();
        let decided = if behind {
            std::thread::scope(|s| {
                // No row is in when it starts: it decides as if unweighted.
                let decider = s.spawn(decide);
                for upto in 1..=h / MB {
                    std::thread::sleep(std::time::Duration::from_millis(2));
                    from.publish(reference, &no_vectors, upto);
                }
                decider.join().unwrap()
            })
        } else {
            from.publish_whole(reference, None);
            decide()
        };
        assert_eq!(publish.rows(), h / MB, "every row published");
        let mut filter = FilterChooser::default();
        decided
            .with_references(vec![growing.frame()])
            .finish(
                &mut EntropyState::new(),
                super::super::encoder::learner(&mut filter, false, src, 1),
            )
            .unwrap()
    }

    #[test]
    fn rows_decided_before_the_weights_are_measured_are_those_decided_after() {
        for brightness in [0.0, 6.0] {
            let [reference, src] = frames(brightness);
            let first = coded(&src, &reference, false);
            assert_eq!(
                first.syntax.header.weights.any(),
                brightness > 0.0,
                "weighted where the light changes"
            );
            let late = coded(&src, &reference, true);
            assert!(
                late.bytes == first.bytes && late.recon == first.recon,
                "light {brightness}: another frame where its weights were measured late"
            );
        }
    }
}
