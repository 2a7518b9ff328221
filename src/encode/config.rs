//! What the encoder is asked to do: QP, GOP, and the P-frame predictor.

use std::fmt;
use std::str::FromStr;

use crate::codec::deblock::DeblockOffsets;
use crate::codec::interp::LumaFilter;
use crate::codec::modes::MAX_REFS;
use crate::codec::transform::MAX_QP;
pub use crate::flow::FlowMethod;
use crate::me::{Method, Subpel, MAX_RANGE};
use crate::metrics::{Metric, Metrics, QualitySettings, SsimWindow};

/// The settings of the block search of the `block` and `obmc` predictors
/// (the search itself is [`crate::me`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SearchSettings {
    /// Search pattern.
    pub method: Method,
    /// Full-pel range, 1..=64.
    pub range: i32,
    /// Sub-pel refinement.
    pub subpel: Subpel,
    /// EPZS's exhaustive window around its best, full pels (0: none; see
    /// `me::MeConfig::window`).
    pub window: i32,
    /// Full-pel positions compared by SAD, only the sub-pel steps by SATD
    /// (x264's way at every subme; see `me::MeConfig::full_pel_sad`).
    pub full_pel_sad: bool,
    /// The sub-pel steps compared by SAD too, the whole search by SAD
    /// (x264's subme 1). The mode decision still weighs the searched
    /// vector by SATD.
    pub sub_pel_sad: bool,
    /// How often each sub-pel step may move the vector
    /// (`me::MeConfig::subpel_moves`).
    pub subpel_moves: u8,
    /// The candidates' own quarter-pel positions as starts of the sub-pel
    /// steps (`me::MeConfig::sub_pel_starts`).
    pub sub_pel_starts: bool,
}

impl Default for SearchSettings {
    fn default() -> SearchSettings {
        SearchSettings {
            method: Method::Epzs,
            range: WIDE_RANGE,
            subpel: Subpel::Quarter,
            // The medium preset's.
            window: 3,
            full_pel_sad: true,
            sub_pel_sad: false,
            subpel_moves: SUBPEL_MOVES,
            // None, as medium (`EncoderConfig::preset` has the figures).
            sub_pel_starts: false,
        }
    }
}

/// The [`SearchSettings::subpel_moves`] from veryfast. Against one move a
/// step (`benches/pair.py`, the 28 sequences, one run each): two took
/// medium -0.54 % for 1.008x its encode time, four -0.77 % for
/// 1.008-1.027x (garden_720p -3.2 %, cartoon_cif -2.8 %, plant_qvga
/// -2.4 %, coin_568 -2.3 %, smile_360p -2.2 %, face_360p -2.0 %; fish_1160
/// +0.9 %, dark_cif +0.9 %), eight -0.70 %; ultrafast -0.84 % for
/// 1.02-1.03x with four.
pub(super) const SUBPEL_MOVES: u8 = 4;

/// How P frames are predicted. Each is a complete path to the bitstream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Predictor {
    /// The previous reconstruction with vector 0 (frame difference).
    Zero,
    /// One searched vector per macroblock, rate-constrained.
    Block(SearchSettings),
    /// One vector per macroblock from a dense flow of the source frames
    /// (the component-wise median over the block), then a search of
    /// `refine` full pixels around it and sub-pel refinement (`refine` 0:
    /// the flow's vector as it is).
    FlowBlock {
        /// The flow.
        flow: FlowMethod,
        /// Full-pel refinement radius, 0..=16.
        refine: i32,
    },
    /// The flow sampled on the codec's motion grid and warped.
    Dense {
        /// The flow.
        flow: FlowMethod,
        /// Grid spacing: 4, 8 or 16.
        grid: usize,
    },
    /// Block vectors, predicted with overlapped block motion compensation.
    Obmc(SearchSettings),
}

impl Default for Predictor {
    fn default() -> Predictor {
        Predictor::Block(SearchSettings::default())
    }
}

impl Predictor {
    /// The short label used in tables and CSV: `zero`, `block:esa`,
    /// `flow-block:lk`, `dense-hs`, `obmc`... Options other than the
    /// method are left out; [`Predictor::describe`] gives them all.
    pub fn label(&self) -> String {
        match self {
            Predictor::Zero => "zero".into(),
            Predictor::Block(s) => format!("block:{}", s.method),
            Predictor::FlowBlock { flow, .. } => format!("flow-block:{}", flow.name()),
            Predictor::Dense { flow, .. } => format!("dense-{}", flow.name()),
            Predictor::Obmc(s) if s.method == SearchSettings::default().method => "obmc".into(),
            Predictor::Obmc(s) => format!("obmc:{}", s.method),
        }
    }

    /// Every setting, for reports.
    pub fn describe(&self) -> String {
        let search = |s: &SearchSettings| {
            let subpel = match s.subpel {
                Subpel::None => "full-pel",
                Subpel::Half => "half-pel",
                Subpel::Quarter => "quarter-pel",
            };
            format!("{}, range {}, {subpel}", s.method, s.range)
        };
        match self {
            Predictor::Zero => "zero".into(),
            Predictor::Block(s) => format!("block ({})", search(s)),
            Predictor::FlowBlock { flow, refine } => format!("flow-block ({}, refine {refine})", flow.name()),
            Predictor::Dense { flow, grid } => format!("dense-{} (grid {grid})", flow.name()),
            Predictor::Obmc(s) => format!("obmc ({})", search(s)),
        }
    }

    /// The block search, for predictors that have one.
    pub fn search_mut(&mut self) -> Option<&mut SearchSettings> {
        match self {
            Predictor::Block(s) | Predictor::Obmc(s) => Some(s),
            _ => None,
        }
    }

    pub(crate) fn check(&self) -> Result<(), String> {
        match *self {
            Predictor::Block(s) | Predictor::Obmc(s) if !(1..=MAX_RANGE).contains(&s.range) => {
                Err(format!("search range {} is not in 1..={MAX_RANGE}", s.range))
            }
            Predictor::FlowBlock { refine, .. } if !(0..=16).contains(&refine) => {
                Err(format!("refinement radius {refine} is not in 0..=16"))
            }
            Predictor::Dense { grid, .. } if !crate::codec::warp::SPACINGS.contains(&grid) => {
                Err(format!("grid spacing {grid} is not 4, 8 or 16"))
            }
            _ => Ok(()),
        }
    }
}

