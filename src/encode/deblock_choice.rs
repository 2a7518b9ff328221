//! Whether a block P frame is deblocked (the frame header's `deblock` bit,
//! FORMAT.md section 11), chosen from what the filter did to the frames
//! before it (encoder side). H.264's filter at its one strength takes
//! real texture for blocking on some footage: without it, medium needs
//! 11.7 % fewer bits on diver_vga (bubbles under water; at QP 27 its
//! first P frame codes 1158 of its 1200 macroblocks intra, and its P
//! frames lose 1.8 dB of mean luma PSNR to the filter over 30 frames)
//! and 9.1 % on fish_1160, and 10-23 % more on ball_576 and
//! static_noise_cif (`--no-deblock`, `benches/pair.py`). libaom picks its
//! loop filter's level per frame by the error the filter leaves; the
//! format here has on and off.
//!
//! The measure is the luma's squared error against the source before and
//! after the filter, on every [`MEASURED_ROW_EVERY`]-th macroblock row
//! ([`DeblockMeter`]), the same whether the frame is filtered row by row
//! or whole. A frame not deblocked measures nothing: every
//! [`PROBE_EVERY`]-th frame is deblocked while the filter is off, to see
//! whether the footage has changed.

use crate::codec::consts::MB;
use crate::codec::deblock::{DeblockOffsets, DeblockStrength, FrameDeblocker};
use crate::codec::Plane;
use crate::metrics::squared_difference_sum;

/// Macroblock rows measured: one in this many (the first of each group).
const MEASURED_ROW_EVERY: usize = 2;

/// While the filter is off, one frame in this many is deblocked anyway.
/// Against 8 (`benches/pair.py`, the 28 sequences): medium -0.59 %
/// against -0.57 %, ultrafast -0.38 % against -0.15 % (fish_1160 -4.0 %
/// against +2.2 %: its error ratios lie near [`OFF_ABOVE`] at QP 27).
const PROBE_EVERY: usize = 16;

/// The averaged after/before error ratio above which frames go
/// undeblocked: a frame whose error the filter leaves about the same
/// predicts the frames after it better deblocked. `benches/pair.py` on
/// the 28 sequences, medium, a probe every 8 frames: 1.0 -0.48 % (room_400 +1.75 %,
/// static_noise_cif +0.97 %), 0.995 +0.68 %, 1.005 -0.57 % (room_400
/// +0.32 %), 1.01 -0.57 % (diver_vga -9.3 %, dark_cif -3.5 %, fish_1160
/// -3.2 %, webcam_cif -0.2 %, no other sequence changed).
const OFF_ABOVE: f64 = 1.01;

/// The offsets tried either side of the frame's (each of alpha's and
/// beta's: x264's `--deblock` one step).
const OFFSET_STEP: i8 = 2;

/// The chosen offsets stay within this either way.
const MAX_CHOSEN_OFFSET: i8 = 8;

/// The luma's squared error against the source on the measured rows,
/// before the frame's filter and after it; and, where the offsets are
/// chosen, on the tried rows (one in [`TRIED_ROW_EVERY`]) just after each
/// one's own filter pass (before the row below's), at the frame's offsets
/// one step weaker, as they are, and one step stronger
/// ([`filter_row_trying`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct DeblockEffect {
    pub before: u64,
    pub after: u64,
    pub tried: [u64; 3],
}

/// The strengths tried: the frame's offsets one step down, as they are,
/// one step up (each within [`DeblockOffsets::MAX`]).
fn tried_strengths(frame: DeblockStrength) -> [DeblockStrength; 3] {
    let o = frame.offsets;
    let moved = |by: i8| DeblockStrength {
        offsets: DeblockOffsets {
            alpha: (o.alpha + by).clamp(-DeblockOffsets::MAX, DeblockOffsets::MAX),
            beta: (o.beta + by).clamp(-DeblockOffsets::MAX, DeblockOffsets::MAX),
        },
        ..frame
    };
    [moved(-OFFSET_STEP), frame, moved(OFFSET_STEP)]
}

