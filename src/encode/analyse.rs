//! The mode decision of a macroblock (x264's `analyse.c`): skip first,
//! then the 16x16 inter candidates, the partitions, intra (16x16, 8x8 and
//! 4x4 blocks), sub-pel RD refinement and the transform size; each kind of
//! candidate one method of the frame's [`InterFrameCoder`], the best by
//! J = SSD + lambda * bits kept in the macroblock's [`MbAnalysis`]. The
//! I frame's choice is [`intra_against`] without an inter bound.

use super::rate;
use super::rdo::{self, reference_bits, RD_MARGIN};
use super::refs_choice::OlderGain;
use super::slice::InterFrameCoder;
use crate::codec::bits::ue_len;
use crate::codec::consts::MB;
use crate::codec::intra::IntraMode;
use crate::codec::recon::IntraEdges;
use crate::codec::syntax::intra_mode_allowed;
use crate::me::dsp::pixel;
use crate::me::{ChromaBlock, Metric};

use super::config::ModeDecision;
use super::intra4x4::{self, Intra4x4Luma, IntraBlockSearch};
use super::intra8x8::Intra8x8Luma;
use super::macroblock::{prefetch_ahead, prefetch_ahead_displaced, Coded, MbCoder, MbSource};
use super::partition::{PartitionSearch, SatdCache, ROUGH_SPLIT_MARGIN};
use crate::codec::intra4x4::LumaIntra;
use crate::codec::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::codec::mv::mvd_bits;
use crate::codec::mv::Mv;
use crate::codec::mvpred::{mv_prediction, mv_prediction_into, walk_partitions};
use crate::codec::partition::{MbVectors, Part, RefMv, Split};
use crate::codec::recon::{predict_inter_blocks_into, predict_inter_into, MbSamples};
use crate::codec::residual::{MbResidual, ResidualCoder, ResidualSyntax};
use crate::codec::syntax::{mb_mode, MbKind, MotionTool};
use crate::codec::transform::Block4;
use crate::codec::Frame;
use crate::me::search::Neighbours;
use crate::me::SQUARE;
use std::cell::RefCell;

/// A 16x16 inter candidate of the mode decision.
pub(super) struct InterCandidate {
    pub(super) mv: RefMv,
    /// The predicted vector into its reference.
    pub(super) mvp: Mv,
    pub(super) satd: u32,
    /// SATD + sqrt(lambda) * (vector and reference index bits).
    pub(super) estimate: f64,
    /// Where its prediction is: a slot of [`MbAnalysis::preds`]; `None`
    /// for the predicted vector's, which is the skip's (read from the
    /// analysis while skip is its best: [`InterFrameCoder::candidate_pred`]).
    pub(super) pred: Option<usize>,
}

/// Where a trial's prediction comes from ([`InterFrameCoder::code_trial`]).
#[derive(Debug, Clone, Copy)]
pub(super) enum TrialPred {
    /// A candidate's slot of [`MbAnalysis::preds`].
    Slot(usize),
    /// The skip's (the best while skip is).
    Skip,
    /// The trial record's own, made there already.
    InPlace,
}

/// What one macroblock's analysis reads besides the frame's inputs: the
/// decisions before it and the coders that price it. In raster order these
/// are the frame's own; on a wavefront each row's worker holds copies
/// kept up to date for the neighbours it reads.
pub(super) struct MbEnv<'e> {
    /// The vectors of the macroblocks before this one in raster order (its
    /// left, top-left, top and top-right neighbours current).
    pub(super) decided: &'e [MbVectors],
    pub(super) modes: &'e ModeCoder,
    pub(super) residual: &'e ResidualCoder,
    /// The reconstruction, current in the neighbours intra prediction reads.
    pub(super) recon: &'e Frame,
    /// The partition search's cache (emptied per macroblock).
    pub(super) satd8: &'e RefCell<SatdCache>,
}

/// How many of macroblock (x, y)'s left and upper neighbours (in
/// `decided`, raster order over `cols` columns) predicted a block from a
/// reference other than the first.
fn older_reference_neighbours(decided: &[MbVectors], (x, y, cols): (usize, usize, usize)) -> usize {
    let index = y * cols + x;
    let left = (x > 0).then(|| index - 1);
    let up = (y > 0).then(|| index - cols);
    [left, up]
        .into_iter()
        .flatten()
        .filter(|&i| decided[i].iter().flatten().any(|m| m.ref_idx > 0))
        .count()
}

/// Luma SATD of a prediction.
pub(super) fn luma_satd(src: &MbSource, pred: &MbSamples) -> u32 {
    crate::me::Metric::Satd.cost(&src.luma, 16, &pred.luma, 16, 16, 16)
}

/// The best intra choice of macroblock `at` by SSD + lambda * bits: the
/// 16x16 luma mode of least SATD, and the 8x8 and 4x4 modes of
/// [`IntraBlockSearch`], each with the chroma mode of least SAD, written
/// into `out` (a record kept from macroblock to macroblock: coded in
/// place, the choice and its samples were copied four or five times).
/// `coders` are the frame's as they stand before the macroblock. With
/// `bound` (inter's, [`InterBound`]), each luma candidate is coded only
/// when its estimate is below inter's times the bound's coding margin.
/// Whether a candidate was coded (always without a bound), and whether
/// the 16x16 one was (its SATD below the bound's, with the margin).
pub(super) fn intra_against(
    coder: &MbCoder,
    s: &MbSource,
    recon: &Frame,
    at: (usize, usize),
    coders: (&ModeCoder, &ResidualCoder),
    bound: Option<InterBound>,
    out: &mut Choice,
) -> (bool, bool) {
    let plane_above = bound.map_or(u32::MAX, |b| {
        (b.plane_margin * f64::from(b.satd)).min(f64::from(u32::MAX)) as u32
    });
    let (luma, satd) = best_intra_16x16_under(coder, s, recon, at, &mut out.pred, plane_above);
    let whole = bound.is_none_or(|b| f64::from(satd) < b.coding_margin * f64::from(b.satd));
    // (Not called where no block size is tried: its two records, returned
    // empty, were a 1.3 KB copy a macroblock.)
    let (blocks8, blocks4) = if coder.intra8x8 || coder.intra4x4 {
        intra_block_searches(coder, s, recon, at, coders, bound, satd)
    } else {
        (None, None)
    };
    if !whole && blocks8.is_none() && blocks4.is_none() {
        return (false, false);
    }
    let chroma = best_intra_chroma(coder, s, recon, at, &mut out.pred);
    let coding = IntraCoding {
        coder,
        s,
        at,
        coders,
        inter_frame: bound.is_some(),
        chroma,
        // The chroma's levels are the same whatever the luma: found once.
        chroma_levels: coder.intra_chroma_levels(s, &out.pred, coders.1),
    };
    if whole {
        // Into the record's own levels where it has them (a new record is
        // a zeroed allocation).
        let levels = out.residual.get_or_insert_with(Box::default);
        coder.intra16x16_luma_into(s, &out.pred, coders.1, levels);
        coding.code_into(out, LumaIntra::Whole(luma), ResidualSyntax::Intra16x16);
    }
    // The block searches' luma levels are those [`MbCoder::code`] would
    // find against their predictions: kept, not found again (moved into
    // the candidate's record where they are, not through a list).
    let chroma_pred = out.pred.chroma;
    let mut coded = whole;
    let mut alternative = |luma_pred: &[u8; 256], luma, syntax, levels: Box<MbResidual>| {
        let mut alt = Choice::empty();
        alt.pred = MbSamples {
            luma: *luma_pred,
            chroma: chroma_pred,
        };
        alt.residual = Some(levels);
        coding.code_into(&mut alt, luma, syntax);
        if !coded || alt.cost < out.cost {
            *out = alt;
            coded = true;
        }
    };
    if let Some(b) = blocks8 {
        let mut levels = Box::<MbResidual>::default();
        levels.luma8 = b.levels;
        alternative(
            &b.pred,
            LumaIntra::Blocks8(b.modes),
            ResidualSyntax::Intra8x8,
            levels,
        );
    }
    if let Some(b) = blocks4 {
        let mut levels = Box::<MbResidual>::default();
        levels.luma = b.levels;
        alternative(&b.pred, LumaIntra::Blocks(b.modes), ResidualSyntax::Intra, levels);
    }
    (coded, whole)
}

/// The 8x8 and 4x4 intra block searches of [`intra_against`], given the
/// 16x16 candidate's SATD.
#[inline(always)]
fn intra_block_searches(
    coder: &MbCoder,
    s: &MbSource,
    recon: &Frame,
    at: (usize, usize),
    (modes, residual_coder): (&ModeCoder, &ResidualCoder),
    bound: Option<InterBound>,
    satd: u32,
) -> (Option<Intra8x8Luma>, Option<Intra4x4Luma>) {
    // In P frames, where inter mostly wins, blocks are searched only where
    // 16x16 intra is within the bound's margin of inter by SATD, and where
    // a block size is tried (ultrafast's and superfast's P frames: none).
    let hopeless = bound.is_some_and(|b| f64::from(satd) > b.search_margin * f64::from(b.satd));
    if !(coder.intra8x8 || coder.intra4x4) || hopeless {
        return (None, None);
    }
    let (around, mode_bits) = intra4x4::pricing(modes, at);
    let search = IntraBlockSearch {
        coder,
        recon,
        at,
        around,
        mode_bits,
        residual: residual_coder,
    };
    let estimate_bound = bound.map_or(f64::INFINITY, |b| b.coding_margin * b.estimate);
    let blocks8 = coder
        .intra8x8
        .then(|| search.run8(s, None, estimate_bound))
        .flatten();
    // The 4x4 search stops once it passes 10/8 of the least of the 16x16
    // SATD and the 8x8 estimate (x264's `i_satd_thresh` under RD mode
    // decision), and inter's estimate.
    let least = blocks8
        .as_ref()
        .map_or(f64::from(satd), |b| b.estimate.min(f64::from(satd)));
    let bound4 = estimate_bound.min(INTRA4_MARGIN * least);
    let blocks4 = coder.intra4x4.then(|| search.run(s, None, bound4)).flatten();
    (blocks8, blocks4)
}