impl fmt::Display for Predictor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.label())
    }
}

/// Default refinement radius of `flow-block`.
pub const DEFAULT_REFINE: i32 = 2;

/// Default grid spacing of `dense-lk` and `dense-hs`.
pub const DEFAULT_GRID: usize = 16;

/// The full-pel search range of every preset and of the default search.
pub const WIDE_RANGE: i32 = 32;

impl FromStr for Predictor {
    type Err = String;
    /// `zero`, `block`, `block:METHOD`, `flow-block`, `flow-block:lk|hs|dis`,
    /// `dense-lk`, `dense-hs`, `dense-dis`, `dense-tvl1`, `obmc`, `obmc:METHOD`; other options keep
    /// their defaults.
    fn from_str(s: &str) -> Result<Predictor, String> {
        let (name, option) = match s.split_once(':') {
            Some((n, o)) => (n, Some(o)),
            None => (s, None),
        };
        let search = |option: Option<&str>| -> Result<SearchSettings, String> {
            let mut b = SearchSettings::default();
            if let Some(m) = option {
                b.method = m.parse()?;
            }
            Ok(b)
        };
        let no_option = |p: Predictor| match option {
            None => Ok(p),
            Some(o) => Err(format!("predictor '{name}' takes no option (got ':{o}')")),
        };
        match name {
            "zero" => no_option(Predictor::Zero),
            "block" => Ok(Predictor::Block(search(option)?)),
            "obmc" => Ok(Predictor::Obmc(search(option)?)),
            "flow-block" => Ok(Predictor::FlowBlock {
                flow: option.map_or(Ok(FlowMethod::Lk), str::parse)?,
                refine: DEFAULT_REFINE,
            }),
            "dense-lk" => no_option(Predictor::Dense {
                flow: FlowMethod::Lk,
                grid: DEFAULT_GRID,
            }),
            "dense-hs" => no_option(Predictor::Dense {
                flow: FlowMethod::Hs,
                grid: DEFAULT_GRID,
            }),
            "dense-dis" => no_option(Predictor::Dense {
                flow: FlowMethod::Dis,
                grid: DEFAULT_GRID,
            }),
            "dense-tvl1" => no_option(Predictor::Dense {
                flow: FlowMethod::Tvl1,
                grid: DEFAULT_GRID,
            }),
            _ => Err(format!(
                "unknown predictor '{s}' (zero, block[:METHOD], flow-block[:lk|hs|dis|tvl1], dense-lk, dense-hs, dense-dis, dense-tvl1, obmc[:METHOD])"
            )),
        }
    }
}

/// How a P macroblock's inter vectors are decided between.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ModeDecision {
    /// The predicted vector and the searched one (when they differ) are
    /// each coded, residual and RDOQ included, and compared by
    /// J = SSD + lambda * bits, unless one's SATD + rate estimate is more
    /// than 5/4 of the other's (as x264's RD decision). The default (the
    /// medium preset's).
    #[default]
    Full,
    /// Only the one with the lower SATD + sqrt(lambda) * vector bits is
    /// coded, and only where 16x16 intra does not beat it by SATD: there
    /// intra alone is coded (x264's decisions below `--subme 6`). Intra
    /// blocks are coded beside either where their estimate is lower. One
    /// residual coding per macroblock instead of two, where P frames try
    /// no intra blocks; without the 8x8 transform (ultrafast), its bits
    /// weighed against skip are estimated from its levels, not priced
    /// bin by bin ([`super::rate::residual_estimate`]).
    Fast,
}

impl ModeDecision {
    /// `full` or `fast`.
    pub fn name(self) -> &'static str {
        match self {
            ModeDecision::Full => "full",
            ModeDecision::Fast => "fast",
        }
    }
}

impl FromStr for ModeDecision {
    type Err = String;
    fn from_str(s: &str) -> Result<ModeDecision, String> {
        match s {
            "full" => Ok(ModeDecision::Full),
            "fast" => Ok(ModeDecision::Fast),
            _ => Err(format!("unknown mode decision '{s}' (full or fast)")),
        }
    }
}

/// Which luma interpolation filter block P frames predict with (FORMAT.md
/// section 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum FilterChoice {
    /// Per frame, from how the two predicted the frames before (sharp
    /// for the first; `filter.rs` says how): camera noise and blur favour
    /// the smooth one, clean detail the sharp one.
    #[default]
    Auto,
    /// Always this one.
    Fixed(LumaFilter),
}

impl FilterChoice {
    /// `auto`, `sharp` or `smooth`.
    pub fn name(self) -> &'static str {
        match self {
            FilterChoice::Auto => "auto",
            FilterChoice::Fixed(LumaFilter::Sharp) => "sharp",
            FilterChoice::Fixed(LumaFilter::Smooth) => "smooth",
        }
    }
}

impl FromStr for FilterChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<FilterChoice, String> {
        match s {
            "auto" => Ok(FilterChoice::Auto),
            "sharp" => Ok(FilterChoice::Fixed(LumaFilter::Sharp)),
            "smooth" => Ok(FilterChoice::Fixed(LumaFilter::Smooth)),
            _ => Err(format!("unknown luma filter '{s}' (auto, sharp or smooth)")),
        }
    }
}