/// Macroblock rows whose filter is also tried at other strengths: one in
/// this many. Against every other row, on the 32 sequences
/// (`benches/pair.py`, 60 frames, one run): medium -0.28 % against
/// -0.16 % for 1.001x the encoder's time against 1.018x, ultrafast
/// -0.05 % against -0.10 % for 1.012x against 1.041x.
const TRIED_ROW_EVERY: usize = 4;

/// Macroblock row `k` of `y` filtered by `d` (its own pass: its vertical
/// edges, its horizontal ones from its top edge down). Where `trial` is
/// given and the row is tried, the lines the pass reads (four above the
/// row, the row) are first copied into its scratch plane and filtered
/// there one step weaker and one stronger ([`tried_strengths`]); the
/// squared error against `source` of the lines the pass can change, at
/// each strength and after the row's own pass, is added to the trial.
pub(crate) fn filter_row_trying(
    d: &FrameDeblocker,
    y: &mut Plane,
    k: usize,
    trial: Option<(&Plane, &mut StrengthTrial)>,
) {
    let Some((source, t)) = trial.filter(|_| k % TRIED_ROW_EVERY == 0) else {
        d.filter_rows(y, 0, k..k + 1);
        return;
    };
    let StrengthTrial {
        scratch: Some(scratch),
        tried,
    } = t
    else {
        d.filter_rows(y, 0, k..k + 1);
        return;
    };
    let (top, bottom) = ((k * MB).saturating_sub(4), ((k + 1) * MB).min(y.height()));
    let changed = (k * MB).saturating_sub(3)..bottom;
    let error = |plane: &Plane| -> u64 {
        changed
            .clone()
            .map(|line| squared_difference_sum(source.row(line), plane.row(line)))
            .sum()
    };
    let [weaker, _, stronger] = tried_strengths(d.strength());
    for (i, strength) in [(0, weaker), (2, stronger)] {
        for line in top..bottom {
            scratch.row_mut(line).copy_from_slice(y.row(line));
        }
        d.filter_rows_at(scratch, 0, k..k + 1, strength);
        tried[i] += error(scratch);
    }
    d.filter_rows(y, 0, k..k + 1);
    tried[1] += error(y);
}

/// What a frame's filter is measured against: the source's luma (coded
/// size), and whether the strengths beside the frame's are tried (where
/// the offsets are chosen).
#[derive(Clone, Copy)]
pub(crate) struct DeblockMeasure<'s> {
    pub source: &'s Plane,
    pub try_strengths: bool,
}

/// What [`filter_row_trying`] sums, and a plane of the frame's size to
/// filter copies in (of which a tried row's lines are written before they
/// are read: taken from the spare planes and given back, a new 1 MB
/// plane a 720p frame otherwise).
pub(crate) struct StrengthTrial {
    /// (`None` only once given back.)
    scratch: Option<Plane>,
    tried: [u64; 3],
}

impl StrengthTrial {
    /// A trial on a luma plane like `y` (coded size).
    pub(crate) fn like(y: &Plane) -> StrengthTrial {
        let scratch = crate::spare_planes::take(y.width(), y.height(), Plane::DEFAULT_PAD)
            .expect("a plane's size is a plane's");
        StrengthTrial {
            scratch: Some(scratch),
            tried: [0; 3],
        }
    }

    /// The errors summed so far.
    pub(crate) fn tried(&self) -> [u64; 3] {
        self.tried
    }
}

impl Drop for StrengthTrial {
    fn drop(&mut self) {
        crate::spare_planes::give_back(self.scratch.take());
    }
}

/// [`DeblockEffect`] of one frame, measured as its rows are filtered: each
/// macroblock row before its own filter (no filter of a row above reaches
/// it) and once final (after the filter of the row below, which changes
/// its last three lines, or at the frame's end).
#[derive(Debug, Default)]
pub(crate) struct DeblockMeter {
    effect: DeblockEffect,
    /// Macroblock rows measured after the filter: those above this one.
    final_rows: usize,
}

impl DeblockMeter {
    /// Macroblock rows `rows` of `recon` about to be filtered for the
    /// first time, against `source` (luma, coded size).
    pub(crate) fn before(&mut self, source: &Plane, recon: &Plane, rows: std::ops::Range<usize>) {
        self.effect.before += measured_sse(source, recon, rows);
    }

