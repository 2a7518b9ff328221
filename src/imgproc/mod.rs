//! Image processing on float pictures, below both [`crate::flow`] and
//! [`crate::features`]: separable filters, Gaussian and binomial pyramids,
//! gradients, contrast normalisation, and the structure tensor's corner
//! response.

pub mod corners;
pub mod dsp;
pub mod pyramid;
pub mod warp;