/// A point of speed against compression, as x264's `--preset` (its names,
/// fastest first): each sets the coding tools' options (the predictor's
/// search pattern stays the predictor's own); options given after it
/// override it. Each adds tools to the one before; where each lands on
/// the speed/compression front beside x264's is measured by
/// `benches/front.py` (README).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum EncoderPreset {
    /// Quarter-pel vectors searched by SAD (one sub-pel move a step, no
    /// sub-pel starts), weighted prediction, intra in 16x16 only (I
    /// frames too), the 4x4 transform only, no RDOQ, the fast mode
    /// decision, fast P-skip before the search.
    Ultrafast,
    /// The 8x8 transform, and I frames' intra in 4x4 and 8x8 blocks.
    Superfast,
    /// 8x8 intra in P frames; sub-pel compared by SATD, four moves a
    /// step.
    Veryfast,
    /// EPZS's exhaustive window of 3 pels.
    Faster,
    /// The full mode decision.
    Fast,
    /// RDOQ, the inter partitions, a second reference searched while it
    /// pays, and the deblocking offsets chosen per frame. The default.
    #[default]
    Medium,
    /// A window of 4 pels, full-pel positions compared by SATD, the
    /// candidates' sub-pel positions as starts of the sub-pel steps,
    /// three references, sub-pel RD refinement, 4x4
    /// intra in P frames, and splits searched where their candidates come
    /// within 1.1 of the whole macroblock's estimate.
    Slow,
    /// Five references, fast P-skip after the search only (every
    /// macroblock searched), and splits searched and coded within 5/4 of
    /// the whole macroblock's estimate.
    Slower,
}

impl EncoderPreset {
    /// Every preset, fastest first.
    pub const ALL: [EncoderPreset; 8] = [
        EncoderPreset::Ultrafast,
        EncoderPreset::Superfast,
        EncoderPreset::Veryfast,
        EncoderPreset::Faster,
        EncoderPreset::Fast,
        EncoderPreset::Medium,
        EncoderPreset::Slow,
        EncoderPreset::Slower,
    ];

    /// Its name, as x264's.
    pub fn name(self) -> &'static str {
        match self {
            EncoderPreset::Ultrafast => "ultrafast",
            EncoderPreset::Superfast => "superfast",
            EncoderPreset::Veryfast => "veryfast",
            EncoderPreset::Faster => "faster",
            EncoderPreset::Fast => "fast",
            EncoderPreset::Medium => "medium",
            EncoderPreset::Slow => "slow",
            EncoderPreset::Slower => "slower",
        }
    }
}

impl FromStr for EncoderPreset {
    type Err = String;
    fn from_str(s: &str) -> Result<EncoderPreset, String> {
        EncoderPreset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = EncoderPreset::ALL.iter().map(|p| p.name()).collect();
                format!("unknown preset '{s}' ({})", names.join(", "))
            })
    }
}

/// The default [`EncoderConfig::ipratio`].
pub const DEFAULT_IPRATIO: f64 = 1.4;

/// Everything the encoder is told, built in the builder style:
///
/// ```
/// use mocomp::encode::{EncoderConfig, Predictor};
/// let config = EncoderConfig::new().qp(32).gop(30).predictor("block:esa".parse().unwrap());
/// assert_eq!(config.qp, 32);
/// assert_eq!(config.predictor.label(), "block:esa");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderConfig {
    /// Quantisation parameter of every frame, 0..=51.
    pub qp: u8,
    /// I-frame period: 0 = only the first frame is intra, N = every N-th.
    pub gop: usize,
    /// How P frames are predicted.
    pub predictor: Predictor,
    /// Multiplies the mode-decision lambda `0.85 * 2^((QP - 12) / 3)`.
    /// 1.4 below fast (the best of 0.5-2.0 on 20 frames of `tree_qvga`
    /// and `pan_cif`), 1.0 from fast: see [`EncoderConfig::preset`].
    pub lambda_scale: f64,
    /// Rate-distortion optimised quantisation: each level moves toward
    /// zero when that lowers SSD + lambda * bits.
    pub rdoq: bool,
    /// How inter vectors are decided between.
    pub decision: ModeDecision,
    /// The metrics to measure on every frame: PSNR always, SSIM (x264's
    /// 8x8 windows: about 1 % of the encoding time) by default, MS-SSIM,
    /// PSNR-HVS and CIEDE2000 on request; VMAF, a whole-sequence measure,
    /// is measured by the callers that see the decoded sequence (`mocomp
    /// encode`, sweeps).
    pub metrics: Metrics,
    /// Quantiser step of P frames over that of I frames, as x264's
    /// `--ipratio`: I frames are coded at `qp - 6 log2(ipratio)` (rounded),
    /// since every later frame predicts from them.
    pub ipratio: f64,
    /// The in-loop deblocking filter (FORMAT.md section 11).
    pub deblock: bool,
    /// The filter's offsets in every frame it runs on (x264's `--deblock`
    /// twice over: FORMAT.md section 11); none: block P frames' chosen
    /// with their deblocking ([`EncoderConfig::deblock_choice`]), the
    /// others' zero.
    pub deblock_offsets: Option<DeblockOffsets>,
    /// Block P frames deblocked or not as the filter did on the frames
    /// before ([`super::deblock_choice`]); every frame where off.
    pub deblock_choice: bool,
    /// Weighted prediction (FORMAT.md section 12): P frames scale and
    /// offset the reference's planes where the light changed.
    pub weightp: bool,
    /// Which macroblock partitions the mode decision of P frames tries
    /// (x264's `--partitions`, its `analyse.inter`).
    pub partitions: Partitions,
    /// The intra blocks I frames try (x264's `analyse.intra`, which
    /// `--partitions` leaves alone): `i4x4`, and `i8x8` with the 8x8
    /// transform on (`p8x8` means nothing there).
    pub i_frame_partitions: Partitions,
    /// Inter macroblocks may code their luma in the 8x8 transform
    /// (FORMAT.md section 10.2), as x264's `--8x8dct`.
    pub transform_8x8: bool,
    /// How many earlier reconstructions P frames may predict from, 1..=8,
    /// as x264's `--ref` (FORMAT.md section 4). `block` frames only: the
    /// other predictors predict from the previous frame.
    pub refs: u8,
    /// Block P frames search their older references only while these
    /// saved enough in the frames before ([`super::refs_choice`]); every
    /// reference in every frame where off.
    pub refs_choice: bool,
    /// Sub-pel RD refinement, as x264's `--subme 8`: a decided 16x16 inter
    /// vector's quarter-pel neighbours of lowest estimate are coded and
    /// weighed by rate and distortion (`block` frames).
    pub subpel_rd: bool,
    /// Splits searched and coded where their estimate is within 5/4 of the
    /// 16x16 one (x264's threshold for coding a partition by RD), not only
    /// below it (`block` frames with `p8x8`).
    pub split_margin: bool,
    /// Splits searched where their candidates alone come within 1.1 of the
    /// 16x16 estimate, not only where they beat it (and coded where the
    /// search makes them beat it; `block` frames with `p8x8`; where
    /// [`EncoderConfig::split_margin`] is on, its margin stands instead).
    pub split_search_margin: bool,
    /// The mode decision's residual prices follow the contexts as they
    /// adapt through a P frame's macroblocks (the row above's at a row's
    /// start, the wavefront's rule). Off, every macroblock of a `block` P
    /// frame is priced with the contexts the frame starts from (trained by
    /// the frames before): the decision skips adapting them, about a fifth
    /// of ultrafast's residual entropy work where residual abounds
    /// (diver_vga). I frames, and the raster-order decisions of the other
    /// predictors, adapt either way.
    pub adaptive_pricing: bool,
    /// Chroma priced beside luma in the 16x16 search's sub-pel steps, as
    /// x264's chroma motion estimation (on from its `--subme 5`; off with
    /// `--no-chroma-me`): vectors that predict the colour too.
    pub chroma_me: bool,
    /// x264's fast P-skip (`--no-fast-pskip` turns it off): a P-frame
    /// macroblock whose skip prediction would code no level is skipped
    /// before its other modes are tried, when the motion search found the
    /// predicted vector, or one within a quarter pel of it beside a skipped
    /// neighbour (left or above).
    pub fast_pskip: bool,
    /// Fast P-skip probed before the motion search too, beside a skipped
    /// left or upper neighbour (beside one, and in the full decision, only
    /// where the skip leaves little error): the search is saved where the
    /// skip holds (x264's rule below `--subme 3`, which probes beside any
    /// skipped neighbour of four). Needs `fast_pskip`.
    pub early_pskip: bool,
    /// The luma interpolation filter of `block` P frames.
    pub luma_filter: FilterChoice,
    /// Whether [`super::Encoder::encode`] gives back each frame's
    /// reconstruction ([`super::EncodedFrame::recon`]; on by default). It
    /// is a copy of the visible picture a frame (2 % of ultrafast's
    /// profile on dog_1080p), which a caller that keeps only the stream and its
    /// statistics does without, as x264 writes its reconstruction only
    /// when asked to (`--dump-yuv`).
    pub reconstruction: bool,
}

