//! The encoder's frame loop (x264's `encoder.c`): the sequence header,
//! and per frame the choice of I or P, the references and their weights,
//! motion analysis, the frame's macroblocks ([`super::slice`]), the
//! statistics, and the reconstructions kept as references; with two
//! threads, block P frames two at a time on frame threads
//! ([`super::frame_thread`]).

use std::borrow::Cow;
use std::collections::VecDeque;
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::time::Instant;

use super::camera::CameraMotion;
use super::config::{EncoderConfig, FilterChoice, ModeDecision, Predictor};
use super::deblock_choice::DeblockChooser;
use super::filter::FilterChooser;
use super::frame_thread::{FrameThreads, InFlight, RowFrame, RowFrameDone, Sequence, Written};
use super::macroblock::MbCoder;
use super::motion::MotionAnalyser;
use super::progress::FrameProgress;
use super::reference::GrowingReference;
use super::refs_choice::RefsChooser;
use super::slice::{self, CodedFrame};
use super::stats::FrameStats;
use super::weights;
use super::{EncodeError, EncodedFrame};
use crate::codec::deblock::DeblockOffsets;
use crate::codec::interp::LumaFilter;
use crate::codec::mv::Mv;
use crate::codec::partition::MbVectors;
use crate::codec::picture::Plane;
use crate::codec::recon::{crop, crop_plane_into, holds_crop};
use crate::codec::syntax::{EntropyState, FrameType, MotionTool, SequenceHeader, Vui, STREAM_END};
use crate::codec::weight::Weights;
use crate::codec::{Frame, PictureError};
use crate::metrics::{psnr_from_mse, FrameQuality};

/// A row frame's references: the one it predicts from as it grows, and the
/// older ones.
type RowReferences = (GrowingReference, Vec<Arc<Frame>>);

/// Encodes a sequence frame by frame. See the [module](super) example.
pub struct Encoder {
    seq: SequenceHeader,
    config: EncoderConfig,
    /// P frames' quantiser and lambda.
    coder: MbCoder,
    /// I frames' (at [`EncoderConfig::intra_qp`]).
    intra_coder: MbCoder,
    analyser: MotionAnalyser,
    /// The reconstructions since the last I frame, the latest first, at
    /// most the configuration's references (coded size, borders
    /// extended), of the frames finished (a frame thread may hold some).
    references: Vec<Arc<Frame>>,
    /// The previous source, coded size (flow predictors read it).
    prev_source: Option<Frame>,
    /// The camera's motion from source to source (block searches centre
    /// their windows on it).
    camera: CameraMotion,
    /// Coded-size frames to reuse (the reference and source before the
    /// previous ones): fresh ones cost page faults every frame.
    spare_recon: Option<Frame>,
    /// A returned reconstruction given back ([`Encoder::recycle`]).
    spare_output: Option<Frame>,
    spare_source: Option<Frame>,
    /// The last weighted reference, to weigh the next one into.
    spare_weighted: Option<Frame>,
    /// The last reference brought in row by row, to bring the next into.
    spare_plain: Option<Frame>,
    /// The last frame's rows as it publishes them (frames decided row by
    /// row bring their reference in from them).
    last_rows: Option<Arc<FrameProgress>>,
    /// A published frame's buffer, to publish the next into.
    spare_rows: Option<Frame>,
    /// The frame pushed last, not returned yet ([`Encoder::push`]).
    /// The frames pushed and not returned yet, oldest first: at most two
    /// on their threads ([`Encoder::push`]).
    pending: VecDeque<Pending>,
    /// The threads of frames in flight, made at the first.
    frame_threads: Option<FrameThreads>,
    /// Where the frame in flight hands on the stream's state once
    /// written, for the next frame thread.
    handoff: Option<Receiver<Written>>,
    /// Contexts carried from frame to frame, as the decoder carries them.
    entropy: EntropyState,
    /// The contexts before the last frame was written: block P frames are
    /// priced from them (two frames back), as a frame thread, started
    /// while the frame before is decided, has them.
    pricing: EntropyState,
    /// What the coded frames say of the luma filters and of deblocking.
    filter: FilterChooser,
    deblock: DeblockChooser,
    /// What they say of the older references.
    refs: RefsChooser,
    /// The choosers as they stood a frame earlier, which give the next
    /// block P frame's filter, deblocking and references (a frame thread
    /// starts before the frame before it is learnt from).
    lagged_filter: FilterChooser,
    lagged_deblock: DeblockChooser,
    lagged_refs: RefsChooser,
    /// The frame after whose learning the lagged choosers are the
    /// choosers (in flight when the last P frame started).
    lagged_after: Option<usize>,
    /// The next frame's number.
    index: usize,
}

/// What a P frame takes from the choosers ([`Encoder::next_chosen`]).
#[derive(Clone, Copy)]
pub(super) struct Chosen {
    pub luma_filter: LumaFilter,
    /// Whether it is deblocked (where the sequence is).
    pub deblock: bool,
    /// The filter's offsets where they are chosen.
    pub deblock_offsets: DeblockOffsets,
    /// How many older references it searches.
    pub older_refs: usize,
}

/// A frame started: its number, kind and camera motion, and when.
#[derive(Clone, Copy)]
pub(super) struct FrameStart {
    pub index: usize,
    pub intra: bool,
    pub inter: bool,
    pub camera: Mv,
    pub start: Instant,
}

