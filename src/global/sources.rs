//! Correspondences for the global fit from each kind of motion the toolkit
//! finds: a dense flow sampled on a grid, block vectors, feature matches.
//! Each gives pairs from the first (earlier) picture to the second.

use ndarray::Array2;

use super::{estimate, Correspondence, GlobalError, GlobalMotion, GlobalParams};
use crate::codec::Plane;
use crate::features::{match_pictures, Match, MatchParams};
use crate::flow::{Flow, FlowEstimator, FlowOptions, Preset};
use crate::imgproc::corners::min_eigen;
use crate::me::{self, MeConfig, Method, MotionField, Subpel};
use crate::raster::plane_to_array;

/// Where a picture pair's correspondences come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// Dense flow (DIS), sampled every 8 pixels ([`from_flow`]).
    Flow,
    /// 16x16 block vectors (EPZS, range 32, quarter-pel; [`from_vectors`]).
    Blocks,
    /// Feature matches ([`from_matches`]).
    Matches,
    /// Block vectors; flow where fewer than [`MIN_INLIER_SHARE`] of them
    /// follow the model fitted (flat water, a shake beyond the search's
    /// range). Under a known shake over eleven real still-camera clips
    /// (`benches/global_truth.py`) blocks were within 0.25 px of the
    /// truth (median corner error) on all but a fish tank's flat water,
    /// where flow was; in a quarter or less of DIS fast's time on the two
    /// clips timed (talk_vga, face_360p).
    Auto,
}

/// The least share of correspondences that must follow a fitted motion for
/// it to be the camera's (a cut gives a few per cent).
pub const MIN_INLIER_SHARE: f64 = 0.25;

impl Source {
    /// Every source.
    pub const ALL: [Source; 4] = [Source::Flow, Source::Blocks, Source::Matches, Source::Auto];

    /// `flow`, `blocks`, `matches` or `auto`.
    pub fn name(self) -> &'static str {
        match self {
            Source::Flow => "flow",
            Source::Blocks => "blocks",
            Source::Matches => "matches",
            Source::Auto => "auto",
        }
    }

    /// The inlier threshold that suits the source, pixels: 2 for matches,
    /// whose positions are a corner detector's, a few tenths of a pixel
    /// apart in the two pictures (at 1 px the fit to the inliers' scale
    /// left good matches out: corners 0.41 -> 0.53 px from the truth on
    /// ball_576; at 2 px, 0.45), 1 for the others.
    pub fn threshold(self) -> f64 {
        match self {
            Source::Matches => 2.0,
            _ => 1.0,
        }
    }
}

impl std::str::FromStr for Source {
    type Err = String;
    fn from_str(s: &str) -> Result<Source, String> {
        Source::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown source '{s}' (flow, blocks, matches, auto)"))
    }
}

/// The correspondences of picture pairs by one source, its estimator made
/// once and kept from pair to pair.
pub struct PairCorrespondences {
    source: Source,
    preset: Preset,
    /// Made at the first flow asked for.
    flow: Option<FlowEstimator>,
    /// Flow correspondences weighed by texture ([`weigh_by_texture`]).
    texture_weights: bool,
}

impl PairCorrespondences {
    /// `source`, with DIS at `preset` for [`Source::Flow`] (and
    /// [`Source::Auto`]'s flow).
    pub fn new(source: Source, preset: Preset) -> PairCorrespondences {
        PairCorrespondences {
            source,
            preset,
            flow: None,
            texture_weights: false,
        }
    }

    /// The same, the flow's correspondences weighed by the texture where
    /// they start ([`weigh_by_texture`]): what `mocomp globalmotion` fits.
    /// The stabiliser and its scorer take them unweighted: where the most
    /// textured thing in the picture moves on its own (a face in
    /// close-up), the weights favour it.
    pub fn weighted_by_texture(mut self) -> PairCorrespondences {
        self.texture_weights = true;
        self
    }

    /// The model that most correspondences from `first` to `second`
    /// follow. The pictures are the same size; for blocks (and
    /// [`Source::Auto`]) padded by at least 56 pixels, as [`me::estimate`]
    /// needs for a range of 32.
    pub fn fit(
        &mut self,
        first: &Plane,
        second: &Plane,
        params: &GlobalParams,
    ) -> Result<PairFit, GlobalError> {
        let own = self.source;
        let mut fit_from = |source| -> Result<_, GlobalError> {
            let points = self.between(source, first, second)?;
            Ok(PairFit {
                fit: estimate(&points, params).ok(),
                points: points.len(),
                source,
            })
        };
        if own != Source::Auto {
            return fit_from(own);
        }
        let blocks = fit_from(Source::Blocks)?;
        if blocks.camera().is_some() {
            return Ok(blocks);
        }
        fit_from(Source::Flow)
    }