/// The macroblock partitions the mode decision tries, as x264's
/// `--partitions`: written `all`, `none` or a comma-separated list of
/// `p8x8`, `i8x8` and `i4x4`. As in x264, `i8x8` needs the 8x8 transform
/// (`--8x8dct`): without it, it is not tried.
///
/// ```
/// use mocomp::encode::Partitions;
/// let p: Partitions = "i4x4".parse().unwrap();
/// assert!(p.i4x4 && !p.p8x8);
/// assert_eq!("all".parse::<Partitions>().unwrap(), Partitions::ALL);
/// assert_eq!(Partitions::ALL.to_string(), "p8x8,i8x8,i4x4");
/// assert!("p4x4".parse::<Partitions>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Partitions {
    /// Inter macroblocks of block frames split into 16x8, 8x16 or 8x8
    /// partitions, each with its own vector (FORMAT.md section 3.2).
    pub p8x8: bool,
    /// Intra luma predicted in 8x8 blocks, its residual in the 8x8
    /// transform (FORMAT.md section 9.2).
    pub i8x8: bool,
    /// Intra luma predicted in 4x4 blocks (FORMAT.md section 9.1).
    pub i4x4: bool,
}

impl Partitions {
    /// Every partition.
    pub const ALL: Partitions = Partitions {
        p8x8: true,
        i8x8: true,
        i4x4: true,
    };
    /// 16x16 only.
    pub const NONE: Partitions = Partitions {
        p8x8: false,
        i8x8: false,
        i4x4: false,
    };
}

impl std::str::FromStr for Partitions {
    type Err = String;

    fn from_str(s: &str) -> Result<Partitions, String> {
        match s {
            "all" => return Ok(Partitions::ALL),
            "none" => return Ok(Partitions::NONE),
            _ => {}
        }
        let mut p = Partitions::NONE;
        for name in s.split(',').map(str::trim) {
            match name {
                "p8x8" => p.p8x8 = true,
                "i8x8" => p.i8x8 = true,
                "i4x4" => p.i4x4 = true,
                _ => {
                    return Err(format!(
                        "unknown partition '{name}': expected all, none, or a list of p8x8, i8x8 and i4x4"
                    ))
                }
            }
        }
        Ok(p)
    }
}

impl std::fmt::Display for Partitions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = [(self.p8x8, "p8x8"), (self.i8x8, "i8x8"), (self.i4x4, "i4x4")]
            .into_iter()
            .filter_map(|(on, name)| on.then_some(name))
            .collect();
        if names.is_empty() {
            f.write_str("none")
        } else {
            f.write_str(&names.join(","))
        }
    }
}

impl Default for EncoderConfig {
    fn default() -> EncoderConfig {
        EncoderConfig {
            qp: 28,
            gop: 0,
            predictor: Predictor::default(),
            lambda_scale: 1.0,
            rdoq: true,
            decision: ModeDecision::default(),
            metrics: Metrics::default(),
            ipratio: DEFAULT_IPRATIO,
            deblock: true,
            deblock_offsets: None,
            deblock_choice: true,
            weightp: true,
            // Medium's: 4x4 intra blocks in P frames from slow.
            partitions: Partitions {
                i4x4: false,
                ..Partitions::ALL
            },
            i_frame_partitions: Partitions::ALL,
            transform_8x8: true,
            // Medium's: two, the second searched where it pays.
            refs: 2,
            refs_choice: true,
            subpel_rd: false,
            split_margin: false,
            split_search_margin: false,
            chroma_me: false,
            adaptive_pricing: true,
            fast_pskip: true,
            early_pskip: true,
            luma_filter: FilterChoice::Auto,
            reconstruction: true,
        }
    }
}

