//! Motion analysis of a P frame (encoder side, not normative): each
//! predictor's vectors for the macroblocks, or its motion grid.

use ndarray::Array2;

#[cfg(doc)]
use super::camera::CameraMotion;
use super::config::{FlowMethod, Predictor, SearchSettings};
use crate::codec::mv::Mv;
use crate::codec::mvpred::mv_prediction;
use crate::codec::partition::{MbVectors, RefMv};
use crate::codec::syntax::MB;
use crate::codec::warp::MotionGrid;
use crate::codec::{Frame, Plane};
use crate::flow::{Flow, FlowEstimator};
use crate::me::halfpel::HalfPel;
use crate::me::pipeline::SharedGrid;
use crate::me::{self, lambda_for_qp, FrameSearch, MeConfig, Metric, MotionField};
use crate::raster::plane_to_array;

/// What motion analysis hands to mode decision.
pub(crate) enum FrameMotion {
    /// Candidate vectors.
    Vectors(BlockMotion),
    /// A motion grid to warp with.
    Grid(MotionGrid),
}

/// Candidate vectors of a block-motion frame.
pub(crate) struct BlockMotion {
    /// One per macroblock (raster order).
    pub mb: Vec<Mv>,
    /// One per 8x8 block (raster order over the picture), when partitions
    /// are analysed: the partitions' candidates.
    pub blocks: Option<Vec<Mv>>,
    /// The reference's half-pel planes, when partitions are analysed (the
    /// search made them; the partitions' search reads them again).
    pub halfpel: Option<HalfPel>,
    /// The search itself, when the mode decision searches the macroblocks
    /// it needs one for (then `mb` is empty).
    pub lazy: Option<Box<LazySearch>>,
}

/// The search of a frame's macroblocks, run from the mode decision (x264's
/// way): a macroblock skipped before it needs a vector is never searched.
pub(crate) struct LazySearch {
    pub search: FrameSearch<'static>,
    /// The previous P frame's decided vectors: the co-located candidates.
    pub prior: Option<MotionField>,
    /// The searches into the older references (index 1, 2, ...).
    pub older: Vec<OlderSearch>,
}

impl LazySearch {
    /// The co-located candidates of macroblock rows `rows` from `prior`
    /// (the previous frame's, one per macroblock, final over `rows`), for
    /// a frame whose search started with none of them in.
    pub fn bring_in_prior(&mut self, prior: &[Mv], rows: std::ops::Range<usize>) {
        if let Some(field) = &mut self.prior {
            field.set_rows(prior, rows.clone(), 1);
        }
        for older in &mut self.older {
            if let Some(field) = &mut older.prior {
                field.set_rows(prior, rows.clone(), older.distance);
            }
        }
    }
}

/// The search into an older reference, run from the mode decision for the
/// macroblocks that get that far (x264 searches every reference there).
pub(crate) struct OlderSearch {
    /// EPZS without its window.
    pub search: FrameSearch<'static>,
    /// The previous P frame's decided vectors scaled by this reference's
    /// distance: the co-located candidates.
    pub prior: Option<MotionField>,
    /// Frames back (2 for reference index 1).
    pub distance: i32,
    /// The vector each searched macroblock found (zero where none was
    /// searched): candidates of the macroblocks below and right, which
    /// the wavefront lets read it only once it is written.
    pub found: SharedGrid,
}

/// A macroblock's co-located candidate for the next frame's search: its
/// first block's vector into the first reference (zero for intra or an
/// older reference).
pub(crate) fn colocated(vectors: &MbVectors) -> Mv {
    vectors[0].filter(|m| m.ref_idx == 0).map_or(Mv::ZERO, |m| m.mv)
}

/// How far beyond the picture the half-pel planes kept for the partition
/// search reach (candidates further out use the codec's filter).
pub(crate) const PARTITION_MARGIN: usize = 48;

/// The state motion analysis keeps between frames.
pub(crate) struct MotionAnalyser {
    predictor: Predictor,
    qp: u8,
    /// The previous frame's field, for EPZS's co-located candidates.
    prior: Option<MotionField>,
    /// Whether partitions are analysed: flows give 8x8 blocks' vectors
    /// too, and the reference's half-pel planes are kept.
    blocks: bool,
    /// The flow predictors' estimator.
    flow: Option<FlowEstimator>,
    /// Whether the older references' sub-pel steps move once and start
    /// from the full-pel best alone (where sub-pel RD is off): in medium
    /// with two references, 0.94x the wall time of refining them as the
    /// first, for -1.31 % against one reference instead of -1.57 %
    /// (`benches/pair.py`, 32 sequences, a scratch build of the choice).
    older_light: bool,
}

