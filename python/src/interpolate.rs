//! Frame interpolation from Python: (Y, U, V) frames at any time between
//! two, from dense flow both ways.

use mocomp::flow::Preset;
use mocomp::interpolate::{InterpolateParams, Interpolator};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use crate::arrays::{frame_from_py, frame_to_py, value_error};

/// Frames between `frame0` and `frame1` ((Y, U, V) tuples of uint8
/// arrays, 4:2:0, one size), one per time in `times` (each in [0, 1]; 0
/// is frame0). The flows both ways are found once for all times.
///
/// preset: the DIS preset. Returns a list of (Y, U, V) tuples; at a scene
/// cut (too few pixels pass the forward-backward check) each time gets the
/// nearer frame (frame0 up to 0.5).
#[pyfunction]
#[pyo3(signature = (frame0, frame1, times=vec![0.5], preset="fast"))]
pub fn interpolate<'py>(
    py: Python<'py>,
    frame0: &Bound<'py, PyAny>,
    frame1: &Bound<'py, PyAny>,
    times: Vec<f64>,
    preset: &str,
) -> PyResult<Bound<'py, PyList>> {
    let (a, b) = (frame_from_py("frame0", frame0)?, frame_from_py("frame1", frame1)?);
    if (a.width(), a.height()) != (b.width(), b.height()) {
        return Err(value_error(format!(
            "frame0 is {}x{} but frame1 {}x{}",
            a.width(),
            a.height(),
            b.width(),
            b.height()
        )));
    }
    if let Some(t) = times.iter().find(|t| !(0.0..=1.0).contains(*t)) {
        return Err(value_error(format!("time {t} is not in [0, 1]")));
    }
    let params = InterpolateParams {
        preset: preset.parse::<Preset>().map_err(value_error)?,
        ..InterpolateParams::default()
    };
    let mut interp = Interpolator::new(&params).map_err(|e| value_error(e.to_string()))?;
    let made = py.detach(|| {
        let pair = interp.pair(&a, &b);
        times
            .iter()
            .map(|&t| interp.at(&pair, &a, &b, t))
            .collect::<Vec<_>>()
    });
    let frames: Vec<Bound<'py, PyTuple>> =
        made.iter().map(|f| frame_to_py(py, f)).collect::<PyResult<_>>()?;
    PyList::new(py, frames)
}
