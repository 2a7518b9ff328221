//! numpy arrays in and out: checked, with errors that name the argument.

use std::sync::{Arc, Mutex};

use mocomp::codec::{Frame, Plane};
use mocomp::flow::Flow;
use mocomp::imgproc::Luma;
use mocomp::io::image::luma_from_rgb;
use mocomp::raster::plane_to_u8_array;
use ndarray::{Array2, ArrayView2, Axis};
use numpy::{
    PyArray2, PyArray3, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// A `ValueError` with `message`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// What `obj` is, for error messages: dtype and shape of an array, else its type.
pub fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.cast::<PyUntypedArray>() {
        Ok(a) => format!("a {} array of shape {:?}", a.dtype(), a.shape()),
        Err(_) => format!(
            "a {}",
            obj.get_type()
                .name()
                .map_or_else(|_| "?".to_string(), |n| n.to_string())
        ),
    }
}

/// The error for `obj` not being one of `expected`: `TypeError` for a
/// wrong type or dtype, `ValueError` for a wrong shape.
fn wrong(name: &str, obj: &Bound<'_, PyAny>, expected: &str) -> PyErr {
    let message = format!("{name}: expected {expected}, got {}", describe(obj));
    match obj.cast::<PyUntypedArray>() {
        Ok(a)
            if a.dtype().is_equiv_to(&numpy::dtype::<u8>(obj.py()))
                || a.dtype().is_equiv_to(&numpy::dtype::<f32>(obj.py())) =>
        {
            PyValueError::new_err(message)
        }
        _ => PyTypeError::new_err(message),
    }
}

const PICTURE: &str = "a uint8 array H x W (luma) or H x W x 3 (RGB), or float32 H x W";

/// A picture as float luma (0..255): uint8 luma, uint8 RGB (BT.601
/// full-range luma, as mocomp reads image files) or float32 luma.
pub fn luma_f32(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Array2<f32>> {
    Ok(LumaArg::extract(name, obj)?.luma().to_f32())
}

/// A picture argument held for one call: the caller's numpy array itself
/// (uint8 or float32 luma, read in place), or the luma of an RGB array.
pub enum LumaArg<'py> {
    /// uint8 luma, borrowed.
    U8(PyReadonlyArray2<'py, u8>),
    /// float32 luma, borrowed.
    F32(PyReadonlyArray2<'py, f32>),
    /// Luma made from RGB.
    Owned(Array2<u8>),
}

impl<'py> LumaArg<'py> {
    /// `obj` as a picture ([`PICTURE`]), its size checked.
    pub fn extract(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<LumaArg<'py>> {
        let arg = if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, u8>>() {
            LumaArg::U8(a)
        } else if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, f32>>() {
            LumaArg::F32(a)
        } else {
            let plane = luma_plane(name, obj, 0).map_err(|_| wrong(name, obj, PICTURE))?;
            LumaArg::Owned(plane_to_u8_array(&plane))
        };
        let (h, w) = arg.luma().dim();
        check_picture_size(name, (h, w))?;
        Ok(arg)
    }

    /// The samples, as the estimators take them.
    pub fn luma(&self) -> Luma<'_> {
        match self {
            LumaArg::U8(a) => Luma::U8(a.as_array()),
            LumaArg::F32(a) => Luma::F32(a.as_array()),
            LumaArg::Owned(a) => Luma::U8(a.view()),
        }
    }
}

/// A uint8 picture (luma, or RGB made luma) as a plane with `pad` pixels of
/// replicated border (at least the default).
pub fn luma_plane(name: &str, obj: &Bound<'_, PyAny>, pad: usize) -> PyResult<Plane> {
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, u8>>() {
        return plane_from_view(name, a.as_array(), pad);
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray3<'_, u8>>() {
        let a = a.as_array();
        let (h, w, c) = a.dim();
        if c == 3 {
            check_picture_size(name, (h, w))?;
            let rgb: Vec<u8> = a.iter().copied().collect();
            let plane = luma_from_rgb(w, h, &rgb).map_err(|e| value_error(format!("{name}: {e}")))?;
            return if pad > plane.pad() {
                plane_from_view(name, plane_to_u8_array(&plane).view(), pad)
            } else {
                Ok(plane)
            };
        }
    }
    Err(wrong(name, obj, "a uint8 array H x W (luma) or H x W x 3 (RGB)"))
}

fn check_picture_size(name: &str, (h, w): (usize, usize)) -> PyResult<()> {
    mocomp::codec::picture::check_size(w, h).map_err(|e| value_error(format!("{name}: {e}")))
}

/// A plane holding `view` (H x W) with at least `pad` pixels of border.
pub fn plane_from_view(name: &str, view: ArrayView2<'_, u8>, pad: usize) -> PyResult<Plane> {
    let (h, w) = view.dim();
    check_picture_size(name, (h, w))?;
    let mut plane = if pad > 0 {
        Plane::with_padding(w, h, pad)
    } else {
        Plane::new(w, h)
    }
    .map_err(|e| value_error(format!("{name}: {e}")))?;
    for (dst, src) in plane.rows_mut().zip(view.axis_iter(Axis(0))) {
        for (d, s) in dst.iter_mut().zip(src.iter()) {
            *d = *s;
        }
    }
    plane.extend_border();
    Ok(plane)
}

/// `plane` as a new numpy array.
pub fn plane_to_py<'py>(py: Python<'py>, plane: &Plane) -> Bound<'py, PyArray2<u8>> {
    PyArray2::from_owned_array(py, plane_to_u8_array(plane))
}