    /// Macroblock rows of `recon` above `upto` final.
    pub(crate) fn after(&mut self, source: &Plane, recon: &Plane, upto: usize) {
        if upto > self.final_rows {
            self.effect.after += measured_sse(source, recon, self.final_rows..upto);
            self.final_rows = upto;
        }
    }

    pub(crate) fn effect(&self) -> DeblockEffect {
        self.effect
    }
}

/// The effect of deblocking `recon` whole with `d` (in place, a row at a
/// time, other strengths tried where `m` says), against `m`'s source:
/// what the rows' filter measures.
pub(crate) fn measured_around(m: DeblockMeasure<'_>, recon: &mut Plane, d: &FrameDeblocker) -> DeblockEffect {
    let rows = recon.height() / MB;
    let mut meter = DeblockMeter::default();
    let mut trial = m.try_strengths.then(|| StrengthTrial::like(recon));
    meter.before(m.source, recon, 0..rows);
    for k in 0..rows {
        filter_row_trying(d, recon, k, trial.as_mut().map(|t| (m.source, t)));
    }
    meter.after(m.source, recon, rows);
    DeblockEffect {
        tried: trial.map_or([0; 3], |t| t.tried),
        ..meter.effect()
    }
}

/// The squared error of `recon` against `source` on the measured rows
/// among macroblock rows `rows` (luma, coded size).
fn measured_sse(source: &Plane, recon: &Plane, rows: std::ops::Range<usize>) -> u64 {
    rows.filter(|r| r % MEASURED_ROW_EVERY == 0)
        .flat_map(|r| r * MB..(r + 1) * MB)
        .map(|y| squared_difference_sum(source.row(y), recon.row(y)))
        .sum()
}

/// Whether the frames to come are deblocked, from the effect of the
/// filter on the frames before.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DeblockChooser {
    /// The after/before ratio, averaged with weight 1/2 on the latest
    /// frame measured; none before the first (the filter on).
    ratio: Option<f64>,
    /// Both offsets of the frames to come.
    offset: i8,
    /// The errors one step weaker and stronger over the frame's own,
    /// averaged as `ratio` since the offset last moved.
    either_side: Option<[f64; 2]>,
}

impl DeblockChooser {
    /// Whether the P frame `index` is deblocked.
    pub(crate) fn deblocks(&self, index: usize) -> bool {
        self.ratio.is_none_or(|r| r <= OFF_ABOVE) || index % PROBE_EVERY == 0
    }

    /// The offsets of the frames to come.
    pub(crate) fn offsets(&self) -> DeblockOffsets {
        DeblockOffsets::both(self.offset)
    }

    /// Learns from a frame's effect (none where it was not deblocked).
    pub(crate) fn learn(&mut self, effect: Option<DeblockEffect>) {
        let Some(e) = effect.filter(|e| e.before > 0) else {
            return;
        };
        let latest = e.after as f64 / e.before as f64;
        self.ratio = Some(self.ratio.map_or(latest, |r| 0.5 * (r + latest)));
        self.learn_offset(e.tried);
    }

    /// One step toward the side whose error stays below the frame's own,
    /// averaged over the frames since the last step.
    fn learn_offset(&mut self, [weaker, own, stronger]: [u64; 3]) {
        if own == 0 {
            return;
        }
        let latest = [weaker as f64 / own as f64, stronger as f64 / own as f64];
        let avg = self
            .either_side
            .map_or(latest, |a| [0.5 * (a[0] + latest[0]), 0.5 * (a[1] + latest[1])]);
        self.either_side = Some(avg);
        let step = if avg[1] < 1.0 - STEP_MARGIN && avg[1] <= avg[0] {
            OFFSET_STEP
        } else if avg[0] < 1.0 - STEP_MARGIN {
            -OFFSET_STEP
        } else {
            return;
        };
        let next = (self.offset + step).clamp(-MAX_CHOSEN_OFFSET, MAX_CHOSEN_OFFSET);
        if next != self.offset {
            self.offset = next;
            self.either_side = None;
        }
    }
}

