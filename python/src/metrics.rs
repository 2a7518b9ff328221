//! Picture quality and BD-rate.

use mocomp::metrics::{psnr_from_mse, ssim as ssim_of};
use mocomp::rd::bdrate::{bd_rate as bd, Fit};
use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{frame_from_py, luma_plane, value_error};

/// PSNR of `b` against `a` (uint8 arrays of one shape: a plane, an RGB
/// picture, a stack), in dB over all samples: 10 log10(255^2 / MSE),
/// capped at 100 dB for identical arrays (as mocomp and x264 report).
#[pyfunction]
pub fn psnr(py: Python<'_>, a: PyReadonlyArrayDyn<'_, u8>, b: PyReadonlyArrayDyn<'_, u8>) -> PyResult<f64> {
    if a.shape() != b.shape() {
        return Err(value_error(format!(
            "a and b differ in shape: {:?} and {:?}",
            a.shape(),
            b.shape()
        )));
    }
    if a.len() == 0 {
        return Err(value_error("a and b are empty"));
    }
    let (a, b) = (a.as_array(), b.as_array());
    let n = a.len() as f64;
    let sse: u64 = py.detach(|| {
        a.iter()
            .zip(b.iter())
            .map(|(&x, &y)| {
                let d = u64::from(x.abs_diff(y));
                d * d
            })
            .sum()
    });
    Ok(psnr_from_mse(sse as f64 / n))
}

/// SSIM of `b` against `a` (uint8 luma H x W, or RGB made luma): Wang et
/// al.'s Gaussian-window SSIM (sigma 1.5, 11 x 11), as scikit-image's
/// structural_similarity(gaussian_weights=True, use_sample_covariance=False).
#[pyfunction]
pub fn ssim(py: Python<'_>, a: &Bound<'_, PyAny>, b: &Bound<'_, PyAny>) -> PyResult<f64> {
    let (pa, pb) = (luma_plane("a", a, 0)?, luma_plane("b", b, 0)?);
    if (pa.width(), pa.height()) != (pb.width(), pb.height()) {
        return Err(value_error(format!(
            "a is {} x {}, b {} x {}",
            pa.height(),
            pa.width(),
            pb.height(),
            pb.width()
        )));
    }
    Ok(py.detach(|| ssim_of(&pa, &pb)))
}

/// Bjontegaard delta rate of curve b against curve a, percent (negative:
/// b needs fewer bits for the same PSNR). Rates in any one unit, at least
/// four points per curve. method: "cubic" (VCEG-M33) or "pchip".
#[pyfunction]
#[pyo3(signature = (rate_a, psnr_a, rate_b, psnr_b, method="cubic"))]
pub fn bd_rate(
    rate_a: Vec<f64>,
    psnr_a: Vec<f64>,
    rate_b: Vec<f64>,
    psnr_b: Vec<f64>,
    method: &str,
) -> PyResult<f64> {
    let fit = match method {
        "cubic" => Fit::Cubic,
        "pchip" => Fit::Pchip,
        _ => return Err(value_error(format!("unknown method '{method}' (cubic or pchip)"))),
    };
    let curve = |name: &str, r: Vec<f64>, p: Vec<f64>| -> PyResult<Vec<(f64, f64)>> {
        if r.len() != p.len() {
            return Err(value_error(format!(
                "rate_{name} and psnr_{name} differ in length: {} and {}",
                r.len(),
                p.len()
            )));
        }
        Ok(r.into_iter().zip(p).collect())
    };
    let (a, b) = (curve("a", rate_a, psnr_a)?, curve("b", rate_b, psnr_b)?);
    bd(&a, &b, fit).map_err(|e| value_error(e.to_string()))
}

/// The quality of `test` against `reference`, both (Y, U, V) uint8 frames
/// (4:2:0, chroma half the luma size rounded up): a dict with `psnr_y`,
/// `psnr_u`, `psnr_v` and the metrics asked for (comma-separated: ssim,
/// ms-ssim, psnr-hvs, ciede2000, or all), as `mocomp quality` reports them
/// (AWCY's figures as libvmaf computes them).
#[pyfunction]
#[pyo3(signature = (reference, test, metrics="psnr,ssim"))]
pub fn quality<'py>(
    py: Python<'py>,
    reference: &Bound<'py, PyAny>,
    test: &Bound<'py, PyAny>,
    metrics: &str,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    use mocomp::metrics::{FrameQuality, Metric, Metrics};
    let which: Metrics = metrics
        .parse()
        .map_err(|e: mocomp::metrics::UnknownMetric| value_error(e.to_string()))?;
    if which.has(Metric::Vmaf) {
        return Err(value_error(
            "vmaf works on sequences: use mocomp quality on Y4M files",
        ));
    }
    let (a, b) = (
        frame_from_py("reference", reference)?,
        frame_from_py("test", test)?,
    );
    if (a.width(), a.height()) != (b.width(), b.height()) {
        return Err(value_error("reference and test differ in size"));
    }
    let q = py.detach(|| FrameQuality::measure_with(&a, &b, which));
    crate::record::to_dict(py, &q)
}
