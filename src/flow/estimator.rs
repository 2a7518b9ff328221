//! Every dense flow method behind one type: a method, a preset and the
//! options that override it ([`FlowOptions`]), made once into a
//! [`FlowEstimator`] that keeps its buffers between pairs (as OpenCV's
//! `DISOpticalFlow` object does). `mocomp flow` and the Python package
//! both choose their flow here.
//!
//! ```
//! use mocomp::flow::{FlowEstimator, FlowMethod, FlowOptions, Preset};
//! use ndarray::Array2;
//! let a = Array2::from_shape_fn((48, 64), |(y, x)| ((x * 7 + y * 3) % 23) as f32 * 10.0);
//! let options = FlowOptions { method: FlowMethod::Lk, preset: Preset::Fast, ..FlowOptions::default() };
//! let mut estimator = FlowEstimator::new(&options).unwrap();
//! let flow = estimator.compute(&a, &a);
//! assert_eq!((flow.width(), flow.height()), (64, 48));
//! ```

use std::fmt;
use std::str::FromStr;

use ndarray::Array2;

use super::dis::{Dis, DisParams, DisPreset};
use super::hs::{horn_schunck, HsParams};
use super::lk::{Lk, LkParams};
use super::tvl1::{tvl1, Tvl1Params};
use super::Flow;
use crate::imgproc::Luma;

/// A dense flow method: what `mocomp flow --method` computes and what
/// guides a flow-based predictor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum FlowMethod {
    /// Pyramidal Lucas-Kanade ([`super::lk`]; the encoder uses
    /// `LkParams::default()`).
    Lk,
    /// Horn-Schunck ([`super::hs`]; the encoder uses the default settings).
    Hs,
    /// Dense inverse search ([`super::dis`]; the encoder uses the medium
    /// preset). The default.
    #[default]
    Dis,
    /// TV-L1 ([`super::tvl1`]; the encoder uses the default settings).
    Tvl1,
}

impl FlowMethod {
    /// Every method.
    pub const ALL: [FlowMethod; 4] = [FlowMethod::Lk, FlowMethod::Hs, FlowMethod::Dis, FlowMethod::Tvl1];

    /// `lk`, `hs`, `dis` or `tvl1`.
    pub fn name(self) -> &'static str {
        match self {
            FlowMethod::Lk => "lk",
            FlowMethod::Hs => "hs",
            FlowMethod::Dis => "dis",
            FlowMethod::Tvl1 => "tvl1",
        }
    }
}

impl fmt::Display for FlowMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for FlowMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<FlowMethod, String> {
        FlowMethod::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown flow method '{s}' (lk, hs, dis or tvl1)"))
    }
}

/// A point of speed against accuracy, for every method (as OpenCV's DIS
/// presets).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Preset {
    /// Fastest.
    Ultrafast,
    /// Fast.
    Fast,
    /// The default.
    #[default]
    Medium,
    /// Most accurate.
    Accurate,
}

impl Preset {
    /// Every preset, fastest first.
    pub const ALL: [Preset; 4] = [Preset::Ultrafast, Preset::Fast, Preset::Medium, Preset::Accurate];

    /// `ultrafast`, `fast`, `medium` or `accurate`.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Ultrafast => "ultrafast",
            Preset::Fast => "fast",
            Preset::Medium => "medium",
            Preset::Accurate => "accurate",
        }
    }
}

impl FromStr for Preset {
    type Err = String;
    fn from_str(s: &str) -> Result<Preset, String> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown preset '{s}' (ultrafast, fast, medium or accurate)"))
    }
}

/// The LK settings of each preset: every one with as many levels as the
/// picture allows and contrast-normalised pictures (what large motion and
/// lighting changes need: see the README's flow benchmark). Fast: window
/// sigma 2.5, stops at half size; medium: sigma 4, full size; accurate:
/// sigma 6. Larger windows suit smooth motion; they blur motion
/// boundaries, so medium stays at sigma 4.
pub fn lk_preset(preset: Preset) -> LkParams {
    let base = LkParams {
        levels: 0,
        normalize: true,
        ..LkParams::default()
    };
    match preset {
        Preset::Ultrafast | Preset::Fast => LkParams {
            sigma: 2.5,
            finest: 1,
            ..base
        },
        Preset::Medium => base,
        Preset::Accurate => LkParams { sigma: 6.0, ..base },
    }
}

/// The HS settings of each preset (alpha 20). On the flowpair: fast (one
/// warp, at most 30 sweeps) EPE 0.074 px in 129 ms; medium (one warp, 60
/// sweeps) 0.065 px in 225 ms; accurate adds warps for larger motion.
pub fn hs_preset(preset: Preset) -> HsParams {
    match preset {
        Preset::Ultrafast | Preset::Fast => HsParams {
            iterations: 30,
            ..HsParams::default()
        },
        Preset::Medium => HsParams::default(),
        Preset::Accurate => HsParams {
            warps: 3,
            iterations: 100,
            tolerance: 0.0005,
            ..HsParams::default()
        },
    }
}

