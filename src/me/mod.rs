//! Block-matching motion estimation.
//!
//! [`estimate`] finds one vector per block of the current picture such that
//! the block matches the reference at `block position + vector`, with the
//! cost of the match. Methods have ffmpeg `mestimate`'s names ([`Method`]);
//! costs are SAD, SSD or SATD ([`Metric`]) plus, optionally, a rate term
//! `lambda * R(mv - mvp)` where `R` is the bit length of the codec's vector
//! code and `mvp` the codec's median predictor, so the search prices vectors
//! as the encoder will pay for them.
//!
//! Full-pel candidates lie within `range` pixels of the block in each
//! direction; they may point outside the picture, into the reference's
//! replicated border, up to `range` pixels beyond the edge (unrestricted
//! vectors). Sub-pel refinement evaluates exactly the prediction the decoder
//! forms (`codec::interp`).
//!
//! Ties are broken the same way by every method: lower cost, then smaller
//! `dx^2 + dy^2`, then raster order (`dy`, then `dx`). `esa` therefore
//! returns the true minimum over the window, deterministically.
//!
//! Blocks run in parallel (rayon). When a block's result depends on its
//! neighbours' (a rate term, EPZS candidates), blocks are processed in
//! diagonal wavefronts so that every neighbour a block reads is final:
//! results never depend on the number of threads.
//!
//! ```
//! use mocomp::codec::Plane;
//! use mocomp::me::{estimate, MeConfig, Method};
//! let reference = Plane::from_fn(64, 64, |x, y| ((x * 7) ^ (y * 13)) as u8).unwrap();
//! // The current picture is the reference moved 3 px right, 1 down.
//! let current = Plane::from_fn(64, 64, |x, y| reference.pixel_clamped(x as isize - 3, y as isize - 1)).unwrap();
//! let field = estimate(&current, &reference, &MeConfig::new(Method::Esa, 16, 8)).unwrap();
//! assert_eq!(field.vector(1, 1).x, -3 * 4); // quarter-pel units
//! assert_eq!(field.vector(1, 1).y, -1 * 4);
//! ```

pub mod cost;
pub mod dsp;
pub(crate) mod halfpel;
pub(crate) mod pipeline;
pub(crate) mod sea;
pub(crate) mod search;
pub(crate) use search::SQUARE;

use std::fmt;
use std::str::FromStr;

use rayon::prelude::*;

use crate::codec::interp::{predict_luma, LumaFilter};
use crate::codec::mv::{mvd_bits, Mv};
use crate::codec::mvpred::predict_in_grid;
use crate::codec::Plane;
pub use cost::Metric;
use dsp::{CappedFn, CostFn};

/// A search method, named as in ffmpeg's `mestimate` filter.
///
/// Reach: `esa` sees the whole window. `tss` and `ntss` reach the sum of
/// their steps, `ceil(range/2)` halved down to 1: 7 pixels at range 7 or 8,
/// 15 at range 16 (the window's last pixel can be out of reach).
/// `tdls`, `fss`, `ds`, `hexbs` and `epzs` walk without a step limit, inside
/// the window; `hexbs` needs one pixel of room inside it for its hexagon.
/// On a smooth, unimodal cost every method finds the minimum within its
/// reach; on real pictures the fast ones can stop in a local minimum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Exhaustive search of the whole window: the true minimum.
    Esa,
    /// Three-step search: 8 points at a step that halves from about half the
    /// range down to 1, moving to the best each time.
    Tss,
    /// New three-step search (Li, Zeng, Liou 1994): the first step adds the 8
    /// neighbours at distance 1 and stops early when the minimum is at or
    /// next to the centre.
    Ntss,
    /// Two-dimensional logarithmic search: a + pattern whose step halves
    /// when the centre wins, then the 8 neighbours at step 1.
    Tdls,
    /// Four-step search (Po, Ma 1996): 9 points at step 2 up to three times,
    /// then the 8 neighbours at step 1.
    Fss,
    /// Diamond search (Zhu, Ma 2000): the large diamond (8 points at distance
    /// 2) until the centre wins, then the small diamond (4 at distance 1).
    Ds,
    /// Hexagon search (Zhu et al. 2002): a 6-point hexagon of radius 2 until
    /// the centre wins, then the 4 points at distance 1.
    Hexbs,
    /// Predictive zonal search (Tourapis 2002): the zero, median, left, top,
    /// top-right and co-located (previous field) candidates, then the small
    /// diamond from the best until the centre wins.
    Epzs,
}

impl Method {
    /// Every method, cheapest-to-explain first.
    pub const ALL: [Method; 8] = [
        Method::Esa,
        Method::Tss,
        Method::Ntss,
        Method::Tdls,
        Method::Fss,
        Method::Ds,
        Method::Hexbs,
        Method::Epzs,
    ];

    /// The ffmpeg `mestimate` name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Esa => "esa",
            Method::Tss => "tss",
            Method::Ntss => "ntss",
            Method::Tdls => "tdls",
            Method::Fss => "fss",
            Method::Ds => "ds",
            Method::Hexbs => "hexbs",
            Method::Epzs => "epzs",
        }
    }

    /// Whether the method reads neighbouring blocks' results.
    fn uses_neighbours(self) -> bool {
        matches!(self, Method::Epzs)
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Method, String> {
        Method::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
            let names: Vec<_> = Method::ALL.iter().map(|m| m.name()).collect();
            format!("unknown search method '{s}' (one of {})", names.join(", "))
        })
    }
}

/// Sub-pel refinement after the full-pel search.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Subpel {
    /// Full-pel vectors only.
    #[default]
    None,
    /// Half-pel: around the best full-pel vector, the four half-pel
    /// neighbours across, then the diagonal between the better two.
    Half,
    /// Half-pel, then the same five quarter-pel steps around the best
    /// half-pel vector.
    Quarter,
}

