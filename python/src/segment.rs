//! Moving-object masks from Python.

use mocomp::codec::Frame;
use mocomp::flow::Preset;
use mocomp::segment::{SegmentParams, Segmenter};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::arrays::{luma_plane, plane_to_py, value_error};

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
    let as_frame = |name: &str, obj: &Bound<'py, PyAny>| -> PyResult<Frame> {
        let y = luma_plane(name, obj, 0)?;
        let (w, h) = (y.width(), y.height());
        let (cw, ch) = Frame::chroma_size(w, h);
        let grey = || mocomp::codec::Plane::filled(cw, ch, 128).expect("a valid size");
        Frame::from_planes(y, grey(), grey()).map_err(|e| value_error(format!("{name}: {e}")))
    };
    let me = as_frame("img", img)?;
    let others = neighbours
        .iter()
        .enumerate()
        .map(|(i, n)| as_frame(&format!("neighbours[{i}]"), &n))
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
    let params = SegmentParams {
        preset: preset.parse::<Preset>().map_err(value_error)?,
        tolerance,
        ..SegmentParams::default()
    };
    let mut seg = Segmenter::new(&params).map_err(|e| value_error(e.to_string()))?;
    let mask = py.detach(|| seg.mask(&me, &others.iter().collect::<Vec<_>>()));
    Ok(plane_to_py(py, &mask))
}