/// The TV-L1 settings of each preset: fewer warps and iterations for
/// speed, more for accuracy.
pub fn tvl1_preset(preset: Preset) -> Tvl1Params {
    let base = Tvl1Params::default();
    match preset {
        Preset::Ultrafast => Tvl1Params {
            warps: 2,
            iterations: 15,
            ..base
        },
        Preset::Fast => Tvl1Params {
            warps: 3,
            iterations: 30,
            ..base
        },
        Preset::Medium => base,
        Preset::Accurate => Tvl1Params {
            warps: 8,
            iterations: 100,
            ..base
        },
    }
}

/// The DIS settings of each preset ([`DisPreset`] of the same name).
pub fn dis_preset(preset: Preset) -> DisParams {
    DisParams::preset(match preset {
        Preset::Ultrafast => DisPreset::Ultrafast,
        Preset::Fast => DisPreset::Fast,
        Preset::Medium => DisPreset::Medium,
        Preset::Accurate => DisPreset::Accurate,
    })
}

/// A method, its preset, and the options that override the preset (each
/// applies to the methods that have it; `None` keeps the preset's).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FlowOptions {
    /// The method (DIS by default).
    pub method: FlowMethod,
    /// The preset the options start from.
    pub preset: Preset,
    /// Pyramid levels, at least 1 (LK, HS, TV-L1).
    pub levels: Option<usize>,
    /// LK window sigma, in (0, 10].
    pub sigma: Option<f32>,
    /// Iterations per level (LK, HS, TV-L1).
    pub iterations: Option<usize>,
    /// HS smoothness weight, positive.
    pub alpha: Option<f32>,
    /// HS gradient-constancy weight, in [0, 10000).
    pub gamma: Option<f32>,
    /// TV-L1 structure-texture weight (see [`Tvl1Params::texture`]).
    pub texture: Option<f32>,
    /// Warps per level (HS, TV-L1), at least 1.
    pub warps: Option<usize>,
    /// Finest pyramid level computed, 0 = full size (LK, DIS; for DIS taken
    /// as given, whatever the picture's size).
    pub finest: Option<usize>,
    /// DIS: each patch's exhaustive match at the coarsest level too.
    pub global_search: bool,
    /// DIS: each patch also started from the nearest feature match.
    pub matches: bool,
    /// DIS: small pictures computed a level finer than the preset's
    /// ([`DisParams::fine_on_small`]; `finest` overrides it).
    pub fine_on_small: bool,
}

/// An option outside its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct FlowOptionError(pub String);

fn bad(message: String) -> FlowOptionError {
    FlowOptionError(message)
}

impl FlowOptions {
    /// The LK settings: the preset's, with the options.
    pub fn lk_params(&self) -> Result<LkParams, FlowOptionError> {
        let mut lk = lk_preset(self.preset);
        if let Some(l) = self.levels {
            lk.levels = l.max(1);
        }
        if let Some(s) = self.sigma {
            if !(s > 0.0 && s <= 10.0) {
                return Err(bad(format!("sigma {s} must be in (0, 10]")));
            }
            lk.sigma = s;
        }
        if let Some(i) = self.iterations {
            lk.iterations = i;
        }
        if let Some(f) = self.finest {
            lk.finest = f;
        }
        Ok(lk)
    }

    /// The Horn-Schunck settings: the preset's, with the options.
    pub fn hs_params(&self) -> Result<HsParams, FlowOptionError> {
        let mut hs = hs_preset(self.preset);
        if let Some(l) = self.levels {
            hs.levels = l.max(1);
        }
        if let Some(i) = self.iterations {
            hs.iterations = i.max(1);
        }
        if let Some(a) = self.alpha {
            if !(a > 0.0 && a < 1e4) {
                return Err(bad(format!("alpha {a} must be positive (and below 10000)")));
            }
            hs.alpha = a;
        }
        if let Some(w) = self.warps {
            hs.warps = w.max(1);
        }
        if let Some(g) = self.gamma {
            if !(0.0..1e4).contains(&g) {
                return Err(bad(format!("gamma {g} must be in [0, 10000)")));
            }
            hs.gamma = g;
        }
        Ok(hs)
    }

    /// The TV-L1 settings: the preset's, with the options.
    pub fn tvl1_params(&self) -> Result<Tvl1Params, FlowOptionError> {
        let mut tv = tvl1_preset(self.preset);
        if let Some(l) = self.levels {
            tv.levels = l.max(1);
        }
        if let Some(i) = self.iterations {
            tv.iterations = i.max(1);
        }
        if let Some(w) = self.warps {
            tv.warps = w.max(1);
        }
        if let Some(t) = self.texture {
            tv.texture = t;
            tv.validate().map_err(bad)?;
        }
        Ok(tv)
    }