impl EncoderConfig {
    /// QP 28, one I frame, `block` with EPZS, range 32, quarter-pel: the
    /// medium preset (RDOQ, full mode decision, deblocking, weighted
    /// prediction), lambda scale 1.0, ipratio 1.4.
    pub fn new() -> EncoderConfig {
        EncoderConfig::default()
    }

    /// Sets the QP.
    pub fn qp(mut self, qp: u8) -> EncoderConfig {
        self.qp = qp;
        self
    }

    /// Sets the I-frame period (0 = only the first).
    pub fn gop(mut self, gop: usize) -> EncoderConfig {
        self.gop = gop;
        self
    }

    /// Sets the P-frame predictor.
    pub fn predictor(mut self, predictor: Predictor) -> EncoderConfig {
        self.predictor = predictor;
        self
    }

    /// Scales the mode-decision lambda.
    pub fn lambda_scale(mut self, scale: f64) -> EncoderConfig {
        self.lambda_scale = scale;
        self
    }

    /// Turns rate-distortion optimised quantisation on or off.
    pub fn rdoq(mut self, on: bool) -> EncoderConfig {
        self.rdoq = on;
        self
    }

    /// Sets how inter vectors are decided between.
    pub fn decision(mut self, decision: ModeDecision) -> EncoderConfig {
        self.decision = decision;
        self
    }

    /// Sets the quantiser step ratio of P frames over I frames.
    pub fn ipratio(mut self, ratio: f64) -> EncoderConfig {
        self.ipratio = ratio;
        self
    }

    /// Turns the in-loop deblocking filter on or off.
    pub fn deblock(mut self, on: bool) -> EncoderConfig {
        self.deblock = on;
        self
    }

    /// The deblocking filter's offsets ([`EncoderConfig::deblock_offsets`]).
    pub fn deblock_offsets(mut self, offsets: DeblockOffsets) -> EncoderConfig {
        self.deblock_offsets = Some(offsets);
        self
    }

    /// Turns the choice of each block P frame's deblocking on or off.
    pub fn deblock_choice(mut self, on: bool) -> EncoderConfig {
        self.deblock_choice = on;
        self
    }

    /// The options of `preset` (the predictor's search pattern kept).
    /// Where each lands, BD-rate and time per encode beside x264's
    /// presets on the development set, is the README's front
    /// (`benches/front.py`); the figures below are what each tool moved a
    /// preset's BD-rate on that set's mean, in points.
    pub fn preset(mut self, preset: EncoderPreset) -> EncoderConfig {
        use EncoderPreset::*;
        self.rdoq = preset >= Medium;
        // From fast, the base lambda as it is (H.264's reference
        // encoder's); below fast 1.4 times it. Against 1.3 (medium's
        // until 2026-12-05), on the 28 sequences (`benches/pair.py`):
        // medium -1.13 % for 1.02x its time, fourteen of the sixteen real
        // clips better (dog_1080p +2.1 %); 1.15 -0.39 %, 0.9 -0.79 %, 0.8
        // -0.74 %; slow -0.35 % (fish_1160 +3.8 %), slower -0.97 %.
        // Below medium 1.0 was mixed on
        // the real clips (ultrafast -0.89 % and fast -1.32 % on the mean,
        // dark_cif and poster_384 most of it; fish_1160 and coin_568
        // +2.8 % in ultrafast): 1.4 kept there. Fast, once its full
        // decision refused early skips that keep their error, took 1.0:
        // -2.25 % for 1.04x its time, twelve of the sixteen real clips
        // better (poster_384 -7.9 %, fish_1160 -6.1 %; coin_568 +1.3 %).
        self.lambda_scale = if preset >= Fast { 1.0 } else { 1.4 };
        // In every preset (x264's from superfast): a flickering light
        // (fish_1160) is half of the bits without it; in ultrafast -6.8
        // (its statistics are about 2.6 % of ultrafast's profile).
        self.weightp = true;
        self.preset_partitions(preset);
        // Fast P-skip before the search up to slow (x264's below subme 3,
        // to veryfast): against the skip after the search alone,
        // ultrafast +1.6 % for about 0.88x its time, superfast +1.7 % for
        // 0.93x, veryfast +1.9 % for 0.87-0.92x, medium +1.3 % for
        // 0.79-0.82x, slow +1.0 % for 0.75x (the 28 sequences, one run).
        // Slower keeps the search on every macroblock. Beside one skipped
        // neighbour (since 2026-12-06), and in the full decision (fast to
        // slow), only skips that leave little error are taken so
        // (`EARLY_SKIP_MAX_SSE` in the analysis).
        self.early_pskip = preset <= Slow;
        self.preset_deblock(preset);
        // The 8x8 transform from superfast: -5.4 against ultrafast, for
        // 1.10x its time.
        self.transform_8x8 = preset >= Superfast;
        // One reference below medium (x264's medium has three). In
        // medium two, the second searched only while it saves 3 % of the
        // estimates (`refs_choice`) and refined by one sub-pel move a
        // step: against one reference -0.95 % on the 28 sequences and
        // four of other kinds for 1.045x the wall time (birds_720p
        // -6.3 %, album_160 -6.2 %, pan_cif -5.1 %; `benches/pair.py`,
        // 60 frames); both searched in every frame as the first is,
        // -1.55 % for 1.16x (fish_1160 +4.2 %: under a flickering light
        // half its inter blocks took the older reference, and the
        // deblocking across the two smoothed its detail). Three in slow,
        // chosen alike (`refs_choice` has the figures); five in slower.
        self.refs = match preset {
            Slower => 5,
            Slow => 3,
            Medium => 2,
            _ => 1,
        };
        self.refs_choice = matches!(preset, Medium | Slow);
        // Sub-pel RD: 1.6 % on the set's mean for 23 % more of medium's
        // instructions (pan_cif): from slow, as x264's subme 8.
        self.subpel_rd = preset >= Slow;
        // Splits within 5/4 of the 16x16 estimate in slower: in medium
        // -1.53 % on the 28 sequences' mean for 1.20x its encode time
        // (cup_vga_30 -4.9 %, plant_qvga and face_360p -4.0 %,
        // testsrc2_qcif -3.7 %: edges of moving objects),
        // in slow -0.85 % for 1.11x, which would take slow from 0.83-0.89x
        // of x264 slow's time to 0.92-0.99x (a margin too thin to spend);
        // 1.1 instead of 5/4, medium -1.35 % for 1.18x.
        self.split_margin = preset >= Slower;
        // Splits searched within 1.1 of the 16x16 estimate from slow
        // (`partition::ROUGH_SPLIT_MARGIN` has the figures): in medium,
        // with the full-pel walk's steps across (no diagonals then),
        // -1.05 % for 1.062x its time against neither (the walk alone
        // -0.19 % for 1.004x), time that medium's against x264 medium's
        // does not leave.
        self.split_search_margin = preset >= Slow;
        // Chroma in the sub-pel cost (x264's from its subme 5) in no
        // preset: medium -0.05 % on the set's mean for 1.045x its encode
        // time (-0.23 % on PSNR of Y, U and V weighted 6:1:1), fast -0.15 %
        // for 1.044x (the 28 sequences, one run).
        self.chroma_me = false;
        // P frames priced with the contexts they start from below medium
        // (whose RDOQ prices every level): against adapting (the 28
        // sequences, one run each) ultrafast -0.03 % for 0.963x its encode
        // time, superfast +0.18 % for 0.960x, veryfast +0.18 % for 0.923x,
        // faster +0.00 % for 0.960x, fast +0.21 % for 0.994x (0.979x its
        // instructions on three sequences); medium +1.9 % for 0.98x (I
        // frames frozen too in that run).
        self.adaptive_pricing = preset >= Medium;
        // The fast decision's intra first (inter coded only where 16x16
        // intra does not beat it by SATD), against coding both and
        // weighing them by cost: ultrafast +0.36 % for 0.952x its encode
        // time (0.947x its instructions on diver_vga, cockatoo_720p,
        // handheld_vga, face_360p and fish_1160: diver_vga 0.886x),
        // superfast +0.51 % for 0.968x, veryfast +0.61 % for 0.970x,
        // faster +0.27 % for 0.976x (the 28 sequences, one run each).
        self.decision = if preset >= Fast {
            ModeDecision::Full
        } else {
            ModeDecision::Fast
        };
        self.preset_search(preset);
        self
    }

