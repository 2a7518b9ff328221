//! Dense motion as float fields: the [`Flow`] type used everywhere, and
//! warping by a flow.
//!
//! Convention (used by every function of mocomp): a forward flow `w` from
//! frame 1 to frame 2 means `frame1(p) ~ frame2(p + w(p))`.

pub mod consistency;
pub mod dis;
mod field;
pub mod hs;
pub mod lk;
pub mod pyramid;
pub mod refine;
pub mod track;
pub mod tvl1;
pub mod warp;

pub use field::Flow;