/// A frame's planes as a (Y, U, V) tuple of numpy arrays.
pub fn frame_to_py<'py>(py: Python<'py>, frame: &Frame) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
    pyo3::types::PyTuple::new(
        py,
        [
            plane_to_py(py, frame.y()),
            plane_to_py(py, frame.u()),
            plane_to_py(py, frame.v()),
        ],
    )
}

/// A 4:2:0 frame from a (Y, U, V) sequence of uint8 arrays (chroma of
/// half the luma size, rounded up).
pub fn frame_from_py(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Frame> {
    let planes: Vec<Bound<'_, PyAny>> = obj
        .try_iter()
        .and_then(|it| it.collect::<PyResult<Vec<_>>>())
        .map_err(|_| PyTypeError::new_err(format!("{name}: expected a (Y, U, V) tuple of uint8 arrays")))?;
    let [y, u, v] = planes.as_slice() else {
        return Err(value_error(format!(
            "{name}: expected 3 planes (Y, U, V), got {}",
            planes.len()
        )));
    };
    let plane = |label: &str, p: &Bound<'_, PyAny>| -> PyResult<Plane> {
        let a = p
            .extract::<PyReadonlyArray2<'_, u8>>()
            .map_err(|_| wrong(&format!("{name} {label}"), p, "a uint8 array H x W"))?;
        plane_from_view(name, a.as_array(), 0)
    };
    let (y, u, v) = (plane("Y", y)?, plane("U", u)?, plane("V", v)?);
    Frame::from_planes(y, u, v).map_err(|e| value_error(format!("{name}: {e}")))
}

/// A flow from a float32 H x W x 2 array (u, then v); pixels with a
/// non-finite or huge component (the .flo "unknown") are invalid.
pub fn flow_from_py(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Flow> {
    let a = obj
        .extract::<PyReadonlyArray3<'_, f32>>()
        .map_err(|_| wrong(name, obj, "a float32 array H x W x 2"))?;
    let a = a.as_array();
    let (h, w, c) = a.dim();
    if c != 2 || h == 0 || w == 0 {
        return Err(wrong(name, obj, "a float32 array H x W x 2"));
    }
    let u = a.index_axis(Axis(2), 0).to_owned();
    let v = a.index_axis(Axis(2), 1).to_owned();
    let known = |x: f32| x.is_finite() && x.abs() <= 1e9;
    let valid = ndarray::Zip::from(&u)
        .and(&v)
        .map_collect(|&a, &b| known(a) && known(b));
    Ok(Flow::from_parts(u, v, valid))
}

/// A flow as a new float32 H x W x 2 array; invalid pixels are NaN.
pub fn flow_to_py<'py>(py: Python<'py>, flow: &Flow) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let out = new_flow_array(py, flow.height(), flow.width());
    flow.write_interleaved(out.readwrite().as_slice_mut()?);
    Ok(out)
}

/// A new float32 H x W x 2 array whose every element the caller writes.
pub fn new_flow_array(py: Python<'_>, h: usize, w: usize) -> Bound<'_, PyArray3<f32>> {
    // numpy's own allocation: it reuses freed memory where a Rust buffer
    // handed over would be a fresh mapping (page faults) on every call.
    // SAFETY: every caller writes all 2 x H x W elements before the array
    // reaches Python (a zeroed array would be written twice).
    unsafe { PyArray3::<f32>::new(py, (h, w, 2), false) }
}

/// The pools of `threads` workers made so far: a pool is made once per size
/// (making one costs about a millisecond, a fast flow's own time).
static POOLS: Mutex<Vec<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(Vec::new());

fn pool(threads: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    let mut pools = POOLS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, p)) = pools.iter().find(|(n, _)| *n == threads) {
        return Ok(p.clone());
    }
    let p = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| value_error(format!("threads: {e}")))?;
    let p = Arc::new(p);
    pools.push((threads, p.clone()));
    Ok(p)
}

/// Runs `f` on a pool of `threads` workers, or on the global pool.
pub fn with_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> PyResult<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(value_error("threads must be at least 1")),
        Some(n) => Ok(pool(n)?.install(f)),
    }
}
