//! Block matching and sparse tracking.

use mocomp::flow::track::{good_features as corners, track as follow, TrackParams};
use mocomp::me::{estimate, lambda_for_qp, MeConfig, Method, Metric, Subpel};
use ndarray::{Array2, Array3};
use numpy::{PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{luma_f32, luma_plane, value_error, with_threads};

/// Block motion of `cur` against `ref`: for each block of `cur`, the
/// vector v such that the block matches `ref` at block position + v.
///
/// cur, ref: uint8 H x W (or H x W x 3 RGB), the same size.
/// method: "esa", "tss", "ntss", "tdls", "fss", "ds", "hexbs" or "epzs"
///     (ffmpeg mestimate's names). block: 4, 8, 16 or 32. search_range:
///     1..64 pixels. subpel: "none", "half" or "quarter". metric: "sad",
///     "ssd" or "satd". qp: when given, vectors are priced as the codec
///     codes them at that QP (rate-constrained search).
///
/// Returns float32 (rows, cols, 2) vectors in pixels (x then y), rows =
/// ceil(H / block); with return_costs=True, a tuple (vectors, costs), the
/// costs uint32 (rows, cols).
#[pyfunction]
#[pyo3(signature = (cur, r#ref, method="epzs", block=16, search_range=16, subpel="quarter", metric="sad",
    qp=None, return_costs=false, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn block_match<'py>(
    py: Python<'py>,
    cur: &Bound<'py, PyAny>,
    r#ref: &Bound<'py, PyAny>,
    method: &str,
    block: usize,
    search_range: i32,
    subpel: &str,
    metric: &str,
    qp: Option<u8>,
    return_costs: bool,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut cfg = MeConfig::new(
        method.parse::<Method>().map_err(value_error)?,
        block,
        search_range,
    );
    cfg.subpel = subpel.parse::<Subpel>().map_err(value_error)?;
    cfg.metric = metric.parse::<Metric>().map_err(value_error)?;
    if let Some(qp) = qp {
        if qp > 51 {
            return Err(value_error(format!("qp {qp} is above 51")));
        }
        cfg.lambda = lambda_for_qp(cfg.metric, qp);
    }
    // The search reads range + block + 8 pixels past the picture.
    let pad = (search_range.clamp(0, 64) as usize + block.min(64) + 8).next_multiple_of(16);
    let (a, b) = (luma_plane("cur", cur, pad)?, luma_plane("ref", r#ref, pad)?);
    let field = py
        .detach(|| with_threads(threads, || estimate(&a, &b, &cfg)))?
        .map_err(|e| value_error(e.to_string()))?;
    let (rows, cols) = (field.rows(), field.cols());
    let vectors = Array3::from_shape_fn((rows, cols, 2), |(r, c, k)| {
        let v = field.vector(c, r);
        (if k == 0 { v.x } else { v.y }) as f32 / 4.0
    });
    let vectors = PyArray3::from_owned_array(py, vectors).into_any();
    if !return_costs {
        return Ok(vectors);
    }
    let costs = Array2::from_shape_fn((rows, cols), |(r, c)| field.cost(c, r));
    Ok(PyTuple::new(py, [vectors, PyArray2::from_owned_array(py, costs).into_any()])?.into_any())
}

/// Corners worth tracking in `img` (uint8 or float32 luma, or uint8 RGB):
/// Shi-Tomasi's minimum eigenvalue, as OpenCV's goodFeaturesToTrack.
/// Returns float32 (N, 2) positions (x, y), strongest first.
#[pyfunction]
#[pyo3(signature = (img, max_corners=200, quality=0.01, min_distance=8.0))]
pub fn good_features<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    max_corners: usize,
    quality: f32,
    min_distance: f32,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let valid = quality > 0.0 && quality <= 1.0 && min_distance >= 0.0;
    if !valid {
        return Err(value_error(
            "quality must be in (0, 1] and min_distance at least 0",
        ));
    }
    let a = luma_f32("img", img)?;
    let points = py.detach(|| corners(&a, max_corners, quality, min_distance));
    Ok(points_to_py(py, &points))
}

fn points_to_py<'py>(py: Python<'py>, points: &[(f32, f32)]) -> Bound<'py, PyArray2<f32>> {
    let out = Array2::from_shape_fn(
        (points.len(), 2),
        |(i, k)| if k == 0 { points[i].0 } else { points[i].1 },
    );
    PyArray2::from_owned_array(py, out)
}

/// Follows points through `frames` (a sequence of pictures of one size)
/// with pyramidal Lucas-Kanade, as OpenCV's calcOpticalFlowPyrLK frame
/// to frame.
///
/// points: float32 (N, 2) positions in frames[0]; by default the
///     strongest max_corners corners of frames[0] (good_features).
/// fb_threshold: drop a point whose forward-backward error exceeds this
///     many pixels (None: no check).
///
/// Returns float32 (T, N, 2): each point's position in each frame, NaN
/// from the frame where it was lost.
#[pyfunction]
#[pyo3(signature = (frames, points=None, max_corners=200, fb_threshold=None))]
pub fn track<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyAny>,
    points: Option<numpy::PyReadonlyArray2<'py, f32>>,
    max_corners: usize,
    fb_threshold: Option<f32>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let pictures: Vec<Array2<f32>> = frames
        .try_iter()?
        .enumerate()
        .map(|(i, f)| luma_f32(&format!("frames[{i}]"), &f?))
        .collect::<PyResult<_>>()?;
    let Some(first) = pictures.first() else {
        return Err(value_error("frames is empty"));
    };
    if let Some(i) = pictures.iter().position(|p| p.dim() != first.dim()) {
        return Err(value_error(format!(
            "frames[{i}] is {:?}, frames[0] {:?}",
            pictures[i].dim(),
            first.dim()
        )));
    }
    let start: Vec<(f32, f32)> = match &points {
        Some(p) => {
            let p = p.as_array();
            if p.ncols() != 2 {
                return Err(value_error(format!("points: expected (N, 2), got {:?}", p.dim())));
            }
            p.rows().into_iter().map(|r| (r[0], r[1])).collect()
        }
        None => corners(first, max_corners, 0.01, 8.0),
    };
    let params = TrackParams {
        fb_threshold,
        ..TrackParams::default()
    };
    let paths = py.detach(|| follow_all(&pictures, &start, &params));
    Ok(PyArray3::from_owned_array(py, paths))
}

/// Each point's position in each picture, NaN once lost.
fn follow_all(pictures: &[Array2<f32>], start: &[(f32, f32)], params: &TrackParams) -> Array3<f32> {
    let mut out = Array3::from_elem((pictures.len(), start.len(), 2), f32::NAN);
    let mut alive: Vec<usize> = (0..start.len()).collect();
    let mut at = start.to_vec();
    for (i, &(x, y)) in start.iter().enumerate() {
        out[[0, i, 0]] = x;
        out[[0, i, 1]] = y;
    }
    for t in 1..pictures.len() {
        let from: Vec<(f32, f32)> = alive.iter().map(|&i| at[i]).collect();
        let tracks = follow(&pictures[t - 1], &pictures[t], &from, params);
        let mut still = Vec::with_capacity(alive.len());
        for (&i, tr) in alive.iter().zip(tracks) {
            if tr.found {
                at[i] = (tr.x, tr.y);
                out[[t, i, 0]] = tr.x;
                out[[t, i, 1]] = tr.y;
                still.push(i);
            }
        }
        alive = still;
    }
    out
}
