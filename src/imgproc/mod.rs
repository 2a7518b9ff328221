//! Image processing on float pictures, below both [`crate::flow`] and
//! [`crate::features`]: separable filters, Gaussian and binomial pyramids,
//! gradients, contrast normalisation, and the structure tensor's corner
//! response.

pub mod corners;
pub mod domain;
pub mod dsp;
pub mod pyramid;
pub mod warp;

use ndarray::{Array2, ArrayView2};

/// A grey picture as the flow estimators take it without a copy: 8-bit
/// samples (numpy's uint8, a decoded luma plane) or floats, both on the
/// 0..255 scale.
#[derive(Debug, Clone, Copy)]
pub enum Luma<'a> {
    /// 8-bit samples.
    U8(ArrayView2<'a, u8>),
    /// Float samples.
    F32(ArrayView2<'a, f32>),
}

impl Luma<'_> {
    /// (height, width).
    pub fn dim(&self) -> (usize, usize) {
        match self {
            Luma::U8(a) => a.dim(),
            Luma::F32(a) => a.dim(),
        }
    }

    /// The samples as floats, in a new array.
    pub fn to_f32(&self) -> Array2<f32> {
        match self {
            Luma::U8(a) => a.mapv(f32::from),
            Luma::F32(a) => a.as_standard_layout().into_owned(),
        }
    }
}

impl<'a> From<&'a Array2<f32>> for Luma<'a> {
    fn from(a: &'a Array2<f32>) -> Luma<'a> {
        Luma::F32(a.view())
    }
}

impl<'a> From<&'a Array2<u8>> for Luma<'a> {
    fn from(a: &'a Array2<u8>) -> Luma<'a> {
        Luma::U8(a.view())
    }
}