/// A frame pushed and not returned.
enum Pending {
    /// Coded (boxed: a frame's statistics outweigh a thread's handle).
    Done(Box<EncodedFrame>),
    /// On its frame thread.
    Running(InFlight),
}

/// The kinds of spare coded-size frames.
enum Spare {
    Recon,
    Plain,
    Rows,
}

impl Drop for Encoder {
    /// A frame still on its thread is waited for (its outcome dropped).
    fn drop(&mut self) {
        for pending in self.pending.drain(..) {
            if let Pending::Running(thread) = pending {
                thread.abandon();
            }
        }
    }
}

impl Encoder {
    /// An encoder for `width x height` pictures at `fps` (numerator,
    /// denominator).
    pub fn new(
        width: usize,
        height: usize,
        fps: (u32, u32),
        config: EncoderConfig,
    ) -> Result<Encoder, EncodeError> {
        config.check().map_err(EncodeError::Config)?;
        crate::codec::picture::check_size(width, height)?;
        if fps.0 == 0 || fps.1 == 0 {
            return Err(EncodeError::Config(format!(
                "frame rate {}/{} is not positive",
                fps.0, fps.1
            )));
        }
        let seq = SequenceHeader {
            width,
            height,
            fps_num: fps.0,
            fps_den: fps.1,
            frame_count: 0,
            vui: Vui::default(),
            max_refs: config.effective_refs(),
        };
        Ok(Encoder {
            seq,
            config,
            coder: MbCoder::new(config.qp, config.lambda_scale, config.rdoq)
                .intra4x4(config.partitions.i4x4)
                .intra8x8(config.intra8x8())
                .transform_8x8(config.transform_8x8)
                .estimated_rates(config.decision == ModeDecision::Fast && !config.transform_8x8),
            intra_coder: MbCoder::new(config.intra_qp(), config.lambda_scale, config.rdoq)
                .intra4x4(config.i_frame_partitions.i4x4)
                .intra8x8(config.i_frame_intra8x8()),
            analyser: MotionAnalyser::of_config(&config),
            references: Vec::new(),
            prev_source: None,
            camera: CameraMotion::default(),
            spare_recon: None,
            spare_output: None,
            spare_source: None,
            spare_weighted: None,
            spare_plain: None,
            last_rows: None,
            spare_rows: None,
            pending: VecDeque::new(),
            frame_threads: None,
            handoff: None,
            entropy: EntropyState::new(),
            pricing: EntropyState::new(),
            filter: FilterChooser::default(),
            deblock: DeblockChooser::default(),
            lagged_filter: FilterChooser::default(),
            lagged_deblock: DeblockChooser::default(),
            refs: RefsChooser::default(),
            lagged_refs: RefsChooser::default(),
            lagged_after: None,
            index: 0,
        })
    }

    /// Sets what the sequence header says about the samples (aspect ratio,
    /// range, chroma siting) for the decoder's output; call it before
    /// [`Encoder::header`].
    pub fn set_vui(&mut self, vui: Vui) {
        self.seq.vui = vui;
    }

    /// The sequence header that starts the stream (frame count 0: not
    /// known in advance).
    pub fn header(&self) -> Vec<u8> {
        self.seq.to_bytes()
    }

    /// The byte that ends the stream.
    pub fn trailer() -> [u8; 1] {
        [STREAM_END]
    }

    /// The sequence header.
    pub fn sequence(&self) -> &SequenceHeader {
        &self.seq
    }

    /// Gives back a reconstruction [`Encoder::encode`] returned, once the
    /// caller is done with it: the next one is written into it instead of
    /// a fresh frame (optional; it saves an allocation a frame).
    pub fn recycle(&mut self, recon: Frame) {
        self.spare_output = Some(recon);
    }

    /// Codes the next frame.
    pub fn encode(&mut self, source: &Frame) -> Result<EncodedFrame, EncodeError> {
        self.nothing_pushed()?;
        let (start, src) = self.padded(source)?;
        let measured = self.measured_apart(source, &src).then_some(source);
        self.code_now(measured, src, start)
    }

    /// Codes the next frame as [`Encoder::encode`] does (the same stream),
    /// taking `source`'s buffer where it can hold the coded size as it is
    /// laid out ([`Frame::new`]'s borders, rows wide enough for the coded
    /// width) and leaving a frame of the same size in its place, its
    /// samples unspecified: the copy into the coded size is saved (the
    /// encode loop reads the next frame into the frame left). A picture
    /// smaller than its whole macroblocks is padded in place, so it is
    /// taken only where no quality is measured (which compares the
    /// picture alone).
    pub fn encode_taking(&mut self, source: &mut Frame) -> Result<EncodedFrame, EncodeError> {
        self.nothing_pushed()?;
        match self.taken(source)? {
            Some((start, src)) => self.code_now(None, src, start),
            None => self.encode(source),
        }
    }

    /// Starts coding the next frame and returns the oldest frame pushed
    /// once it is coded, if one is (x264's API: with two threads two
    /// frames are on their threads, [`super::frame_thread`], and frames
    /// come back up to two calls late). The same stream as
    /// [`Encoder::encode`]'s; [`Encoder::flush`] gives the frames left.
    /// Not to be mixed with `encode` before they are flushed.
    pub fn push(&mut self, source: &Frame) -> Result<Option<EncodedFrame>, EncodeError> {
        let (start, src) = self.padded(source)?;
        // The picture is measured against after this call returns.
        let kept = self.measured_apart(source, &src).then(|| source.clone());
        self.push_coded(kept, src, start)
    }

