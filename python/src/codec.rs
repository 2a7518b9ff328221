//! Encoding, decoding and rate-distortion sweeps.

use std::path::PathBuf;

use mocomp::codec::Frame;
use mocomp::encode::{encode_sequence, EncoderConfig, FrameStats, Predictor, SequenceInfo};
use mocomp::io::y4m::Y4mReader;
use mocomp::rd::{sweep, Sequence};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyTuple};

use crate::arrays::{frame_from_py, frame_to_py, value_error, with_threads};
use crate::record::to_dict;

/// Frames as a list of (Y, U, V) tuples of arrays.
fn frames_to_py<'py>(py: Python<'py>, frames: &[Frame]) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for f in frames {
        out.append(frame_to_py(py, f)?)?;
    }
    Ok(out)
}

/// Frames to code: from a Y4M path (with its frame rate) or a sequence of
/// (Y, U, V) arrays (at `fps`).
fn read_source(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    fps: (u32, u32),
    max_frames: Option<usize>,
) -> PyResult<(String, Vec<Frame>, (u32, u32))> {
    let limit = max_frames.unwrap_or(usize::MAX);
    if let Ok(path) = source.extract::<PathBuf>() {
        let read = || -> Result<_, mocomp::io::y4m::Y4mError> {
            let mut reader = Y4mReader::open(&path)?;
            let info = reader.info().clone();
            let mut frames = Vec::new();
            let mut frame = Frame::new(info.width, info.height)?;
            while frames.len() < limit && reader.read_frame_into(&mut frame)? {
                frames.push(frame.clone());
            }
            Ok((info, frames))
        };
        let (info, frames) = py.detach(read).map_err(|e| crate::y4m_error(&path, e))?;
        let fps = (
            u32::try_from(info.fps.0).unwrap_or(25),
            u32::try_from(info.fps.1).unwrap_or(1).max(1),
        );
        let name = path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        return Ok((name, frames, fps));
    }
    if source.is_instance_of::<pyo3::types::PyString>() || source.is_instance_of::<PyBytes>() {
        return Err(PyTypeError::new_err(
            "source: expected a Y4M path or a sequence of (Y, U, V) arrays",
        ));
    }
    let items = source
        .try_iter()
        .map_err(|_| PyTypeError::new_err("source: expected a Y4M path or a sequence of (Y, U, V) arrays"))?;
    let mut frames = Vec::new();
    for (i, item) in items.enumerate().take(limit) {
        frames.push(frame_from_py(&format!("source[{i}]"), &item?)?);
    }
    Ok((String::new(), frames, fps))
}

/// The encoder's configuration: `preset`, then `qp` and `predictor`, then
/// every other keyword argument as an option by name
/// (`EncoderConfig::set`, as `mocomp encode`'s options: the same checks
/// and messages; `_` for `-`; None leaves an option to the preset).
fn config(
    preset: &str,
    first: &[(&str, String)],
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<EncoderConfig> {
    let mut c = EncoderConfig::from_preset(preset).map_err(value_error)?;
    for (name, value) in first {
        c.set(name, value).map_err(value_error)?;
    }
    for (key, value) in options.into_iter().flat_map(|d| d.iter()) {
        let name: String = key.extract()?;
        if let Some(text) = option_text(&name, &value)? {
            c.set(&name, &text).map_err(value_error)?;
        }
    }
    Ok(c)
}

/// A keyword argument's value as an option's text: booleans on/off (for
/// partitions all/none), numbers and strings as they print; None: not
/// given.
fn option_text(name: &str, value: &Bound<'_, PyAny>) -> PyResult<Option<String>> {
    if value.is_none() {
        return Ok(None);
    }
    if let Ok(b) = value.extract::<bool>() {
        let text = match (name, b) {
            ("partitions" | "i_partitions" | "i-partitions", true) => "all",
            ("partitions" | "i_partitions" | "i-partitions", false) => "none",
            (_, true) => "on",
            (_, false) => "off",
        };
        return Ok(Some(text.to_string()));
    }
    Ok(Some(value.str()?.to_string()))
}

/// What one encode gives back to Python.
struct Encoded {
    stream: Vec<u8>,
    stats: Vec<FrameStats>,
    recons: Vec<Frame>,
}

fn encode_all(frames: &[Frame], fps: (u32, u32), config: EncoderConfig, keep: bool) -> PyResult<Encoded> {
    let first = frames
        .first()
        .ok_or_else(|| value_error("source holds no frames"))?;
    let info = SequenceInfo {
        width: first.width(),
        height: first.height(),
        fps,
        vui: Default::default(),
    };
    let mut out = Encoded {
        stream: Vec::new(),
        stats: Vec::with_capacity(frames.len()),
        recons: Vec::new(),
    };
    let config = config.reconstruction(keep);
    encode_sequence(&mut frames.iter(), info, config, None, &mut out.stream, |coded| {
        out.stats.push(coded.stats);
        if keep {
            out.recons.extend(coded.recon.clone());
        }
        Ok(())
    })
    .map_err(|e| value_error(e.to_string()))?;
    Ok(out)
}

/// Encodes `source` into a mocomp stream.
///
/// source: a Y4M path, or a sequence of (Y, U, V) uint8 arrays (4:2:0:
///     chroma half the luma size, rounded up) at `fps`.
/// qp: 0..51. predictor: "zero", "block[:method]", "flow-block[:lk|hs|dis|tvl1]",
///     "dense-lk" / "dense-hs" / "dense-dis" / "dense-tvl1", "obmc" (as `mocomp encode`).
/// preset: "ultrafast", "superfast", "veryfast", "faster", "fast",
///     "medium" (default), "slow" or "slower", as
///     `mocomp encode --preset`; every other keyword argument is one of
///     the encoder's options by name, overriding the preset where given,
///     as `mocomp encode`'s: gop, me, range, subpel, flow, refine, grid,
///     lambda_scale, rdoq, decision ("fast" or "full"), ipratio, deblock
///     (True, False, or x264's offsets "A:B", each -6..=6), deblock_choice, weightp, refs, subpel_rd, split_margin, split_search_margin,
///     chroma_me, adaptive_pricing, fast_pskip, early_pskip, dct8x8 (or 8x8dct),
///     luma_filter ("auto", "sharp" or "smooth"), partitions (True,
///     False, or x264's names: "p8x8,i8x8,i4x4"), i_partitions (I
///     frames' intra blocks: True, False or "i8x8,i4x4"), metrics ("psnr,ssim",
///     "all", ...), ssim (`mocomp.encoder_options()` lists them).
/// frames: code at most this many frames.
///
/// Returns (stream bytes, per-frame statistics as dicts: every field of
/// the library's frame record, metrics not measured left out); with
/// reconstruction=True, (stream, stats, reconstructed (Y, U, V) frames),
/// which `decode(stream)` reproduces exactly.
#[pyfunction]
#[pyo3(signature = (source, qp=28, predictor="block", *, preset="medium", frames=None, fps=(25, 1),
    threads=None, reconstruction=false, **options))]