    /// The deblocking offsets of `preset`: a part of
    /// [`EncoderConfig::preset`].
    fn preset_deblock(&mut self, preset: EncoderPreset) {
        use EncoderPreset::*;
        // The deblocking offsets chosen per frame from medium (against
        // zero, the 32 sequences, `benches/pair.py`, 60 frames, one run
        // each): medium -0.28 % for 1.006x its encode time, slow +0.01 %
        // for 1.003x (cockatoo_720p -3.4 and -3.8 %, static_noise_cif
        // -3.4 and -1.5 %, the others within about 1 % either way);
        // ultrafast -0.05 % for 1.027x, superfast -0.08 % for 1.025x,
        // veryfast -0.03 % for 1.014x, fast -0.14 % for 1.013x: off the
        // front there, zero without the trial.
        self.deblock_offsets = if preset >= Medium {
            None
        } else {
            Some(DeblockOffsets::ZERO)
        };
    }

    /// The intra blocks and inter partitions of `preset`: a part of
    /// [`EncoderConfig::preset`].
    fn preset_partitions(&mut self, preset: EncoderPreset) {
        use EncoderPreset::*;
        // I frames in blocks from superfast (as x264's; its ultrafast has
        // none): one frame in 30 and most of the bits of a still scene
        // (talk_vga). In ultrafast (one sub-pel move, no starts), their
        // first 60 frames, none against all: +5.46 % on the 28 sequences'
        // mean for 0.921x the whole process's time (0.948x the encoder's
        // own; `benches/pair.py`, one run): with them ultrafast took
        // about twice x264 ultrafast's time. At 30 frames +8.0 % for
        // 0.974x the encoder's time (2026-12-04).
        self.i_frame_partitions = if preset == Ultrafast {
            Partitions::NONE
        } else {
            Partitions::ALL
        };
        // P frames' intra blocks from veryfast (x264's from superfast):
        // 4x4 intra in P frames alone took 46 % more of ultrafast's time
        // for about 1 % fewer bits. 4x4 blocks from slow: in medium they
        // won 771 of 339,670 P macroblocks analysed at QP 22 (8x8 blocks
        // 26,640), and without them medium took +0.12 % for 0.923x its
        // time, veryfast +0.31 % for 0.950x. The inter partitions in
        // medium (as x264's faster presets leave p8x8 out).
        self.partitions = Partitions {
            p8x8: preset >= Medium,
            i8x8: preset >= Veryfast,
            i4x4: preset >= Slow,
        };
    }