impl Subpel {
    /// `none`, `half` or `quarter`.
    pub fn name(self) -> &'static str {
        match self {
            Subpel::None => "none",
            Subpel::Half => "half",
            Subpel::Quarter => "quarter",
        }
    }
}

impl FromStr for Subpel {
    type Err = String;
    fn from_str(s: &str) -> Result<Subpel, String> {
        match s {
            "none" => Ok(Subpel::None),
            "half" => Ok(Subpel::Half),
            "quarter" => Ok(Subpel::Quarter),
            _ => Err(format!("unknown sub-pel level '{s}' (none, half, quarter)")),
        }
    }
}

/// Block sizes [`estimate`] accepts.
pub const BLOCK_SIZES: [usize; 4] = [4, 8, 16, 32];

/// Largest search range.
pub const MAX_RANGE: i32 = 64;

/// How to search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeConfig {
    /// The search pattern.
    pub method: Method,
    /// Square block side: 4, 8, 16 or 32.
    pub block: usize,
    /// Full-pel search range, 1..=64.
    pub range: i32,
    /// Sub-pel refinement.
    pub subpel: Subpel,
    /// Distortion measure.
    pub metric: Metric,
    /// Weight of the vector's bits, or 0 for none. See [`lambda_for_qp`].
    pub lambda: f64,
    /// EPZS only: after its descent, every full-pel position within this
    /// many pels of the best is tried, and the descent resumed (0: none).
    /// Flat shapes over smooth backgrounds leave the descent in a local
    /// minimum; a window of 4 closes most of the gap to exhaustive search.
    pub window: i32,
    /// Full-pel positions are compared by SAD, only the sub-pel steps by
    /// `metric` (x264's way: SATD where it decides little costs most).
    pub full_pel_sad: bool,
    /// Exhaustive search (`esa`, and EPZS's window) skips the positions
    /// whose lower bound from sums of the block's quadrants already
    /// exceeds the best cost ([`sea`]), and where that does not pay (EPZS's
    /// small windows) takes a window row's 16x16 SADs sixteen at once: the
    /// same vectors, far less work. Off only to compare with the plain
    /// search, every position evaluated one at a time.
    pub successive_elimination: bool,
    /// How many times each sub-pel step (half, then quarter) may move the
    /// vector: the step is tried again around each new best until the
    /// best stays, at most this often (x264 walks its sub-pel diamonds
    /// twice each at `--subme 7`; 1 is one move a step).
    pub subpel_moves: u8,
    /// The candidates' own quarter-pel positions (the neighbours' and the
    /// previous field's vectors, as they are) are starts of the sub-pel
    /// refinement beside the full-pel best, measured through the codec's
    /// filter: where one costs less, the refinement walks from it.
    pub sub_pel_starts: bool,
}

/// The most [`MeConfig::subpel_moves`] allowed.
pub const MAX_SUBPEL_MOVES: u8 = 8;

impl MeConfig {
    /// `method` with `block` x `block` blocks and `range`; SAD, full-pel, no
    /// rate term.
    pub fn new(method: Method, block: usize, range: i32) -> MeConfig {
        MeConfig {
            method,
            block,
            range,
            subpel: Subpel::None,
            metric: Metric::Sad,
            lambda: 0.0,
            window: 0,
            full_pel_sad: false,
            successive_elimination: true,
            subpel_moves: 1,
            sub_pel_starts: false,
        }
    }

    /// The measure of full-pel positions.
    fn full_pel_metric(&self) -> Metric {
        if self.full_pel_sad {
            Metric::Sad
        } else {
            self.metric
        }
    }

    fn check(&self) -> Result<(), MeError> {
        if !BLOCK_SIZES.contains(&self.block) {
            return Err(MeError::Block(self.block));
        }
        if !(1..=MAX_RANGE).contains(&self.range) {
            return Err(MeError::Range(self.range));
        }
        if !(self.lambda >= 0.0 && self.lambda < 1e6) {
            return Err(MeError::Lambda(self.lambda));
        }
        if !(0..=MAX_RANGE).contains(&self.window) {
            return Err(MeError::Range(self.window));
        }
        if !(1..=MAX_SUBPEL_MOVES).contains(&self.subpel_moves) {
            return Err(MeError::SubpelMoves(self.subpel_moves));
        }
        Ok(())
    }
}

/// The H.264 reference encoder's motion lambda for `qp`: the weight of one
/// bit against SAD or SATD is `sqrt(0.85 * 2^((qp - 12) / 3))`; against SSD
/// its square.
pub fn lambda_for_qp(metric: Metric, qp: u8) -> f64 {
    let l2 = 0.85 * 2f64.powf((f64::from(qp) - 12.0) / 3.0);
    match metric {
        Metric::Ssd => l2,
        Metric::Sad | Metric::Satd => l2.sqrt(),
    }
}

/// Why a search cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeError {
    /// Unsupported block size.
    #[error("block size {0} is not one of 4, 8, 16, 32")]
    Block(usize),
    /// Range outside 1..=64.
    #[error("search range {0} is outside 1..=64")]
    Range(i32),
    /// Negative or absurd lambda.
    #[error("lambda {0} is out of range")]
    Lambda(f64),
    /// Sub-pel moves outside 1..=8.
    #[error("sub-pel moves {0} is outside 1..=8")]
    SubpelMoves(u8),
    /// The pictures differ in size, or their border is too narrow.
    #[error("{0}")]
    Pictures(String),
}

/// `v` times `k`, kept within the codec's range.
fn scale_mv(v: Mv, k: i32) -> Mv {
    let limit = crate::codec::mv::MV_LIMIT;
    let scale = |c: i32| c.saturating_mul(k).clamp(-limit, limit);
    Mv::new(scale(v.x), scale(v.y))
}

/// One vector and its cost per block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MotionField {
    block: usize,
    cols: usize,
    rows: usize,
    vectors: Vec<Mv>,
    costs: Vec<u32>,
}