#[allow(clippy::too_many_arguments)]
pub fn encode<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    qp: i64,
    predictor: &str,
    preset: &str,
    frames: Option<usize>,
    fps: (u32, u32),
    threads: Option<usize>,
    reconstruction: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let first = [("qp", qp.to_string()), ("predictor", predictor.to_string())];
    let cfg = config(preset, &first, options)?;
    if fps.0 == 0 || fps.1 == 0 {
        return Err(value_error(
            "fps must be two positive integers (numerator, denominator)",
        ));
    }
    let (_, input, fps) = read_source(py, source, fps, frames)?;
    let encoded = py.detach(|| with_threads(threads, || encode_all(&input, fps, cfg, reconstruction)))??;
    let stats = PyList::empty(py);
    for s in &encoded.stats {
        stats.append(to_dict(py, s)?)?;
    }
    let stream = PyBytes::new(py, &encoded.stream).into_any();
    if !reconstruction {
        return PyTuple::new(py, [stream, stats.into_any()]);
    }
    let recons = frames_to_py(py, &encoded.recons)?;
    PyTuple::new(py, [stream, stats.into_any(), recons.into_any()])
}

/// The encoder's options by name, with what each takes (what `encode` and
/// `rd` accept as keyword arguments beside `preset`).
#[pyfunction]
pub fn encoder_options() -> Vec<(&'static str, &'static str)> {
    mocomp::encode::OPTIONS.to_vec()
}

/// Reads a Y4M file (8-bit 4:2:0, every variant ffmpeg writes) into a
/// list of (Y, U, V) uint8 arrays; at most `frames` frames.
#[pyfunction]
#[pyo3(signature = (path, frames=None))]
pub fn read_y4m<'py>(py: Python<'py>, path: PathBuf, frames: Option<usize>) -> PyResult<Bound<'py, PyList>> {
    let (_, frames, _) = read_source(py, &path.into_pyobject(py)?.into_any(), (25, 1), frames)?;
    frames_to_py(py, &frames)
}

/// Decodes a mocomp stream (bytes) into a list of (Y, U, V) uint8 arrays.
/// Raises ValueError on a damaged or truncated stream.
#[pyfunction]
pub fn decode<'py>(py: Python<'py>, stream: &[u8]) -> PyResult<Bound<'py, PyList>> {
    let (_, frames) = py
        .detach(|| mocomp::codec::decoder::decode(stream))
        .map_err(|e| value_error(format!("stream: {e}")))?;
    frames_to_py(py, &frames)
}

/// A rate-distortion sweep: every source at every QP with every
/// predictor, jobs in parallel. sources: Y4M paths. Returns the rows of
/// `mocomp rd`'s CSV as dicts (codec is the predictor's label, kbps at the
/// source's frame rate).
#[pyfunction]
#[pyo3(signature = (sources, qps=vec![22, 27, 32, 37], predictors=vec!["block:esa".to_string(), "block".to_string()],
    frames=None, threads=None, *, preset="medium", **options))]
#[allow(clippy::too_many_arguments)]
pub fn rd<'py>(
    py: Python<'py>,
    sources: Vec<PathBuf>,
    qps: Vec<u8>,
    predictors: Vec<String>,
    frames: Option<usize>,
    threads: Option<usize>,
    preset: &str,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyList>> {
    let base = config(preset, &[], options)?;
    for &q in &qps {
        base.clone().set("qp", &q.to_string()).map_err(value_error)?;
    }
    let predictors: Vec<Predictor> = predictors
        .iter()
        .map(|p| p.parse::<Predictor>().map_err(value_error))
        .collect::<PyResult<_>>()?;
    let mut sequences = Vec::with_capacity(sources.len());
    for path in &sources {
        let (name, frames, fps) =
            read_source(py, &path.clone().into_pyobject(py)?.into_any(), (25, 1), frames)?;
        sequences.push(Sequence { name, frames, fps });
    }
    let points = py
        .detach(|| with_threads(threads, || sweep(&sequences, &qps, &predictors, base, || {})))?
        .map_err(|e| value_error(e.to_string()))?;
    let out = PyList::empty(py);
    for p in &points {
        out.append(to_dict(py, p)?)?;
    }
    Ok(out)
}