    /// The search settings of `preset` (the predictor's pattern kept): a
    /// part of [`EncoderConfig::preset`].
    fn preset_search(&mut self, preset: EncoderPreset) {
        use EncoderPreset::*;
        if let Some(search) = self.predictor.search_mut() {
            // Quarter-pel in every preset: in ultrafast -4.5, for no time
            // this machine could show (x264's ultrafast has full-pel only,
            // subme 0).
            search.subpel = Subpel::Quarter;
            // The window reaches 32 pels from the camera's motion in every
            // preset (before 2026-12-07, 16 below slow): a hand-held camera
            // turns and moves closer as well as pans, and one vector for the
            // frame leaves the picture's corners, and a bird flying across
            // it, further from it than 16 (cockatoo_720p: -5.4 % in medium,
            // -7.6 % in ultrafast). On the 28 sequences and four of other
            // kinds (`benches/pair.py`, 60 frames, one run each) medium
            // -0.12 % for 0.991x its wall time, ultrafast -0.25 % for
            // 1.011x; 24 pels gave -0.11 % and -0.22 %. x264 reaches
            // further still: its window is centred on each block's
            // predictors.
            search.range = WIDE_RANGE;
            // 3 pels in medium: 0.2 % more bits than 4 on the development
            // set's mean, for 7 % fewer instructions (pan_cif).
            search.window = match preset {
                Ultrafast | Superfast | Veryfast => 0,
                Faster | Fast | Medium => 3,
                Slow | Slower => 4,
            };
            // SAD at full pel up to medium (x264's at every subme but
            // tesa's): against SATD -1.0 in ultrafast and in veryfast,
            // -0.5 in faster for 0.97x its time, -0.0 in fast for 0.91x,
            // -0.3 in medium for the same time; +0.8 in slow (its window
            // of 4 and range 32) for 0.98x.
            search.full_pel_sad = preset <= Medium;
            // SAD at sub-pel too up to superfast (x264's subme 1): +1.0 in
            // ultrafast for 0.93x its time, +1.4 in superfast for 0.93x;
            // in veryfast +1.0 for no time this machine could show.
            search.sub_pel_sad = preset <= Superfast;
            // Up to superfast, as x264's subme 1 (one half-pel and one
            // quarter-pel pass), one move a sub-pel step and no sub-pel
            // starts: against four moves and the starts (`benches/pair.py`,
            // the 28 sequences, their first 60 frames, one run) ultrafast
            // +1.80 % for 0.912-0.922x its wall time (two runs), superfast
            // +1.77 % for 0.910x, on the slope between the presets; veryfast
            // +1.96 % for 0.950x, off it. Starts alone in ultrafast +0.99 %
            // for 0.951x, one move alone +0.81 % for 0.954x.
            let subme1 = preset <= Superfast;
            search.subpel_moves = if subme1 { 1 } else { SUBPEL_MOVES };
            // The starts from slow. Against them (`benches/pair.py`, the
            // 28 sequences and five of other kinds, 60 frames, one run
            // each, 2026-12-07): medium +0.63 % (pchip +0.40 %) for 0.935x
            // its wall time, where medium sat at 0.97-1.02x x264 medium's
            // time at -9.1 % (the bar +5 % at 1.0x); fast +0.69 % for
            // 0.965x, veryfast +0.87 % for 0.973x (about its slope to
            // superfast: the presets stay each the one before with tools
            // added). Slow and slower keep them (not measured again).
            search.sub_pel_starts = preset >= Slow;
        }
    }

    /// Whether intra luma is tried in 8x8 blocks: `i8x8` among the
    /// partitions, with the 8x8 transform on (as x264 ties it to
    /// `--8x8dct`).
    pub fn intra8x8(&self) -> bool {
        self.partitions.i8x8 && self.transform_8x8
    }

    /// Whether I frames try intra luma in 8x8 blocks: `i8x8` among
    /// [`EncoderConfig::i_frame_partitions`], with the 8x8 transform on.
    pub fn i_frame_intra8x8(&self) -> bool {
        self.i_frame_partitions.i8x8 && self.transform_8x8
    }

    /// The predictor `p` in this configuration: a search predictor keeps
    /// the search settings the preset gave (sub-pel, range, window) and
    /// takes its own pattern; other predictors come as they are.
    pub fn with_predictor(mut self, mut p: Predictor) -> EncoderConfig {
        if let (Some(old), Some(new)) = (self.predictor.search_mut().copied(), p.search_mut()) {
            *new = SearchSettings {
                method: new.method,
                ..old
            };
        }
        self.predictor = p;
        self
    }

    /// The macroblock partitions P frames try.
    pub fn partitions(mut self, p: Partitions) -> EncoderConfig {
        self.partitions = p;
        self
    }

    /// The intra blocks I frames try.
    pub fn i_frame_partitions(mut self, p: Partitions) -> EncoderConfig {
        self.i_frame_partitions = p;
        self
    }

    /// Turns the adaptive 8x8 transform of inter luma on or off.
    pub fn transform_8x8(mut self, on: bool) -> EncoderConfig {
        self.transform_8x8 = on;
        self
    }

    /// How many references P frames may predict from (x264's `--ref`).
    pub fn refs(mut self, refs: u8) -> EncoderConfig {
        self.refs = refs;
        self
    }

    /// The luma interpolation filter of `block` P frames.
    pub fn luma_filter(mut self, choice: FilterChoice) -> EncoderConfig {
        self.luma_filter = choice;
        self
    }

    /// Turns fast P-skip on or off.
    pub fn fast_pskip(mut self, on: bool) -> EncoderConfig {
        self.fast_pskip = on;
        self
    }

    /// Turns the fast P-skip probe before the motion search on or off.
    pub fn early_pskip(mut self, on: bool) -> EncoderConfig {
        self.early_pskip = on;
        self
    }

    /// Turns the reconstruction given back with each frame on or off.
    pub fn reconstruction(mut self, on: bool) -> EncoderConfig {
        self.reconstruction = on;
        self
    }

    /// Turns the decision's adaptive residual pricing on or off.
    pub fn adaptive_pricing(mut self, on: bool) -> EncoderConfig {
        self.adaptive_pricing = on;
        self
    }

    /// Turns chroma motion estimation on or off.
    pub fn chroma_me(mut self, on: bool) -> EncoderConfig {
        self.chroma_me = on;
        self
    }

    /// Turns the splits' search margin on or off
    /// ([`EncoderConfig::split_search_margin`]).
    pub fn split_search_margin(mut self, on: bool) -> EncoderConfig {
        self.split_search_margin = on;
        self
    }

    /// Turns the splits' margin on or off ([`EncoderConfig::split_margin`]).
    pub fn split_margin(mut self, on: bool) -> EncoderConfig {
        self.split_margin = on;
        self
    }

    /// Turns sub-pel RD refinement on or off.
    pub fn subpel_rd(mut self, on: bool) -> EncoderConfig {
        self.subpel_rd = on;
        self
    }

    /// The references P frames predict from: the configuration's for
    /// `block`, one for the other predictors.
    pub fn effective_refs(&self) -> u8 {
        match self.predictor {
            Predictor::Block(_) => self.refs,
            _ => 1,
        }
    }

