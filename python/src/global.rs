//! Global (camera) motion: a model fitted robustly to correspondences, or
//! to the motion between two pictures.

use mocomp::flow::Preset;
use mocomp::global::sources::{PairCorrespondences, Source};
use mocomp::global::{estimate, Correspondence, GlobalMotion, GlobalParams, Model};
use ndarray::{Array1, Array2};
use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::{luma_plane, value_error, with_threads};

/// Points as an (N, 2) float array (float64 or float32).
fn points(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<(f64, f64)>> {
    let rows = |a: ndarray::ArrayView2<'_, f64>| -> PyResult<Vec<(f64, f64)>> {
        if a.ncols() != 2 {
            return Err(value_error(format!(
                "{name} must be N x 2 (x, y), not {:?}",
                a.dim()
            )));
        }
        Ok(a.rows().into_iter().map(|r| (r[0], r[1])).collect())
    };
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        return rows(a.as_array());
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f32>>() {
        return rows(a.as_array().mapv(f64::from).view());
    }
    Err(value_error(format!(
        "{name} must be a float64 or float32 array N x 2"
    )))
}

fn params(model: &str, threshold: f64) -> PyResult<GlobalParams> {
    Ok(GlobalParams {
        threshold,
        ..GlobalParams::new(model.parse::<Model>().map_err(value_error)?)
    })
}

fn matrix<'py>(py: Python<'py>, fit: &GlobalMotion) -> Bound<'py, PyArray2<f64>> {
    let m = fit.transform.0;
    PyArray2::from_owned_array(py, Array2::from_shape_fn((3, 3), |(r, c)| m[r * 3 + c]))
}

/// The camera model that most correspondences `src -> dst` follow, as
/// OpenCV's findHomography / estimateAffine2D: RANSAC, then reweighted
/// least squares over every point.
///
/// src, dst: float (N, 2) points (x, y) of the first and second picture.
/// model: "translation", "similarity", "affine" (default) or "homography".
/// threshold: a point within this many pixels of the model is an inlier.
///
/// Returns (matrix, inliers): the float64 3 x 3 matrix taking src to dst
/// (homogeneous), and a bool (N,) mask.
#[pyfunction]
#[pyo3(signature = (src, dst, model="affine", threshold=1.0))]
pub fn estimate_global<'py>(
    py: Python<'py>,
    src: &Bound<'py, PyAny>,
    dst: &Bound<'py, PyAny>,
    model: &str,
    threshold: f64,
) -> PyResult<Bound<'py, PyTuple>> {
    let (a, b) = (points("src", src)?, points("dst", dst)?);
    if a.len() != b.len() {
        return Err(value_error(format!(
            "src has {} points, dst {}",
            a.len(),
            b.len()
        )));
    }
    let pairs: Vec<Correspondence> = a
        .into_iter()
        .zip(b)
        .map(|(p, q)| Correspondence::new(p, q))
        .collect();
    let p = params(model, threshold)?;
    let fit = py
        .detach(|| estimate(&pairs, &p))
        .map_err(|e| value_error(e.to_string()))?;
    let mask = PyArray1::from_owned_array(py, Array1::from_vec(fit.inliers.clone()));
    PyTuple::new(py, [matrix(py, &fit).into_any(), mask.into_any()])
}

/// The camera's motion from `img1` to `img2`.
///
/// img1, img2: uint8 H x W (or H x W x 3 RGB); one size.
/// model: as estimate_global (default "similarity": a camera that pans,
/// turns and zooms). source: "auto" (block vectors; flow where
/// fewer than a quarter of them follow the model), "flow" (DIS at
/// `preset`, sampled every 8 pixels, weighed by texture), "blocks" (16x16
/// EPZS vectors, quarter-pel) or "matches" (feature matches).
/// threshold: inlier distance, pixels (default: 2 for matches, else 1).
///
/// Returns a dict: matrix (float64 3 x 3, img1 to img2), inliers and
/// points (counts), rms (the inliers' distance to the model, pixels),
/// source (what the points came from: with "auto", "blocks" or "flow").
#[pyfunction]
#[pyo3(signature = (img1, img2, model="similarity", source="auto", threshold=None, preset="medium", threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn global_motion<'py>(
    py: Python<'py>,
    img1: &Bound<'py, PyAny>,
    img2: &Bound<'py, PyAny>,
    model: &str,
    source: &str,
    threshold: Option<f64>,
    preset: &str,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let source = source.parse::<Source>().map_err(value_error)?;
    let p = params(model, threshold.unwrap_or(source.threshold()))?;
    let preset = preset.parse::<Preset>().map_err(value_error)?;
    // Padded for the block search's range of 32.
    let (first, second) = (luma_plane("img1", img1, 64)?, luma_plane("img2", img2, 64)?);
    if (first.width(), first.height()) != (second.width(), second.height()) {
        return Err(value_error(format!(
            "img1 and img2 differ in size: {}x{} and {}x{}",
            first.width(),
            first.height(),
            second.width(),
            second.height()
        )));
    }
    let mut correspondences = PairCorrespondences::new(source, preset).weighted_by_texture();
    let pair = py
        .detach(|| with_threads(threads, || correspondences.fit(&first, &second, &p)))?
        .map_err(|e| value_error(e.to_string()))?;
    let Some(fit) = &pair.fit else {
        return Err(value_error(format!(
            "no {model} model fits the {} correspondences",
            pair.points
        )));
    };
    let out = PyDict::new(py);
    out.set_item("matrix", matrix(py, fit))?;
    out.set_item("inliers", fit.inlier_count)?;
    out.set_item("points", pair.points)?;
    out.set_item("rms", fit.rms)?;
    out.set_item("source", pair.source.name())?;
    Ok(out)
}