impl MotionAnalyser {
    /// `partitions`: flow predictors give 8x8 blocks' vectors too.
    pub fn new(predictor: Predictor, qp: u8, partitions: bool) -> MotionAnalyser {
        MotionAnalyser {
            predictor,
            qp,
            prior: None,
            blocks: partitions,
            flow: None,
            older_light: false,
        }
    }

    /// The analyser an encoder of `config` starts with.
    pub fn of_config(config: &super::EncoderConfig) -> MotionAnalyser {
        MotionAnalyser {
            older_light: !config.subpel_rd,
            ..MotionAnalyser::new(config.predictor, config.qp, config.partitions.p8x8)
        }
    }

    /// Whether `block` frames' macroblocks are searched from the mode
    /// decision ([`LazySearch`]), into every reference.
    pub fn searches_in_decision(&self) -> bool {
        matches!(self.predictor, Predictor::Block(_))
    }

    /// The decided vectors of a P frame of `width x height` (one per
    /// macroblock, raster order): the next frame's co-located candidates
    /// when the mode decision searches ([`LazySearch`]).
    pub fn remember(&mut self, width: usize, height: usize, vectors: Vec<Mv>) {
        if self.searches_in_decision() {
            self.prior = MotionField::from_vectors(width, height, MB, vectors);
        }
    }

    /// The co-located candidates the next block frame searches with (the
    /// last P frame's decided vectors, [`MotionAnalyser::remember`]).
    pub fn prior(&self) -> Option<&[Mv]> {
        self.prior.as_ref().map(MotionField::vectors)
    }

    /// Motion of `source` (coded size) against `reference` (the previous
    /// reconstruction) and, for `block`, against the `older` ones (the
    /// frame before it first); flow predictors look at `prev_source`
    /// instead. Block searches centre their windows on `camera` (the
    /// camera's motion from `prev_source`, [`CameraMotion`]).
    pub fn analyse(
        &mut self,
        source: &Frame,
        prev_source: &Frame,
        reference: &Frame,
        older: &[&Frame],
        camera: Mv,
    ) -> FrameMotion {
        let cols = source.width() / MB;
        let rows = source.height() / MB;
        match self.predictor {
            Predictor::Zero => FrameMotion::Vectors(BlockMotion {
                mb: vec![Mv::ZERO; cols * rows],
                blocks: None,
                halfpel: self.planes(reference),
                lazy: None,
            }),
            Predictor::Block(s) => {
                let prior = self.prior.as_ref();
                self.decision_search(reference, older, (s, camera, prior), Self::planes)
            }
            Predictor::Obmc(s) => FrameMotion::Vectors(BlockMotion {
                mb: self.search(source.y(), reference.y(), s, None, camera),
                blocks: None,
                halfpel: None,
                lazy: None,
            }),
            Predictor::FlowBlock { flow, refine } => {
                let f = self.flow(flow, source.y(), prev_source.y());
                let mut cfg = MeConfig::new(me::Method::Esa, MB, refine.max(1));
                cfg.subpel = me::Subpel::Quarter;
                // The block searches' walk.
                cfg.subpel_moves = super::config::SUBPEL_MOVES;
                cfg.metric = Metric::Satd;
                cfg.lambda = lambda_for_qp(Metric::Satd, self.qp);
                let mut vectors: Vec<MbVectors> = Vec::with_capacity(cols * rows);
                for r in 0..rows {
                    for c in 0..cols {
                        let seed = block_median(&f, c * MB, r * MB, MB);
                        let mv = if refine > 0 {
                            let mvp = mv_prediction(&vectors, c, r, cols);
                            let at = (c * MB, r * MB);
                            // The configuration was checked with the
                            // encoder's and the block is inside the frame.
                            me::search_around(source.y(), reference.y(), at, seed, mvp, &cfg)
                                .map_or(seed, |best| best.mv)
                        } else {
                            seed
                        };
                        vectors.push([Some(RefMv::previous(mv)); 4]);
                    }
                }
                // The flow's 8x8 medians: the partitions' candidates.
                let blocks = self.blocks.then(|| {
                    (0..2 * rows)
                        .flat_map(|r| (0..2 * cols).map(move |c| (c, r)))
                        .map(|(c, r)| block_median(&f, c * 8, r * 8, 8))
                        .collect()
                });
                FrameMotion::Vectors(BlockMotion {
                    mb: vectors.into_iter().map(|v| v[0].unwrap_or_default().mv).collect(),
                    blocks,
                    halfpel: self.planes(reference),
                    lazy: None,
                })
            }
            Predictor::Dense { flow, grid } => {
                let f = self.flow(flow, source.y(), prev_source.y());
                FrameMotion::Grid(grid_from_flow(&f, source.width(), source.height(), grid))
            }
        }
    }

