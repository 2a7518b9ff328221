//! Dense motion as float fields: the [`Flow`] type used everywhere, the
//! methods that estimate it (one [`FlowEstimator`] over them all), and
//! warping by a flow.
//!
//! Convention (used by every function of mocomp): a forward flow `w` from
//! frame 1 to frame 2 means `frame1(p) ~ frame2(p + w(p))`.

pub mod consistency;
pub mod dis;
mod estimator;
mod field;
pub mod hs;
pub mod lk;
pub mod pyramid;
pub mod refine;
pub mod track;
pub mod tvl1;
pub mod warp;

pub use estimator::{
    dis_preset, hs_preset, lk_preset, tvl1_preset, FlowEstimator, FlowMethod, FlowOptionError, FlowOptions,
    Preset,
};
pub use field::Flow;
