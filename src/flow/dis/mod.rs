//! Dense inverse search (Kroeger, Timofte, Dai and Van Gool, "Fast optical
//! flow using dense inverse search", ECCV 2016): the method behind OpenCV's
//! `DISOpticalFlow`.
//!
//! Coarse to fine over a Gaussian pyramid, each level:
//! 1. **Patch search** ([`search`]): square patches of the first picture on
//!    a regular grid; each finds its displacement in the second picture by
//!    inverse-compositional Lucas-Kanade (the patch's gradients and Hessian
//!    computed once, the second picture sampled bilinearly at each step),
//!    optionally on mean-normalised intensities (robust to a brightness
//!    change), starting from the best of the coarser level's flow and the
//!    already-searched neighbours' vectors (spatial propagation).
//! 2. **Densification** ([`densify`]): each pixel's flow is the average of
//!    the vectors of the patches that overlap it, weighted by how well each
//!    vector predicts the pixel.
//! 3. **Variational refinement** ([`super::refine`]): a few fixed-point
//!    iterations of a robust energy with brightness and gradient constancy
//!    and smoothness, which sharpens the blocky field and fixes small errors.
//!
//! The coarsest level is chosen so that it is a few patches across (motion
//! of a quarter of the picture stays within reach); the finest level
//! computed can stop above full size (`finest`), the flow then being
//! upsampled, as OpenCV's presets do, at every picture size; small
//! pictures can be computed finer (`min_side`, [`DisParams::fine_on_small`]:
//! more accurate, for 2-4 times the time).

pub(crate) mod densify;
pub(crate) mod search;

use ndarray::Array2;

use super::refine::{RefineParams, Refiner};
use super::Flow;
use crate::imgproc::pyramid::{
    parallel_worth, upsample2, upsample_levels_interleaved, upsample_levels_into, Pyramid,
};
use crate::imgproc::Luma;

/// Settings of dense inverse search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisParams {
    /// Finest pyramid level computed (0 = full size); its flow is upsampled.
    /// A small picture is computed finer (see `min_side`).
    pub finest: usize,
    /// The longer side, in pixels, the finest level computed should have:
    /// where the level whose longer side is nearest `min_side` (in
    /// octaves) is finer than `finest`, it is computed instead. Patches of
    /// 8 pixels on a CIF picture at quarter size (88x72) cover too much of
    /// it; OpenCV's presets, with a fixed level, were made for pictures of
    /// 640 and more, where this changes nothing. 0 keeps `finest` at
    /// every size, as the presets do (OpenCV's time on small pictures);
    /// [`DisParams::fine_on_small`] sets it.
    pub min_side: usize,
    /// Coarsest level; `None` chooses it from the picture size (the level
    /// at which the picture is about four patches across).
    pub coarsest: Option<usize>,
    /// Patch side, pixels: 4, 8, 12 or 16.
    pub patch: usize,
    /// Distance between neighbouring patches, pixels (1..=patch).
    pub stride: usize,
    /// Gauss-Newton steps per patch and level (split over the two
    /// propagation passes).
    pub iterations: usize,
    /// Compare patches after subtracting their means (robust to brightness
    /// changes between the pictures).
    pub mean_normalize: bool,
    /// Try the neighbouring patches' vectors before each search.
    pub propagate: bool,
    /// Damping of each patch's Gauss-Newton step below the coarsest level,
    /// at full size (Levenberg-Marquardt: added to the Hessian's diagonal,
    /// per pixel of the patch, in squared Sobel-gradient units). There the
    /// coarser level's flow is already close; undamped, a patch on a lone
    /// edge or a flat area slides along it, and propagation spreads the
    /// slide (a noise-free scene with flat regions: 2 % of pixels off by
    /// more than a pixel at full size). The coarsest level, which must find
    /// large motion by descent, is barely damped.
    pub damping: f32,
    /// Whether each level coarser than full size has a quarter of the
    /// damping of the level below it (the presets), rather than `damping`
    /// at every level (the finer mode, [`DisParams::fine_on_small`]). Each
    /// halving quarters the variance of the picture's noise, so the data
    /// earn four times the weight against the start; with full size's
    /// damping at quarter size, patches on moving real footage kept the
    /// coarser level's error (the side-by-side's record in
    /// `docs/results/flow.md`, room_400 ultrafast: EPE 1.22 against 0.64). On mostly still footage the
    /// weaker damping lets flat, noisy areas drift: the encoder's flow
    /// predictor, which uses the finer mode, took 5.6 % more bits with it
    /// on fish_1160 at CIF, so the finer mode keeps the full damping.
    pub damping_falls: bool,
    /// At the coarsest level, also try each patch's exhaustive whole-pixel
    /// match over the whole picture (median of its neighbours'), taken
    /// where the patch is textured and the match fits four times better
    /// than the local search's result.
    /// Reaches motions of a quarter of the picture and more; off in the
    /// presets because it can lock low-texture regions under rotation
    /// onto wrong matches (see the README's flow benchmark).
    pub global_search: bool,
    /// Also start from sparse feature matches ([`crate::features`]) spread
    /// into a dense field, which each patch tries as a candidate: motion
    /// beyond the pyramid's reach, where the pictures have corners to
    /// match. Used when no initial flow is given.
    pub seed_matches: bool,
    /// The finest level whose patches try the matches' field (0: every
    /// level; the coarsest level always does). Where the coarser levels
    /// have found the motion already, a match's vector, exact at its
    /// corner and spread to the pixels around it, pulls full-size patches
    /// off it at motion boundaries (the accurate preset: 1).
    pub seed_finest: usize,
    /// Variational refinement after each level (`iterations: 0` turns it off).
    pub refine: RefineParams,
}