impl MotionField {
    /// A zero field for a `width x height` picture in `block`-sized blocks
    /// (the last column and row may be partial).
    pub fn new(width: usize, height: usize, block: usize) -> MotionField {
        let (cols, rows) = (width.div_ceil(block), height.div_ceil(block));
        MotionField {
            block,
            cols,
            rows,
            vectors: vec![Mv::ZERO; cols * rows],
            costs: vec![0; cols * rows],
        }
    }

    /// The field of `vectors` (one per block, raster order) over a `width
    /// x height` picture; `None` when their number is not the blocks'.
    pub(crate) fn from_vectors(
        width: usize,
        height: usize,
        block: usize,
        vectors: Vec<Mv>,
    ) -> Option<MotionField> {
        let mut field = MotionField::new(width, height, block);
        (vectors.len() == field.vectors.len()).then(|| {
            field.vectors = vectors;
            field
        })
    }

    /// Block side in pixels.
    pub fn block(&self) -> usize {
        self.block
    }

    /// Blocks per row.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Rows of blocks.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The vector of block (col, row), quarter-pel.
    pub fn vector(&self, col: usize, row: usize) -> Mv {
        self.vectors[row * self.cols + col]
    }

    /// The cost of block (col, row) (distortion plus rate term).
    pub fn cost(&self, col: usize, row: usize) -> u32 {
        self.costs[row * self.cols + col]
    }

    /// All vectors, row after row.
    pub fn vectors(&self) -> &[Mv] {
        &self.vectors
    }

    /// All costs, row after row.
    pub fn costs(&self) -> &[u32] {
        &self.costs
    }

    /// The field with every vector times `k` (kept within the codec's
    /// range): the motion over `k` frames of what moves steadily.
    pub fn scaled(&self, k: i32) -> MotionField {
        MotionField {
            vectors: self.vectors.iter().map(|&v| scale_mv(v, k)).collect(),
            ..self.clone()
        }
    }

    /// Block rows `rows` set to `vectors`' (one per block of the whole
    /// field, raster order) times `k`, as [`MotionField::scaled`] scales
    /// them: a field filled as the frame it comes from is decided.
    pub(crate) fn set_rows(&mut self, vectors: &[Mv], rows: std::ops::Range<usize>, k: i32) {
        let blocks = rows.start * self.cols..rows.end * self.cols;
        for (to, &from) in self.vectors[blocks.clone()].iter_mut().zip(&vectors[blocks]) {
            *to = scale_mv(from, k);
        }
    }

    /// The codec's predicted vector for block (col, row) from the blocks
    /// before it in raster order.
    pub fn predictor(&self, col: usize, row: usize) -> Mv {
        predict_in_grid(self.cols, col, row, |c, r| Some(self.vectors[r * self.cols + c]))
    }
}

/// Everything one block's search reads.
pub(crate) struct SearchContext<'a> {
    cur: &'a Plane,
    reference: &'a Plane,
    x: isize,
    y: isize,
    cfg: &'a MeConfig,
    mvp: Mv,
    lambda_q8: u64,
    halfpel: Option<&'a halfpel::HalfPel>,
    /// The full-pel centre of the window: zero, or a seed's.
    origin: (i32, i32),
    /// What a block's many positions share, found once: the full-pel
    /// metric's kernel, the block's samples and the offsets
    /// `[min dx, max dx, min dy, max dy]` at which the reference's border
    /// holds the whole block.
    full_pel_kernel: CostFn,
    block: &'a [u8],
    in_place: [i32; 4],
    /// The capped kernel where the full-pel metric is SATD on 16x16 blocks.
    capped: Option<CappedFn>,
    /// The same kernel where the sub-pel metric is SATD on 16x16 blocks
    /// (uncapped: past the size dispatch of [`Metric::cost`]).
    sub_pel_satd16: Option<CappedFn>,
    /// The reference's quadrant sums, for successive elimination.
    sums: Option<&'a sea::QuadrantSums>,
    /// The block's chroma, priced beside its luma in the sub-pel steps.
    chroma: Option<ChromaBlock<'a>>,
}

/// A 16x16 block's two 8x8 chroma blocks and the reference's chroma
/// planes: x264's chroma motion estimation (`--chroma-me`, from its
/// `--subme 5`), the sub-pel steps' cost the sum of the three planes'.
#[derive(Clone, Copy)]
pub(crate) struct ChromaBlock<'a> {
    /// Cb and Cr of the block being searched.
    pub source: &'a [[u8; 64]; 2],
    /// Cb and Cr of the reference (as predicted from: weighted where the
    /// luma is).
    pub reference: [&'a Plane; 2],
}