    /// The DIS settings: the preset's, with the options. A finest level
    /// given overrides the finer mode as a whole.
    pub fn dis_params(&self) -> DisParams {
        let base = match (self.fine_on_small, self.finest) {
            (true, None) => dis_preset(self.preset).fine_on_small(),
            _ => dis_preset(self.preset),
        };
        DisParams {
            global_search: self.global_search,
            seed_matches: base.seed_matches || self.matches,
            finest: self.finest.unwrap_or(base.finest),
            ..base
        }
    }
}

/// The chosen method, made once; repeated pairs reuse its buffers.
pub enum FlowEstimator {
    /// Lucas-Kanade.
    Lk(Box<Lk>),
    /// Horn-Schunck.
    Hs(HsParams),
    /// Dense inverse search.
    Dis(Box<Dis>),
    /// TV-L1.
    Tvl1(Tvl1Params),
}

impl FlowEstimator {
    /// The method `options` choose. Every method's options are checked, so
    /// a bad value is an error whichever method runs.
    pub fn new(options: &FlowOptions) -> Result<FlowEstimator, FlowOptionError> {
        let (lk, hs, tv) = (options.lk_params()?, options.hs_params()?, options.tvl1_params()?);
        Ok(match options.method {
            FlowMethod::Lk => FlowEstimator::Lk(Box::new(Lk::new(lk))),
            FlowMethod::Hs => FlowEstimator::Hs(hs),
            FlowMethod::Dis => FlowEstimator::Dis(Box::new(Dis::new(options.dis_params()))),
            FlowMethod::Tvl1 => FlowEstimator::Tvl1(tv),
        })
    }

    /// The method with its own default settings (`LkParams::default()`,
    /// `HsParams::default()`, DIS medium finer on small pictures,
    /// `Tvl1Params::default()`): what the encoder's flow predictors use.
    pub fn with_defaults(method: FlowMethod) -> FlowEstimator {
        match method {
            FlowMethod::Lk => FlowEstimator::Lk(Box::new(Lk::new(LkParams::default()))),
            FlowMethod::Hs => FlowEstimator::Hs(HsParams::default()),
            FlowMethod::Dis => FlowEstimator::Dis(Box::new(Dis::new(
                DisParams::preset(DisPreset::Medium).fine_on_small(),
            ))),
            FlowMethod::Tvl1 => FlowEstimator::Tvl1(Tvl1Params::default()),
        }
    }

    /// Its method.
    pub fn method(&self) -> FlowMethod {
        match self {
            FlowEstimator::Lk(_) => FlowMethod::Lk,
            FlowEstimator::Hs(_) => FlowMethod::Hs,
            FlowEstimator::Dis(_) => FlowMethod::Dis,
            FlowEstimator::Tvl1(_) => FlowMethod::Tvl1,
        }
    }

    /// The flow from `a` to `b` (same size): `a(p) ~ b(p + flow(p))`.
    pub fn compute(&mut self, a: &Array2<f32>, b: &Array2<f32>) -> Flow {
        match self {
            FlowEstimator::Lk(lk) => lk.compute(a, b).flow,
            FlowEstimator::Hs(hs) => horn_schunck(a, b, hs).0,
            FlowEstimator::Dis(dis) => dis.compute(a, b),
            FlowEstimator::Tvl1(tv) => tvl1(a, b, tv),
        }
    }

    /// [`FlowEstimator::compute`] from 8-bit or float pictures: DIS reads
    /// 8-bit samples without a conversion pass; the other methods convert
    /// first.
    pub fn compute_luma(&mut self, a: Luma<'_>, b: Luma<'_>) -> Flow {
        match self {
            FlowEstimator::Dis(dis) => dis.compute_luma(a, b, None),
            other => other.compute(&a.to_f32(), &b.to_f32()),
        }
    }

    /// [`FlowEstimator::compute_luma`] written over `out`, whose buffers DIS
    /// keeps where they have the pictures' size (a frame loop's field, as
    /// OpenCV's `calc` reuses its output); the other methods replace it.
    pub fn compute_luma_into(&mut self, a: Luma<'_>, b: Luma<'_>, out: &mut Flow) {
        match self {
            FlowEstimator::Dis(dis) => dis.compute_luma_into(a, b, None, out),
            other => *out = other.compute_luma(a, b),
        }
    }

    /// [`FlowEstimator::compute_luma`] written into `out` as (u, v) pairs
    /// row by row (`2 h w` floats, OpenCV's layout), NaN where not valid:
    /// DIS writes its last upsampling there directly. Panics if the
    /// pictures differ in size or `out` has another length.
    pub fn compute_interleaved(&mut self, a: Luma<'_>, b: Luma<'_>, out: &mut [f32]) {
        match self {
            FlowEstimator::Dis(dis) => dis.compute_interleaved(a, b, out),
            other => other.compute_luma(a, b).write_interleaved(out),
        }
    }
}