/// What coding an intra candidate of one macroblock shares: the chroma's
/// mode and levels, the same for every luma choice.
struct IntraCoding<'a> {
    coder: &'a MbCoder,
    s: &'a MbSource,
    at: (usize, usize),
    coders: (&'a ModeCoder, &'a ResidualCoder),
    inter_frame: bool,
    chroma: IntraMode,
    chroma_levels: [[Block4; 4]; 2],
}

impl IntraCoding<'_> {
    /// The candidate of luma `luma` coded as `syntax` into `out`, whose
    /// prediction and luma levels are the candidate's.
    fn code_into(&self, out: &mut Choice, luma: LumaIntra, syntax: ResidualSyntax) {
        let (coder, (modes, residual_coder)) = (self.coder, self.coders);
        let (_, residual, samples) = out.records_over_pred();
        residual.chroma = self.chroma_levels;
        let (bits, ssd) =
            coder.reconstruct_in_place(self.s, residual, samples, (residual_coder, syntax), self.at);
        let mode = MbMode::Intra {
            luma,
            chroma: self.chroma,
        };
        let mode_bits = rdo::bits(rate::mode_cost(
            modes,
            self.at,
            self.inter_frame,
            VectorSyntax::None,
            &mode,
        ));
        out.cost = rdo::cost(coder.lambda, ssd, bits + mode_bits);
        out.residual_cost = rdo::cost(coder.lambda, ssd, bits);
        out.kind = MbKind::Intra {
            luma,
            chroma: self.chroma,
        };
    }
}

/// What intra must beat in a P frame: inter's least SATD and least
/// estimate (SATD + sqrt(lambda) * bits), how far above that SATD 16x16
/// intra's may be for the 8x8 and 4x4 searches to run, and how far above
/// inter's SATD and estimate an intra candidate's may be to be coded.
#[derive(Debug, Clone, Copy)]
pub(super) struct InterBound {
    pub satd: u32,
    pub estimate: f64,
    pub search_margin: f64,
    pub coding_margin: f64,
    /// How far above `satd` the best of the vertical, horizontal and DC
    /// predictions may be for the plane prediction to be tried.
    pub plane_margin: f64,
}

/// How far above inter's SATD and estimate the full decision codes an
/// intra candidate (x264's `intra_rd` under RD mode decision: within 5/4
/// of inter's SATD); the fast decision codes it only below inter's, where
/// a 16x16 intra coded means inter is not. Against 1.0
/// (`benches/pair.py`, the 28 sequences and four kinds, 60 frames, one
/// run each): medium -0.56 % for 1.013x the wall time (cartoon_cif
/// -6.6 %, fish_1160 -4.1 %, ball_576 -2.1 %, diver_vga -2.0 %;
/// calais_214 and handheld_vga +1.5 %), fast -0.65 % for 1.021x, slow
/// -0.93 % for 1.013x the encoder's own time, slower -0.82 % for 1.00x;
/// 1.5 in medium -0.78 % for about 1.02x (beside a CI run).
const INTRA_CODING_MARGIN: f64 = 1.25;

/// How far above inter's SATD a P frame's 16x16 intra SATD may be for
/// the 8x8 and 4x4 searches to run (x264's fast-intra threshold). On the
/// synthetic development set 1.0 cost 0.4 % more bits than 1.25 for 7 %
/// less time; on the 28 sequences with real footage, 1.25 took 1.18 % off
/// medium's bits against 1.0 in the same time (cockatoo_720p -5.2 %,
/// diver_vga -4.7 %: hand-held footage, where motion blur makes intra
/// pay), and 2.0 1.58 % for 6.5 % more time.
const INTRA_SEARCH_MARGIN: f64 = 1.25;

/// [`INTRA_SEARCH_MARGIN`] beside an intra neighbour (left or above),
/// where intra is likely: x264 searches every intra size there, and
/// elsewhere where 16x16 intra is within twice inter's SATD; mocomp takes
/// that twice beside the neighbour, 1.25 elsewhere. Against
/// 1.25 there (`benches/pair.py`, the 28 sequences, one run): medium
/// -0.32 % in the same time (cockatoo_720p -2.6 %, fish_1160 -2.4 %,
/// band_qcif -1.3 %, coin_568 -1.2 %; ball_576 +0.6 %, garden_720p
/// +0.4 %); ultrafast 0.00 % on the mean (its streams may differ).
const INTRA_LIKELY_SEARCH_MARGIN: f64 = 2.0;

/// How far above inter's SATD, times the coding margin, the best of a
/// P frame's vertical, horizontal and DC 16x16 predictions may be for
/// the plane prediction to be tried, away from intra neighbours (x264's
/// fast intra in P frames: twice inter's SATD from subme 5, where it
/// tries plane only under that). Against the plane always tried
/// (`benches/pair.py`, the 28 sequences and the four kinds, 60 frames,
/// one run each): ultrafast +0.03 % for 0.986x the encoder's time
/// (0.969x the wall time), medium -0.04 % for 1.003x (its margin is
/// 2.5 times inter's SATD).
const PLANE_MARGIN: f64 = 2.0;

/// The most squared luma error, in lambdas, a skip taken before the
/// search may leave in the full decision, and beside one skipped
/// neighbour in the fast one. A still background skipped
/// frame after frame keeps the error it once had, and no level the skip's
/// residual would code corrects it; x264's medium, which never skips
/// before its search, refreshes such blocks with intra or a residual.
/// Against no limit (`benches/pair.py`, the 28 sequences, one run each):
/// 16 lambdas took medium -2.01 % for 1.13x its encode time (fish_1160
/// -11.9 %, dog_1080p -6.2 %, ball_576 -5.8 %), 32 -1.32 % for 1.05x, 8
/// -2.14 % for 1.22x; slow -2.10 % for 1.17x. Against 16, 24 gave medium
/// +0.50 % for 0.955x its time (fish_1160 +3.4 %), 32 +0.76 % for
/// 0.926x: 24 keeps medium's time under x264 medium's with a margin on
/// the real clips (0.95x of it there with 16). In ultrafast (the fast
/// decision) 16 gave -1.96 % for 1.10x, 32 -1.09 % for 1.03x: a dearer
/// trade than its others (half-pel instead of quarter-pel, +8 % for
/// 0.95x), not taken.
const EARLY_SKIP_MAX_SSE: f64 = 24.0;

/// How far above the lowest estimate (SATD + sqrt(lambda) * vector bits)
/// a 16x16 inter candidate of the full decision may be and still be
/// coded. x264 codes one 16x16 vector a reference, the best of its search;
/// mocomp took its 5/4 threshold of RD mode decision (`RD_MARGIN`), as
/// good on the synthetic development set's mean for 2 % fewer
/// instructions than coding all (pan_cif, callgrind). Against 5/4
/// (`benches/pair.py`, the 28 sequences and the four kinds, 60 frames,
/// one run each): medium -0.13 % for 0.956x its wall time (fish_1160
/// -2.2 %; light_cif +1.4 %), 1.0 (the best alone) +0.54 % for 0.919x;
/// fast -0.03 % for 0.993x, slow +0.23 % for 0.969x, slower +0.26 % for
/// 0.966x.
const CANDIDATE_MARGIN: f64 = 1.1;

/// How far above the 4x4 coding's cost the plainly quantised 8x8
/// alternative of an inter macroblock may come for the 8x8 transform's
/// RDOQ to be tried ([`InterFrameCoder::analyse_transform`]). Against
/// RDOQ on every alternative (`benches/pair.py`, the 28 sequences and the
/// four kinds, 60 frames, one run each): medium +0.15 % for 0.967x its
/// wall time (dark_cif +2.8 %, cuts_cif -1.3 %), 1.05 +0.02 % for
/// 0.987x, without the 8x8 alternative +2.33 % for 0.926x; slow +0.07 %
/// for 0.961x, slower -0.24 % for 0.989x.
const LUMA8_RDOQ_MARGIN: f64 = 1.0;

/// How far above the 16x16 and 8x8 estimates the 4x4 search may run
/// before it stops (x264's 10/8).
const INTRA4_MARGIN: f64 = 1.25;

/// One way to code a macroblock, with its cost.
pub(super) struct Choice {
    pub(super) cost: f64,
    /// The part of `cost` the residual accounts for (its SSD + lambda *
    /// bits; 0 for skip).
    pub(super) residual_cost: f64,
    pub(super) kind: MbKind,
    pub(super) pred: MbSamples,
    pub(super) residual: Option<Box<MbResidual>>,
    /// The reconstruction it gives: `None` for the prediction itself
    /// (skip: not a copy of it).
    pub(super) samples: Option<MbSamples>,
}

impl Choice {
    /// A record to be written (its content: nothing meaningful).
    fn empty() -> Choice {
        Choice {
            cost: f64::INFINITY,
            residual_cost: 0.0,
            kind: MbKind::Skip,
            pred: MbSamples::default(),
            residual: None,
            samples: None,
        }
    }

    /// Its prediction, its levels' record (a new one where it has none)
    /// and its samples set to the prediction, for a residual to be coded
    /// and added over it.
    fn records_over_pred(&mut self) -> (&MbSamples, &mut MbResidual, &mut MbSamples) {
        let Choice {
            pred,
            residual,
            samples,
            ..
        } = self;
        if let Some(samples) = samples {
            samples.clone_from(pred);
        }
        let samples = samples.get_or_insert_with(|| pred.clone());
        (pred, residual.get_or_insert_with(Box::default), samples)
    }

    /// The reconstruction the choice gives.
    pub(super) fn reconstruction(&self) -> &MbSamples {
        self.samples.as_ref().unwrap_or(&self.pred)
    }
}