/// Speed / accuracy points, in the spirit of OpenCV's DIS presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DisPreset {
    /// Quarter-size flow, no refinement.
    Ultrafast,
    /// Quarter-size flow with refinement.
    Fast,
    /// Half-size flow, denser patches, more steps.
    Medium,
    /// Full-size flow, started from feature matches as well (motion
    /// beyond the pyramid's reach) and refined as DeepFlow refines (ten
    /// fixed-point iterations of ten sweeps a level); many times slower
    /// than `Medium`.
    Accurate,
}

impl DisParams {
    /// The settings of a preset: OpenCV's pyramid levels at every size
    /// (its finest level 2 for ultrafast and fast, 1 for medium), so that
    /// each preset takes no more than OpenCV's preset of the same name on
    /// small pictures too (the README's side-by-side; the finer levels'
    /// cost on small pictures is in `docs/results/flow.md`).
    pub fn preset(preset: DisPreset) -> DisParams {
        let base = DisParams {
            finest: 2,
            min_side: 0,
            coarsest: None,
            patch: 8,
            stride: 4,
            iterations: 16,
            mean_normalize: true,
            propagate: true,
            damping: 20.0,
            damping_falls: true,
            global_search: false,
            seed_matches: false,
            seed_finest: 0,
            refine: RefineParams::default(),
        };
        match preset {
            DisPreset::Ultrafast => DisParams {
                iterations: 12,
                refine: RefineParams {
                    iterations: 0,
                    ..RefineParams::default()
                },
                ..base
            },
            DisPreset::Fast => base,
            DisPreset::Medium => DisParams {
                finest: 1,
                stride: 3,
                iterations: 25,
                ..base
            },
            // Refined as DeepFlow refines (ten fixed-point iterations of
            // ten sweeps; a stiffer smoothness term, less gradient
            // constancy), the patches less damped and the matches tried
            // from half size up: on the README's seven pairs EPE 0.288
            // against 0.426 (fish_1160) and 0.151 against 0.205
            // (smile_360p), where DeepFlow had 0.305 and 0.158.
            DisPreset::Accurate => DisParams {
                finest: 0,
                min_side: 0,
                stride: 3,
                iterations: 25,
                damping: 2.0,
                seed_matches: true,
                seed_finest: 1,
                refine: RefineParams {
                    iterations: 10,
                    sor_iterations: 10,
                    alpha: 40.0,
                    gamma: 5.0,
                    ..RefineParams::default()
                },
                ..base
            },
        }
    }