impl<'a> SearchContext<'a> {
    /// The search of the block at `(x, y)`: no predicted vector, no rate
    /// term, no half-pel planes, the window centred on zero.
    fn new(
        cur: &'a Plane,
        reference: &'a Plane,
        (x, y): (usize, usize),
        cfg: &'a MeConfig,
    ) -> SearchContext<'a> {
        let (x, y) = (x as isize, y as isize);
        let (pad, b) = (reference.pad() as isize, cfg.block as isize);
        let span = |at: isize, side: usize| [-pad - at, side as isize + pad - b - at].map(|d| d as i32);
        let ([x0, x1], [y0, y1]) = (span(x, reference.width()), span(y, reference.height()));
        SearchContext {
            cur,
            reference,
            x,
            y,
            cfg,
            mvp: Mv::ZERO,
            lambda_q8: 0,
            halfpel: None,
            origin: (0, 0),
            full_pel_kernel: cfg.full_pel_metric().kernel(),
            block: &cur.data()[cur.index(x, y)..],
            in_place: [x0, x1, y0, y1],
            capped: (cfg.block == 16 && cfg.full_pel_metric() == Metric::Satd)
                .then(|| dsp::pixel().satd_16x16_capped),
            sub_pel_satd16: (cfg.block == 16 && cfg.metric == Metric::Satd)
                .then(|| dsp::pixel().satd_16x16_capped),
            sums: None,
            chroma: None,
        }
    }

    /// Distortion of the block against the reference at full-pel offset
    /// (dx, dy): read in place when the reference's border holds the block
    /// there, else through the codec's (clamping) prediction. Above `cap`,
    /// it may be any value above `cap` (the capped kernel's half).
    #[inline]
    fn distortion(&self, dx: i32, dy: i32, cap: u32) -> u32 {
        let [x0, x1, y0, y1] = self.in_place;
        if (x0..=x1).contains(&dx) && (y0..=y1).contains(&dy) {
            let at = self.reference.index(self.x + dx as isize, self.y + dy as isize);
            return self.distortion_at(at, cap);
        }
        self.distortion_clamped(dx, dy)
    }

    /// [`SearchContext::distortion`] of the reference's block at index
    /// `at` of its buffer (the caller knows it lies inside).
    #[inline]
    fn distortion_at(&self, at: usize, cap: u32) -> u32 {
        let (b, r, stride) = (
            self.cfg.block,
            &self.reference.data()[at..],
            self.reference.stride(),
        );
        match self.capped {
            Some(capped) => capped(self.block, self.cur.stride(), r, stride, cap),
            None => (self.full_pel_kernel)(self.block, self.cur.stride(), r, stride, b, b),
        }
    }

    /// [`SearchContext::distortion`] where the block reaches past the
    /// reference's border.
    #[cold]
    #[inline(never)]
    fn distortion_clamped(&self, dx: i32, dy: i32) -> u32 {
        let b = self.cfg.block;
        let mut scratch = [0u8; 32 * 32];
        predict_luma(
            LumaFilter::Sharp,
            self.reference,
            self.x,
            self.y,
            4 * dx,
            4 * dy,
            b,
            b,
            &mut scratch,
            b,
        );
        (self.full_pel_kernel)(self.block, self.cur.stride(), &scratch, b, b, b)
    }

    /// Rate term of a quarter-pel vector, in cost units.
    fn rate(&self, mv: Mv) -> u64 {
        if self.lambda_q8 == 0 {
            return 0;
        }
        (self.lambda_q8 * u64::from(mvd_bits(mv, self.mvp)) + 128) >> 8
    }

    /// The better of `best` and the off-grid vectors of `candidates` in
    /// the sub-pel measure ([`MeConfig::sub_pel_starts`]).
    fn sub_pel_start(&self, mut best: Candidate, candidates: &[Mv]) -> Candidate {
        if self.cfg.subpel == Subpel::None {
            return best;
        }
        with_scratch(self.cfg.block, |scratch| {
            for (i, &mv) in candidates.iter().enumerate() {
                let on_grid = mv.x & 3 == 0 && mv.y & 3 == 0;
                if on_grid || mv == best.mv || candidates[..i].contains(&mv) || !mv.in_range() {
                    continue;
                }
                let c = Candidate {
                    cost: self.sub_pel_cost(mv, scratch),
                    mv,
                };
                if c.beats(&best) {
                    best = c;
                }
            }
            best
        })
    }

    /// `best` of the full-pel search with its cost in the measure of the
    /// sub-pel steps, which compare against it.
    fn in_sub_pel_measure(&self, best: Candidate) -> Candidate {
        let same_measure = !self.cfg.full_pel_sad || self.cfg.metric == Metric::Sad;
        if self.cfg.subpel == Subpel::None || (same_measure && self.chroma.is_none()) {
            return best;
        }
        Candidate {
            cost: with_scratch(self.cfg.block, |scratch| self.sub_pel_cost(best.mv, scratch)),
            mv: best.mv,
        }
    }

    /// Full cost of full-pel (dx, dy) or, when it exceeds `bound`, a cost
    /// that does (positions that cannot beat `bound` may stop early).
    #[inline]
    fn full_pel_cost(&self, dx: i32, dy: i32, bound: u64) -> u64 {
        let rate = self.rate(Mv::full_pel(dx, dy));
        let cap = bound.saturating_sub(rate).min(u64::from(u32::MAX)) as u32;
        u64::from(self.distortion(dx, dy, cap)) + rate
    }

    /// Full cost of a quarter-pel vector: on the reference's half-pel
    /// planes where they reach (quarter-pel positions approximated), else on
    /// the decoder's prediction.
    pub(crate) fn sub_pel_cost(&self, mv: Mv, scratch: &mut [u8]) -> u64 {
        self.sub_pel_cost_in(None, mv, scratch)
    }

    /// [`SearchContext::sub_pel_cost`], read through `window` (of this
    /// block on this context's half-pel phases) where it holds `mv`.
    fn sub_pel_cost_in(&self, window: Option<&halfpel::PhaseWindow<'_>>, mv: Mv, scratch: &mut [u8]) -> u64 {
        let b = self.cfg.block;
        let (samples, stride) = match window {
            Some(w) if w.holds(mv) => w.block(mv, scratch),
            _ => halfpel::block_or_predicted(self.halfpel, self.reference, (self.x, self.y), mv, b, scratch),
        };
        let luma = match self.sub_pel_satd16 {
            Some(satd16) => satd16(self.block, self.cur.stride(), samples, stride, u32::MAX),
            None => self
                .cfg
                .metric
                .cost(self.block, self.cur.stride(), samples, stride, b, b),
        };
        u64::from(luma) + self.chroma_cost(mv) + self.rate(mv)
    }

    /// The chroma blocks' distortion at quarter-pel `mv` (the decoder's
    /// eighth-pel chroma prediction), 0 without chroma.
    fn chroma_cost(&self, mv: Mv) -> u64 {
        let Some(chroma) = &self.chroma else {
            return 0;
        };
        let (x, y) = (self.x / 2, self.y / 2);
        let mut pred = [0u8; 64];
        (0..2)
            .map(|p| {
                crate::codec::interp::predict_chroma(
                    chroma.reference[p],
                    x,
                    y,
                    mv.x,
                    mv.y,
                    8,
                    8,
                    &mut pred,
                    8,
                );
                u64::from(self.cfg.metric.cost(&chroma.source[p], 8, &pred, 8, 8, 8))
            })
            .sum()
    }
}