    /// [`Encoder::push`] taking `source`'s buffer as
    /// [`Encoder::encode_taking`] does.
    pub fn push_taking(&mut self, source: &mut Frame) -> Result<Option<EncodedFrame>, EncodeError> {
        match self.taken(source)? {
            Some((start, src)) => self.push_coded(None, src, start),
            None => self.push(source),
        }
    }

    /// The oldest frame pushed and not returned, once coded (waiting for
    /// it); none when every frame is returned. Called until none after the
    /// last push.
    pub fn flush(&mut self) -> Result<Option<EncodedFrame>, EncodeError> {
        if let Some(Pending::Running(_)) = self.pending.front() {
            self.finish_oldest()?;
        }
        match self.pending.pop_front() {
            Some(Pending::Done(coded)) => Ok(Some(*coded)),
            Some(Pending::Running(_)) => unreachable!("the oldest frame was finished"),
            None => Ok(None),
        }
    }

    /// Whether `source`, measured against, is another picture than its
    /// coded form `src` (a size not of whole macroblocks).
    fn measured_apart(&self, source: &Frame, src: &Frame) -> bool {
        let visible = (src.width(), src.height()) != (source.width(), source.height());
        visible && !self.config.metrics.is_none()
    }

    /// [`Encoder::code`] on this thread, nothing pushed before.
    fn code_now(
        &mut self,
        source: Option<&Frame>,
        src: Frame,
        start: Instant,
    ) -> Result<EncodedFrame, EncodeError> {
        self.code(source.map(Cow::Borrowed), src, start, false)?;
        self.flush()?
            .ok_or_else(|| EncodeError::Config("a frame coded and not returned".into()))
    }

    fn nothing_pushed(&self) -> Result<(), EncodeError> {
        match self.pending.is_empty() {
            false => Err(EncodeError::Config(
                "frames pushed are not flushed: `encode` after `push`".into(),
            )),
            true => Ok(()),
        }
    }

    /// `source` padded to the coded size, and when it started.
    fn padded(&mut self, source: &Frame) -> Result<(Instant, Frame), EncodeError> {
        self.check_size(source)?;
        let start = Instant::now();
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        Ok((start, pad_to_coded(source, self.spare_source.take(), cw, ch)?))
    }

    /// `source`'s buffer as the coded frame, where it can be taken (see
    /// [`Encoder::encode_taking`]), and when it started.
    fn taken(&mut self, source: &mut Frame) -> Result<Option<(Instant, Frame)>, EncodeError> {
        self.check_size(source)?;
        if !self.can_take(source) {
            return Ok(None);
        }
        let start = Instant::now();
        let (w, h) = (source.width(), source.height());
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        let spare = match self.spare_source.take() {
            Some(f) => f,
            None => Frame::new(cw, ch)?,
        };
        let mut src = std::mem::replace(source, spare);
        // The frame left is a coded one, whose rows fit the picture's size.
        let lent = source.reshape(w, h);
        debug_assert!(lent, "a coded frame reshapes to the picture's size");
        if (w, h) != (cw, ch) {
            let grown = src.reshape(cw, ch);
            debug_assert!(
                grown,
                "`can_take` checked that the picture grows to the coded size"
            );
            let visible = [(w, h), Frame::chroma_size(w, h), Frame::chroma_size(w, h)];
            for (plane, (pw, ph)) in src.planes_mut().iter_mut().zip(visible) {
                plane.repeat_edges_beyond(pw, ph);
            }
        }
        // As the copy would leave them, whatever the caller's were.
        for plane in src.planes_mut() {
            plane.extend_border();
        }
        Ok(Some((start, src)))
    }

    fn check_size(&self, source: &Frame) -> Result<(), EncodeError> {
        if (source.width(), source.height()) != (self.seq.width, self.seq.height) {
            return Err(EncodeError::FrameSize {
                got_w: source.width(),
                got_h: source.height(),
                width: self.seq.width,
                height: self.seq.height,
            });
        }
        Ok(())
    }

    /// Whether `frame` (the picture's size) can become one of the
    /// coded-size frames the encoder keeps ([`Frame::new`] at the coded
    /// size) in its own buffer: the same borders, and no quality measured
    /// against it where it has to grow.
    fn can_take(&self, frame: &Frame) -> bool {
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        let chroma = Frame::chroma_size(cw, ch);
        let pads = [
            Plane::DEFAULT_PAD,
            Plane::DEFAULT_PAD.div_ceil(2),
            Plane::DEFAULT_PAD.div_ceil(2),
        ];
        let sizes = [(cw, ch), chroma, chroma];
        let coded = (frame.width(), frame.height()) == (cw, ch);
        (coded || self.config.metrics.is_none())
            && (0..3).all(|p| {
                let plane = frame.plane(p);
                let (pw, ph) = sizes[p];
                plane.pad() == pads[p] && plane.reshapes_to(pw, ph)
            })
    }

