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
/// preset: the DIS preset. before, after: the frame before frame0 and the
/// one after frame1 (same spacing), if known: pixels then move along
/// parabolas through three frames, as `mocomp interpolate` moves them
/// (each costs two more flows). Returns a list of (Y, U, V) tuples; at a
/// scene cut (too few pixels pass the forward-backward check, and the
/// histogram changed) each time gets the nearer frame (frame0 up to 0.5).
#[pyfunction]
#[pyo3(signature = (frame0, frame1, times=vec![0.5], preset="fast", before=None, after=None))]
pub fn interpolate<'py>(
    py: Python<'py>,
    frame0: &Bound<'py, PyAny>,
    frame1: &Bound<'py, PyAny>,
    times: Vec<f64>,
    preset: &str,
    before: Option<&Bound<'py, PyAny>>,
    after: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyList>> {
    let (a, b) = (frame_from_py("frame0", frame0)?, frame_from_py("frame1", frame1)?);
    let optional = |name: &str, f: Option<&Bound<'py, PyAny>>| f.map(|f| frame_from_py(name, f)).transpose();
    let (before, after) = (optional("before", before)?, optional("after", after)?);
    for (name, f) in [
        ("frame1", Some(&b)),
        ("before", before.as_ref()),
        ("after", after.as_ref()),
    ] {
        if let Some(f) = f.filter(|f| (f.width(), f.height()) != (a.width(), a.height())) {
            return Err(value_error(format!(
                "frame0 is {}x{} but {name} {}x{}",
                a.width(),
                a.height(),
                f.width(),
                f.height()
            )));
        }
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
        let outer_before = before.as_ref().map(|f| interp.pair(f, &a));
        let outer_after = after.as_ref().map(|f| interp.pair(&b, f));
        let mut pair = interp.pair(&a, &b);
        pair.accelerate(outer_before.as_ref(), outer_after.as_ref());
        times
            .iter()
            .map(|&t| interp.at(&pair, &a, &b, t))
            .collect::<Vec<_>>()
    });
    let frames: Vec<Bound<'py, PyTuple>> =
        made.iter().map(|f| frame_to_py(py, f)).collect::<PyResult<_>>()?;
    PyList::new(py, frames)
}