    /// [`MotionAnalyser::analyse`] of a `block` frame whose `reference`
    /// is brought in a band of rows at a time ([`super::reference`]): the
    /// search made ready with half-pel planes to fill as the rows arrive.
    /// `None` for other predictors, and for searches that read the whole
    /// reference when they are made. The co-located candidates are zero
    /// where `prior` (to be brought in as the rows are:
    /// [`LazySearch::bring_in_prior`]), else none.
    pub fn analyse_growing(
        &self,
        reference: &Frame,
        older: &[&Frame],
        camera: Mv,
        prior: bool,
    ) -> Option<FrameMotion> {
        let Predictor::Block(s) = self.predictor else {
            return None;
        };
        let unfilled = |analyser: &Self, reference: &Frame| {
            analyser
                .blocks
                .then(|| HalfPel::unfilled(reference.y(), PARTITION_MARGIN))
                .flatten()
        };
        let zero = prior.then(|| MotionField::new(reference.width(), reference.height(), MB));
        let motion = self.decision_search(reference, older, (s, camera, zero.as_ref()), unfilled);
        match &motion {
            FrameMotion::Vectors(BlockMotion { lazy: Some(lazy), .. })
                if !lazy.search.needs_whole_reference() =>
            {
                Some(motion)
            }
            _ => None,
        }
    }

    /// `block` frames' motion when the decision searches ([`LazySearch`]):
    /// the search by `s` made ready against `reference` with half-pel
    /// planes from `planes`, its window on `camera`, `prior` its
    /// co-located candidates; no vectors yet.
    fn decision_search(
        &self,
        reference: &Frame,
        older: &[&Frame],
        (s, camera, prior): (SearchSettings, Mv, Option<&MotionField>),
        planes: impl Fn(&Self, &Frame) -> Option<HalfPel>,
    ) -> FrameMotion {
        let cfg = self.search_config(s);
        // The partitions' search reads the planes too, further out. Without
        // it, each searched macroblock filters the half-pel patch it needs
        // (x264 filters whole planes; here, where a macroblock skipped
        // before its search needs none, patches took ultrafast 0.966x and
        // 0.994x its time in two runs over 28 sequences, for +0.5 % of its
        // instructions on eight, and 44 MiB of peak memory against 55 on
        // dog_1080p; the other presets below medium were not timed).
        let search = match planes(self, reference) {
            Some(planes) => FrameSearch::owning(reference.y(), &cfg, planes),
            None => FrameSearch::per_block(reference.y(), &cfg),
        }
        .map(|search| search.centred_on(camera));
        let (cols, rows) = (reference.width() / MB, reference.height() / MB);
        FrameMotion::Vectors(match search {
            Ok(search) => BlockMotion {
                mb: Vec::new(),
                blocks: None,
                halfpel: None,
                lazy: Some(Box::new(LazySearch {
                    search,
                    prior: prior.cloned(),
                    older: self.older_searches(older, (s, camera, prior)),
                })),
            },
            // The configuration was checked when the encoder was made: this
            // is not reached.
            Err(_) => BlockMotion {
                mb: vec![Mv::ZERO; cols * rows],
                blocks: None,
                halfpel: None,
                lazy: None,
            },
        })
    }

    /// The half-pel planes of `reference`'s luma, when partitions are
    /// analysed.
    fn planes(&self, reference: &Frame) -> Option<HalfPel> {
        self.blocks
            .then(|| HalfPel::new(reference.y(), PARTITION_MARGIN))
            .flatten()
    }

    /// The searched vector of every macroblock (`planes`: the reference's
    /// half-pel planes, when made already).
    fn search(
        &mut self,
        cur: &Plane,
        reference: &Plane,
        s: SearchSettings,
        planes: Option<&HalfPel>,
        camera: Mv,
    ) -> Vec<Mv> {
        let cfg = self.search_config(s);
        // The configuration was checked when the encoder was made and the
        // frames are the encoder's own, so the search cannot refuse them.
        match me::estimate_with_planes(cur, reference, &cfg, self.prior.as_ref(), planes, camera) {
            Ok(field) => {
                let v = field.vectors().to_vec();
                self.prior = Some(field);
                v
            }
            Err(_) => vec![Mv::ZERO; (cur.width() / MB) * (cur.height() / MB)],
        }
    }

    /// Macroblock search by `s`, SATD + rate at the encoder's QP.
    fn search_config(&self, s: SearchSettings) -> MeConfig {
        let mut cfg = MeConfig::new(s.method, MB, s.range);
        cfg.subpel = s.subpel;
        cfg.window = s.window;
        cfg.metric = Metric::Satd;
        cfg.full_pel_sad = s.full_pel_sad;
        cfg.subpel_moves = s.subpel_moves;
        cfg.sub_pel_starts = s.sub_pel_starts;
        cfg.lambda = lambda_for_qp(Metric::Satd, self.qp);
        if s.sub_pel_sad {
            cfg.metric = Metric::Sad;
            cfg.lambda = lambda_for_qp(Metric::Sad, self.qp);
        }
        cfg
    }