    /// Codes `src` (coded size, borders extended), the frame `source`
    /// (visible size, where measured against apart from `src`) into the
    /// queue of frames pushed: a block P frame decided row by row on a
    /// frame thread where `threads` (once the frame two before it is
    /// finished), any other frame now (once every frame before it is).
    fn code(
        &mut self,
        source: Option<Cow<'_, Frame>>,
        src: Frame,
        start: Instant,
        threads: bool,
    ) -> Result<(), EncodeError> {
        let rows = self.may_decide_rows();
        if !rows {
            self.finish_all()?;
        }
        let (frame, weights) = self.start_frame(&src, start, rows)?;
        if !rows {
            return self.code_whole(&frame, source.as_deref(), src, weights);
        }
        // The frame two before is finished before this one starts: its
        // contexts price this one, it is among its references.
        while self.running() > 1 {
            self.finish_oldest()?;
        }
        match self.row_frame(&frame, (source.map(Cow::into_owned), src), threads)? {
            Ok(job) if threads => {
                let threads = match &self.frame_threads {
                    Some(threads) => threads,
                    None => self.frame_threads.insert(FrameThreads::new()?),
                };
                let thread = threads.start(frame.index, job);
                self.pending.push_back(Pending::Running(thread));
                Ok(())
            }
            Ok(job) => {
                let done = job.run()?;
                let coded = self.finish_row(done);
                self.pending.push_back(Pending::Done(Box::new(coded)));
                Ok(())
            }
            Err((source, src)) => {
                self.finish_all()?;
                self.code_whole(&frame, source.as_ref(), src, weights)
            }
        }
    }

    /// [`Encoder::code`] of a frame that reads the whole frame before it
    /// (every frame before it finished).
    fn code_whole(
        &mut self,
        frame: &FrameStart,
        source: Option<&Frame>,
        src: Frame,
        weights: Option<Weights>,
    ) -> Result<(), EncodeError> {
        let (coded, me_ms) = self.code_whole_frame(frame, &src, weights)?;
        let coded = self.finish_frame(*frame, source, (coded, me_ms), src)?;
        self.pending.push_back(Pending::Done(Box::new(coded)));
        Ok(())
    }

    /// [`Encoder::code`] for `push`: on frame threads with two threads;
    /// the oldest frame back where it is coded.
    fn push_coded(
        &mut self,
        source: Option<Frame>,
        src: Frame,
        start: Instant,
    ) -> Result<Option<EncodedFrame>, EncodeError> {
        let threads = rayon::current_num_threads() == 2;
        self.code(source.map(Cow::Owned), src, start, threads)?;
        match self.pending.front() {
            Some(Pending::Done(_)) => self.flush(),
            _ => Ok(None),
        }
    }

    /// How many frames are on their threads.
    fn running(&self) -> usize {
        self.pending
            .iter()
            .filter(|p| matches!(p, Pending::Running(_)))
            .count()
    }

    /// Whether the frame before is on its thread.
    fn in_flight(&self) -> bool {
        matches!(self.pending.back(), Some(Pending::Running(_)))
    }

    /// Waits for the oldest frame on its thread, if any, and takes its
    /// outcome into the encoder's state.
    fn finish_oldest(&mut self) -> Result<(), EncodeError> {
        let Some(at) = self.pending.iter().position(|p| matches!(p, Pending::Running(_))) else {
            return Ok(());
        };
        let Some(Pending::Running(thread)) = self.pending.remove(at) else {
            unreachable!("a running frame at {at}");
        };
        let done = thread.wait()?;
        let coded = self.finish_row(done);
        self.pending.insert(at, Pending::Done(Box::new(coded)));
        Ok(())
    }

    /// Every frame on its thread finished.
    fn finish_all(&mut self) -> Result<(), EncodeError> {
        while self.running() > 0 {
            self.finish_oldest()?;
        }
        Ok(())
    }

    /// Whether frame `index` is an I frame (the I-frame period's).
    fn is_intra(&self, index: usize) -> bool {
        self.config.gop > 0 && index % self.config.gop == 0
    }

    /// Whether the next frame may be a block P frame decided row by row
    /// (whether it is depends on its search too: [`Encoder::row_frame`]).
    fn may_decide_rows(&self) -> bool {
        !self.is_intra(self.index)
            && self.prev_source.is_some()
            && rayon::current_num_threads() <= 2
            && matches!(self.config.predictor, Predictor::Block(_))
            && self.last_rows.is_some()
    }

    /// The next frame's place in the sequence and its camera motion (and,
    /// beside it, where a P frame reads the whole previous frame on
    /// several threads, its weights; not where it may be decided row by
    /// row, `rows`).
    fn start_frame(
        &mut self,
        src: &Frame,
        start: Instant,
        rows: bool,
    ) -> Result<(FrameStart, Option<Weights>), EncodeError> {
        let index = self.index;
        self.index += 1;
        let intra = self.is_intra(index);
        let inter = !intra && self.prev_source.is_some();
        let threads = rayon::current_num_threads();
        // Two passes over the frame that nothing else waits on, each on
        // one thread (frames decided row by row measure their weights on
        // the reference's rows as they come: `frame_thread`).
        let tracker = &mut self.camera;
        let (camera, weights) = rayon::join(
            // Every source, I frames' too: each is the next one's previous.
            || match self.config.predictor {
                Predictor::Block(_) | Predictor::Obmc(_) => tracker.next(src.y()),
                _ => Ok(Mv::ZERO),
            },
            || match self.references.first() {
                Some(reference) if inter && !rows && threads > 1 => {
                    Some(weights_of(&self.config, &self.seq, src, reference))
                }
                _ => None,
            },
        );
        let frame = FrameStart {
            index,
            intra,
            inter,
            camera: camera?,
            start,
        };
        Ok((frame, weights))
    }