    /// These settings computed a level finer on small pictures (the level
    /// whose longer side is nearest 160 pixels for ultrafast and fast, 320
    /// for medium, where that is finer than `finest`): CIF at half size
    /// (fast) or full size (medium). About half the end-point error of
    /// OpenCV's preset there, for 2-4 times its time; what the
    /// applications (global motion, stabilisation, interpolation,
    /// segmentation) and the encoder's flow predictors use; every level
    /// below the coarsest has the full damping ([`DisParams::damping_falls`]).
    /// A preset whose `finest` is 0 is unchanged.
    pub fn fine_on_small(self) -> DisParams {
        let min_side = match self.finest {
            0 => return self,
            1 => 320,
            _ => 160,
        };
        DisParams {
            min_side,
            damping_falls: false,
            ..self
        }
    }

    /// Checks the settings, saying which is out of range.
    pub fn validate(&self) -> Result<(), String> {
        if ![4, 8, 12, 16].contains(&self.patch) {
            return Err(format!("patch size {} is not 4, 8, 12 or 16", self.patch));
        }
        if self.stride == 0 || self.stride > self.patch {
            return Err(format!(
                "patch stride {} is not in 1..={}",
                self.stride, self.patch
            ));
        }
        if self.iterations == 0 {
            return Err("at least one Gauss-Newton step per patch is needed".into());
        }
        if !(self.damping >= 0.0 && self.damping.is_finite()) {
            return Err(format!("damping {} is not a finite number >= 0", self.damping));
        }
        self.refine.validate()
    }
}

impl Default for DisParams {
    fn default() -> DisParams {
        DisParams::preset(DisPreset::Medium)
    }
}

/// The damping of the coarsest level's steps: just enough to keep a flat
/// patch's step finite (such steps are then refused by the distance check).
const COARSEST_DAMPING: f32 = 0.01;

/// The coarsest level to start from: about four patches across the longer
/// side (so a quarter of the picture is within a patch's reach there), and
/// no level smaller than a patch.
fn coarsest_level(w: usize, h: usize, patch: usize) -> usize {
    let long = w.max(h) as f64 / (4.0 * patch as f64);
    let by_motion = if long > 1.0 {
        long.log2().round() as usize
    } else {
        0
    };
    let short = w.min(h) as f64 / patch as f64;
    let by_size = if short > 1.0 {
        short.log2().floor() as usize
    } else {
        0
    };
    by_motion.min(by_size)
}

/// The finest level computed for a `w x h` picture: `finest`, or finer
/// where the picture is small (the level whose longer side is nearest
/// `min_side`, in octaves). Without refinement, never full size unless
/// `finest` says so: there each patch's failure stays in the field (a
/// 160x120 pair measured 2.7 % of pixels off by more than a pixel, none
/// from half size).
fn finest_level(w: usize, h: usize, p: &DisParams) -> usize {
    if p.min_side == 0 {
        return p.finest;
    }
    let octaves = (w.max(h) as f64 / p.min_side as f64).log2().round().max(0.0) as usize;
    let floor = usize::from(p.refine.iterations == 0);
    p.finest.min(octaves.max(floor))
}

/// Dense flow from `i1` to `i2` (same size, grey levels 0..255).
///
/// ```
/// use mocomp::flow::dis::{dis_flow, DisParams, DisPreset};
/// use ndarray::Array2;
/// let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos();
/// let i1 = Array2::from_shape_fn((96, 128), |(y, x)| f(x as f32, y as f32));
/// let i2 = Array2::from_shape_fn((96, 128), |(y, x)| f(x as f32 - 6.5, y as f32 + 2.0));
/// let flow = dis_flow(&i1, &i2, &DisParams::preset(DisPreset::Medium));
/// let (u, v) = flow.get(64, 48);
/// assert!((u - 6.5).abs() < 0.1 && (v + 2.0).abs() < 0.1);
/// ```
pub fn dis_flow(i1: &Array2<f32>, i2: &Array2<f32>, p: &DisParams) -> Flow {
    Dis::new(*p).compute(i1, i2)
}

