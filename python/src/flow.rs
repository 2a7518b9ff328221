//! Dense flow, warping, colour coding, .flo files, flow errors.

use std::cell::RefCell;
use std::path::PathBuf;

use mocomp::flow::warp::warp_bilinear;
use mocomp::flow::{FlowEstimator, FlowMethod, FlowOptions, Preset};
use mocomp::io::flo;
use ndarray::{Array2, Array3, Axis};
use numpy::{PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{describe, flow_from_py, flow_to_py, new_flow_array, value_error, with_threads, LumaArg};

/// Dense optical flow from `img1` to `img2`: `img1(p) ~ img2(p + flow(p))`.
///
/// img1, img2: uint8 H x W (luma) or H x W x 3 (RGB, made BT.601 luma), or
///     float32 H x W (grey levels 0..255); the same size.
/// method: "dis" (default), "lk", "hs" or "tvl1".
/// preset: "ultrafast", "fast", "medium" (default) or "accurate".
/// threads: worker threads (default: all cores).
/// Keyword options override the preset where the method has them:
/// levels, sigma (LK), iterations, alpha and gamma (HS), texture (TV-L1),
/// warps (HS, TV-L1), finest (LK, DIS), global_search, matches and
/// fine_on_small (DIS: finer pyramid levels on small pictures, about half
/// the error for 2-4 times the time, as the applications use it; `finest`
/// overrides it).
///
/// Returns float32 H x W x 2: u (x motion) then v, in pixels.
#[pyfunction]
#[pyo3(signature = (img1, img2, method=None, preset="medium", threads=None, *, levels=None, sigma=None,
    iterations=None, alpha=None, gamma=None, texture=None, warps=None, finest=None, global_search=false,
    matches=false, fine_on_small=false))]
#[allow(clippy::too_many_arguments)]
pub fn flow<'py>(
    py: Python<'py>,
    img1: &Bound<'py, PyAny>,
    img2: &Bound<'py, PyAny>,
    method: Option<&str>,
    preset: &str,
    threads: Option<usize>,
    levels: Option<usize>,
    sigma: Option<f32>,
    iterations: Option<usize>,
    alpha: Option<f32>,
    gamma: Option<f32>,
    texture: Option<f32>,
    warps: Option<usize>,
    finest: Option<usize>,
    global_search: bool,
    matches: bool,
    fine_on_small: bool,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let options = flow_options(
        method,
        preset,
        FlowOptions {
            levels,
            sigma,
            iterations,
            alpha,
            gamma,
            texture,
            warps,
            finest,
            global_search,
            matches,
            fine_on_small,
            ..FlowOptions::default()
        },
    )?;
    // The estimator (and its buffers) is kept for the next call with the
    // same options, as a DenseFlow object would be.
    LAST_FLOW.with(|last| -> PyResult<_> {
        let mut last = last.borrow_mut();
        if last.as_ref().is_none_or(|r| r.options != options) {
            *last = Some(FlowRunner::new(options)?);
        }
        let Some(runner) = last.as_mut() else {
            unreachable!("set above")
        };
        runner.calc(py, img1, img2, None, threads)
    })
}

/// `options` with the method and preset parsed from their names.
fn flow_options(method: Option<&str>, preset: &str, options: FlowOptions) -> PyResult<FlowOptions> {
    Ok(FlowOptions {
        method: method
            .map_or(Ok(FlowMethod::Dis), str::parse)
            .map_err(value_error)?,
        preset: preset.parse::<Preset>().map_err(value_error)?,
        ..options
    })
}

/// An estimator with the options it was made with, reused from call to
/// call (its pyramids and buffers with it).
struct FlowRunner {
    options: FlowOptions,
    estimator: FlowEstimator,
}

impl FlowRunner {
    fn new(options: FlowOptions) -> PyResult<FlowRunner> {
        let estimator = FlowEstimator::new(&options).map_err(|e| value_error(e.to_string()))?;
        Ok(FlowRunner { options, estimator })
    }

    /// The flow from `img1` to `img2`, the GIL released while it runs. The
    /// pictures are read in place (uint8 or float32 luma) and the flow is
    /// written straight into `out` when given (float32 H x W x 2,
    /// C-contiguous, writeable), else into a new array: no conversion or
    /// copy around the estimator.
    fn calc<'py>(
        &mut self,
        py: Python<'py>,
        img1: &Bound<'py, PyAny>,
        img2: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let (arg1, arg2) = (LumaArg::extract("img1", img1)?, LumaArg::extract("img2", img2)?);
        let (a, b) = (arg1.luma(), arg2.luma());
        if a.dim() != b.dim() {
            return Err(value_error(format!(
                "img1 and img2 differ in size: {:?} and {:?}",
                a.dim(),
                b.dim()
            )));
        }
        let (h, w) = a.dim();
        let out = match out {
            Some(array) => flow_out_array(array, h, w)?,
            None => new_flow_array(py, h, w),
        };
        {
            let mut writer = out
                .try_readwrite()
                .map_err(|e| value_error(format!("flow: {e}")))?;
            let dst = writer
                .as_slice_mut()
                .map_err(|_| value_error("flow: the array must be C-contiguous"))?;
            let estimator = &mut self.estimator;
            py.detach(|| with_threads(threads, || estimator.compute_interleaved(a, b, dst)))?;
        }
        Ok(out)
    }
}