    /// The work of a block P frame decided row by row
    /// ([`super::frame_thread`]), from what the frame before publishes
    /// (`src` back where its search needs the whole reference); to run on
    /// a frame thread where `threads`.
    fn row_frame(
        &mut self,
        frame: &FrameStart,
        (source, src): (Option<Frame>, Frame),
        threads: bool,
    ) -> Result<Result<RowFrame, (Option<Frame>, Frame)>, EncodeError> {
        let Some(from) = self.last_rows.clone() else {
            return Ok(Err((source, src)));
        };
        // The frame before is not among the references while in flight;
        // finished, it is the first, read as it is.
        let in_flight = self.in_flight();
        // What `next_chosen` gives below (nothing learnt in between).
        let older_refs = self.older_refs(frame.index);
        let Some((reference, older)) = self.row_references(in_flight, older_refs)? else {
            return Ok(Err((source, src)));
        };
        let t = Instant::now();
        let older_frames: Vec<&Frame> = older.iter().map(|f| &**f).collect();
        let motion =
            self.analyser
                .analyse_growing(reference.plain(), &older_frames, frame.camera, from.has_prior());
        let me_ms = t.elapsed().as_secs_f64() * 1e3;
        let Some(motion) = motion else {
            if let (Some(plain), _) = reference.into_frames() {
                self.spare_plain = Some(plain);
            }
            return Ok(Err((source, src)));
        };
        let chosen = self.next_chosen(frame.index);
        // Only a frame on a thread may have the frame after it start
        // before it is finished: only its samples are published.
        let samples = match threads {
            true => Some(self.coded_frame(Spare::Rows)?),
            false => None,
        };
        let size = (self.seq.coded_width(), self.seq.coded_height());
        let publish = Arc::new(FrameProgress::new(size, samples, true));
        self.last_rows = Some(Arc::clone(&publish));
        // Priced two frames back: the last finished where one is in flight.
        let pricing = match in_flight {
            true => self.entropy.clone(),
            false => self.pricing.clone(),
        };
        let (after, next) = mpsc::channel();
        let before = self.handoff_from_before(in_flight);
        self.handoff = Some(next);
        Ok(Ok(RowFrame {
            sequence: self.frame_sequence(),
            frame: *frame,
            source,
            output: self.spare_output.take(),
            src,
            recon: self.coded_frame(Spare::Recon)?,
            weighted: self.spare_weighted.take(),
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
        }))
    }

    /// A row frame's growing reference and its older references: the frame
    /// in flight, growing as its rows are published, and the finished ones
    /// before it; or, none in flight, the last finished frame and the ones
    /// older than it, at most `older` of those. `None` where there is no
    /// reference yet.
    fn row_references(
        &mut self,
        in_flight: bool,
        older: usize,
    ) -> Result<Option<RowReferences>, EncodeError> {
        if in_flight {
            let older = self.references.iter().take(older).cloned().collect();
            return Ok(Some((
                GrowingReference::new(self.coded_frame(Spare::Plain)?),
                older,
            )));
        }
        Ok(self.references.first().map(|before| {
            (
                GrowingReference::finished(Arc::clone(before)),
                self.references.iter().skip(1).take(older).cloned().collect(),
            )
        }))
    }

    /// Where a row frame receives what the frame before it leaves to the
    /// writer (contexts, filter, deblocking): the frame in flight's handoff,
    /// or, none in flight, what the encoder holds now, sent at once.
    fn handoff_from_before(&mut self, in_flight: bool) -> mpsc::Receiver<Written> {
        if let Some(before) = self.handoff.take().filter(|_| in_flight) {
            return before;
        }
        let (now, before) = mpsc::channel();
        let written = Written {
            entropy: self.entropy.clone(),
            filter: self.filter,
            deblock: self.deblock,
        };
        // The receiver is right here.
        let _ = now.send(written);
        before
    }

    /// What a frame thread's frame has of the sequence.
    pub(super) fn frame_sequence(&self) -> Sequence {
        Sequence {
            seq: self.seq,
            config: self.config,
            coder: self.coder,
        }
    }

    /// A spare coded-size frame of the kind asked, or a new one.
    fn coded_frame(&mut self, spare: Spare) -> Result<Frame, PictureError> {
        let kept = match spare {
            Spare::Recon => self.spare_recon.take(),
            Spare::Plain => self.spare_plain.take(),
            Spare::Rows => self.spare_rows.take(),
        };
        let (w, h) = (self.seq.coded_width(), self.seq.coded_height());
        match (kept, spare) {
            (Some(f), _) => Ok(f),
            // Published rows are copied out row by row, never read beyond
            // the picture: no borders (a third less memory at 720p).
            (None, Spare::Rows) => Frame::with_padding(w, h, 0),
            (None, _) => Frame::new(w, h),
        }
    }