/// Dense inverse search keeping its pyramids from one call to the next.
#[derive(Debug)]
pub struct Dis {
    params: DisParams,
    p1: Pyramid,
    p2: Pyramid,
    /// One for every level, its buffers those of the finest (reserved
    /// first), so that a second pair of the same size allocates nothing in
    /// the refinement.
    refiner: Refiner,
}

impl Dis {
    /// An estimator with these settings. Panics on settings that
    /// [`DisParams::validate`] refuses.
    pub fn new(params: DisParams) -> Dis {
        if let Err(e) = params.validate() {
            panic!("dis: {e}");
        }
        Dis {
            params,
            p1: Pyramid::default(),
            p2: Pyramid::default(),
            refiner: Refiner::default(),
        }
    }

    /// The settings.
    pub fn params(&self) -> &DisParams {
        &self.params
    }

    /// Dense flow from `i1` to `i2` (same size, grey levels 0..255).
    pub fn compute(&mut self, i1: &Array2<f32>, i2: &Array2<f32>) -> Flow {
        self.compute_from(i1, i2, None)
    }

    /// As [`Dis::compute`], with an initial flow at full size whose vectors
    /// each patch also tries (as OpenCV's DIS does with a given flow): for
    /// sequences, or a flow interpolated from sparse matches. Panics if the
    /// pictures or the initial flow differ in size.
    pub fn compute_from(&mut self, i1: &Array2<f32>, i2: &Array2<f32>, initial: Option<&Flow>) -> Flow {
        self.compute_luma(i1.into(), i2.into(), initial)
    }

    /// As [`Dis::compute_from`], from 8-bit or float pictures without
    /// converting them first.
    pub fn compute_luma(&mut self, i1: Luma<'_>, i2: Luma<'_>, initial: Option<&Flow>) -> Flow {
        let mut out = Flow::zeros(0, 0);
        self.compute_luma_into(i1, i2, initial, &mut out);
        out
    }

    /// As [`Dis::compute_luma`], written over `out` (any size; its buffers
    /// are kept where it has the pictures' size, as OpenCV's `calc` keeps
    /// its output): a frame loop then allocates and clears no field (the
    /// clearing was 8 % of ultrafast's time on 640x360).
    pub fn compute_luma_into(&mut self, i1: Luma<'_>, i2: Luma<'_>, initial: Option<&Flow>, out: &mut Flow) {
        let (h0, w0) = i1.dim();
        let (u, v, finest) = self.coarse_to_fine(i1, i2, initial);
        if finest == 0 {
            *out = Flow::from_uv(u, v);
            return;
        }
        let f = (1usize << finest) as f32;
        let (ou, ov) = out.overwrite_all_valid(w0, h0);
        both(
            parallel_worth(w0 * h0),
            || upsample_levels_into(&u, finest, f, ou),
            || upsample_levels_into(&v, finest, f, ov),
        );
    }

    /// The flow from `i1` to `i2` written into `out` as (u, v) pairs row by
    /// row (`2 h w` floats, OpenCV's and the .flo layout), with no planar
    /// field in between: the same values as [`Dis::compute_luma`]. Panics
    /// if the pictures differ in size or `out` is not `2 h w` long.
    pub fn compute_interleaved(&mut self, i1: Luma<'_>, i2: Luma<'_>, out: &mut [f32]) {
        let (h0, w0) = i1.dim();
        assert_eq!(out.len(), 2 * h0 * w0, "dis: output size");
        let (u, v, finest) = self.coarse_to_fine(i1, i2, None);
        upsample_levels_interleaved(&u, &v, h0, w0, finest, (1usize << finest) as f32, out);
    }