    /// Turns weighted prediction on or off.
    pub fn weightp(mut self, on: bool) -> EncoderConfig {
        self.weightp = on;
        self
    }

    /// The QP of I frames: `qp - 6 log2(ipratio)`, rounded, at least 0.
    pub fn intra_qp(&self) -> u8 {
        let offset = (6.0 * self.ipratio.log2()).round();
        (f64::from(self.qp) - offset).clamp(0.0, f64::from(MAX_QP)) as u8
    }

    /// Turns SSIM measurement on or off.
    pub fn ssim(mut self, on: bool) -> EncoderConfig {
        self.metrics = self.metrics.with(Metric::Ssim, on);
        self
    }

    /// The metrics to measure (see [`EncoderConfig::metrics`]).
    pub fn metrics(mut self, metrics: Metrics) -> EncoderConfig {
        self.metrics = metrics;
        self
    }

    /// What the encoder's quality record measures: these metrics, SSIM
    /// over x264's 8x8 windows.
    pub fn quality(&self) -> QualitySettings {
        QualitySettings {
            metrics: self.metrics,
            ssim: SsimWindow::Blocks8x8,
        }
    }

    pub(crate) fn check(&self) -> Result<(), String> {
        if self.qp > MAX_QP {
            return Err(format!("QP {} is not in 0..={MAX_QP}", self.qp));
        }
        if !(self.lambda_scale > 0.0 && self.lambda_scale < 1e3) {
            return Err(format!("lambda scale {} is not in (0, 1000)", self.lambda_scale));
        }
        if !(1.0..=16.0).contains(&self.ipratio) {
            return Err(format!("ipratio {} is not in 1..=16", self.ipratio));
        }
        if !(1..=MAX_REFS).contains(&self.refs) {
            return Err(format!("{} references is not in 1..={MAX_REFS}", self.refs));
        }
        self.predictor.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_label_parses_back_to_its_predictor() {
        for s in [
            "zero",
            "block:esa",
            "block:tss",
            "flow-block:lk",
            "flow-block:hs",
            "flow-block:dis",
            "flow-block:tvl1",
            "dense-tvl1",
            "dense-lk",
            "dense-dis",
            "dense-hs",
            "obmc",
        ] {
            let p: Predictor = s.parse().unwrap();
            assert_eq!(p.label(), s);
        }
        assert_eq!("block".parse::<Predictor>().unwrap(), Predictor::default());
    }

    #[test]
    fn presets_set_the_tools_and_keep_the_search_pattern() {
        let esa: Predictor = "block:esa".parse().unwrap();
        let base = EncoderConfig::new().predictor(esa);
        for p in EncoderPreset::ALL {
            use EncoderPreset::*;
            assert_eq!(p.name().parse::<EncoderPreset>(), Ok(p));
            let c = base.preset(p);
            let s = *c.predictor.clone().search_mut().unwrap();
            assert_eq!(s.method, Method::Esa, "{p:?}");
            assert_eq!(c.rdoq, p >= Medium);
            assert_eq!(c.transform_8x8, p >= Superfast);
            assert_eq!(s.full_pel_sad, p <= Medium);
            assert_eq!(s.sub_pel_sad, p <= Superfast);
            assert_eq!(c.refs, [1, 1, 1, 1, 1, 2, 3, 5][p as usize]);
            assert_eq!(c.refs_choice, matches!(p, Medium | Slow));
            assert!(c.weightp);
            let i_blocks = if p >= Superfast {
                Partitions::ALL
            } else {
                Partitions::NONE
            };
            assert_eq!(c.i_frame_partitions, i_blocks);
            assert_eq!(s.subpel_moves, if p >= Veryfast { SUBPEL_MOVES } else { 1 });
            assert_eq!(s.sub_pel_starts, p >= Slow);
            assert_eq!(c.partitions.p8x8, p >= Medium);
            assert_eq!(c.partitions.i4x4, p >= Slow);
            assert_eq!(c.early_pskip, p <= Slow);
            assert_eq!(c.intra8x8(), p >= Veryfast);
            assert_eq!(s.subpel, Subpel::Quarter);
            assert_eq!(c.decision == ModeDecision::Full, p >= Fast);
            assert_eq!(s.range, WIDE_RANGE);
            assert_eq!(s.window, [0, 0, 0, 3, 3, 3, 4, 4][p as usize]);
            assert_eq!(c.subpel_rd, p >= Slow);
            assert_eq!(c.split_margin, p >= Slower);
            assert_eq!(c.split_search_margin, p >= Slow);
        }
        // Each preset is the one before with tools added: nothing is off
        // that a faster one has on.
        for w in EncoderPreset::ALL.windows(2) {
            let (a, b) = (base.preset(w[0]), base.preset(w[1]));
            assert!(b.rdoq >= a.rdoq && b.weightp >= a.weightp && b.transform_8x8 >= a.transform_8x8);
            assert!(b.refs >= a.refs && b.subpel_rd >= a.subpel_rd && b.split_margin >= a.split_margin);
            assert!(b.split_search_margin >= a.split_search_margin);
            let (mut pa, mut pb) = (a.predictor, b.predictor);
            let (sa, sb) = (pa.search_mut().unwrap(), pb.search_mut().unwrap());
            assert!(sb.subpel_moves >= sa.subpel_moves && sb.sub_pel_starts >= sa.sub_pel_starts);
            assert!(b.i_frame_partitions.i4x4 >= a.i_frame_partitions.i4x4);
        }
        // The default configuration is the medium preset's.
        assert_eq!(
            EncoderConfig::new().preset(EncoderPreset::Medium),
            EncoderConfig::new()
        );
        assert!("placebo".parse::<EncoderPreset>().is_err());
    }

    #[test]
    fn bad_names_are_errors() {
        for s in ["", "blok", "block:xyz", "zero:esa", "dense-lk:3", "flow-block:tv"] {
            assert!(s.parse::<Predictor>().is_err(), "{s}");
        }
        assert!(EncoderConfig::new().qp(52).check().is_err());
    }
}