/// How far beyond the picture a search's half-pel planes reach: the
/// window's reach (range, plus one for the sub-pel steps and one for the
/// quarter-pel average's neighbour), rounded up to 8.
fn planes_margin(cfg: &MeConfig) -> usize {
    (cfg.range as usize + 2).div_ceil(8) * 8
}

/// The full-pel position nearest a quarter-pel vector (halves rounded up).
pub(crate) fn nearest_full_pel(mv: Mv) -> (i32, i32) {
    ((mv.x + 2) >> 2, (mv.y + 2) >> 2)
}

/// A vector and its cost (distortion plus rate term), ordered by the common
/// tie-break.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Candidate {
    /// Distortion plus `lambda` times the vector's bits.
    pub cost: u64,
    /// Quarter-pel.
    pub mv: Mv,
}

impl Candidate {
    fn key(&self) -> (u64, i64, i32, i32) {
        let (x, y) = (i64::from(self.mv.x), i64::from(self.mv.y));
        (self.cost, x * x + y * y, self.mv.y, self.mv.x)
    }

    /// Whether `self` beats `other`.
    pub fn beats(&self, other: &Candidate) -> bool {
        self.key() < other.key()
    }
}

fn check_pictures(cur: &Plane, reference: &Plane, cfg: &MeConfig) -> Result<(), MeError> {
    if cur.width() != reference.width() || cur.height() != reference.height() {
        return Err(MeError::Pictures(format!(
            "current {}x{} and reference {}x{} differ in size",
            cur.width(),
            cur.height(),
            reference.width(),
            reference.height()
        )));
    }
    // Full-pel reads reach range + block - 1 past the picture; sub-pel ones
    // go through the codec predictor, which needs block + 8.
    let need = cfg.range as usize + cfg.block + 8;
    for (name, p) in [("current", cur), ("reference", reference)] {
        if p.pad() < need {
            return Err(MeError::Pictures(format!(
                "the {name} picture's border is {} pixels, the search needs {need}",
                p.pad()
            )));
        }
    }
    Ok(())
}

/// Estimates the motion of `cur` against `reference` (same size, borders
/// extended), without a previous field for predictive candidates.
pub fn estimate(cur: &Plane, reference: &Plane, cfg: &MeConfig) -> Result<MotionField, MeError> {
    estimate_with_prior(cur, reference, cfg, None)
}

/// As [`estimate`], with the previous picture's field (same block size) as
/// the source of co-located candidates for predictive methods.
pub fn estimate_with_prior(
    cur: &Plane,
    reference: &Plane,
    cfg: &MeConfig,
    prior: Option<&MotionField>,
) -> Result<MotionField, MeError> {
    estimate_with_planes(cur, reference, cfg, prior, None, Mv::ZERO)
}

/// What the searches of one picture's blocks against one reference share,
/// made once: the configuration, the reference's half-pel planes and its
/// quadrant sums. [`estimate_with_planes`] searches every block with it;
/// the encoder searches a macroblock at a time, only those its mode
/// decision needs, with candidates of its own (x264's motion search
/// inside the macroblock analysis).
pub(crate) struct FrameSearch<'p> {
    cfg: MeConfig,
    lambda_q8: u64,
    halfpel: Option<Planes<'p>>,
    sums: Option<sea::QuadrantSums>,
    /// The full-pel centre of every block's window (zero unless
    /// [`FrameSearch::centred_on`]).
    centre: (i32, i32),
}

/// Half-pel planes the caller gave, or made for the search, or patches
/// made by each block's search.
enum Planes<'p> {
    Given(&'p halfpel::HalfPel),
    Own(halfpel::HalfPel),
    /// [`halfpel::with_patch`]es for this margin.
    PerBlock(usize),
}

impl Planes<'_> {
    fn get(&self) -> Option<&halfpel::HalfPel> {
        match self {
            Planes::Given(p) => Some(p),
            Planes::Own(p) => Some(p),
            Planes::PerBlock(_) => None,
        }
    }
}