    /// The flow at the finest level computed, and that level.
    fn coarse_to_fine(
        &mut self,
        i1: Luma<'_>,
        i2: Luma<'_>,
        initial: Option<&Flow>,
    ) -> (Array2<f32>, Array2<f32>, usize) {
        assert_eq!(i1.dim(), i2.dim(), "dis: pictures of different sizes");
        if let Some(f) = initial {
            assert_eq!(
                (f.height(), f.width()),
                i1.dim(),
                "dis: initial flow and pictures differ in size"
            );
        }
        let p = self.params;
        let (h0, w0) = i1.dim();
        let coarsest = p.coarsest.unwrap_or_else(|| coarsest_level(w0, h0, p.patch));
        let finest = finest_level(w0, h0, &p).min(coarsest);
        // The two pyramids are independent: one worker each where there
        // are two. Level 0 is filled only when the search reads it.
        let build = |p: &mut Pyramid, img: Luma<'_>| p.build_binomial_luma(img, coarsest + 1, 1, finest == 0);
        let (p1, p2) = (&mut self.p1, &mut self.p2);
        both(parallel_worth(w0 * h0), || build(p1, i1), || build(p2, i2));
        let top = self.p1.levels.len() - 1;
        if p.refine.iterations > 0 {
            let (h, w) = self.p1.levels[finest].dim();
            self.refiner.reserve(w, h);
        }
        let (mut u, mut v) = (
            Array2::zeros(self.p1.levels[top].dim()),
            Array2::zeros(self.p1.levels[top].dim()),
        );
        let (hints, hinted_from) = self.hints(i1, i2, initial, finest);
        for level in (finest..=top).rev() {
            let (h, w) = self.p1.levels[level].dim();
            if u.dim() != (h, w) {
                u = upsample2(&u, h, w, 2.0);
                v = upsample2(&v, h, w, 2.0);
            }
            let hint = hints
                .as_ref()
                .filter(|_| level >= hinted_from)
                .map(|hs| &hs[level - hinted_from]);
            self.solve_level(level, hint, (&mut u, &mut v));
        }
        (u, v, finest)
    }

    /// The start flows per level from the finest hinted up, and that
    /// level: the caller's `initial` at every level, or the feature
    /// matches' (where the parameters seed them) from `seed_finest`.
    fn hints(
        &self,
        i1: Luma<'_>,
        i2: Luma<'_>,
        initial: Option<&Flow>,
        finest: usize,
    ) -> (Option<Vec<LevelFlow>>, usize) {
        let p = &self.params;
        let (h0, w0) = i1.dim();
        let top = self.p1.levels.len() - 1;
        let seed = match initial {
            None if p.seed_matches => {
                let (a, b) = (i1.to_f32(), i2.to_f32());
                let matches =
                    crate::features::match_pictures(&a, &b, &crate::features::MatchParams::default());
                crate::flow::matches_to_flow(&matches, w0, h0)
            }
            _ => None,
        };
        let hinted_from = if initial.is_some() {
            finest
        } else {
            p.seed_finest.max(finest).min(top)
        };
        let hints = initial
            .or(seed.as_ref())
            .map(|f| hint_pyramid(f, &self.p1.levels, hinted_from));
        (hints, hinted_from)
    }

    /// One level's flow into `u`, `v` (the coarser level's, upsampled to
    /// this level's size): its patches searched from it (and from `hint`),
    /// densified, refined.
    fn solve_level(
        &mut self,
        level: usize,
        hint: Option<&LevelFlow>,
        (u, v): (&mut Array2<f32>, &mut Array2<f32>),
    ) {
        let p = self.params;
        let top = self.p1.levels.len() - 1;
        let (a1, a2) = (&self.p1.levels[level], &self.p2.levels[level]);
        let (h, w) = a1.dim();
        let patch = p.patch.min(w).min(h);
        let padded = search::Padded::new(a2.as_slice().expect("standard"), w, h, patch + 2);
        let input = search::LevelSearch {
            a1,
            a2: &padded,
            u: &*u,
            v: &*v,
            hint,
            params: &p,
            exhaustive: p.global_search && level == top,
            damping: match (level == top, p.damping_falls) {
                (true, _) => COARSEST_DAMPING,
                (false, true) => p.damping / 4f32.powi(level as i32),
                (false, false) => p.damping,
            },
            refines: level < top,
        };
        let sparse = search::search_level(&input, patch);
        densify::densify(a1, &padded, &sparse, u, v);
        if p.refine.iterations > 0 {
            self.refiner.refine(a1, a2, u, v, &p.refine);
        }
    }
}