    /// The luma filter and deblocking of the P frame `index` (the
    /// choosers as they stood when the P frame before started: they learn
    /// a frame late, as frame threads do), the next one's set to the
    /// choosers once the frame before this one is learnt from.
    fn next_chosen(&mut self, index: usize) -> Chosen {
        let chosen = Chosen {
            luma_filter: self.lagged_filter.next(self.config.luma_filter),
            deblock: !self.config.deblock_choice || self.lagged_deblock.deblocks(index),
            deblock_offsets: self.lagged_deblock.offsets(),
            older_refs: self.older_refs(index),
        };
        match self.in_flight() {
            true => self.lagged_after = index.checked_sub(1),
            false => self.lag_choosers(),
        }
        chosen
    }

    /// Takes a row-by-row frame's outcome into the encoder's state.
    fn finish_row(&mut self, done: RowFrameDone) -> EncodedFrame {
        self.pricing = done.before;
        self.entropy = done.after.entropy;
        self.filter = done.after.filter;
        self.deblock = done.after.deblock;
        self.refs.learn(done.coded.older_gain);
        self.remember_vectors(&done.coded);
        self.spare_plain = done.plain.or(self.spare_plain.take());
        self.spare_weighted = done.weighted.or(self.spare_weighted.take());
        drop(done.older);
        if let Ok(rows) = Arc::try_unwrap(done.from) {
            self.spare_rows = rows.into_samples().or(self.spare_rows.take());
        }
        self.keep(&done.frame, done.coded.recon, done.src);
        done.encoded
    }

    /// An I frame, or a P frame decided from the whole of the frame
    /// before (on the pool's threads), with motion analysis' time; its
    /// reconstruction published whole.
    fn code_whole_frame(
        &mut self,
        frame: &FrameStart,
        src: &Frame,
        weights: Option<Weights>,
    ) -> Result<(CodedFrame, f64), EncodeError> {
        let recon = self.coded_frame(Spare::Recon)?;
        let before = self.entropy.clone();
        let (coded, me_ms) = match (self.references.first(), frame.inter) {
            (Some(_), true) => self.code_p_frame(frame, src, recon, weights)?,
            _ => {
                let i = slice::code_intra(
                    &self.seq,
                    &self.intra_coder,
                    src,
                    self.config
                        .deblock
                        .then_some(self.config.deblock_offsets.unwrap_or_default()),
                    &mut self.entropy,
                    recon,
                )?;
                (i, 0.0)
            }
        };
        self.pricing = before;
        self.publish_whole(&coded.recon);
        Ok((coded, me_ms))
    }

    /// The coded frame reported ([`report`]); its reconstruction kept as
    /// a reference, `src` as the previous source.
    fn finish_frame(
        &mut self,
        frame: FrameStart,
        source: Option<&Frame>,
        (mut coded, me_ms): (CodedFrame, f64),
        src: Frame,
    ) -> Result<EncodedFrame, EncodeError> {
        let reporting = (&self.seq, &self.config, self.spare_output.take());
        let encoded = report(reporting, &frame, source.unwrap_or(&src), (&mut coded, me_ms))?;
        self.keep(&frame, coded.recon, src);
        Ok(encoded)
    }

    /// A finished frame's reconstruction kept as a reference, `src` as the
    /// previous source.
    fn keep(&mut self, frame: &FrameStart, recon: Frame, src: Frame) {
        if frame.intra {
            self.references.clear();
        }
        if self.references.len() == usize::from(self.seq.max_refs) {
            let oldest = self.references.pop();
            // A frame thread may hold it still.
            self.spare_recon = oldest.and_then(|f| Arc::try_unwrap(f).ok());
        }
        self.references.insert(0, Arc::new(recon));
        self.spare_source = self.prev_source.replace(src);
        if self.lagged_after == Some(frame.index) {
            self.lag_choosers();
            self.lagged_after = None;
        }
    }

    /// The lagged choosers brought up to the choosers.
    fn lag_choosers(&mut self) {
        (self.lagged_filter, self.lagged_deblock) = (self.filter, self.deblock);
        self.lagged_refs = self.refs;
    }

    /// How many older references block P frame `index` searches: those
    /// the sequence keeps, while they pay where chosen
    /// ([`super::refs_choice`]; the lagged chooser, as
    /// [`Encoder::next_chosen`] reads it, so the same for any number of
    /// threads).
    fn older_refs(&self, index: usize) -> usize {
        let max = self.seq.max_refs;
        let refs = match self.config.refs_choice {
            true => self.lagged_refs.refs(index, max),
            false => max,
        };
        usize::from(refs.saturating_sub(1))
    }

    /// Publishes a frame coded whole for the next, where the next may be
    /// decided row by row (block frames, one or two threads): its vectors
    /// alone, since it is finished before the next starts (which reads its
    /// reconstruction as it is).
    fn publish_whole(&mut self, recon: &Frame) {
        let threads = rayon::current_num_threads();
        if threads > 2 || !matches!(self.config.predictor, Predictor::Block(_)) {
            return;
        }
        let prior = self.analyser.prior();
        let size = (self.seq.coded_width(), self.seq.coded_height());
        let rows = FrameProgress::new(size, None, prior.is_some());
        rows.publish_whole(recon, prior);
        if let Some(old) = self.last_rows.replace(Arc::new(rows)) {
            if let Ok(old) = Arc::try_unwrap(old) {
                self.spare_rows = old.into_samples().or(self.spare_rows.take());
            }
        }
    }