/// One macroblock under analysis: its source, its predicted vector and the
/// best choice so far (x264's per-macroblock analysis context).
pub(super) struct MbAnalysis {
    pub(super) index: usize,
    pub(super) mb_x: usize,
    pub(super) mb_y: usize,
    pub(super) source: MbSource,
    pub(super) mvp: Mv,
    /// The best choice so far: skip, predicted at `mvp`, until another
    /// is considered ([`MbAnalysis::skip_pred`]).
    pub(super) best: Box<Choice>,
    /// Where an inter choice is coded before it is weighed against the
    /// best ([`MbAnalysis::consider_trial`]): built in place and swapped
    /// with the best by pointer, not returned and moved (the 850-byte
    /// choice was copied twice a coded candidate).
    pub(super) trial: Box<Choice>,
    /// Whether any choice but skip can win (see [`InterFrameCoder::analyse_skip`]).
    pub(super) exhaustive: bool,
    /// The skip prediction's squared luma error (the frame's prediction
    /// PSNR takes it where skip wins, not measured again).
    pub(super) skip_luma_sse: u64,
    /// Whether skipping loses nothing ([`InterFrameCoder::skip_loses_nothing`]),
    /// once asked: the checks before and after the search ask it of the
    /// same prediction.
    pub(super) skip_verdict: Option<bool>,
    /// Motion analysis' vector (the predicted one until it is searched).
    pub(super) searched: Mv,
    /// The lowest luma SATD of the inter candidates, for intra's early out.
    pub(super) inter_satd: u32,
    /// The lowest SATD + sqrt(lambda) * vector bits of the 16x16 inter
    /// candidates, which a split must beat to be coded.
    pub(super) inter_estimate: f64,
    /// What the older references' candidates saved on the first's
    /// ([`super::refs_choice`]).
    pub(super) older_gain: OlderGain,
    /// The inter candidates' predictions, made in place (slots kept from
    /// macroblock to macroblock: a prediction returned by value was
    /// copied three or four times before it was coded).
    pub(super) preds: Vec<MbSamples>,
    /// The luma differences coding a trial uses (kept: cleared for every
    /// candidate, they were a kilobyte's memset).
    pub(super) diffs: [Block4; 16],
}

impl MbAnalysis {
    /// A record for [`InterFrameCoder::analyse_skip`] to fill (its
    /// content until then: nothing meaningful).
    pub(super) fn empty() -> MbAnalysis {
        MbAnalysis {
            index: 0,
            mb_x: 0,
            mb_y: 0,
            source: MbSource {
                luma: [0; 256],
                chroma: [[0; 64]; 2],
            },
            mvp: Mv::ZERO,
            best: Box::new(Choice::empty()),
            trial: Box::new(Choice::empty()),
            exhaustive: false,
            skip_luma_sse: 0,
            skip_verdict: None,
            searched: Mv::ZERO,
            inter_satd: u32::MAX,
            inter_estimate: f64::INFINITY,
            older_gain: OlderGain::default(),
            preds: Vec::new(),
            diffs: [[[0; 4]; 4]; 16],
        }
    }

    /// Keeps the trial choice if it costs less than the best so far.
    pub(super) fn consider_trial(&mut self) {
        if self.trial.cost < self.best.cost {
            std::mem::swap(&mut self.best, &mut self.trial);
        }
    }

    /// The skip prediction (the inter prediction at `mvp`) while skip is
    /// the best choice, as it is until another is considered: kept once,
    /// as the choice's (a copy of 384 bytes a macroblock fewer).
    pub(super) fn skip_pred(&self) -> Option<&MbSamples> {
        matches!(self.best.kind, MbKind::Skip).then_some(&self.best.pred)
    }
}

impl InterFrameCoder<'_, '_> {
    /// Decides macroblock `mb` (made by [`Self::analyse_skip`]) beyond
    /// skip: inter and intra where they can win. It works on the record in
    /// place: returned by value, the 1.7 KB record was copied out twice a
    /// macroblock.
    pub(super) fn analyse_beyond_skip(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) {
        if !mb.exhaustive || self.skips_before_search(mb, env) {
            return;
        }
        mb.searched = self.searched_vector(mb, env);
        if self.skips_early(mb, env) {
            return;
        }
        let candidates = self.inter_candidates(mb, env);
        if self.decision == ModeDecision::Fast {
            // Intra first, inter coded only where intra's 16x16 SATD does
            // not beat it (see [`ModeDecision::Fast`]).
            if !self.analyse_intra(mb, env) {
                self.code_inter(mb, env, candidates);
            }
            self.analyse_split(mb, env);
        } else {
            self.code_inter(mb, env, candidates);
            self.analyse_split(mb, env);
            self.analyse_intra(mb, env);
        }
        self.analyse_subpel_rd(mb, env);
        self.analyse_transform(mb, env);
    }

    /// The macroblock's searched vector: motion analysis', or, when the
    /// decision searches ([`super::motion::LazySearch`]), found now from
    /// the predicted vector, the decided left, top and top-right vectors
    /// and the previous frame's co-located, right and lower ones (EPZS's
    /// candidates, x264's from the decided neighbours).
    fn searched_vector(&self, mb: &MbAnalysis, env: &MbEnv<'_>) -> Mv {
        let Some(lazy) = &self.lazy else {
            return self.searched[mb.index];
        };
        let (cols, x, y) = (self.seq.mb_cols(), mb.mb_x, mb.mb_y);
        let decided = |i: usize| env.decided[i][0].filter(|m| m.ref_idx == 0).map(|m| m.mv);
        let prior = |x: usize, y: usize| {
            let p = lazy.prior.as_ref()?;
            (x < p.cols() && y < p.rows()).then(|| p.vector(x, y))
        };
        let candidates = Neighbours::list(
            mb.mvp,
            [
                (x > 0).then(|| decided(mb.index - 1)).flatten(),
                (y > 0).then(|| decided(mb.index - cols)).flatten(),
                (y > 0 && x + 1 < cols)
                    .then(|| decided(mb.index - cols + 1))
                    .flatten(),
                prior(x, y),
                prior(x + 1, y),
                prior(x, y + 1),
            ]
            .into_iter()
            .flatten(),
        );
        let (src, reference) = (self.src.y(), self.references[0]);
        let chroma = self.chroma_block(&mb.source, reference);
        lazy.search
            .search((src, reference.y()), (x, y), mb.mvp, &candidates, chroma)
            .mv
    }

    /// x264's fast P-skip after its 16x16 search: skip is taken before any
    /// other mode is tried when motion analysis found the predicted vector
    /// and its prediction would code no level. On the development set's
    /// mean (ultrafast; medium): +0.7 % bits for 7 % less time; +0.7 % for
    /// 13 %. Taking a vector within a quarter pel of the predicted one
    /// too, beside a skipped neighbour, cost the 28 sequences 0.32 % more
    /// in medium, 0.26 % in ultrafast and 0.27 % in slow for no time this
    /// machine could show (`benches/pair.py`, one run each); any vector
    /// beside a skipped neighbour (x264's test before its search, below
    /// subme 3): +4.7 % for 12 % (ultrafast).
    fn skips_early(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) -> bool {
        self.fast_pskip && mb.searched == mb.mvp && self.skip_loses_nothing_once(mb, env)
    }

    /// x264's fast P-skip below `--subme 3`, before the motion search:
    /// beside a skipped left or upper neighbour, where the skip would code
    /// no level. Between two skips the fast decision takes it whatever its
    /// error; beside one, and in the full decision, only where it leaves at
    /// most [`EARLY_SKIP_MAX_SSE`] lambdas of luma error. x264 probes
    /// beside any skipped neighbour of four, without a bound on the error:
    /// beside either of two, ultrafast took +2.6 % bits on the 28
    /// sequences' mean for 0.90x its time. Against both neighbours alone
    /// (the rule until 2026-12-06; `benches/pair.py`, the 28 at 60 frames):
    /// ultrafast +0.6 % for 0.92-0.94x its wall time (a bound of 8 lambdas
    /// beside one: +0.0 % for 0.95-0.98x, 64: +2.0 % for 0.91x), superfast
    /// +0.7 % for 0.96x, veryfast +0.8 % for 0.96x, fast +0.7 % for 0.93x,
    /// medium +0.6 % for 0.92x, slow +1.0 % for 0.95x. Where the two
    /// neighbours' vectors also had to equal the predicted one (an earlier
    /// trial): medium +0.7 % for 0.90x, against +1.3 % for 0.82x.
    fn skips_before_search(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) -> bool {
        if !(self.fast_pskip && self.early_pskip) {
            return false;
        }
        let little_error = mb.skip_luma_sse as f64 <= EARLY_SKIP_MAX_SSE * self.coder.lambda;
        let beside = match env.modes.skipped_neighbours(mb.mb_x, mb.mb_y) {
            2 => self.decision == ModeDecision::Fast || little_error,
            1 => little_error,
            _ => false,
        };
        beside && self.skip_loses_nothing_once(mb, env)
    }

    /// [`InterFrameCoder::skip_loses_nothing`], found once a macroblock.
    fn skip_loses_nothing_once(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) -> bool {
        if let Some(verdict) = mb.skip_verdict {
            return verdict;
        }
        let verdict = self.skip_loses_nothing(mb, env);
        mb.skip_verdict = Some(verdict);
        verdict
    }

    /// The macroblock's chroma and `reference`'s, for the search's
    /// sub-pel cost where chroma motion estimation is on.
    fn chroma_block<'c>(&self, source: &'c MbSource, reference: &'c Frame) -> Option<ChromaBlock<'c>> {
        self.chroma_me.then(|| ChromaBlock {
            source: &source.chroma,
            reference: [reference.plane(1), reference.plane(2)],
        })
    }

    /// Whether skipping loses nothing another mode would code: its
    /// prediction codes no level, and beside an intra neighbour, or one
    /// that predicted from an older reference, intra's 16x16 prediction
    /// is no closer.
    fn skip_loses_nothing(&self, mb: &MbAnalysis, env: &MbEnv<'_>) -> bool {
        let Some(skip_pred) = mb.skip_pred() else {
            return false;
        };
        if !self.coder.codes_nothing(&mb.source, skip_pred) {
            return false;
        }
        // Beside an intra neighbour, intra may win where the skip codes
        // nothing (rippling water under a flickering light): skipped only
        // where intra's 16x16 prediction is no closer by SATD. Without
        // this, with the search in the decision, fish_1160 took 5.8 % more
        // bits in medium and 11 % in ultrafast. A neighbour that took an
        // older reference says the same of the first, which the skip reads:
        // with three references most of fish_1160's intra neighbours
        // became such, and slow took 8 % more bits than with one. Against
        // intra neighbours alone (`benches/pair.py`, the 28 sequences and
        // the four kinds, 60 frames): medium -0.27 % for 0.998x its wall
        // time (fish_1160 -4.9 %; cartoon_cif +1.0 %), slow -0.63 % for
        // 1.004x (fish_1160 -10.2 %, dark_cif -3.1 %; coin_568 +0.6 %),
        // slower -0.48 % for 0.999x (fish_1160 -8.9 %); one reference, the
        // same streams.
        let at = (mb.mb_x, mb.mb_y, self.seq.mb_cols());
        if env.modes.intra_neighbours(mb.mb_x, mb.mb_y) == 0
            && older_reference_neighbours(env.decided, at) == 0
        {
            return true;
        }
        let mut intra = MbSamples::default();
        let (_, intra_satd) =
            best_intra_16x16(self.coder, &mb.source, env.recon, (mb.mb_x, mb.mb_y), &mut intra);
        intra_satd >= luma_satd(&mb.source, skip_pred)
    }