impl<'p> FrameSearch<'p> {
    /// The searches of `cfg` against `reference` (borders extended), with
    /// its half-pel `planes` when the caller has them (wide enough margin)
    /// rather than making its own.
    pub(crate) fn new(
        reference: &Plane,
        cfg: &MeConfig,
        planes: Option<&'p halfpel::HalfPel>,
    ) -> Result<FrameSearch<'p>, MeError> {
        FrameSearch::with_planes(reference, cfg, planes.map(Planes::Given))
    }

    /// [`FrameSearch::new`] keeping `planes` (the reference's half-pel
    /// planes, used when their margin is wide enough; others read them
    /// after, [`FrameSearch::halfpel`]).
    pub(crate) fn owning(
        reference: &Plane,
        cfg: &MeConfig,
        planes: halfpel::HalfPel,
    ) -> Result<FrameSearch<'static>, MeError> {
        FrameSearch::with_planes(reference, cfg, Some(Planes::Own(planes)))
    }

    /// [`FrameSearch::new`] without whole half-pel planes: each block's
    /// search filters the patch its sub-pel steps read
    /// ([`halfpel::with_patch`]), for the same vectors. Cheaper where
    /// most blocks are never searched (an encoder's skipped macroblocks);
    /// nothing is left for others to read after ([`FrameSearch::halfpel`]
    /// is `None`).
    /// Blocks larger than [`halfpel::PATCH_BLOCK_MAX`] keep whole planes.
    pub(crate) fn per_block(reference: &Plane, cfg: &MeConfig) -> Result<FrameSearch<'static>, MeError> {
        if cfg.block > halfpel::PATCH_BLOCK_MAX {
            return FrameSearch::with_planes(reference, cfg, None);
        }
        FrameSearch::with_planes(reference, cfg, Some(Planes::PerBlock(planes_margin(cfg))))
    }

    fn with_planes(
        reference: &Plane,
        cfg: &MeConfig,
        planes: Option<Planes<'p>>,
    ) -> Result<FrameSearch<'p>, MeError> {
        cfg.check()?;
        // Half-pel planes over the window's reach, when the border holds
        // them.
        let margin = planes_margin(cfg);
        let wide_enough = |p: &Planes<'_>| p.get().is_none_or(|p| p.margin() >= margin);
        let halfpel = match (cfg.subpel, planes.filter(wide_enough)) {
            (Subpel::None, _) => None,
            (_, Some(given)) => Some(given),
            _ => halfpel::HalfPel::new(reference, margin).map(Planes::Own),
        };
        // Sums for successive elimination, once per reference, where a
        // search is exhaustive over a window.
        let radius = match cfg.method {
            Method::Esa => cfg.range,
            Method::Epzs => cfg.window,
            _ => 0,
        };
        let sums = (cfg.successive_elimination && sea::pays(cfg.full_pel_metric(), radius))
            .then(|| sea::QuadrantSums::new(reference, cfg.block, dsp::pixel()));
        Ok(FrameSearch {
            cfg: *cfg,
            lambda_q8: (cfg.lambda * 256.0).round() as u64,
            halfpel,
            sums,
            centre: (0, 0),
        })
    }

    /// The searches with every window (`range` pels each way) centred on
    /// `mv` rounded to full pel instead of on zero: on the camera's motion
    /// (see the encoder's `camera.rs`), a hand-held camera's 20-40 px a
    /// frame are within reach of a range of 16 (the presets' is 32: the
    /// picture's corners and what crosses it move further), as
    /// x264's `--merange` bounds the search around its predictors, not
    /// the vector. Centred on each block's own predictors instead, the
    /// vectors of flat areas drift from block to block and frame to frame
    /// (fish_1160: four times as many beyond 16 px, +6.4 % bits).
    pub(crate) fn centred_on(mut self, mv: Mv) -> FrameSearch<'p> {
        self.centre = nearest_full_pel(mv);
        self
    }

    /// The half-pel planes the search owns, to be filled as a reference
    /// brought in a band at a time arrives ([`halfpel::HalfPel::fill_rows`]).
    pub(crate) fn planes_mut(&mut self) -> Option<&mut halfpel::HalfPel> {
        match &mut self.halfpel {
            Some(Planes::Own(p)) => Some(p),
            _ => None,
        }
    }

    /// Whether the search was made from the whole reference (successive
    /// elimination's sums): a reference brought in a band at a time must
    /// be whole before such a search is made.
    pub(crate) fn needs_whole_reference(&self) -> bool {
        self.sums.is_some()
    }

    /// How far below a block's top row, in luma rows, the search of a
    /// block `block` tall can read the reference: the window's lowest
    /// full-pel position, the quarter-pel step beyond it and the 8-tap
    /// filter's reach (4 rows) below that.
    pub(crate) fn reach_below(&self, block: usize) -> usize {
        let lowest = (self.centre.1 + self.cfg.range).max(0) as usize;
        lowest + block + 1 + 4
    }

    /// The reference's half-pel planes the search reads.
    pub(crate) fn halfpel(&self) -> Option<&halfpel::HalfPel> {
        self.halfpel.as_ref().and_then(Planes::get)
    }

    /// The best vector of the block (col, row) of `cur` (same size as the
    /// reference): `candidates` and the method's pattern at full pel, then
    /// the sub-pel refinement, the rate priced against `mvp`, the chroma
    /// priced too where given (16x16 blocks).
    pub(crate) fn search(
        &self,
        (cur, reference): (&Plane, &Plane),
        (col, row): (usize, usize),
        mvp: Mv,
        candidates: &search::Neighbours,
        chroma: Option<ChromaBlock<'_>>,
    ) -> Candidate {
        let block = self.cfg.block;
        debug_assert!(chroma.is_none() || block == 16, "chroma blocks are 8x8");
        let s = SearchContext {
            mvp,
            lambda_q8: self.lambda_q8,
            halfpel: self.halfpel(),
            sums: self.sums.as_ref(),
            origin: self.centre,
            chroma: chroma.filter(|_| block == 16),
            ..SearchContext::new(cur, reference, (col * block, row * block), &self.cfg)
        };
        let best = s.in_sub_pel_measure(search::full_pel(&s, candidates));
        let best = if self.cfg.sub_pel_starts {
            // Measured alike with whole planes and with patches.
            let exact = SearchContext { halfpel: None, ..s };
            exact.sub_pel_start(best, candidates.candidates())
        } else {
            best
        };
        let Some(Planes::PerBlock(margin)) = self.halfpel else {
            return search::refine(&s, best);
        };
        // Each patch holds the steps near its full-pel position: where the
        // steps walk further, a patch around the best takes over (its
        // samples those of whole planes, so the vectors are the same).
        // Around its nearest full pel the best's next step always fits
        // (`search::PATCH_REACH`), so every pass moves on.
        let mut refinement = search::Refinement::new(best);
        loop {
            let (dx, dy) = nearest_full_pel(refinement.best.mv);
            let at = (s.x + dx as isize, s.y + dy as isize);
            let done = halfpel::with_patch(reference, margin, at, block, |patch| {
                let s = SearchContext { halfpel: patch, ..s };
                refinement.run(&s, Some((dx, dy)))
            });
            if done {
                return refinement.best;
            }
        }
    }
}

