//! The encoder's frame loop (x264's `encoder.c`): the sequence header,
//! and per frame the choice of I or P, the references and their weights,
//! motion analysis, the frame's macroblocks ([`super::slice`]), the
//! statistics, and the reconstructions kept as references.

use std::time::Instant;

use super::camera::CameraMotion;
use super::config::{EncoderConfig, FilterChoice, Predictor};
use super::filter::FilterChooser;
use super::macroblock::MbCoder;
use super::motion::MotionAnalyser;
use super::progress::FrameProgress;
use super::reference::GrowingReference;
use super::slice::{self, CodedFrame};
use super::stats::FrameStats;
use super::weights;
use super::{EncodeError, EncodedFrame};
use crate::codec::interp::LumaFilter;
use crate::codec::mv::Mv;
use crate::codec::partition::MbVectors;
use crate::codec::picture::Plane;
use crate::codec::recon::{crop, crop_plane_into, holds_crop};
use crate::codec::syntax::{EntropyState, FrameType, MotionTool, SequenceHeader, Vui, STREAM_END};
use crate::codec::weight::Weights;
use crate::codec::{Frame, PictureError};
use crate::metrics::{psnr_from_mse, FrameQuality};

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
    /// most the configuration's references (coded size, borders extended).
    references: Vec<Frame>,
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
    /// The last frame's rows as it published them (one thread: P frames
    /// bring their reference in from them, as a frame thread would).
    last_rows: Option<FrameProgress>,
    /// This frame's, where it published them as it decided them.
    rows_now: Option<FrameProgress>,
    /// The frame before's, to publish the next into.
    spare_rows: Option<Frame>,
    /// Contexts carried from frame to frame, as the decoder carries them.
    entropy: EntropyState,
    /// The contexts before the last frame was written: block P frames are
    /// priced from them (two frames back), as a frame thread, started
    /// while the frame before is decided, has them.
    pricing: EntropyState,
    /// What the coded frames say of the luma filters.
    filter: FilterChooser,
    /// The chooser as it stood a frame earlier, which gives the next block
    /// P frame's filter (a frame thread starts before the frame before it
    /// is learnt from).
    lagged_filter: FilterChooser,
    index: usize,
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
                .transform_8x8(config.transform_8x8),
            intra_coder: MbCoder::new(config.intra_qp(), config.lambda_scale, config.rdoq)
                .intra4x4(config.i_frame_partitions.i4x4)
                .intra8x8(config.i_frame_intra8x8()),
            analyser: MotionAnalyser::new(config.predictor, config.qp, config.partitions.p8x8),
            references: Vec::new(),
            prev_source: None,
            camera: CameraMotion::default(),
            spare_recon: None,
            spare_output: None,
            spare_source: None,
            spare_weighted: None,
            spare_plain: None,
            last_rows: None,
            rows_now: None,
            spare_rows: None,
            entropy: EntropyState::new(),
            pricing: EntropyState::new(),
            filter: FilterChooser::default(),
            lagged_filter: FilterChooser::default(),
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
        self.check_size(source)?;
        let start = Instant::now();
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        let src = pad_to_coded(source, self.spare_source.take(), cw, ch)?;
        self.encode_coded(Some(source), src, start)
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
        self.check_size(source)?;
        if !self.can_take(source) {
            return self.encode(source);
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
        self.encode_coded(None, src, start)
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
    /// (visible size; `None` where `src` is that size already).
    fn encode_coded(
        &mut self,
        source: Option<&Frame>,
        src: Frame,
        start: Instant,
    ) -> Result<EncodedFrame, EncodeError> {
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        let recon = match self.spare_recon.take() {
            Some(f) => f,
            None => Frame::new(cw, ch)?,
        };
        let intra = self.config.gop > 0 && self.index % self.config.gop == 0;
        let inter = !intra && self.prev_source.is_some();
        // The camera's motion beside the weights' statistics: two passes
        // over the frame that nothing else waits on, each on one thread
        // (one thread measures the weights on the reference's rows as they
        // are brought in: `code_p_rows`).
        let tracker = &mut self.camera;
        let (camera, weights) = rayon::join(
            // Every source, I frames' too: each is the next one's previous.
            || match self.config.predictor {
                Predictor::Block(_) | Predictor::Obmc(_) => tracker.next(src.y()),
                _ => Ok(Mv::ZERO),
            },
            || match self.references.first() {
                Some(reference) if inter && rayon::current_num_threads() > 1 => {
                    Some(weights_of(&self.config, &self.seq, &src, reference))
                }
                _ => None,
            },
        );
        let camera = camera?;
        let before = self.entropy.clone();
        let (coded, me_ms) = match (self.references.first(), inter) {
            (Some(_), true) => self.code_p_frame(&src, recon, camera, weights)?,
            _ => {
                let i = slice::code_intra(
                    &self.seq,
                    &self.intra_coder,
                    &src,
                    self.config.deblock,
                    &mut self.entropy,
                    recon,
                )?;
                (i, 0.0)
            }
        };
        let measured = !self.config.metrics.is_none();
        let recon = if self.config.reconstruction || measured {
            Some(self.visible_recon(&coded.recon)?)
        } else {
            None
        };
        // The quality measurements are not coding time: some cost more than
        // the coding.
        let coding_ms = start.elapsed().as_secs_f64() * 1e3;
        let stats = self.frame_stats(source.unwrap_or(&src), recon.as_ref(), &coded, (me_ms, coding_ms));
        let recon = recon.filter(|_| self.config.reconstruction);
        if intra {
            self.references.clear();
        }
        if self.references.len() == usize::from(self.seq.max_refs) {
            self.spare_recon = self.references.pop();
        }
        self.publish_rows(&coded.recon)?;
        let bytes = coded.bytes;
        self.references.insert(0, coded.recon);
        self.spare_source = self.prev_source.replace(src);
        self.pricing = before;
        self.index += 1;
        Ok(EncodedFrame { bytes, recon, stats })
    }

    /// Keeps the frame's published rows for the next (one thread, block
    /// frames: the frames that bring their reference in row by row):
    /// those it published as it decided them, or else `recon`'s (the
    /// coded reconstruction, final) published whole.
    fn publish_rows(&mut self, recon: &Frame) -> Result<(), PictureError> {
        let rows_now = self.rows_now.take();
        if rayon::current_num_threads() > 1 || !matches!(self.config.predictor, Predictor::Block(_)) {
            return Ok(());
        }
        let rows = match rows_now {
            Some(rows) => rows,
            None => {
                let frame = match self.spare_rows.take() {
                    Some(f) => f,
                    None => Frame::new(recon.width(), recon.height())?,
                };
                let prior = self.analyser.prior();
                let rows = FrameProgress::new(frame, prior.is_some());
                rows.publish_whole(recon, prior);
                rows
            }
        };
        if let Some(old) = self.last_rows.replace(rows) {
            self.spare_rows = Some(old.into_frame());
        }
        Ok(())
    }

    /// The visible part of a coded reconstruction, in the frame given back
    /// where it fits: luma beside chroma, as the source was padded.
    fn visible_recon(&mut self, coded: &Frame) -> Result<Frame, PictureError> {
        let (w, h) = (self.seq.width, self.seq.height);
        let Some(mut out) = self.spare_output.take().filter(|f| holds_crop(f, w, h)) else {
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

    /// A P frame: the reference weighted by `weights` (measured here where
    /// not yet), motion analysed, the macroblocks decided and coded; with
    /// the motion analysis' time, ms. On one thread, a block frame is
    /// decided row by row from its reference brought in as the rows need
    /// it, as a frame thread decides it (the same stream as the
    /// wavefront's from the whole reference).
    fn code_p_frame(
        &mut self,
        src: &Frame,
        recon: Frame,
        camera: Mv,
        weights: Option<Weights>,
    ) -> Result<(CodedFrame, f64), EncodeError> {
        let tool = match self.config.predictor {
            Predictor::Obmc(_) => MotionTool::Obmc,
            Predictor::Dense { grid, .. } => MotionTool::Grid(grid),
            _ => MotionTool::Block,
        };
        let luma_filter = self.lagged_filter.next(self.config.luma_filter);
        self.lagged_filter = self.filter;
        let coded = if rayon::current_num_threads() == 1 && tool == MotionTool::Block {
            self.code_p_rows(src, recon, camera, luma_filter)?
        } else {
            Err(recon)
        };
        let (coded, me_ms) = match coded {
            Ok(coded) => coded,
            Err(recon) => {
                let weights = match (weights, self.references.first()) {
                    (Some(w), _) => w,
                    (None, Some(reference)) => weights_of(&self.config, &self.seq, src, reference),
                    (None, None) => Weights::NONE,
                };
                self.code_p_whole(src, recon, camera, (weights, luma_filter, tool))?
            }
        };
        if self.analyser.searches_in_decision() {
            let mvs = coded
                .vectors
                .iter()
                .map(|v| v[0].filter(|m| m.ref_idx == 0).map_or(Mv::ZERO, |m| m.mv))
                .collect();
            self.analyser.remember(src.width(), src.height(), mvs);
        }
        Ok((coded, me_ms))
    }

    /// A block P frame decided row by row ([`slice::code_inter_rows`]),
    /// where its search allows (else `recon` back), its weights measured
    /// on the reference's top half as soon as it is in.
    fn code_p_rows(
        &mut self,
        src: &Frame,
        recon: Frame,
        camera: Mv,
        luma_filter: LumaFilter,
    ) -> Result<Result<(CodedFrame, f64), Frame>, EncodeError> {
        let Some(from) = self.last_rows.as_ref() else {
            return Ok(Err(recon));
        };
        let (cw, ch) = (self.seq.coded_width(), self.seq.coded_height());
        let plain = match self.spare_plain.take() {
            Some(f) => f,
            None => Frame::new(cw, ch)?,
        };
        let t = Instant::now();
        let motion = self
            .analyser
            .analyse_growing(&plain, &self.references[1..], camera, from.has_prior());
        let me_ms = t.elapsed().as_secs_f64() * 1e3;
        let Some(motion) = motion else {
            self.spare_plain = Some(plain);
            return Ok(Err(recon));
        };
        let mut growing = GrowingReference::new(plain);
        let top = weight_rows(&self.seq) / crate::codec::consts::MB;
        from.with_rows(top, |f, _| growing.bring_in(f, top, None));
        let weights = weights_of(&self.config, &self.seq, src, growing.plain());
        if weights.any() {
            let weighted = match self.spare_weighted.take() {
                Some(f) => f,
                None => Frame::new(cw, ch)?,
            };
            growing.weigh(weights, weighted);
        }
        let frame = match self.spare_rows.take() {
            Some(f) => f,
            None => Frame::new(cw, ch)?,
        };
        let publish = FrameProgress::new(frame, true);
        let older: Vec<&Frame> = self.references[1..].iter().collect();
        let inputs = inter_inputs(
            &self.config,
            &self.pricing,
            motion,
            MotionTool::Block,
            (weights, luma_filter),
        );
        let learn = self.config.luma_filter == FilterChoice::Auto;
        let refs = slice::RowReferences {
            from,
            growing: &mut growing,
            older: &older,
            publish: &publish,
        };
        let coded = slice::code_inter_rows(
            &self.seq,
            &self.coder,
            src,
            inputs,
            refs,
            (&mut self.entropy, recon),
            learner(&mut self.filter, learn, src, self.index),
        )?;
        let (plain, weighted) = growing.into_frames();
        self.spare_plain = Some(plain);
        self.rows_now = Some(publish);
        self.spare_weighted = weighted.or(self.spare_weighted.take());
        Ok(Ok((coded, me_ms)))
    }

    /// A P frame decided from the whole reference (weighted first) on the
    /// pool's threads.
    fn code_p_whole(
        &mut self,
        src: &Frame,
        recon: Frame,
        camera: Mv,
        (weights, luma_filter, tool): (Weights, LumaFilter, MotionTool),
    ) -> Result<(CodedFrame, f64), EncodeError> {
        let (Some(unweighted), Some(prev)) = (self.references.first(), &self.prev_source) else {
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
        let motion = self
            .analyser
            .analyse(src, prev, reference, &self.references[1..], camera);
        let me_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut inputs = inter_inputs(&self.config, &self.pricing, motion, tool, (weights, luma_filter));
        // Weights apply to reference 0 alone (FORMAT.md section 12).
        inputs.references = std::iter::once(reference).chain(&self.references[1..]).collect();
        // Which filter the next frame takes, learnt while this one is
        // written.
        let learn = tool == MotionTool::Block && self.config.luma_filter == FilterChoice::Auto;
        let coded = slice::code_inter(
            &self.seq,
            &self.coder,
            src,
            inputs,
            (&mut self.entropy, recon),
            learner(&mut self.filter, learn, src, self.index),
        )?;
        self.spare_weighted = weighted.or(self.spare_weighted.take());
        Ok((coded, me_ms))
    }

    /// The statistics of a coded frame: its rate, its reconstruction's
    /// quality (one record), the macroblocks' kinds and the times.
    fn frame_stats(
        &self,
        source: &Frame,
        recon: Option<&Frame>,
        coded: &CodedFrame,
        (me_ms, total_ms): (f64, f64),
    ) -> FrameStats {
        let header = &coded.syntax.header;
        FrameStats {
            index: self.index,
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
            quality: FrameQuality::measure_as(source, recon.unwrap_or(source), &self.config.quality()),
            prediction_psnr_y: psnr_from_mse(
                coded.prediction_sse as f64 / (self.seq.width * self.seq.height) as f64,
            ),
            skip_mbs: coded.kinds[0],
            inter_mbs: coded.kinds[1],
            intra_mbs: coded.kinds[2],
            me_ms,
            total_ms,
        }
    }
}

/// What runs beside a P frame's writing: the `index`-th frame `src`, its
/// vectors and references, learnt from by `filter` where `learn`.
fn learner<'f>(
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
fn inter_inputs<'r>(
    config: &EncoderConfig,
    pricing: &'r EntropyState,
    motion: super::motion::FrameMotion,
    tool: MotionTool,
    (weights, luma_filter): (Weights, LumaFilter),
) -> slice::InterInputs<'r> {
    slice::InterInputs {
        references: Vec::new(),
        luma_filter,
        motion,
        tool,
        decision: config.decision,
        deblock: config.deblock,
        weights,
        partitions: config.partitions.p8x8,
        subpel_rd: config.subpel_rd,
        split_margin: config.split_margin,
        chroma_me: config.chroma_me,
        adaptive_pricing: config.adaptive_pricing,
        fast_pskip: config.fast_pskip,
        early_pskip: config.early_pskip,
        pricing,
    }
}

/// The weights of a P frame `src` predicted from `reference` (their top
/// halves), where `config` weighs.
fn weights_of(config: &EncoderConfig, seq: &SequenceHeader, src: &Frame, reference: &Frame) -> Weights {
    if config.weightp {
        weights::estimate(src, reference, weight_rows(seq))
    } else {
        Weights::NONE
    }
}

/// How many of the reference's luma rows a P frame's weights are measured
/// on: its top half, whole macroblock rows (the rows a frame thread has
/// when it starts the next frame).
fn weight_rows(seq: &SequenceHeader) -> usize {
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