/// `array` as the float32 H x W x 2 array a flow of `h` x `w` is written
/// into (as OpenCV's `calc(I0, I1, flow)` takes one): kept from call to
/// call, it spares a new allocation per frame pair.
fn flow_out_array<'py>(array: &Bound<'py, PyAny>, h: usize, w: usize) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let expected = format!("a float32 array {h} x {w} x 2");
    let out = array
        .cast::<PyArray3<f32>>()
        .map_err(|_| value_error(format!("flow: expected {expected}, got {}", describe(array))))?;
    if out.shape() != [h, w, 2] {
        return Err(value_error(format!(
            "flow: expected {expected}, got shape {:?}",
            out.shape()
        )));
    }
    Ok(out.clone())
}

thread_local! {
    /// What `flow` keeps between calls on one thread.
    static LAST_FLOW: RefCell<Option<FlowRunner>> = const { RefCell::new(None) };
}

/// A dense flow estimator made once and called per frame pair, as OpenCV's
/// `cv2.DISOpticalFlow_create(preset)` and its `calc`: the settings are
/// checked once and the buffers kept between calls.
///
/// DenseFlow(method="dis", preset="medium", threads=None, **options), the
/// options as `flow` takes them; `calc(img1, img2, flow=None)` (or calling
/// the object) returns the flow from img1 to img2 as `flow` does, written
/// into `flow` when one is passed.
#[pyclass(name = "DenseFlow", module = "mocomp")]
pub struct DenseFlow {
    runner: FlowRunner,
    threads: Option<usize>,
}

#[pymethods]
impl DenseFlow {
    #[new]
    #[pyo3(signature = (method=None, preset="medium", threads=None, *, levels=None, sigma=None,
        iterations=None, alpha=None, gamma=None, texture=None, warps=None, finest=None,
        global_search=false, matches=false, fine_on_small=false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        method: Option<&str>,
        preset: &str,
        threads: Option<usize>,
        levels: Option<usize>,
        sigma: Option<f32>,
        iterations: Option<usize>,
        alpha: Option<f32>,
        gamma: Option<f32>,
        texture: Option<f32>,
        warps: Option<usize>,
        finest: Option<usize>,
        global_search: bool,
        matches: bool,
        fine_on_small: bool,
    ) -> PyResult<DenseFlow> {
        if threads == Some(0) {
            return Err(value_error("threads must be at least 1"));
        }
        let options = flow_options(
            method,
            preset,
            FlowOptions {
                levels,
                sigma,
                iterations,
                alpha,
                gamma,
                texture,
                warps,
                finest,
                global_search,
                matches,
                fine_on_small,
                ..FlowOptions::default()
            },
        )?;
        Ok(DenseFlow {
            runner: FlowRunner::new(options)?,
            threads,
        })
    }

    /// The flow from `img1` to `img2`: float32 H x W x 2. Given `flow` (a
    /// float32 H x W x 2 C-contiguous array, as OpenCV's `calc(I0, I1,
    /// flow)`), the flow is written into it and it is returned; a frame
    /// loop that passes the last result back allocates nothing per pair.
    #[pyo3(signature = (img1, img2, flow=None))]
    fn calc<'py>(
        &mut self,
        py: Python<'py>,
        img1: &Bound<'py, PyAny>,
        img2: &Bound<'py, PyAny>,
        flow: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        self.runner.calc(py, img1, img2, flow, self.threads)
    }

    #[pyo3(signature = (img1, img2, flow=None))]
    fn __call__<'py>(
        &mut self,
        py: Python<'py>,
        img1: &Bound<'py, PyAny>,
        img2: &Bound<'py, PyAny>,
        flow: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        self.calc(py, img1, img2, flow)
    }

    /// The method's name: "dis", "lk", "hs" or "tvl1".
    #[getter]
    fn method(&self) -> &'static str {
        self.runner.options.method.name()
    }

    /// The preset's name.
    #[getter]
    fn preset(&self) -> &'static str {
        self.runner.options.preset.name()
    }

    fn __repr__(&self) -> String {
        format!(
            "DenseFlow(method={:?}, preset={:?})",
            self.method(),
            self.preset()
        )
    }
}

