//! `import mocomp`: the toolkit from numpy. A thin layer over the `mocomp`
//! crate: arrays are checked and converted (errors as ValueError /
//! TypeError, never a crash), the GIL is released while Rust computes.

mod analyze;
mod arrays;
mod codec;
mod flow;
mod global;
mod interpolate;
mod metrics;
mod motion;
mod record;
mod segment;
mod stabilize;

use std::path::Path;

use pyo3::prelude::*;

/// An error reading or writing `path`, as Python expects it: OSError when
/// the file system refused (`io` is the error's I/O cause), ValueError for
/// bad contents.
fn io_error(path: &Path, e: impl std::fmt::Display, io: Option<&std::io::Error>) -> PyErr {
    let message = format!("{}: {e}", path.display());
    match io {
        Some(_) => pyo3::exceptions::PyOSError::new_err(message),
        None => arrays::value_error(message),
    }
}

/// [`io_error`] for a .flo error.
fn flo_error(path: &Path, e: mocomp::io::flo::FloError) -> PyErr {
    let io = match &e {
        mocomp::io::flo::FloError::Io(io) => Some(io),
        _ => None,
    };
    io_error(path, &e, io)
}

/// [`io_error`] for a Y4M error.
fn y4m_error(path: &Path, e: mocomp::io::y4m::Y4mError) -> PyErr {
    let io = match &e {
        mocomp::io::y4m::Y4mError::Io(io) => Some(io),
        _ => None,
    };
    io_error(path, &e, io)
}

#[pymodule]
fn _mocomp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(flow::flow, m)?)?;
    m.add_class::<flow::DenseFlow>()?;
    m.add_function(wrap_pyfunction!(global::estimate_global, m)?)?;
    m.add_function(wrap_pyfunction!(global::global_motion, m)?)?;
    m.add_function(wrap_pyfunction!(stabilize::stabilize_path, m)?)?;
    m.add_function(wrap_pyfunction!(interpolate::interpolate, m)?)?;
    m.add_function(wrap_pyfunction!(segment::motion_mask, m)?)?;
    m.add_function(wrap_pyfunction!(segment::motion_masks, m)?)?;
    m.add_function(wrap_pyfunction!(stabilize::warp_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(flow::warp, m)?)?;
    m.add_function(wrap_pyfunction!(flow::flow_to_color, m)?)?;
    m.add_function(wrap_pyfunction!(flow::read_flo, m)?)?;
    m.add_function(wrap_pyfunction!(flow::write_flo, m)?)?;
    m.add_function(wrap_pyfunction!(flow::flow_errors, m)?)?;
    m.add_function(wrap_pyfunction!(motion::block_match, m)?)?;
    m.add_function(wrap_pyfunction!(motion::good_features, m)?)?;
    m.add_function(wrap_pyfunction!(motion::track, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encode, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encoder_options, m)?)?;
    m.add_function(wrap_pyfunction!(codec::decode, m)?)?;
    m.add_function(wrap_pyfunction!(codec::rd, m)?)?;
    m.add_function(wrap_pyfunction!(codec::read_y4m, m)?)?;
    m.add_function(wrap_pyfunction!(analyze::analyze, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::psnr, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::ssim, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::bd_rate, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::quality, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
