//! Dense motion as float fields: the [`Flow`] type used everywhere, the
//! methods that estimate it (one [`FlowEstimator`] over them all), and
//! warping by a flow.
//!
//! Convention (used by every function of mocomp): a forward flow `w` from
//! frame 1 to frame 2 means `frame1(p) ~ frame2(p + w(p))`.

pub mod consistency;
pub mod dis;
pub(crate) mod dsp;
mod estimator;
mod field;
pub mod hs;
pub mod lk;
/// The image filters and pyramids flow is built on (they live in
/// [`crate::imgproc`], below flow and features).
pub use crate::imgproc::pyramid;
pub mod refine;
mod seed;
pub mod track;
pub mod tvl1;
pub mod warp;

pub use estimator::{
    dis_preset, hs_preset, lk_preset, tvl1_preset, FlowEstimator, FlowMethod, FlowOptionError, FlowOptions,
    Preset,
};
pub use field::Flow;
pub use seed::matches_to_flow;