    /// Sub-pel RD refinement (x264's `--subme 8`): when a 16x16 inter
    /// vector won, its eight quarter-pel neighbours are estimated (SATD +
    /// sqrt(lambda) * vector bits), and the two of lowest estimate within
    /// [`RD_MARGIN`] of the winner's are coded and weighed by RD.
    pub(super) fn analyse_subpel_rd(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) {
        let MbKind::Inter { mv } = mb.best.kind else {
            return;
        };
        if !self.subpel_rd || self.tool != MotionTool::Block {
            return;
        }
        let at = (mb.mb_x, mb.mb_y, self.seq.mb_cols());
        let mvp = mv_prediction_into(env.decided, at, mv.ref_idx);
        let (_, winner) = self.inter_estimate(&mb.source, &mb.best.pred, mv, mvp);
        // The eight quarter-pel steps around it.
        let steps: Vec<RefMv> = SQUARE
            .iter()
            .map(|&(dx, dy)| Mv::new(mv.mv.x + dx, mv.mv.y + dy))
            .filter(|m| m.in_range())
            .map(|m| RefMv::new(m, mv.ref_idx))
            .collect();
        let mut candidates: Vec<InterCandidate> = steps
            .into_iter()
            .enumerate()
            .map(|(slot, m)| {
                self.predict_candidate(mb, slot, m);
                self.inter_candidate(mb, m, mvp, Some(slot))
            })
            .filter(|c| c.estimate <= RD_MARGIN * winner)
            .collect();
        candidates.sort_by(|a, b| a.estimate.total_cmp(&b.estimate));
        for c in candidates.into_iter().take(2) {
            self.code_candidate(mb, env, c);
        }
    }

    /// An inter choice's luma in the 8x8 transform, kept when it costs
    /// less than in 4x4 ones.
    pub(super) fn analyse_transform(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) {
        let best = &mut mb.best;
        let (MbKind::Inter { .. } | MbKind::Split { .. }, Some(residual)) = (&best.kind, &best.residual)
        else {
            return;
        };
        let at = (mb.mb_x, mb.mb_y);
        let coded4 = (&**residual, best.reconstruction());
        let alternative =
            |coder: &MbCoder| coder.luma8_alternative(&mb.source, &best.pred, coded4, env.residual, at);
        // With RDOQ, the 8x8 levels are found plainly first, and RDOQ's
        // pass (the costly part) runs only where those come within
        // `LUMA8_RDOQ_MARGIN` of the 4x4 coding's cost: RDOQ seldom
        // brings a transform from above its rival to below (x264's
        // `--trellis 1` prices its transform choice without trellis too).
        if self.coder.rdoq {
            let plain = alternative(&self.coder.rdoq(false));
            let near = |c: &Coded| {
                rdo::cost(self.coder.lambda, c.ssd, c.bits) <= LUMA8_RDOQ_MARGIN * best.residual_cost
            };
            if !plain.as_ref().is_some_and(near) {
                return;
            }
        }
        let Some(c8) = alternative(self.coder) else {
            return;
        };
        let cost8 = rdo::cost(self.coder.lambda, c8.ssd, c8.bits);
        if cost8 < best.residual_cost {
            best.cost += cost8 - best.residual_cost;
            best.residual_cost = cost8;
            best.residual = Some(c8.residual);
            best.samples = Some(c8.samples);
        }
    }

    /// `mb` made the analysis context of macroblock `index`, with skip as
    /// its best. The record is the caller's, kept from macroblock to
    /// macroblock: the source and the skip prediction are written into it
    /// in place (returned by value, the 1.3 KB record and the samples in
    /// it were copied two or three times a macroblock).
    pub(super) fn analyse_skip(&self, index: usize, env: &MbEnv<'_>, mb: &mut MbAnalysis) {
        let cols = self.seq.mb_cols();
        let (mb_x, mb_y) = (index % cols, index / cols);
        mb.source.load_into(self.src, mb_x, mb_y);
        prefetch_ahead(self.src, mb_x, mb_y);
        let mvp = if self.syntax.any() {
            mv_prediction(env.decided, mb_x, mb_y, cols)
        } else {
            Mv::ZERO
        };
        prefetch_ahead_displaced(self.references[0], mb_x, mb_y, mvp);
        predict_inter_into(
            &self.inter_context(),
            mb_x,
            mb_y,
            RefMv::previous(mvp),
            &mut mb.best.pred,
        );
        let lambda = self.coder.lambda;
        let skip_bits = self.mode_bits_at(env, (mb_x, mb_y), &MbMode::Skip);
        let (skip_luma_sse, skip_chroma_sse) = mb.source.ssd_by_plane(&mb.best.pred);
        let cost = rdo::cost(lambda, skip_luma_sse + skip_chroma_sse, skip_bits);
        // Every other choice spends at least the flag saying it is not
        // skipped: when skip costs no more, nothing can beat it.
        let not_skipped = rdo::bits(rate::not_skipped_cost(env.modes, (mb_x, mb_y)));
        (mb.index, mb.mb_x, mb.mb_y, mb.mvp) = (index, mb_x, mb_y, mvp);
        let best = &mut mb.best;
        (best.cost, best.residual_cost, best.kind) = (cost, 0.0, MbKind::Skip);
        (best.samples, best.residual) = (None, None);
        mb.exhaustive = cost > rdo::cost(lambda, 0, not_skipped);
        mb.skip_luma_sse = skip_luma_sse;
        mb.skip_verdict = None;
        mb.searched = mvp;
        mb.inter_satd = u32::MAX;
        mb.inter_estimate = f64::INFINITY;
        mb.older_gain = OlderGain::default();
    }

    /// The 16x16 inter candidates, estimated, not yet coded: the predicted
    /// vector, the searched one and each older reference's searched
    /// vector. Sets the macroblock's least inter SATD and estimate.
    pub(super) fn inter_candidates(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) -> Vec<InterCandidate> {
        let searched = mb.searched;
        let searched_mv = (self.syntax.any() && searched != mb.mvp).then_some(searched);
        let mut candidates = Vec::with_capacity(1 + usize::from(self.syntax.refs()));
        let mut slots = 0..;
        for mv in std::iter::once(mb.mvp).chain(searched_mv) {
            let mv = RefMv::previous(mv);
            let pred = match mb.skip_pred() {
                Some(_) if mv.mv == mb.mvp => None,
                _ => slots.next(),
            };
            if let Some(slot) = pred {
                self.predict_candidate(mb, slot, mv);
            }
            candidates.push(self.inter_candidate(mb, mv, mb.mvp, pred));
        }
        for ref_idx in 1..self.syntax.refs() {
            let slot = slots.next().unwrap_or_default();
            candidates.extend(self.older_reference_candidate(mb, ref_idx, env, slot));
        }
        mb.inter_satd = candidates.iter().map(|c| c.satd).min().unwrap_or(u32::MAX);
        let least = |older: bool| {
            candidates
                .iter()
                .filter(|c| (c.mv.ref_idx > 0) == older)
                .map(|c| c.estimate)
                .fold(f64::INFINITY, f64::min)
        };
        let (first, older) = (least(false), least(true));
        mb.inter_estimate = first.min(older);
        if self.syntax.refs() > 1 {
            mb.older_gain = OlderGain::of(first, older);
        }
        candidates
    }

    /// The inter `candidates` ([`Self::inter_candidates`]) coded and
    /// weighed against the best choice so far: with
    /// [`ModeDecision::Fast`], only the one of lowest SATD + rate
    /// estimate; with the full decision, those within [`CANDIDATE_MARGIN`]
    /// of it.
    pub(super) fn code_inter(
        &self,
        mb: &mut MbAnalysis,
        env: &MbEnv<'_>,
        mut candidates: Vec<InterCandidate>,
    ) {
        if self.decision == ModeDecision::Fast {
            // The lowest SATD + sqrt(lambda) * vector bits is coded alone
            // (the first of equals; found, not sorted: a sort moved the
            // 416-byte candidates).
            let least = candidates
                .iter()
                .enumerate()
                .min_by(|(_, a), (_, b)| a.estimate.total_cmp(&b.estimate))
                .map(|(i, _)| i);
            if let Some(i) = least {
                self.code_candidate(mb, env, candidates.swap_remove(i));
            }
            return;
        }
        // Only the candidates whose estimate is near the best's are coded
        // (`CANDIDATE_MARGIN`).
        candidates.retain(|c| c.estimate <= CANDIDATE_MARGIN * mb.inter_estimate);
        for c in candidates {
            self.code_candidate(mb, env, c);
        }
    }

    /// Inter candidate `c` coded and weighed against the best choice so far.
    fn code_candidate(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>, c: InterCandidate) {
        let mode = MbMode::Inter {
            mvd: c.mv.mv - c.mvp,
            ref_idx: c.mv.ref_idx,
        };
        let kind = MbKind::Inter { mv: c.mv };
        if self.candidate_pred(mb, c.pred).is_none() {
            predict_inter_into(&self.inter_context(), mb.mb_x, mb.mb_y, c.mv, &mut mb.trial.pred);
            self.code_trial(mb, kind, &mode, TrialPred::InPlace, env);
        } else {
            let from = c.pred.map_or(TrialPred::Skip, TrialPred::Slot);
            self.code_trial(mb, kind, &mode, from, env);
        }
        mb.consider_trial();
    }