    /// A P frame decided from the whole reference (weighted by `weights`,
    /// measured here where not yet): motion analysed, the macroblocks
    /// decided and coded; with the motion analysis' time, ms.
    fn code_p_frame(
        &mut self,
        frame: &FrameStart,
        src: &Frame,
        recon: Frame,
        weights: Option<Weights>,
    ) -> Result<(CodedFrame, f64), EncodeError> {
        let tool = match self.config.predictor {
            Predictor::Obmc(_) => MotionTool::Obmc,
            Predictor::Dense { grid, .. } => MotionTool::Grid(grid),
            _ => MotionTool::Block,
        };
        let chosen = self.next_chosen(frame.index);
        let weights = match (weights, self.references.first()) {
            (Some(w), _) => w,
            (None, Some(reference)) => weights_of(&self.config, &self.seq, src, reference),
            (None, None) => Weights::NONE,
        };
        let coded = self.code_p_whole((frame, src), recon, (weights, chosen, tool))?;
        self.remember_vectors(&coded.0);
        Ok(coded)
    }

    /// A block P frame's decided vectors into its first reference: the
    /// next block frame's co-located candidates.
    fn remember_vectors(&mut self, coded: &CodedFrame) {
        if self.analyser.searches_in_decision() {
            let mvs = coded.vectors.iter().map(super::motion::colocated).collect();
            let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
            self.analyser.remember(cw, ch, mvs);
        }
    }

    /// A P frame decided from the whole reference (weighted first) on the
    /// pool's threads.
    fn code_p_whole(
        &mut self,
        (frame, src): (&FrameStart, &Frame),
        recon: Frame,
        (weights, chosen, tool): (Weights, Chosen, MotionTool),
    ) -> Result<(CodedFrame, f64), EncodeError> {
        let (index, camera) = (frame.index, frame.camera);
        let (Some(unweighted), Some(prev)) = (self.references.first().map(|f| &**f), &self.prev_source)
        else {
            return Err(EncodeError::Config("a P frame without a reference".into()));
        };
        let weighted = weights.any().then(|| {
            // Every sample of `out` is written, borders included.
            let layout =
                |f: &Frame| [0, 1, 2].map(|p| (f.plane(p).width(), f.plane(p).height(), f.plane(p).pad()));
            let mut out = match self.spare_weighted.take() {
                Some(f) if layout(&f) == layout(unweighted) => f,
                _ => unweighted.clone(),
            };
            weights.apply_into(unweighted, &mut out);
            out
        });
        let reference = weighted.as_ref().unwrap_or(unweighted);
        let t = Instant::now();
        // Older references: `block` only (the list holds one frame for the
        // other predictors).
        let older: Vec<&Frame> = self.references[1..]
            .iter()
            .take(chosen.older_refs)
            .map(|f| &**f)
            .collect();
        let motion = self.analyser.analyse(src, prev, reference, &older, camera);
        let me_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut inputs = inter_inputs(&self.config, &self.pricing, motion, tool, (weights, chosen));
        // Weights apply to reference 0 alone (FORMAT.md section 12).
        inputs.references = std::iter::once(reference).chain(older.iter().copied()).collect();
        // Which filter the next frame takes, learnt while this one is
        // written.
        let learn = tool == MotionTool::Block && self.config.luma_filter == FilterChoice::Auto;
        let coded = slice::code_inter(
            &self.seq,
            &self.coder,
            src,
            inputs,
            (&mut self.entropy, recon),
            learner(&mut self.filter, learn, src, index),
        )?;
        self.deblock.learn(coded.deblock_effect);
        self.refs.learn(coded.older_gain);
        self.spare_weighted = weighted.or(self.spare_weighted.take());
        Ok((coded, me_ms))
    }
}

/// A coded frame as [`Encoder::encode`] returns it, its bytes taken: its
/// visible reconstruction (into `output` where it fits) where asked for
/// or measured, and its statistics against `source` (the picture, or the
/// coded source where that is its size).
pub(super) fn report(
    (seq, config, output): (&SequenceHeader, &EncoderConfig, Option<Frame>),
    frame: &FrameStart,
    source: &Frame,
    (coded, me_ms): (&mut CodedFrame, f64),
) -> Result<EncodedFrame, PictureError> {
    let measured = !config.metrics.is_none();
    // A coded reconstruction of the picture's size is measured as it is:
    // a copy only where one is given out or the coded size is larger.
    let as_coded = (coded.recon.width(), coded.recon.height()) == (seq.width, seq.height);
    let recon = if config.reconstruction || (measured && !as_coded) {
        Some(visible_recon(&coded.recon, (seq.width, seq.height), output)?)
    } else {
        None
    };
    let measured_recon = recon.as_ref().or(measured.then_some(&coded.recon));
    // The quality measurements are not coding time: some cost more than
    // the coding.
    let coding_ms = frame.start.elapsed().as_secs_f64() * 1e3;
    let times = (me_ms, coding_ms);
    let stats = frame_stats((seq, config), frame.index, (source, measured_recon), coded, times);
    Ok(EncodedFrame {
        bytes: std::mem::take(&mut coded.bytes),
        recon: recon.filter(|_| config.reconstruction),
        stats,
    })
}

/// The visible part (`w x h`) of a coded reconstruction, in `output`
/// where it fits: luma beside chroma, as the source was padded.
fn visible_recon(
    coded: &Frame,
    (w, h): (usize, usize),
    output: Option<Frame>,
) -> Result<Frame, PictureError> {
    let Some(mut out) = output.filter(|f| holds_crop(f, w, h)) else {
        return crop(coded, w, h);
    };
    let [y, u, v] = out.planes_mut();
    rayon::join(
        || crop_plane_into(coded.plane(0), y),
        || {
            crop_plane_into(coded.plane(1), u);
            crop_plane_into(coded.plane(2), v);
        },
    );
    Ok(out)
}

