//! Moving-object masks from Python.

use mocomp::codec::Frame;
use mocomp::flow::Preset;
use mocomp::segment::{SegmentParams, Segmenter};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::arrays::{luma_plane, plane_to_py, value_error};

/// A Python picture as a frame: its luma, grey chroma.
fn as_frame(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Frame> {
    let y = luma_plane(name, obj, 0)?;
    let (w, h) = (y.width(), y.height());
    let (cw, ch) = Frame::chroma_size(w, h);
    let grey = || mocomp::codec::Plane::filled(cw, ch, 128).expect("a valid size");
    Frame::from_planes(y, grey(), grey()).map_err(|e| value_error(format!("{name}: {e}")))
}

/// The segmenter of `preset` and `tolerance`.
fn segmenter(preset: &str, tolerance: f32) -> PyResult<Segmenter> {
    let params = SegmentParams {
        preset: preset.parse::<Preset>().map_err(value_error)?,
        tolerance,
        ..SegmentParams::default()
    };
    Segmenter::new(&params).map_err(|e| value_error(e.to_string()))
}

/// The mask of what moves against the camera in `img`: 255 where the flow
/// to its neighbours departs from the camera's homography, 0 elsewhere.
///
/// img: uint8 H x W (or H x W x 3 RGB). neighbours: the frame before
/// and/or after, the same size. preset: DIS preset. tolerance: residual
/// (pixels, plus 10 % of the motion) at which a pixel counts as moving.
#[pyfunction]
#[pyo3(signature = (img, neighbours, preset="fast", tolerance=1.0))]
pub fn motion_mask<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    neighbours: &Bound<'py, PyList>,
    preset: &str,
    tolerance: f32,
) -> PyResult<Bound<'py, PyArray2<u8>>> {
    let me = as_frame(img, "img")?;
    let others = neighbours
        .iter()
        .enumerate()
        .map(|(i, n)| as_frame(&n, &format!("neighbours[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    if others.is_empty() {
        return Err(value_error(
            "neighbours is empty: give the frame before and/or after",
        ));
    }
    if let Some(i) = others
        .iter()
        .position(|f| (f.width(), f.height()) != (me.width(), me.height()))
    {
        return Err(value_error(format!("neighbours[{i}] is not the size of img")));
    }
    let mut seg = segmenter(preset, tolerance)?;
    let mask = py.detach(|| seg.mask(&me, &others.iter().collect::<Vec<_>>()));
    Ok(plane_to_py(py, &mask))
}

/// The masks of a whole sequence (`frames`, in order, two or more of one
/// size): [`motion_mask`]'s of each frame against the frames either side,
/// each frame's score first made consistent in time (the median of its
/// own and its neighbours', read along the flow to them), as `mocomp
/// segment` makes them. A list of uint8 H x W masks, 255 where something
/// moves against the camera.
#[pyfunction]
#[pyo3(signature = (frames, preset="fast", tolerance=1.0))]
pub fn motion_masks<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyList>,
    preset: &str,
    tolerance: f32,
) -> PyResult<Vec<Bound<'py, PyArray2<u8>>>> {
    let frames = frames
        .iter()
        .enumerate()
        .map(|(i, f)| as_frame(&f, &format!("frames[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    if frames.len() < 2 {
        return Err(value_error(format!(
            "frames holds {}: segmentation needs two or more",
            frames.len()
        )));
    }
    let size = |f: &Frame| (f.width(), f.height());
    if let Some(i) = frames.iter().position(|f| size(f) != size(&frames[0])) {
        return Err(value_error(format!("frames[{i}] is not the size of frames[0]")));
    }
    let mut seg = segmenter(preset, tolerance)?;
    let mut masks = Vec::with_capacity(frames.len());
    py.detach(|| {
        seg.masks(&frames, |_, m| -> Result<(), std::convert::Infallible> {
            masks.push(m);
            Ok(())
        })
    })
    .unwrap_or_else(|never| match never {});
    Ok(masks.iter().map(|m| plane_to_py(py, m)).collect())
}
