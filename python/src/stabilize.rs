//! Stabilisation from Python: the per-frame warps of a shaky sequence, and
//! a bicubic warp of a picture by a 3 x 3 matrix (as cv2.warpPerspective
//! with WARP_INVERSE_MAP).

use mocomp::flow::Preset;
use mocomp::global::sources::Source;
use mocomp::global::{Model, Transform};
use mocomp::imgproc::warp::{warp_plane, Border};
use mocomp::stabilize::{plan, MotionTrack, Smoothing, StabilizeParams, Zoom};
use ndarray::{Array1, Array3};
use numpy::{PyArray1, PyArray3, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{luma_plane, plane_to_py, value_error, with_threads};

fn zoom(value: Option<&Bound<'_, PyAny>>) -> PyResult<Zoom> {
    let Some(value) = value else {
        return Ok(Zoom::Auto);
    };
    if let Ok(s) = value.extract::<String>() {
        return match s.as_str() {
            "auto" => Ok(Zoom::Auto),
            "adaptive" => Ok(Zoom::Adaptive),
            _ => Err(value_error(format!("zoom '{s}': 'auto', 'adaptive' or a number"))),
        };
    }
    Ok(Zoom::Fixed(value.extract::<f64>().map_err(|_| {
        value_error("zoom must be 'auto', 'adaptive' or a number")
    })?))
}

/// The warps that stabilise a sequence (vid.stab's two passes in one call).
///
/// frames: a list of uint8 H x W (luma) or H x W x 3 (RGB) pictures, one size.
/// smoothing: Gaussian window, frames either side (ignored with l1=True).
/// l1: the L1-optimal path (Grundmann et al. 2011) instead.
/// zoom: "auto" or None (the least fixed zoom hiding the border in a share
/// `coverage` of frames), "adaptive" (per frame) or a number (1: none).
/// model: "similarity" or "translation"; source: "auto" (block vectors,
/// flow where they fit no motion), "blocks", "flow", "matches"; preset:
/// the flow preset.
///
/// Returns a dict: warps (float64 N x 3 x 3, each output pixel to its
/// input pixel: warp_matrix(frame, warps[i]) is the stabilised frame), zoom (N,),
/// cuts (frame indices that begin a new shot).
#[pyfunction]
#[pyo3(signature = (frames, smoothing=10, l1=false, zoom=None, coverage=0.75, max_zoom=1.5, model="similarity", source="auto", preset="ultrafast", threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn stabilize_path<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyList>,
    smoothing: usize,
    l1: bool,
    zoom: Option<Bound<'py, PyAny>>,
    coverage: f64,
    max_zoom: f64,
    model: &str,
    source: &str,
    preset: &str,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let params = StabilizeParams {
        model: model.parse::<Model>().map_err(value_error)?,
        smoothing: if l1 {
            Smoothing::L1
        } else {
            Smoothing::Gaussian(smoothing)
        },
        zoom: self::zoom(zoom.as_ref())?,
        max_zoom,
        coverage,
        source: source.parse::<Source>().map_err(value_error)?,
        preset: preset.parse::<Preset>().map_err(value_error)?,
        ..StabilizeParams::default()
    };
    let planes = frames
        .iter()
        .enumerate()
        .map(|(i, f)| luma_plane(&format!("frames[{i}]"), &f, 64))
        .collect::<PyResult<Vec<_>>>()?;
    let Some(first) = planes.first() else {
        return Err(value_error("frames is empty"));
    };
    let (w, h) = (first.width(), first.height());
    if let Some(i) = planes.iter().position(|p| (p.width(), p.height()) != (w, h)) {
        return Err(value_error(format!("frames[{i}] is not {w}x{h} as frames[0]")));
    }
    let (motions, plan) = py
        .detach(|| {
            with_threads(threads, || {
                let mut track = MotionTrack::new(&params)?;
                for p in &planes {
                    track.push(p)?;
                }
                let motions = track.motions().to_vec();
                plan(&motions, w, h, &params).map(|plan| (motions, plan))
            })
        })?
        .map_err(|e| value_error(e.to_string()))?;
    let warps = Array3::from_shape_fn((plan.warps.len(), 3, 3), |(i, r, c)| plan.warps[i].0[r * 3 + c]);
    let cuts: Vec<usize> = (1..=motions.len())
        .filter(|&t| motions[t - 1].is_none())
        .collect();
    let out = PyDict::new(py);
    out.set_item("warps", PyArray3::from_owned_array(py, warps))?;
    out.set_item(
        "zoom",
        PyArray1::from_owned_array(py, Array1::from_vec(plan.zoom)),
    )?;
    out.set_item("cuts", cuts)?;
    Ok(out)
}

/// `image` resampled through `matrix` (bicubic): output pixel (x, y) is
/// the input at matrix @ (x, y, 1), as cv2.warpPerspective with
/// WARP_INVERSE_MAP.
///
/// image: uint8 H x W. matrix: float64 3 x 3. size: (width, height) of the
/// output (default: the input's). border: "replicate" or a value 0-255.
#[pyfunction]
#[pyo3(signature = (image, matrix, size=None, border=None))]
pub fn warp_matrix<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    matrix: PyReadonlyArray2<'py, f64>,
    size: Option<(usize, usize)>,
    border: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, numpy::PyArray2<u8>>> {
    let m = matrix.as_array();
    if m.dim() != (3, 3) {
        return Err(value_error(format!("matrix must be 3 x 3, not {:?}", m.dim())));
    }
    let map = Transform(std::array::from_fn(|i| m[(i / 3, i % 3)]));
    if map.0.iter().any(|v| !v.is_finite()) {
        return Err(value_error("matrix holds a non-finite value"));
    }
    let border = match border {
        None => Border::Replicate,
        Some(b) if b.extract::<String>().is_ok_and(|s| s == "replicate") => Border::Replicate,
        Some(b) => Border::Constant(
            b.extract::<u8>()
                .map_err(|_| value_error("border must be 'replicate' or a value 0-255"))?,
        ),
    };
    let src = luma_plane("image", image, 0)?;
    let (w, h) = size.unwrap_or((src.width(), src.height()));
    mocomp::codec::picture::check_size(w, h).map_err(|e| value_error(format!("size: {e}")))?;
    let out = py.detach(|| warp_plane(&src, w, h, &map.0, border));
    Ok(plane_to_py(py, &out))
}