    /// A candidate's prediction, to be coded: its own slot's, or the
    /// skip's while skip is the best; `None` where another choice has
    /// taken the skip's place (as an intra block search can before the
    /// fast decision codes inter): to be predicted again.
    fn candidate_pred<'m>(&self, mb: &'m MbAnalysis, slot: Option<usize>) -> Option<&'m MbSamples> {
        match slot {
            Some(s) => mb.preds.get(s),
            None => mb.skip_pred(),
        }
    }

    /// The inter prediction at `mv` into slot `slot` of the analysis'
    /// candidate predictions.
    fn predict_candidate(&self, mb: &mut MbAnalysis, slot: usize, mv: RefMv) {
        if mb.preds.len() <= slot {
            mb.preds.resize_with(slot + 1, MbSamples::default);
        }
        predict_inter_into(&self.inter_context(), mb.mb_x, mb.mb_y, mv, &mut mb.preds[slot]);
    }

    /// A 16x16 inter candidate (its prediction in `slot`, or the skip's)
    /// with its SATD and its estimate ([`InterFrameCoder::inter_estimate`]).
    pub(super) fn inter_candidate(
        &self,
        mb: &MbAnalysis,
        mv: RefMv,
        mvp: Mv,
        slot: Option<usize>,
    ) -> InterCandidate {
        let samples = self
            .candidate_pred(mb, slot)
            .expect("a candidate's prediction or the skip's");
        let (satd, estimate) = self.inter_estimate(&mb.source, samples, mv, mvp);
        InterCandidate {
            mv,
            mvp,
            estimate,
            satd,
            pred: slot,
        }
    }

    /// The luma SATD of the prediction `samples` at `mv` and its estimate,
    /// SATD + sqrt(lambda) * (vector and reference index bits).
    fn inter_estimate(&self, src: &MbSource, samples: &MbSamples, mv: RefMv, mvp: Mv) -> (u32, f64) {
        let satd = luma_satd(src, samples);
        let bits = mvd_bits(mv.mv, mvp) + reference_bits(mv.ref_idx, self.syntax.refs());
        (satd, rdo::estimate(self.coder.lambda, satd, bits))
    }

    /// The 16x16 candidate into older reference `ref_idx`, searched now
    /// from its predicted vector, the vectors the left, top and top-right
    /// macroblocks found into it, the vector into the previous frame
    /// scaled by the distance and the previous frame's field scaled
    /// alike.
    pub(super) fn older_reference_candidate(
        &self,
        mb: &mut MbAnalysis,
        ref_idx: u8,
        env: &MbEnv<'_>,
        slot: usize,
    ) -> Option<InterCandidate> {
        let older = self.lazy.as_ref()?.older.get(usize::from(ref_idx) - 1)?;
        let (cols, x, y) = (self.seq.mb_cols(), mb.mb_x, mb.mb_y);
        let mvp = mv_prediction_into(env.decided, (x, y, cols), ref_idx);
        let prior = |x: usize, y: usize| {
            let p = older.prior.as_ref()?;
            (x < p.cols() && y < p.rows()).then(|| p.vector(x, y))
        };
        let scaled = Mv::new(
            mb.searched.x.saturating_mul(older.distance),
            mb.searched.y.saturating_mul(older.distance),
        );
        let found = &older.found;
        let candidates = Neighbours::list(
            mvp,
            [
                (x > 0).then(|| found.vector(x - 1, y)),
                (y > 0).then(|| found.vector(x, y - 1)),
                (y > 0 && x + 1 < cols).then(|| found.vector(x + 1, y - 1)),
                Some(scaled),
                prior(x, y),
                prior(x + 1, y),
            ]
            .into_iter()
            .flatten(),
        );
        let reference = self.references.get(usize::from(ref_idx))?;
        let chroma = self.chroma_block(&mb.source, reference);
        // Refined every time: x264's half-pel threshold (sub-pel only
        // where 7/8 of the full-pel cost is within the previous frame's)
        // took medium with three references from -1.99 % to -1.51 %
        // BD-rate on the development set's mean for 0.93-0.99x the time.
        let best = older
            .search
            .search((self.src.y(), reference.y()), (x, y), mvp, &candidates, chroma);
        found.set(x, y, best.mv);
        let mv = RefMv::new(best.mv, ref_idx);
        self.predict_candidate(mb, slot, mv);
        Some(self.inter_candidate(mb, mv, mvp, Some(slot)))
    }

    /// The macroblock split into partitions (block frames): the 8x8 split
    /// first, then, when it beats the 16x16 estimate (or comes within
    /// [`RD_MARGIN`] of it, [`InterFrameCoder::split_margin`]), 16x8 and
    /// 8x16 seeded with its vectors (as x264); the best of them by SATD +
    /// lambda * bits is coded and considered.
    pub(super) fn analyse_split(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) {
        if !self.partitions {
            return;
        }
        let search = PartitionSearch {
            source: &mb.source.luma,
            reference: self.references[0].y(),
            halfpel: self.partition_planes(),
            mb: (mb.mb_x, mb.mb_y),
            sad_lambda: self.coder.lambda.sqrt(),
            satd8: env.satd8,
            windows: Default::default(),
        };
        env.satd8.borrow_mut().clear();
        // The candidates alone first: when they do not come within
        // `ROUGH_SPLIT_MARGIN` of the 16x16 estimate, the search (most of
        // the work) is not done; a split searched is coded where it beats
        // the estimate.
        // x264 codes every partition within 5/4 of the best estimate; one
        // split coded (the best of the three) gave as much here (-1.53 %
        // against -1.57 % on the 28 sequences' mean, medium) for 0.88x the
        // time.
        let bound = if self.split_margin { RD_MARGIN } else { 1.0 } * mb.inter_estimate;
        let rough = self.search_split(mb, &search, Split::Quad, None, false, env);
        // Where splits are searched within 5/4 already, that margin
        // stands (on top of it slower took +0.05 % for 1.064x its time,
        // coin_568 +11.3 %; with it alone -0.11 % for 1.026x, coin_568
        // +9.7 %: `benches/pair.py`, the 28 and four kinds, one run each).
        let search_margin = if self.split_search_margin && !self.split_margin {
            ROUGH_SPLIT_MARGIN
        } else {
            1.0
        };
        if rough.0 >= search_margin * bound {
            return;
        }
        let quad = self.search_split(mb, &search, Split::Quad, None, true, env);
        if quad.0 >= bound {
            return;
        }
        let best = [Split::Horizontal, Split::Vertical]
            .map(|split| self.search_split(mb, &search, split, Some(&quad.2), true, env))
            .into_iter()
            .fold(quad, |a, b| if b.0 < a.0 { b } else { a });
        let (_, split, mvs) = best;
        let kind = MbKind::Split {
            split,
            mvs: mvs.map(RefMv::previous),
        };
        let at = (mb.mb_x, mb.mb_y, self.seq.mb_cols());
        let mode = mb_mode(&kind, env.decided, at, self.syntax);
        predict_inter_blocks_into(
            &self.inter_context(),
            mb.mb_x,
            mb.mb_y,
            &split.block_vectors(&mvs.map(RefMv::previous)),
            &mut mb.trial.pred,
        );
        self.code_trial(mb, kind, &mode, TrialPred::InPlace, env);
        mb.consider_trial();
    }

    /// The vectors of `split`'s partitions, each searched against its
    /// predicted vector (which reads the partitions before it), with their
    /// total SATD + lambda * bits (the split's own bits included).
    /// Candidates: the 8x8 vectors under the partition, the macroblock's,
    /// and `quad`'s (the 8x8 split's decided vectors) when given.
    pub(super) fn search_split(
        &self,
        mb: &MbAnalysis,
        search: &PartitionSearch<'_>,
        split: Split,
        quad: Option<&[Mv; 4]>,
        refine: bool,
        env: &MbEnv<'_>,
    ) -> (f64, Split, [Mv; 4]) {
        let (mut mvs, mut total) = ([Mv::ZERO; 4], 0.0);
        let mut candidates = Vec::with_capacity(16);
        walk_partitions(
            split,
            env.decided,
            (mb.mb_x, mb.mb_y, self.seq.mb_cols()),
            |k, predict| {
                let mvp = predict(0);
                let p = &split.parts()[k];
                self.partition_candidates(mb, p, quad, env, &mut candidates);
                let best = search.best(p, &candidates, mvp, refine);
                mvs[k] = best.mv;
                total += best.cost;
                Some(RefMv::previous(best.mv))
            },
        );
        // The split's own flags, over a 16x16 macroblock's.
        let flags = self.mode_bits(
            env,
            mb,
            &MbMode::Split {
                split,
                mvds: [Mv::ZERO; 4],
                refs: [0; 4],
            },
        ) - self.mode_bits(
            env,
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
    /// vectors of the macroblocks the block touches (a block on a motion
    /// edge moves with one of them): motion analysis', or when the
    /// decision searches, the decided ones (the adjacent 8x8 block's)
    /// before it and the previous frame's after it.
    pub(super) fn partition_candidates(
        &self,
        mb: &MbAnalysis,
        p: &Part,
        quad: Option<&[Mv; 4]>,
        env: &MbEnv<'_>,
        out: &mut Vec<Mv>,
    ) {
        let (cols, rows) = (self.seq.mb_cols(), self.seq.mb_rows());
        out.clear();
        out.push(mb.searched);
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
                    let (x, y) = (x as usize, y as usize);
                    // The neighbour's 8x8 block beside block b.
                    let adjacent = ((b % 2) ^ usize::from(ox != 0)) | (((b / 2) ^ usize::from(oy != 0)) << 1);
                    out.extend(self.neighbour_vector(env, (x, y), adjacent));
                }
            }
        }
    }

    /// The vector of 8x8 block `block` of macroblock (x, y) as the
    /// partitions' candidate: motion analysis' (the macroblock's), or when
    /// the decision searches, the decided one (none for intra) where it is
    /// decided, the previous frame's where not.
    fn neighbour_vector(&self, env: &MbEnv<'_>, (x, y): (usize, usize), block: usize) -> Option<Mv> {
        let index = y * self.seq.mb_cols() + x;
        let Some(lazy) = &self.lazy else {
            return Some(self.searched[index]);
        };
        match env.decided.get(index) {
            Some(v) => v[block].filter(|m| m.ref_idx == 0).map(|m| m.mv),
            None => lazy.prior.as_ref().map(|p| p.vector(x, y)),
        }
    }

    /// The half-pel planes the partitions' search reads.
    fn partition_planes(&self) -> Option<&crate::me::halfpel::HalfPel> {
        match &self.lazy {
            Some(lazy) => lazy.search.halfpel(),
            None => self.halfpel.as_ref(),
        }
    }

    /// Intra, each luma candidate coded only when its estimate is below
    /// inter's (the 16x16 SATD below inter's SATD, as the H.264 reference
    /// encoder's fast modes; the 4x4 search's below inter's SATD + vector
    /// cost, where it stops early). Whether the 16x16 one was coded.
    pub(super) fn analyse_intra(&self, mb: &mut MbAnalysis, env: &MbEnv<'_>) -> bool {
        let at = (mb.mb_x, mb.mb_y);
        let intra_likely = env.modes.intra_neighbours(at.0, at.1) > 0;
        let coding_margin = match self.decision {
            ModeDecision::Full => INTRA_CODING_MARGIN,
            ModeDecision::Fast => 1.0,
        };
        let bound = InterBound {
            satd: mb.inter_satd,
            estimate: mb.inter_estimate,
            search_margin: if intra_likely {
                INTRA_LIKELY_SEARCH_MARGIN
            } else {
                INTRA_SEARCH_MARGIN
            },
            coding_margin,
            plane_margin: if intra_likely {
                f64::INFINITY
            } else {
                PLANE_MARGIN * coding_margin
            },
        };
        let coders = (env.modes, env.residual);
        let (coded, whole) = intra_against(
            self.coder,
            &mb.source,
            env.recon,
            at,
            coders,
            Some(bound),
            &mut mb.trial,
        );
        if coded {
            mb.consider_trial();
        }
        whole
    }

    /// An inter choice of `kind` coded into the trial record, priced as
    /// `mode`, its prediction where `from` says.
    pub(super) fn code_trial(
        &self,
        mb: &mut MbAnalysis,
        kind: MbKind,
        mode: &MbMode,
        from: TrialPred,
        env: &MbEnv<'_>,
    ) {
        let mode_bits = self.mode_bits(env, mb, mode);
        let MbAnalysis {
            source,
            best,
            trial,
            preds,
            diffs,
            ..
        } = mb;
        match from {
            TrialPred::Slot(slot) => trial.pred.clone_from(&preds[slot]),
            TrialPred::Skip => trial.pred.clone_from(&best.pred),
            TrialPred::InPlace => {}
        }
        let (at, coder) = ((mb.mb_x, mb.mb_y), self.coder);
        let (pred, residual, samples) = trial.records_over_pred();
        coder.levels_into((source, pred), false, env.residual, residual, diffs);
        let syntax = ResidualSyntax::of_4x4(false);
        let (bits, ssd) = coder.reconstruct_in_place(source, residual, samples, (env.residual, syntax), at);
        trial.kind = kind;
        trial.cost = rdo::cost(coder.lambda, ssd, mode_bits + bits);
        trial.residual_cost = rdo::cost(coder.lambda, ssd, bits);
    }
}