/// As [`estimate_with_prior`], with the reference's half-pel planes when
/// the caller has them (wide enough margin) rather than making its own
/// (the encoder's partition search reads the same planes afterwards), and
/// the windows centred on `centre` ([`FrameSearch::centred_on`]).
pub(crate) fn estimate_with_planes(
    cur: &Plane,
    reference: &Plane,
    cfg: &MeConfig,
    prior: Option<&MotionField>,
    planes: Option<&halfpel::HalfPel>,
    centre: Mv,
) -> Result<MotionField, MeError> {
    cfg.check()?;
    check_pictures(cur, reference, cfg)?;
    let mut field = MotionField::new(cur.width(), cur.height(), cfg.block);
    let prior = prior.filter(|p| p.cols == field.cols && p.rows == field.rows && p.block == field.block);
    let (cols, rows) = (field.cols, field.rows);
    let frame = FrameSearch::new(reference, cfg, planes)?.centred_on(centre);
    let lambda_q8 = frame.lambda_q8;
    let search_one = |grid: &pipeline::SharedGrid, col: usize, row: usize| -> Candidate {
        let mvp = if lambda_q8 > 0 || cfg.method.uses_neighbours() {
            grid.predictor(col, row)
        } else {
            Mv::ZERO
        };
        frame.search(
            (cur, reference),
            (col, row),
            mvp,
            &search::Neighbours::of(grid, prior, col, row),
            None,
        )
    };
    if lambda_q8 > 0 || cfg.method.uses_neighbours() {
        // Each block reads its left, top and top-right neighbours' final
        // vectors: rows in a pipeline.
        (field.vectors, field.costs) = pipeline::search_rows(cols, rows, &search_one);
    } else {
        let zero = pipeline::SharedGrid::new(cols, rows);
        let results: Vec<Vec<Candidate>> = (0..rows)
            .into_par_iter()
            .map(|r| (0..cols).map(|c| search_one(&zero, c, r)).collect())
            .collect();
        for (r, row) in results.into_iter().enumerate() {
            for (c, best) in row.into_iter().enumerate() {
                field.vectors[r * cols + c] = best.mv;
                field.costs[r * cols + c] = best.cost.min(u64::from(u32::MAX)) as u32;
            }
        }
    }
    Ok(field)
}

/// Searches around `seed` (a flow's vector, say) instead of zero for the
/// block of `cur` at (x, y): `cfg`'s method over the window of `cfg.range`
/// full pels around the seed rounded to full pel, then its sub-pel
/// refinement around the better of the full-pel best and the seed itself. `mvp` is the vector the
/// rate term is priced against. Vectors may reach past the reference's
/// border (read as the decoder reads them, clamped).
pub fn search_around(
    cur: &Plane,
    reference: &Plane,
    (x, y): (usize, usize),
    seed: Mv,
    mvp: Mv,
    cfg: &MeConfig,
) -> Result<Candidate, MeError> {
    cfg.check()?;
    let b = cfg.block;
    if cur.width() != reference.width()
        || cur.height() != reference.height()
        || x + b > cur.width()
        || y + b > cur.height()
    {
        return Err(MeError::Pictures(format!(
            "a {b}x{b} block at ({x}, {y}) of a {}x{} picture against a {}x{} reference",
            cur.width(),
            cur.height(),
            reference.width(),
            reference.height()
        )));
    }
    let s = SearchContext {
        mvp,
        lambda_q8: (cfg.lambda * 256.0).round() as u64,
        origin: nearest_full_pel(seed),
        ..SearchContext::new(cur, reference, (x, y), cfg)
    };
    let at_seed = Candidate {
        cost: with_scratch(b, |scratch| s.sub_pel_cost(seed, scratch)),
        mv: seed,
    };
    let full = s.in_sub_pel_measure(search::full_pel(&s, &search::Neighbours::single(mvp)));
    Ok(search::refine(
        &s,
        if at_seed.beats(&full) { at_seed } else { full },
    ))
}