    /// The search into each older reference: EPZS without its window
    /// (its candidates: `older_reference_candidate` in `analyse.rs`),
    /// the window centred on the camera's motion over that distance.
    fn older_searches(
        &self,
        older: &[&Frame],
        (s, camera, prior): (SearchSettings, Mv, Option<&MotionField>),
    ) -> Vec<OlderSearch> {
        let cfg = self.search_config(SearchSettings {
            method: me::Method::Epzs,
            window: 0,
            subpel_moves: if self.older_light { 1 } else { s.subpel_moves },
            sub_pel_starts: s.sub_pel_starts && !self.older_light,
            ..s
        });
        older
            .iter()
            .zip(2..)
            .map(|(reference, distance)| {
                let centre = Mv::new(
                    camera.x.saturating_mul(distance),
                    camera.y.saturating_mul(distance),
                );
                // As in `decision_search`: the configuration was checked.
                let search = FrameSearch::per_block(reference.y(), &cfg).ok()?;
                Some(OlderSearch {
                    search: search.centred_on(centre),
                    prior: prior.map(|f| f.scaled(distance)),
                    distance,
                    found: SharedGrid::new(reference.width() / MB, reference.height() / MB),
                })
            })
            // None fails: all or none, so that index i is reference i + 1.
            .collect::<Option<Vec<_>>>()
            .unwrap_or_default()
    }

    /// Flow from `cur` to `prev`: `cur(x) ~ prev(x + flow(x))`, which is the
    /// codec's vector convention.
    fn flow(&mut self, method: FlowMethod, cur: &Plane, prev: &Plane) -> Flow {
        let (a, b) = (plane_to_array(cur), plane_to_array(prev));
        // One method per encoder: its estimator is made once, its buffers
        // kept between frames.
        self.flow
            .get_or_insert_with(|| FlowEstimator::with_defaults(method))
            .compute(&a, &b)
    }
}

/// Quarter-pel rounding of a flow value, kept inside the codec's range.
fn to_qpel(v: f32) -> i32 {
    let limit = (crate::codec::mv::MV_LIMIT - 1) as f32;
    (v * 4.0).round().clamp(-limit, limit) as i32
}

/// The component-wise median of the flow over a `size` block at (x0, y0):
/// robust to the occlusion edges and outliers a mean would follow.
pub(crate) fn block_median(flow: &Flow, x0: usize, y0: usize, size: usize) -> Mv {
    let (u, v) = (flow.u(), flow.v());
    let mut us = Vec::with_capacity(size * size);
    let mut vs = Vec::with_capacity(size * size);
    for y in y0..(y0 + size).min(flow.height()) {
        for x in x0..(x0 + size).min(flow.width()) {
            us.push(u[[y, x]]);
            vs.push(v[[y, x]]);
        }
    }
    let median = |s: &mut Vec<f32>| -> f32 {
        if s.is_empty() {
            return 0.0;
        }
        let mid = s.len() / 2;
        *s.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    Mv::new(to_qpel(median(&mut us)), to_qpel(median(&mut vs)))
}

/// A `spacing` grid for a `width x height` picture from a dense flow: each
/// node the average of the flow under its bilinear hat (the weights with
/// which the node reaches each pixel), so the warp follows the flow in the
/// least-blurred way the grid can.
pub(crate) fn grid_from_flow(flow: &Flow, width: usize, height: usize, spacing: usize) -> MotionGrid {
    // The picture sizes come from the encoder (checked), and spacing was
    // checked with the configuration.
    let Ok(mut grid) = MotionGrid::new(width, height, spacing) else {
        unreachable!("checked sizes and spacing")
    };
    let s = spacing as isize;
    let (fw, fh) = (flow.width() as isize, flow.height() as isize);
    let (u, v): (&Array2<f32>, &Array2<f32>) = (flow.u(), flow.v());
    for row in 0..grid.rows() {
        for col in 0..grid.cols() {
            let (nx, ny) = (col as isize * s, row as isize * s);
            let (mut su, mut sv, mut sw) = (0f64, 0f64, 0f64);
            for y in (ny - s + 1).max(0)..(ny + s).min(fh) {
                let wy = (s - (y - ny).abs()) as f64;
                for x in (nx - s + 1).max(0)..(nx + s).min(fw) {
                    let w = wy * (s - (x - nx).abs()) as f64;
                    su += w * f64::from(u[[y as usize, x as usize]]);
                    sv += w * f64::from(v[[y as usize, x as usize]]);
                    sw += w;
                }
            }
            if sw > 0.0 {
                grid.set(
                    col,
                    row,
                    Mv::new(to_qpel((su / sw) as f32), to_qpel((sv / sw) as f32)),
                );
            }
        }
    }
    grid
}