/// `a()` and `b()`, on two workers when `parallel` (the same results).
fn both<A: Send, B: Send>(
    parallel: bool,
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    if parallel {
        rayon::join(a, b)
    } else {
        (a(), b())
    }
}

/// The initial flow at every level from `finest` up, scaled to each level.
/// A flow's two components at one level of the pyramid.
type LevelFlow = (Array2<f32>, Array2<f32>);

fn hint_pyramid(flow: &Flow, levels: &[Array2<f32>], finest: usize) -> Vec<LevelFlow> {
    let mut out = Vec::new();
    let (mut u, mut v) = (flow.u().clone(), flow.v().clone());
    for (level, img) in levels.iter().enumerate() {
        if level > 0 {
            u = crate::imgproc::pyramid::downsample(&u) * 0.5;
            v = crate::imgproc::pyramid::downsample(&v) * 0.5;
            debug_assert_eq!(u.dim(), img.dim());
        }
        if level >= finest {
            out.push((u.clone(), v.clone()));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_coarsest_level_leaves_a_few_patches() {
        assert_eq!(coarsest_level(640, 480, 8), 4);
        assert_eq!(coarsest_level(352, 288, 8), 3);
        assert_eq!(coarsest_level(1282, 1110, 8), 5);
        assert_eq!(coarsest_level(20, 12, 8), 0);
        assert_eq!(coarsest_level(3, 2, 8), 0);
    }

    #[test]
    fn small_pictures_are_computed_finer() {
        let (fast, medium) = (
            DisParams::preset(DisPreset::Fast).fine_on_small(),
            DisParams::preset(DisPreset::Medium).fine_on_small(),
        );
        let ultrafast = DisParams::preset(DisPreset::Ultrafast).fine_on_small();
        // 640 and more: the preset's level, as OpenCV's.
        assert_eq!(finest_level(640, 480, &fast), 2);
        assert_eq!(finest_level(640, 480, &medium), 1);
        assert_eq!(finest_level(1282, 1110, &medium), 1);
        // CIF: one level finer for fast, full size for medium.
        assert_eq!(finest_level(352, 288, &fast), 1);
        assert_eq!(finest_level(352, 288, &medium), 0);
        assert_eq!(finest_level(584, 388, &medium), 1);
        assert_eq!(finest_level(40, 30, &fast), 0);
        // Without refinement, half size at the least.
        assert_eq!(finest_level(352, 288, &ultrafast), 1);
        assert_eq!(finest_level(160, 120, &ultrafast), 1);
        let fixed = DisParams { min_side: 0, ..fast };
        assert_eq!(finest_level(352, 288, &fixed), 2);
        // The presets themselves: OpenCV's level at every size.
        for (preset, level) in [
            (DisPreset::Ultrafast, 2),
            (DisPreset::Fast, 2),
            (DisPreset::Medium, 1),
        ] {
            for (w, h) in [(1280, 720), (640, 480), (352, 288), (176, 144)] {
                assert_eq!(
                    finest_level(w, h, &DisParams::preset(preset)),
                    level,
                    "{preset:?} {w}x{h}"
                );
            }
        }
        let accurate = DisParams::preset(DisPreset::Accurate);
        assert_eq!(accurate.fine_on_small(), accurate);
    }

    #[test]
    fn presets_are_valid_and_odd_settings_are_refused() {
        for p in [
            DisPreset::Ultrafast,
            DisPreset::Fast,
            DisPreset::Medium,
            DisPreset::Accurate,
        ] {
            DisParams::preset(p).validate().unwrap();
        }
        let bad = DisParams {
            patch: 7,
            ..DisParams::default()
        };
        assert!(bad.validate().unwrap_err().contains("patch size"));
        let bad = DisParams {
            stride: 9,
            ..DisParams::default()
        };
        assert!(bad.validate().is_err());
    }
}