/// `f` given a block's scratch samples (`b x b`, at most 32 x 32,
/// checked with the config): a macroblock's 256 cleared, not 1024.
fn with_scratch<T>(b: usize, f: impl FnOnce(&mut [u8]) -> T) -> T {
    if b <= 16 {
        f(&mut [0u8; 16 * 16][..b * b])
    } else {
        f(&mut [0u8; 32 * 32][..b * b])
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::codec::interp::predict_chroma;

    /// A 64x64 picture, zero but for the 16x16 block at (at, at): the
    /// codec's prediction of it from `reference` at quarter-pel `mv`.
    pub(crate) fn block_moved_by(reference: &Plane, at: usize, mv: Mv) -> Plane {
        let mut block = [0u8; 256];
        let p = at as isize;
        crate::codec::interp::predict_luma(
            crate::codec::interp::LumaFilter::Sharp,
            reference,
            p,
            p,
            mv.x,
            mv.y,
            16,
            16,
            &mut block,
            16,
        );
        Plane::from_fn(64, 64, |x, y| {
            if (at..at + 16).contains(&x) && (at..at + 16).contains(&y) {
                block[(y - at) * 16 + x - at]
            } else {
                0
            }
        })
        .unwrap()
    }

    /// A chroma plane of noise (a hash of the position), borders extended.
    fn noise_plane(w: usize, h: usize, seed: u32) -> Plane {
        let mut p = Plane::from_fn(w, h, |x, y| {
            let v = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(40_503) ^ seed;
            (v.wrapping_mul(2_246_822_519) >> 24) as u8
        })
        .unwrap();
        p.extend_border();
        p
    }

    /// Flat luma, and chroma moved by a half pel of luma both ways: the
    /// luma says nothing, so the search keeps the predicted vector; priced
    /// with its chroma, it finds the chroma's motion.
    #[test]
    fn chroma_in_the_sub_pel_cost_finds_motion_the_luma_cannot_show() {
        let (w, h) = (64, 64);
        let mut luma = Plane::filled(w, h, 128).unwrap();
        luma.extend_border();
        let reference = [noise_plane(w / 2, h / 2, 1), noise_plane(w / 2, h / 2, 2)];
        let motion = Mv::new(2, -2);
        let (col, row) = (1, 1);
        let mut source = [[0u8; 64]; 2];
        for p in 0..2 {
            let (x, y) = ((col * 8) as isize, (row * 8) as isize);
            predict_chroma(&reference[p], x, y, motion.x, motion.y, 8, 8, &mut source[p], 8);
        }
        let cfg = MeConfig {
            subpel: Subpel::Quarter,
            metric: Metric::Satd,
            lambda: lambda_for_qp(Metric::Satd, 27),
            ..MeConfig::new(Method::Epzs, 16, 16)
        };
        let search = FrameSearch::new(&luma, &cfg, None).unwrap();
        let chroma = ChromaBlock {
            source: &source,
            reference: [&reference[0], &reference[1]],
        };
        let found = |c: Option<ChromaBlock<'_>>| {
            let candidates = search::Neighbours::list(Mv::ZERO, []);
            search
                .search((&luma, &luma), (col, row), Mv::ZERO, &candidates, c)
                .mv
        };
        assert_eq!(found(None), Mv::ZERO);
        assert_eq!(found(Some(chroma)), motion);
    }

    /// Blocks searched with a patch of half-pel samples each, whose
    /// sub-pel steps walk up to four times a step past the first patch's
    /// reach (the motion, 2.75 and 1.5 pels, beyond a full-pel window of
    /// one pel), find what whole planes find: the same vectors and costs.
    /// The picture's finest ripple makes the codec's quarter-pel filter
    /// and the planes' averages differ, so that a step read off the patch
    /// through the filter would show.
    #[test]
    fn patches_find_what_whole_planes_find_however_far_the_steps_walk() {
        let (w, h) = (96, 64);
        let mut reference = Plane::from_fn(w, h, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0
                + 50.0 * (x * 0.29).sin() * (y * 0.21).cos()
                + 25.0 * ((x + 2.0 * y) * 0.13).sin()
                + 6.0 * (x * 1.9).sin() * (y * 1.7).cos()) as u8
        })
        .unwrap();
        reference.extend_border();
        // The source: the reference moved by (2.75, -1.5) pels, with a
        // little noise, so that blocks' best vectors scatter.
        let mut moved = [0u8; 16];
        let cur = Plane::from_fn(w, h, |x, y| {
            crate::codec::interp::predict_luma(
                crate::codec::interp::LumaFilter::Sharp,
                &reference,
                x as isize,
                y as isize,
                11,
                -6,
                1,
                1,
                &mut moved,
                1,
            );
            moved[0].saturating_add(((x * 7 + y * 13) % 5) as u8)
        })
        .unwrap();
        let cfg = MeConfig {
            subpel: Subpel::Quarter,
            metric: Metric::Satd,
            lambda: lambda_for_qp(Metric::Satd, 27),
            subpel_moves: 4,
            ..MeConfig::new(Method::Epzs, 16, 1)
        };
        let planes = halfpel::HalfPel::new(&reference, planes_margin(&cfg)).unwrap();
        let mut walked = 0;
        // Without and with the candidates' own vectors as starts (two of
        // them off the full-pel grid, near the motion).
        for starts in [false, true] {
            let cfg = MeConfig {
                sub_pel_starts: starts,
                ..cfg
            };
            let whole = FrameSearch::new(&reference, &cfg, Some(&planes)).unwrap();
            let patched = FrameSearch::per_block(&reference, &cfg).unwrap();
            walked += walks_alike(&cur, &reference, (&whole, &patched));
        }
        assert!(walked > 0, "no block's steps walked past the first patch");
    }

    /// How many blocks of `cur` walked past the first patch, asserting
    /// that both searches find the same vectors and costs.
    fn walks_alike(
        cur: &Plane,
        reference: &Plane,
        (whole, patched): (&FrameSearch<'_>, &FrameSearch<'_>),
    ) -> usize {
        let mut walked = 0;
        for row in 0..cur.height() / 16 {
            for col in 0..cur.width() / 16 {
                let candidates = search::Neighbours::list(Mv::ZERO, [Mv::new(9, -5), Mv::new(13, -7)]);
                let at =
                    |f: &FrameSearch<'_>| f.search((cur, reference), (col, row), Mv::ZERO, &candidates, None);
                let (a, b) = (at(whole), at(patched));
                assert_eq!((a.mv, a.cost), (b.mv, b.cost), "block ({col}, {row})");
                // Past the window's pel: more than three quarter-pels
                // from any full-pel position it holds.
                walked += usize::from(a.mv.x > 4 + 3 || a.mv.y < -4 - 3);
            }
        }
        walked
    }

    /// A block moved by exactly a candidate's quarter-pel vector, beyond
    /// a full-pel window of one pel and more than one sub-pel move from
    /// it: found at no cost from the candidate, missed without it.
    #[test]
    fn a_candidates_own_quarter_pel_vector_starts_the_sub_pel_steps() {
        let mut reference = Plane::from_fn(64, 64, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 50.0 * (x * 0.29).sin() * (y * 0.21).cos() + 25.0 * ((x + 2.0 * y) * 0.13).sin()) as u8
        })
        .unwrap();
        reference.extend_border();
        let truth = Mv::new(13, -7);
        let cur = block_moved_by(&reference, 16, truth);
        let found = |starts: bool| {
            let cfg = MeConfig {
                subpel: Subpel::Quarter,
                metric: Metric::Satd,
                sub_pel_starts: starts,
                ..MeConfig::new(Method::Epzs, 16, 1)
            };
            let search = FrameSearch::new(&reference, &cfg, None).unwrap();
            let candidates = search::Neighbours::list(Mv::ZERO, [truth]);
            search.search((&cur, &reference), (1, 1), Mv::ZERO, &candidates, None)
        };
        assert_ne!(found(false).mv, truth);
        let started = found(true);
        assert_eq!((started.mv, started.cost), (truth, 0));
    }
}