    /// The correspondences from `first` to `second` by `source` (flow for
    /// [`Source::Auto`]).
    fn between(
        &mut self,
        source: Source,
        first: &Plane,
        second: &Plane,
    ) -> Result<Vec<Correspondence>, GlobalError> {
        Ok(match source {
            Source::Flow | Source::Auto => {
                let preset = self.preset;
                let estimator = self.flow.get_or_insert_with(|| {
                    let options = FlowOptions {
                        preset,
                        fine_on_small: true,
                        ..FlowOptions::default()
                    };
                    FlowEstimator::new(&options).expect("a preset's own settings are valid")
                });
                let first = plane_to_array(first);
                let flow = estimator.compute(&first, &plane_to_array(second));
                let mut points = from_flow(&flow, 8);
                if self.texture_weights {
                    weigh_by_texture(&mut points, &first);
                }
                points
            }
            Source::Blocks => {
                let mut cfg = MeConfig::new(Method::Epzs, 16, 32);
                cfg.subpel = Subpel::Quarter;
                cfg.window = 2;
                let field =
                    me::estimate(second, first, &cfg).map_err(|e| GlobalError::Motion(e.to_string()))?;
                from_vectors(&field)
            }
            Source::Matches => from_matches(&match_pictures(
                &plane_to_array(first),
                &plane_to_array(second),
                &MatchParams::default(),
            )),
        })
    }
}

/// One picture pair's fit.
#[derive(Debug, Clone)]
pub struct PairFit {
    /// The model most correspondences follow (`None` where none fits).
    pub fit: Option<GlobalMotion>,
    /// How many correspondences there were.
    pub points: usize,
    /// Where they came from ([`Source::Blocks`] or [`Source::Flow`] for
    /// [`Source::Auto`]).
    pub source: Source,
}

impl PairFit {
    /// The fit where at least [`MIN_INLIER_SHARE`] of the correspondences
    /// follow it: the camera's motion (else a cut, or a picture without
    /// texture).
    pub fn camera(&self) -> Option<&GlobalMotion> {
        self.fit
            .as_ref()
            .filter(|f| f.inlier_count as f64 >= MIN_INLIER_SHARE * self.points as f64)
    }
}

/// The flow from the first picture to the second at every `step`-th pixel
/// of each row and column (from `step / 2`), its invalid pixels left out.
pub fn from_flow(flow: &Flow, step: usize) -> Vec<Correspondence> {
    let step = step.max(1);
    let mut out = Vec::new();
    for y in (step / 2..flow.height()).step_by(step) {
        for x in (step / 2..flow.width()).step_by(step) {
            let (u, v) = flow.get(x, y);
            if flow.is_valid(x, y) && u.is_finite() && v.is_finite() {
                let (x, y) = (x as f64, y as f64);
                out.push(Correspondence::new((x, y), (x + f64::from(u), y + f64::from(v))));
            }
        }
    }
    out
}

/// The texture (the structure tensor's smaller eigenvalue, as
/// [`min_eigen`] gives it) at which a flow correspondence weighs half of
/// one on a richly textured place ([`weigh_by_texture`]).
pub const TEXTURE_HALF_WEIGHT: f32 = 10.0;

/// Weighs each correspondence by the texture of the first picture where it
/// starts: `l / (l + TEXTURE_HALF_WEIGHT)`, `l` the structure tensor's
/// smaller eigenvalue there ([`min_eigen`]). A dense flow has a vector
/// everywhere, and on flat walls, sky and along straight edges (the
/// aperture problem) that vector is the smoothness term's guess: close to
/// the camera's motion, so RANSAC keeps it, but off by a few tenths of a
/// pixel, which bias the least-squares fit. Under a known shake over
/// eleven real still-camera clips (`benches/global_truth.py`, DIS fast,
/// a similarity) these weights brought the fits' corners closer to the
/// truth on nine (lego_560 0.75 -> 0.34 px, median over pairs) and
/// further on one, where a textured face moving on its own outweighs a
/// plain background (1.24 -> 1.99 px).
pub fn weigh_by_texture(points: &mut [Correspondence], first: &Array2<f32>) {
    let texture = min_eigen(first);
    let (h, w) = texture.dim();
    for c in points {
        let (x, y) = (c.from.0.round(), c.from.1.round());
        if x < 0.0 || y < 0.0 || x as usize >= w || y as usize >= h {
            continue;
        }
        let l = texture[[y as usize, x as usize]].max(0.0);
        c.weight *= f64::from(l / (l + TEXTURE_HALF_WEIGHT));
    }
}

/// A block search of the second picture (current) against the first
/// (reference): each block's centre in the second picture and where its
/// vector finds it in the first, as pairs from the first to the second.
/// Blocks whose match cost is among the worst tenth, or that lie on the
/// picture's border row or column, are left out (their vectors are the
/// least reliable).
pub fn from_vectors(field: &MotionField) -> Vec<Correspondence> {
    let b = field.block() as f64;
    let (cols, rows) = (field.cols(), field.rows());
    let mut costs: Vec<u32> = field.costs().to_vec();
    costs.sort_unstable();
    let worst = costs.get(costs.len() * 9 / 10).copied().unwrap_or(u32::MAX);
    let mut out = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let inner = cols < 3 || rows < 3 || (c > 0 && r > 0 && c + 1 < cols && r + 1 < rows);
            if !inner || field.cost(c, r) > worst {
                continue;
            }
            let mv = field.vector(c, r);
            let (x, y) = (c as f64 * b + (b - 1.0) / 2.0, r as f64 * b + (b - 1.0) / 2.0);
            let (dx, dy) = (f64::from(mv.x) / 4.0, f64::from(mv.y) / 4.0);
            out.push(Correspondence::new((x + dx, y + dy), (x, y)));
        }
    }
    out
}

/// Feature matches from the first picture to the second.
pub fn from_matches(matches: &[Match]) -> Vec<Correspondence> {
    matches
        .iter()
        .map(|m| {
            Correspondence::new(
                (f64::from(m.x1), f64::from(m.y1)),
                (f64::from(m.x2), f64::from(m.y2)),
            )
        })
        .collect()
}