/// The luma intra mode allowed at (mb_x, mb_y) with the smallest SATD
/// plus the mode's bits, its prediction (into `pred.luma`) and SATD.
/// (Luma and chroma modes are independent: each plane's is chosen on
/// its own.)
pub(super) fn best_intra_16x16(
    coder: &MbCoder,
    src: &MbSource,
    recon: &Frame,
    at: (usize, usize),
    pred: &mut MbSamples,
) -> (IntraMode, u32) {
    best_intra_16x16_under(coder, src, recon, at, pred, u32::MAX)
}

/// [`best_intra_16x16`], the plane prediction tried only where the best
/// of the other three is at most `plane_above` (x264's fast intra: the
/// plane costs a prediction and a SATD of its own, the others share one
/// transform).
fn best_intra_16x16_under(
    coder: &MbCoder,
    src: &MbSource,
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    pred: &mut MbSamples,
    plane_above: u32,
) -> (IntraMode, u32) {
    let sad_lambda = coder.lambda.sqrt();
    let (mut luma, mut best_cost, mut satd) = (IntraMode::Dc, f64::INFINITY, 0);
    let edges = IntraEdges::of(recon, 0, mb_x, mb_y);
    // Vertical, horizontal and DC from one transform of the source; a
    // missing edge's mode is not allowed, so its figure goes unread.
    let none = [0u8; MB];
    let x3 = (pixel().intra_satd_x3_16x16)(
        &src.luma,
        edges.top().unwrap_or(&none),
        edges.left().unwrap_or(&none),
        edges.dc(),
    );
    for m in allowed_intra_modes(mb_x, mb_y) {
        let d = match m {
            IntraMode::Vertical => x3[0],
            IntraMode::Horizontal => x3[1],
            IntraMode::Dc => x3[2],
            IntraMode::Plane if satd > plane_above => continue,
            IntraMode::Plane => {
                edges.predict(m, &mut pred.luma);
                Metric::Satd.cost(&src.luma, MB, &pred.luma, MB, MB, MB)
            }
        };
        let c = f64::from(d) + sad_lambda * f64::from(ue_len(m as u32));
        if c < best_cost {
            (luma, best_cost, satd) = (m, c, d);
        }
    }
    if luma != IntraMode::Plane {
        edges.predict(luma, &mut pred.luma);
    }
    (luma, satd)
}

/// The chroma intra mode allowed at (mb_x, mb_y) with the smallest SAD
/// (both planes) plus the mode's bits, and its prediction (into
/// `pred.chroma`).
pub(super) fn best_intra_chroma(
    coder: &MbCoder,
    src: &MbSource,
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    pred: &mut MbSamples,
) -> IntraMode {
    let sad_lambda = coder.lambda.sqrt();
    let mut chroma = IntraMode::Dc;
    let mut best_c = f64::INFINITY;
    let mut trial = [[0u8; 64]; 2];
    let edges = [1, 2].map(|p| IntraEdges::of(recon, p, mb_x, mb_y));
    for m in allowed_intra_modes(mb_x, mb_y) {
        let mut c = sad_lambda * f64::from(ue_len(m as u32));
        for (k, t) in trial.iter_mut().enumerate() {
            edges[k].predict(m, t);
            c += f64::from(Metric::Sad.cost(&src.chroma[k], 8, t, 8, 8, 8));
        }
        if c < best_c {
            (chroma, best_c) = (m, c);
            pred.chroma = trial;
        }
    }
    chroma
}

/// The intra modes macroblock (mb_x, mb_y) has the neighbours for.
fn allowed_intra_modes(mb_x: usize, mb_y: usize) -> impl Iterator<Item = IntraMode> {
    IntraMode::ALL
        .into_iter()
        .filter(move |&m| intra_mode_allowed(m, mb_x, mb_y))
}

#[cfg(test)]
mod tests {
    //! The decisions on small crafted frames whose right answer is known:
    //! what a P frame of 48x48 (9 macroblocks) codes each macroblock as.

    use super::*;
    use crate::codec::partition::MbVectors;
    use crate::codec::recon::frame_vectors;
    use crate::codec::syntax::{EntropyState, SequenceHeader, Vui};
    use crate::codec::weight::Weights;
    use crate::encode::config::ModeDecision;
    use crate::encode::motion::{BlockMotion, FrameMotion, LazySearch, PARTITION_MARGIN};
    use crate::encode::slice::{code_inter, InterInputs};
    use crate::me::halfpel::HalfPel;
    use crate::me::{lambda_for_qp, FrameSearch, MeConfig, Method, Metric, Subpel};

    const SIZE: usize = 48;

    #[test]
    fn a_trial_takes_the_best_place_only_when_it_costs_less() {
        let inter = MbKind::Inter {
            mv: RefMv::previous(Mv::new(4, -2)),
        };
        let mut mb = MbAnalysis::empty();
        (mb.best.cost, mb.best.kind) = (10.0, MbKind::Skip);
        (mb.trial.cost, mb.trial.kind) = (10.0, inter);
        // The first of equals stays.
        mb.consider_trial();
        assert_eq!((mb.best.cost, mb.best.kind), (10.0, MbKind::Skip));
        mb.trial.cost = 9.5;
        mb.consider_trial();
        assert_eq!((mb.best.cost, mb.best.kind), (9.5, inter));
        // The record it replaced is the next trial's.
        assert_eq!((mb.trial.cost, mb.trial.kind), (10.0, MbKind::Skip));
    }

    /// A texture with detail at every scale (no two blocks alike).
    fn texture(x: isize, y: isize) -> u8 {
        let (x, y) = (x as f64, y as f64);
        (128.0 + 50.0 * (x * 0.37).sin() * (y * 0.29).cos() + 30.0 * ((x * 1.7 + y * 0.6).sin())) as u8
    }

    fn frame(f: impl Fn(isize, isize) -> u8) -> Frame {
        let mut out = Frame::filled(SIZE, SIZE, 0, 128, 128).unwrap();
        let y = out.plane_mut(0);
        for r in 0..SIZE {
            for (c, v) in y.row_mut(r).iter_mut().enumerate() {
                *v = f(c as isize, r as isize);
            }
        }
        out.extend_borders();
        out
    }

    /// The P frame `src` coded against `reference` with motion analysis'
    /// vectors `mb` (one per macroblock, quarter-pel): each macroblock's
    /// kind and its 8x8 blocks' vectors.
    fn decide(src: &Frame, reference: &Frame, mb: Vec<Mv>, partitions: bool) -> Vec<(MbKind, MbVectors)> {
        decide_with(src, reference, mb, (partitions, false, false))
    }

    /// [`decide`] with fast P-skip on or off, after the search and before.
    fn decide_with(
        src: &Frame,
        reference: &Frame,
        mb: Vec<Mv>,
        skips: (bool, bool, bool),
    ) -> Vec<(MbKind, MbVectors)> {
        decide_motion(src, reference, mb, None, (skips, ModeDecision::Full))
    }