/// Warps `img` backward by `flow`: out(p) = img(p + flow(p)), bilinear,
/// borders replicated (so `warp(img2, flow(img1, img2))` resembles img1).
///
/// img: uint8 H x W or H x W x C, or float32 H x W; flow: float32 H x W x 2.
/// Returns an array of img's dtype and shape.
#[pyfunction]
pub fn warp<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    flow: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let f = flow_from_py("flow", flow)?;
    let check = |h: usize, w: usize| -> PyResult<()> {
        if (w, h) != (f.width(), f.height()) {
            return Err(value_error(format!(
                "img is {h} x {w}, flow {} x {}",
                f.height(),
                f.width()
            )));
        }
        Ok(())
    };
    if let Ok(a) = img.extract::<PyReadonlyArray2<'_, f32>>() {
        let a = a.as_array().to_owned();
        check(a.nrows(), a.ncols())?;
        let out = py.detach(|| warp_bilinear(&a, &f));
        return Ok(PyArray2::from_owned_array(py, out).into_any());
    }
    let plane = img.extract::<PyReadonlyArray2<'_, u8>>().ok();
    let channels: Vec<Array2<f32>> = if let Some(a) = &plane {
        vec![a.as_array().mapv(f32::from)]
    } else if let Ok(a) = img.extract::<PyReadonlyArray3<'_, u8>>() {
        a.as_array()
            .axis_iter(Axis(2))
            .map(|c| c.mapv(f32::from))
            .collect()
    } else {
        return Err(pyo3::exceptions::PyTypeError::new_err(
            "img: expected a uint8 array H x W or H x W x C, or float32 H x W",
        ));
    };
    let (h, w) = channels.first().map_or((0, 0), |c| c.dim());
    check(h, w)?;
    let warped: Vec<Array2<f32>> = py.detach(|| channels.iter().map(|c| warp_bilinear(c, &f)).collect());
    let to_u8 = |v: f32| v.round().clamp(0.0, 255.0) as u8;
    if plane.is_some() {
        return Ok(PyArray2::from_owned_array(py, warped[0].mapv(to_u8)).into_any());
    }
    let out = Array3::from_shape_fn((h, w, warped.len()), |(y, x, c)| to_u8(warped[c][[y, x]]));
    Ok(PyArray3::from_owned_array(py, out).into_any())
}

/// The Middlebury colour coding of `flow` (float32 H x W x 2): hue is the
/// direction, saturation the magnitude over `max_flow` (default: the
/// largest valid magnitude). Invalid (NaN) pixels are black.
/// Returns uint8 H x W x 3 RGB.
#[pyfunction]
#[pyo3(signature = (flow, max_flow=None))]
pub fn flow_to_color<'py>(
    py: Python<'py>,
    flow: &Bound<'py, PyAny>,
    max_flow: Option<f32>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let f = flow_from_py("flow", flow)?;
    if max_flow.is_some_and(|m| !(m > 0.0 && m.is_finite())) {
        return Err(value_error("max_flow must be positive"));
    }
    let rgb = py.detach(|| mocomp::viz::flow_to_rgb(&f, max_flow));
    let out = Array3::from_shape_vec((rgb.height, rgb.width, 3), rgb.data)
        .map_err(|e| value_error(e.to_string()))?;
    Ok(PyArray3::from_owned_array(py, out))
}

/// Reads a Middlebury .flo file: float32 H x W x 2, unknown pixels NaN.
#[pyfunction]
pub fn read_flo<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let f = py
        .detach(|| flo::read_flo(&path))
        .map_err(|e| crate::flo_error(&path, e))?;
    flow_to_py(py, &f)
}

/// Writes `flow` (float32 H x W x 2; NaN pixels as unknown) as a
/// Middlebury .flo file, atomically.
#[pyfunction]
pub fn write_flo(py: Python<'_>, path: PathBuf, flow: &Bound<'_, PyAny>) -> PyResult<()> {
    let f = flow_from_py("flow", flow)?;
    py.detach(|| flo::write_flo(&path, &f))
        .map_err(|e| crate::flo_error(&path, e))
}

/// Errors of `flow` against ground truth `gt` (both float32 H x W x 2)
/// over the pixels valid in `gt`: a dict of epe (mean end-point error,
/// px), ae (mean angular error, degrees), r1 and r3 (percent of pixels
/// with an end-point error above 1 and 3 px) and pixels (how many).
#[pyfunction]
pub fn flow_errors<'py>(
    py: Python<'py>,
    flow: &Bound<'py, PyAny>,
    gt: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let (f, g) = (flow_from_py("flow", flow)?, flow_from_py("gt", gt)?);
    if (f.width(), f.height()) != (g.width(), g.height()) {
        return Err(value_error(format!(
            "flow is {} x {}, gt {} x {}",
            f.height(),
            f.width(),
            g.height(),
            g.width()
        )));
    }
    let e = mocomp::metrics::flow_errors(&f, &g).ok_or_else(|| value_error("gt has no valid pixel"))?;
    let d = PyDict::new(py);
    d.set_item("epe", e.epe)?;
    d.set_item("ae", e.ae)?;
    d.set_item("r1", e.r1)?;
    d.set_item("r3", e.r3)?;
    d.set_item("pixels", e.pixels)?;
    Ok(d)
}