/// The statistics of a coded frame: its rate, its reconstruction's
/// quality against `source` (one record), the macroblocks' kinds and the
/// times.
fn frame_stats(
    (seq, config): (&SequenceHeader, &EncoderConfig),
    index: usize,
    (source, recon): (&Frame, Option<&Frame>),
    coded: &CodedFrame,
    (me_ms, total_ms): (f64, f64),
) -> FrameStats {
    let header = &coded.syntax.header;
    FrameStats {
        index,
        frame_type: if header.frame_type == FrameType::Intra {
            'I'
        } else {
            'P'
        },
        qp: header.qp,
        bytes: coded.bytes.len(),
        bits_header: coded.bits.header,
        bits_motion: coded.bits.motion,
        bits_residual: coded.bits.residual,
        // Without a reconstruction no metric is asked for: a record
        // of unknowns, as the measurement of none would give.
        quality: FrameQuality::measure_as(source, recon.unwrap_or(source), &config.quality()),
        prediction_psnr_y: psnr_from_mse(coded.prediction_sse as f64 / (seq.width * seq.height) as f64),
        skip_mbs: coded.kinds[0],
        inter_mbs: coded.kinds[1],
        intra_mbs: coded.kinds[2],
        me_ms,
        total_ms,
    }
}

/// What runs beside a P frame's writing: the `index`-th frame `src`, its
/// vectors and references, learnt from by `filter` where `learn`.
pub(super) fn learner<'f>(
    filter: &'f mut FilterChooser,
    learn: bool,
    src: &'f Frame,
    index: usize,
) -> impl FnOnce(&[MbVectors], &[&Frame]) + Send + 'f {
    move |vectors, references| {
        if learn {
            filter.learn(src, references, vectors, index);
        }
    }
}

/// A P frame's inputs under `config` (no references yet).
pub(super) fn inter_inputs<'r>(
    config: &EncoderConfig,
    pricing: &'r EntropyState,
    motion: super::motion::FrameMotion,
    tool: MotionTool,
    (weights, chosen): (Weights, Chosen),
) -> slice::InterInputs<'r> {
    slice::InterInputs {
        references: Vec::new(),
        luma_filter: chosen.luma_filter,
        motion,
        tool,
        decision: config.decision,
        deblock: config.deblock && chosen.deblock,
        // Fixed by the caller, or chosen where the deblocking is.
        deblock_offsets: match (config.deblock_offsets, config.deblock_choice) {
            (Some(fixed), _) => fixed,
            (None, true) => chosen.deblock_offsets,
            (None, false) => DeblockOffsets::ZERO,
        },
        measure_deblock: config.deblock_choice && tool == MotionTool::Block,
        try_deblock_offsets: config.deblock_offsets.is_none(),
        weights,
        partitions: config.partitions.p8x8,
        subpel_rd: config.subpel_rd,
        split_margin: config.split_margin,
        split_search_margin: config.split_search_margin,
        chroma_me: config.chroma_me,
        adaptive_pricing: config.adaptive_pricing,
        fast_pskip: config.fast_pskip,
        early_pskip: config.early_pskip,
        pricing,
    }
}

/// The weights of a P frame `src` predicted from `reference` (their top
/// halves), where `config` weighs.
pub(super) fn weights_of(
    config: &EncoderConfig,
    seq: &SequenceHeader,
    src: &Frame,
    reference: &Frame,
) -> Weights {
    if config.weightp {
        weights::estimate(src, reference, weight_rows(seq))
    } else {
        Weights::NONE
    }
}

/// How many of the reference's luma rows a P frame's weights are measured
/// on: its top half, whole macroblock rows (on a frame thread, measured
/// once the frame before has published them).
pub(super) fn weight_rows(seq: &SequenceHeader) -> usize {
    (seq.mb_rows() / 2).max(1) * crate::codec::consts::MB
}

/// `frame` at the coded size: the right column and bottom row repeated
/// into the macroblocks' padding (which costs few bits and no distortion
/// that anyone sees), borders extended; written into `reuse` when given.
fn pad_to_coded(
    frame: &Frame,
    reuse: Option<Frame>,
    width: usize,
    height: usize,
) -> Result<Frame, PictureError> {
    let mut out = match reuse {
        Some(f) => f,
        None => Frame::new(width, height)?,
    };
    let pad_plane = |p: usize, dst: &mut Plane| {
        let src = frame.plane(p);
        let (sw, sh) = (src.width(), src.height());
        for y in 0..dst.height() {
            let row = src.row(y.min(sh - 1));
            let d = dst.row_mut(y);
            d[..sw].copy_from_slice(row);
            let last = row[sw - 1];
            d[sw..].fill(last);
        }
        dst.extend_border();
    };
    // Luma beside the two chroma planes (two thirds of the samples against
    // one): a copy the frame's threads would otherwise wait for.
    let [y, u, v] = out.planes_mut();
    rayon::join(
        || pad_plane(0, y),
        || {
            pad_plane(1, u);
            pad_plane(2, v);
        },
    );
    Ok(out)
}