    /// [`decide_with`], with vectors `mb` or, given `lazy`, the decision's
    /// own search.
    fn decide_motion(
        src: &Frame,
        reference: &Frame,
        mb: Vec<Mv>,
        lazy: Option<Box<LazySearch>>,
        ((partitions, fast_pskip, early_pskip), decision): ((bool, bool, bool), ModeDecision),
    ) -> Vec<(MbKind, MbVectors)> {
        let seq = SequenceHeader {
            width: SIZE,
            height: SIZE,
            fps_num: 25,
            fps_den: 1,
            frame_count: 0,
            vui: Vui::default(),
            max_refs: 1,
        };
        let coder = MbCoder::new(28, 1.4, true);
        let halfpel = partitions
            .then(|| HalfPel::new(reference.y(), PARTITION_MARGIN))
            .flatten();
        // The state at a stream's start: priced and written from it.
        let pricing = EntropyState::new();
        let inputs = InterInputs {
            references: vec![reference],
            motion: FrameMotion::Vectors(BlockMotion {
                mb,
                blocks: None,
                halfpel,
                lazy,
            }),
            tool: MotionTool::Block,
            decision,
            deblock: true,
            deblock_offsets: crate::codec::deblock::DeblockOffsets::ZERO,
            measure_deblock: false,
            try_deblock_offsets: true,
            weights: Weights::NONE,
            luma_filter: crate::codec::interp::LumaFilter::Sharp,
            partitions,
            subpel_rd: false,
            split_margin: false,
            split_search_margin: false,
            chroma_me: false,
            adaptive_pricing: true,
            fast_pskip,
            early_pskip,
            pricing: &pricing,
        };
        let mut state = EntropyState::new();
        let recon = Frame::new(SIZE, SIZE).unwrap();
        let coded = code_inter(&seq, &coder, src, inputs, (&mut state, recon), |_, _| ()).unwrap();
        let vectors = frame_vectors(&seq, &coded.syntax);
        coded.syntax.mbs.iter().map(|m| m.kind).zip(vectors).collect()
    }

    #[test]
    fn the_fast_decision_takes_intra_by_satd_and_the_full_one_by_cost() {
        // A grey picture; in the middle macroblock, each 4x4 block a
        // checkerboard of 2x2 squares 7 above and 7 below grey. The
        // reference has it a macroblock to the right (the vector given;
        // skip, from the neighbours' zero vectors, sees a flat 200 there),
        // with one sample of each block 8 higher: it predicts with a 4x4
        // SATD of 64 a block, grey intra with 56. But intra needs a level
        // in every block, and the reference's error of one sample a block
        // codes nothing.
        let centre = |x: isize, y: isize| (16..32).contains(&x) && (16..32).contains(&y);
        let offset = |x: isize, y: isize| if (x % 4 < 2) == (y % 4 < 2) { 135 } else { 121 };
        let src = frame(|x, y| if centre(x, y) { offset(x, y) } else { 128 });
        let spike = |x: isize, y: isize| x % 4 == 1 && y % 4 == 2;
        let reference = frame(|x, y| match (centre(x, y), centre(x - 16, y), spike(x, y)) {
            (true, _, _) => 200,
            (_, true, true) => offset(x, y) + 8,
            (_, true, false) => offset(x, y),
            _ => 128,
        });
        let shift = Mv::full_pel(16, 0);
        let mut vectors = vec![Mv::ZERO; 9];
        vectors[4] = shift;
        let kind = |decision| {
            let decided = decide_motion(
                &src,
                &reference,
                vectors.clone(),
                None,
                ((false, false, false), decision),
            );
            decided[4].0
        };
        let fast = kind(ModeDecision::Fast);
        let full = kind(ModeDecision::Full);
        assert!(matches!(fast, MbKind::Intra { .. }), "{fast:?}");
        assert_eq!(
            full,
            MbKind::Inter {
                mv: RefMv::previous(shift)
            }
        );
    }

    #[test]
    fn a_picture_the_reference_predicts_exactly_is_all_skipped() {
        let reference = frame(texture);
        let decided = decide(&reference.clone(), &reference, vec![Mv::ZERO; 9], true);
        assert!(decided.iter().all(|(k, _)| *k == MbKind::Skip), "{decided:?}");
    }

    #[test]
    fn a_shifted_picture_takes_the_shift_once_and_skips_along_it() {
        // The source is the reference moved 3 px left and 2 px up: each
        // block matches the reference at its position + (3, 2).
        let reference = frame(texture);
        let src = frame(|x, y| texture(x + 3, y + 2));
        let shift = Mv::full_pel(3, 2);
        let decided = decide(&src, &reference, vec![shift; 9], false);
        // The first macroblock codes the vector (its prediction is zero);
        // its neighbours predict it, and any that skip move along it.
        assert!(
            matches!(decided[0].0, MbKind::Inter { mv } if mv.mv == shift),
            "{:?}",
            decided[0]
        );
        for (i, (kind, vectors)) in decided.iter().enumerate() {
            assert!(!matches!(kind, MbKind::Intra { .. }), "macroblock {i}: {kind:?}");
            assert!(
                vectors.iter().all(|v| v.map(|v| v.mv) == Some(shift)),
                "macroblock {i}: {vectors:?}"
            );
        }
        // Those whose moved block stays inside the picture (the others read
        // the replicated border, which the texture does not continue)
        // predict it exactly: skipped.
        for i in [1, 3, 4] {
            assert_eq!(decided[i].0, MbKind::Skip, "macroblock {i}");
        }
    }