/// How much lower than the frame's own error a side's must be for the
/// offsets to move toward it. Medium on the 32 sequences, every other row
/// tried: 0.002 -0.16 %; 0.005 toward stronger and 0.002 toward weaker
/// -0.09 %, 0.005 both ways -0.07 %, 0.01 both ways -0.05 %; 0 toward
/// stronger and 0.01 toward weaker +0.62 % (drifting up on most
/// sequences: the filter one step stronger than the error wants costs
/// the frames after it too).
const STEP_MARGIN: f64 = 0.002;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::mv::Mv;
    use crate::codec::syntax::{EntropyState, MotionTool, SequenceHeader, Vui};
    use crate::codec::weight::Weights;
    use crate::codec::Frame;
    use crate::encode::config::ModeDecision;
    use crate::encode::macroblock::MbCoder;
    use crate::encode::motion::{BlockMotion, FrameMotion};
    use crate::encode::slice::{code_inter, CodedFrame, InterInputs};

    /// A 64x64 P frame (four macroblock rows) of a smooth texture moved
    /// by (6, 6) from its reference, coded at QP 38 with every
    /// macroblock's vector zero (so all intra, every edge filtered),
    /// deblocked or not, its filter's effect measured, on a pool of
    /// `threads`.
    fn coded(deblock: bool, threads: usize) -> (Frame, CodedFrame) {
        let texture = |dx: usize| {
            let mut f = Frame::filled(64, 64, 0, 128, 128).unwrap();
            *f.plane_mut(0) = Plane::from_fn(64, 64, |x, y| {
                let (x, y) = ((x + dx) as f64, (y + dx) as f64);
                (128.0 + 50.0 * (x * 0.21).sin() * (y * 0.17).cos()) as u8
            })
            .unwrap();
            f.extend_borders();
            f
        };
        let (src, reference) = (texture(6), texture(0));
        let seq = SequenceHeader {
            width: 64,
            height: 64,
            fps_num: 25,
            fps_den: 1,
            frame_count: 0,
            vui: Vui::default(),
            max_refs: 1,
        };
        let pricing = EntropyState::new();
        let inputs = InterInputs {
            references: vec![&reference],
            motion: FrameMotion::Vectors(BlockMotion {
                mb: vec![Mv::ZERO; 16],
                blocks: None,
                halfpel: None,
                lazy: None,
            }),
            tool: MotionTool::Block,
            decision: ModeDecision::Full,
            deblock,
            deblock_offsets: crate::codec::deblock::DeblockOffsets::ZERO,
            measure_deblock: true,
            try_deblock_offsets: true,
            weights: Weights::NONE,
            luma_filter: crate::codec::interp::LumaFilter::Sharp,
            partitions: false,
            subpel_rd: false,
            split_margin: false,
            split_search_margin: false,
            chroma_me: false,
            adaptive_pricing: true,
            fast_pskip: false,
            early_pskip: false,
            pricing: &pricing,
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let coder = MbCoder::new(38, 1.0, false);
        let recon = Frame::new(64, 64).unwrap();
        let frame = pool.install(|| {
            code_inter(
                &seq,
                &coder,
                &src,
                inputs,
                (&mut EntropyState::new(), recon),
                |_, _| (),
            )
            .unwrap()
        });
        (src, frame)
    }

    #[test]
    fn the_effect_is_the_measured_rows_error_before_and_after_the_filter_on_any_number_of_workers() {
        // One thread: one worker filters each row behind its decisions;
        // three: three workers, the filter over the whole frame at its end.
        let (src, plain) = coded(false, 1);
        assert_eq!(plain.deblock_effect, None, "not deblocked: nothing measured");
        let before = measured_sse(src.y(), plain.recon.y(), 0..4);
        let mut tried = Vec::new();
        for threads in [1, 3] {
            let (_, deblocked) = coded(true, threads);
            let after = measured_sse(src.y(), deblocked.recon.y(), 0..4);
            assert_ne!(before, after, "the filter changed nothing to measure");
            let e = deblocked.deblock_effect.expect("measured");
            assert_eq!((e.before, e.after), (before, after), "{threads} threads");
            tried.push(e.tried);
        }
        // The strengths tried alike either way (the next frames' offsets
        // follow from them), and each moved the error.
        assert_eq!(tried[0], tried[1]);
        let [weaker, own, stronger] = tried[0];
        assert!(weaker != own && stronger != own, "{:?}", tried[0]);
    }

    #[test]
    fn the_filter_goes_off_where_it_adds_error_and_probes_while_off() {
        let mut chooser = DeblockChooser::default();
        assert!((0..20).all(|i| chooser.deblocks(i)), "on until measured");
        chooser.learn(Some(DeblockEffect {
            before: 1000,
            after: 1300,
            ..DeblockEffect::default()
        }));
        let probes: Vec<usize> = (1..40).filter(|&i| chooser.deblocks(i)).collect();
        assert_eq!(probes, [16, 32]);
        // Not deblocked: nothing learnt.
        chooser.learn(None);
        assert!(!chooser.deblocks(9));
        // Two frames that the filter helps bring it back: (1.3 + 0.8) / 2
        // is still above 1, (1.05 + 0.8) / 2 is not.
        chooser.learn(Some(DeblockEffect {
            before: 1000,
            after: 800,
            ..DeblockEffect::default()
        }));
        assert!(!chooser.deblocks(9));
        chooser.learn(Some(DeblockEffect {
            before: 1000,
            after: 800,
            ..DeblockEffect::default()
        }));
        assert!(chooser.deblocks(9));
    }

    #[test]
    fn the_offsets_step_toward_the_side_that_lowers_the_error() {
        let tried = |weaker, stronger| {
            Some(DeblockEffect {
                before: 1000,
                after: 900,
                tried: [weaker, 1000, stronger],
            })
        };
        let mut chooser = DeblockChooser::default();
        assert_eq!(chooser.offsets(), DeblockOffsets::ZERO);
        // Within the margin either way: no step.
        chooser.learn(tried(999, 1001));
        assert_eq!(chooser.offsets(), DeblockOffsets::ZERO);
        // Stronger lowers the error: a step up each frame, to the limit.
        for want in [2, 4, 6, 8, 8] {
            chooser.learn(tried(1010, 980));
            assert_eq!(chooser.offsets(), DeblockOffsets::both(want));
        }
        // Then weaker: down again. A step resets the average, so one
        // frame's evidence moves it.
        chooser.learn(tried(950, 1020));
        assert_eq!(chooser.offsets(), DeblockOffsets::both(6));
        // Both lower: the lower side.
        chooser.learn(tried(970, 990));
        assert_eq!(chooser.offsets(), DeblockOffsets::both(4));
        // A frame not deblocked, or not measured, teaches nothing.
        chooser.learn(None);
        chooser.learn(Some(DeblockEffect::default()));
        assert_eq!(chooser.offsets(), DeblockOffsets::both(4));
        // The strengths tried lie one step either side, within H.264's
        // range.
        let at = |alpha, beta| DeblockStrength {
            qp: 30,
            offsets: DeblockOffsets { alpha, beta },
        };
        assert_eq!(tried_strengths(at(0, 11)), [at(-2, 9), at(0, 11), at(2, 12)]);
    }

    #[test]
    fn rows_measured_before_and_once_final_count_each_line_once() {
        let source = Plane::from_fn(32, 64, |x, y| (x + y) as u8).unwrap();
        let before = Plane::from_fn(32, 64, |x, y| (x + y + 2) as u8).unwrap();
        let after = Plane::from_fn(32, 64, |x, y| (x + y + 1) as u8).unwrap();
        let mut meter = DeblockMeter::default();
        for r in 0..4 {
            meter.before(&source, &before, r..r + 1);
            meter.after(&source, &after, r.saturating_sub(1));
        }
        meter.after(&source, &after, 4);
        // Rows 0 and 2 measured: 2 x 16 lines of 32 samples.
        let lines = (2 * MB * 32) as u64;
        assert_eq!(
            meter.effect(),
            DeblockEffect {
                before: 4 * lines,
                after: lines,
                tried: [0; 3]
            }
        );
    }
}