    #[test]
    fn the_decision_s_own_search_finds_a_shift_from_zero() {
        // No motion analysis: each macroblock the decision does not skip
        // first is searched from its predicted vector, its decided
        // neighbours' and zero. A smooth texture (one minimum within the
        // range) moved 2 px left and 1 px down.
        let smooth = |x: isize, y: isize| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 70.0 * (x * 0.11).sin() * (y * 0.09 + 0.5).cos() + 20.0 * (x * 0.05 + y * 0.07).cos())
                as u8
        };
        let reference = frame(smooth);
        let src = frame(|x, y| smooth(x + 2, y - 1));
        let shift = Mv::full_pel(2, -1);
        let mut cfg = MeConfig::new(Method::Epzs, MB, 16);
        cfg.subpel = Subpel::Quarter;
        cfg.metric = Metric::Satd;
        cfg.lambda = lambda_for_qp(Metric::Satd, 28);
        let lazy = Box::new(LazySearch {
            search: FrameSearch::new(reference.y(), &cfg, None).unwrap(),
            prior: None,
            older: Vec::new(),
        });
        let decided = decide_motion(
            &src,
            &reference,
            Vec::new(),
            Some(lazy),
            ((false, true, false), ModeDecision::Full),
        );
        // The first macroblock searches from zero alone and finds the
        // shift; its neighbours predict it. Those whose moved block stays
        // inside the picture take it; none is intra.
        for i in [0, 1, 3, 4] {
            let (kind, vectors) = &decided[i];
            assert!(!matches!(kind, MbKind::Intra { .. }), "macroblock {i}: {kind:?}");
            assert!(
                vectors.iter().all(|v| v.map(|v| v.mv) == Some(shift)),
                "macroblock {i}: {vectors:?}"
            );
        }
    }

    #[test]
    fn what_the_reference_does_not_hold_and_the_row_above_predicts_is_intra() {
        // Vertical stripes over a flat reference: inter has nothing to
        // copy, while the intra vertical mode continues the row above.
        let reference = frame(|_, _| 128);
        let src = frame(|x, _| if (x / 3) % 2 == 0 { 40 } else { 220 });
        let decided = decide(&src, &reference, vec![Mv::ZERO; 9], true);
        for (i, (kind, _)) in decided.iter().enumerate().skip(3) {
            assert!(matches!(kind, MbKind::Intra { .. }), "macroblock {i}: {kind:?}");
        }
    }

    /// [`intra_against`] of the middle macroblock of a textured frame
    /// against an inter bound `ratio` times below its 16x16 intra SATD,
    /// with the bound's search and coding margins: whether a candidate
    /// and the 16x16 one were coded, and the choice.
    fn intra_against_textured(ratio: f64, search_margin: f64, coding_margin: f64) -> (bool, bool, Choice) {
        let src = frame(texture);
        let s = MbSource::load(&src, 1, 1);
        let coder = MbCoder::new(28, 1.0, true);
        let (modes, residual) = (ModeCoder::new(3, 3), ResidualCoder::new(3, 3));
        let (_, satd) = best_intra_16x16(&coder, &s, &src, (1, 1), &mut MbSamples::default());
        let bound = InterBound {
            satd: (f64::from(satd) / ratio) as u32,
            estimate: f64::INFINITY,
            search_margin,
            coding_margin,
            plane_margin: f64::INFINITY,
        };
        let mut choice = Choice::empty();
        let at = (1, 1);
        let (coded, whole) = intra_against(
            &coder,
            &s,
            &src,
            at,
            (&modes, &residual),
            Some(bound),
            &mut choice,
        );
        (coded, whole, choice)
    }

    #[test]
    fn the_plane_prediction_is_tried_only_under_its_bound() {
        // A diagonal ramp: the plane fits it exactly, the other three
        // modes do not. Under a bound below their SATD the plane is not
        // tried (and one of them is returned); without one it wins.
        let src = frame(|x, y| (40 + 3 * x + 2 * y) as u8);
        let s = MbSource::load(&src, 1, 1);
        let coder = MbCoder::new(28, 1.0, true);
        let mut pred = MbSamples::default();
        let (mode, satd) = best_intra_16x16(&coder, &s, &src, (1, 1), &mut pred);
        assert_eq!((mode, satd), (IntraMode::Plane, 0));
        let (bounded, other) = best_intra_16x16_under(&coder, &s, &src, (1, 1), &mut pred, 1);
        assert_ne!(bounded, IntraMode::Plane);
        assert!(other > 1, "{other}");
        assert_eq!(
            best_intra_16x16_under(&coder, &s, &src, (1, 1), &mut pred, other).0,
            IntraMode::Plane
        );
    }

    #[test]
    fn the_full_decision_codes_intra_within_its_margin_of_inter() {
        // A textured macroblock whose 16x16 intra SATD is 1.1 times
        // inter's: coded for the RD comparison within the full decision's
        // margin (x264's 5/4 under RD mode decision), not where intra must
        // beat inter's SATD (the fast decision's).
        let coded_at = |margin| {
            let (coded, whole, _) = intra_against_textured(1.1, 1.0, margin);
            (coded, whole)
        };
        assert_eq!(coded_at(1.0), (false, false));
        assert_eq!(coded_at(INTRA_CODING_MARGIN), (true, true));
    }

    #[test]
    fn intra_blocks_are_searched_within_the_bounds_margin() {
        // A textured macroblock whose 16x16 intra SATD is 1.5 times
        // inter's: hopeless for the blocks at the usual margin (1.25, and
        // 16x16 intra does not beat inter), searched at the margin beside
        // an intra neighbour (2.0), where the 8x8 blocks are coded.
        let at = |margin| {
            let (coded, _, choice) = intra_against_textured(1.5, margin, 1.0);
            coded.then_some(choice)
        };
        assert!(at(INTRA_SEARCH_MARGIN).is_none());
        let likely = at(INTRA_LIKELY_SEARCH_MARGIN).expect("the blocks searched");
        assert!(
            matches!(
                likely.kind,
                MbKind::Intra {
                    luma: LumaIntra::Blocks8(_) | LumaIntra::Blocks(_),
                    ..
                }
            ),
            "{:?}",
            likely.kind
        );
    }

    #[test]
    fn two_motions_in_one_macroblock_split_it() {
        // Each macroblock's left half moves one way, its right half
        // another: analysis offers both vectors (neighbours alternate), and
        // a 16x16 vector fits neither half.
        let reference = frame(texture);
        let src = frame(|x, y| {
            if x % 16 < 8 {
                texture(x + 4, y)
            } else {
                texture(x - 4, y + 1)
            }
        });
        let (left, right) = (Mv::full_pel(4, 0), Mv::full_pel(-4, 1));
        let mb: Vec<Mv> = (0..9).map(|i| if i % 2 == 0 { left } else { right }).collect();
        let decided = decide(&src, &reference, mb.clone(), true);
        let split = decided
            .iter()
            .filter(|(k, _)| matches!(k, MbKind::Split { .. }))
            .count();
        assert!(split >= 5, "{decided:?}");
        // Without partitions nothing can be split.
        let whole = decide(&src, &reference, mb, false);
        assert!(
            whole.iter().all(|(k, _)| !matches!(k, MbKind::Split { .. })),
            "{whole:?}"
        );
    }
    #[test]
    fn fast_pskip_skips_where_the_search_found_the_skip_vector() {
        // A smooth picture moved a quarter pel right, but for its first
        // macroblock: the others' skip prediction (the first's zero
        // vector) misses by little, what quantisation leaves nothing of;
        // their searched vector, a quarter pel away, predicts them better.
        let smooth = |x: f64, y: f64| (128.0 + 40.0 * (0.3 * x + 0.13 * y).sin()) as u8;
        let reference = frame(|x, y| smooth(x as f64, y as f64));
        let src = frame(|x, y| {
            let dx = if x < 16 && y < 16 { 0.0 } else { 0.25 };
            smooth(x as f64 + dx, y as f64)
        });
        let mut quarter = vec![Mv::new(1, 0); 9];
        quarter[0] = Mv::ZERO;
        let full = decide_with(&src, &reference, quarter.clone(), (false, false, false));
        let fast = decide_with(&src, &reference, quarter, (false, true, false));
        assert_eq!(full[0].0, MbKind::Skip);
        for i in [1, 3] {
            assert!(
                matches!(full[i].0, MbKind::Inter { mv } if mv.mv == Mv::new(1, 0)),
                "{:?}",
                full[i]
            );
            // A searched vector that is not the skip's: no fast skip (x264
            // tests the vector its 16x16 search found), the same choice.
            assert_eq!(fast[i].0, full[i].0);
        }
        // Where the search found the skip's vector, the skip that codes
        // nothing is taken at once.
        let found = decide_with(&src, &reference, vec![Mv::ZERO; 9], (false, true, false));
        assert!(found.iter().all(|(k, _)| *k == MbKind::Skip), "{found:?}");
    }

    #[test]
    fn early_pskip_skips_between_two_skips_before_any_search() {
        // A smooth picture, the centre macroblock's part moved half a pel
        // left: the searched vector (a half pel) predicts it better than
        // the skip (zero), and is not within a quarter pel of it, so fast
        // P-skip after the search codes it; probed before the search,
        // between its skipped left and upper neighbours, the skip codes
        // nothing and is taken (its squared error, 675, under 24 lambdas:
        // about 1150 at QP 28, lambda scale 1.4).
        let smooth = |x: f64, y: f64| (128.0 + 15.0 * (0.3 * x + 0.13 * y).sin()) as u8;
        let reference = frame(|x, y| smooth(x as f64, y as f64));
        let centre = |x: isize, y: isize| (16..32).contains(&x) && (16..32).contains(&y);
        let src = frame(|x, y| smooth(x as f64 + if centre(x, y) { 0.5 } else { 0.0 }, y as f64));
        let mut mb = vec![Mv::ZERO; 9];
        mb[4] = Mv::new(2, 0);
        let after = decide_with(&src, &reference, mb.clone(), (false, true, false));
        let before = decide_with(&src, &reference, mb, (false, true, true));
        for i in [0, 1, 3] {
            assert_eq!(
                (after[i].0, before[i].0),
                (MbKind::Skip, MbKind::Skip),
                "macroblock {i}"
            );
        }
        assert!(
            matches!(after[4].0, MbKind::Inter { mv } if mv.mv == Mv::new(2, 0)),
            "{:?}",
            after[4]
        );
        assert_eq!(before[4].0, MbKind::Skip);
    }

    #[test]
    fn early_pskip_beside_one_skipped_neighbour_takes_only_a_skip_with_little_error() {
        let fast = |src: &Frame, reference: &Frame, mb: Vec<Mv>, early| {
            decide_motion(
                src,
                reference,
                mb,
                None,
                ((false, true, early), ModeDecision::Fast),
            )
        };
        // The top row's middle macroblock (its left neighbour skipped, none
        // above) moved half a pel, as in the test between two skips: the
        // skip leaves little error (under 24 lambdas) and codes nothing.
        let smooth = |x: f64, y: f64| (128.0 + 15.0 * (0.3 * x + 0.13 * y).sin()) as u8;
        let reference = frame(|x, y| smooth(x as f64, y as f64));
        let moved = |x: isize, y: isize| (16..32).contains(&x) && y < 16;
        let src = frame(|x, y| smooth(x as f64 + if moved(x, y) { 0.5 } else { 0.0 }, y as f64));
        let mut mb = vec![Mv::ZERO; 9];
        mb[1] = Mv::new(2, 0);
        let after = fast(&src, &reference, mb.clone(), false);
        assert_eq!(after[0].0, MbKind::Skip);
        assert!(
            matches!(after[1].0, MbKind::Inter { mv } if mv.mv == Mv::new(2, 0)),
            "{:?}",
            after[1]
        );
        assert_eq!(fast(&src, &reference, mb, true)[1].0, MbKind::Skip);
        // The same macroblock 3 too bright in the reference: the skip codes
        // nothing but leaves 2304 of squared error, over 24 lambdas; beside
        // one skipped neighbour it is analysed, and intra (DC from the left
        // neighbour, exact) refreshes it.
        let src = frame(|_, _| 100);
        let reference = frame(|x, y| if moved(x, y) { 103 } else { 100 });
        let mut mb = vec![Mv::ZERO; 9];
        mb[1] = Mv::new(4, 0);
        let before = fast(&src, &reference, mb, true);
        assert_eq!(before[0].0, MbKind::Skip);
        assert!(matches!(before[1].0, MbKind::Intra { .. }), "{:?}", before[1]);
    }

    #[test]
    fn neighbours_that_took_an_older_reference_are_counted_left_and_above() {
        let first = Some(RefMv::previous(Mv::new(4, 0)));
        let older = Some(RefMv::new(Mv::ZERO, 1));
        // 3 x 2 macroblocks: the top middle one took an older reference in
        // one of its blocks, the top left none (intra: no vectors).
        let decided: Vec<MbVectors> = vec![
            [None; 4],
            [first, first, older, first],
            [first; 4],
            [first; 4],
            [first; 4],
            [first; 4],
        ];
        let count = |x, y| older_reference_neighbours(&decided, (x, y, 3));
        assert_eq!(count(0, 0), 0, "no neighbours");
        assert_eq!(count(2, 0), 1, "left");
        assert_eq!(count(1, 1), 1, "above");
        assert_eq!(count(2, 1), 0, "above-left does not count");
        assert_eq!(count(0, 1), 0, "intra above");
    }

    #[test]
    fn early_pskip_leaves_a_skip_that_keeps_too_much_error() {
        // A flat picture whose reference is 3 too bright on the centre
        // macroblock (an error left by an earlier frame): the skip's
        // residual codes no level, and its squared error (2304) is above
        // 24 lambdas (about 1150 at QP 28, lambda scale 1.4). Between two
        // exact skips the full decision analyses it and refreshes it with
        // intra (DC from the neighbours, exact); the fast decision skips
        // it.
        let src = frame(|_, _| 100);
        let centre = |x: isize, y: isize| (16..32).contains(&x) && (16..32).contains(&y);
        let reference = frame(|x, y| if centre(x, y) { 103 } else { 100 });
        // Motion analysis found a vector a pel right for it (as a search
        // does over noise), so fast P-skip after the search does not
        // take it either.
        let mut mb = vec![Mv::ZERO; 9];
        mb[4] = Mv::new(4, 0);
        let full = decide_with(&src, &reference, mb.clone(), (false, true, true));
        for i in [0, 1, 3] {
            assert_eq!(full[i].0, MbKind::Skip, "macroblock {i}");
        }
        assert!(matches!(full[4].0, MbKind::Intra { .. }), "{:?}", full[4]);
        let fast = decide_motion(
            &src,
            &reference,
            mb,
            None,
            ((false, true, true), ModeDecision::Fast),
        );
        assert_eq!(fast[4].0, MbKind::Skip);
    }
}
