//! What a stream holds, as numpy arrays per frame.

use mocomp::analyze::Analyzer;
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{frame_to_py, value_error};

/// Macroblock kinds in the `kind` arrays.
const KINDS: [&str; 3] = ["skip", "inter", "intra"];
/// Partitions in the `partition` arrays.
const PARTITIONS: [&str; 5] = ["16x16", "16x8", "8x16", "8x8", "4x4"];

/// Analyses a mocomp stream (bytes): one dict per frame with `type`, `qp`,
/// `tool`, `luma_filter` (`sharp` or `smooth`), `deblock` (whether the
/// filter ran), `deblock_offsets` (its (alpha, beta) offsets), `bytes`, `bits_header`, `bits_motion`, `bits_residual` (as the
/// encoder counts them), `picture` (the decoded (Y, U, V)), and per
/// macroblock arrays of shape (mb_rows, mb_cols): `kind` (0 skip, 1 inter,
/// 2 intra), `partition` (0 16x16, 1 16x8, 2 8x16, 3 8x8, 4 intra 4x4),
/// `coded_blocks` (luma and chroma 4x4 blocks with levels), `bits`
/// (mb_rows, mb_cols, 3: header, motion, residual); per 8x8 block,
/// `vectors` (2 mb_rows, 2 mb_cols, 2) in quarter-pel (x, y) with
/// `has_vector` false for intra, and `refs` (2 mb_rows, 2 mb_cols) the
/// reference index of each vector (0: the previous frame; -1 for intra); `grid` (rows, cols, 2) for grid frames,
/// else None. Raises ValueError on a damaged stream.
#[pyfunction]
pub fn analyze<'py>(py: Python<'py>, stream: &[u8]) -> PyResult<Bound<'py, PyList>> {
    let frames: Vec<_> = py
        .detach(|| Analyzer::new(stream).and_then(|a| a.collect::<Result<Vec<_>, _>>()))
        .map_err(|e| value_error(format!("stream: {e}")))?;
    let out = PyList::empty(py);
    for f in &frames {
        let cols = f.picture.width().div_ceil(16);
        let rows = f.mbs.len() / cols.max(1);
        let mut kind = Array2::<u8>::zeros((rows, cols));
        let mut partition = Array2::<u8>::zeros((rows, cols));
        let mut coded = Array2::<u8>::zeros((rows, cols));
        let mut bits = Array3::<f64>::zeros((rows, cols, 3));
        let mut vectors = Array3::<i32>::zeros((2 * rows, 2 * cols, 2));
        let mut has_vector = Array2::<bool>::from_elem((2 * rows, 2 * cols), false);
        let mut refs = Array2::<i8>::from_elem((2 * rows, 2 * cols), -1);
        for m in &f.mbs {
            let (r, c) = (m.mb_y, m.mb_x);
            kind[[r, c]] = KINDS.iter().position(|&k| k == m.kind).unwrap_or(0) as u8;
            partition[[r, c]] = PARTITIONS.iter().position(|&p| p == m.partition).unwrap_or(0) as u8;
            coded[[r, c]] = m.coded_luma_blocks + m.coded_chroma_blocks;
            for (i, b) in [m.bits_header, m.bits_motion, m.bits_residual]
                .into_iter()
                .enumerate()
            {
                bits[[r, c, i]] = b;
            }
            for (k, v) in m.vectors.iter().enumerate() {
                let (y, x) = (2 * r + k / 2, 2 * c + k % 2);
                if let Some((vx, vy)) = *v {
                    vectors[[y, x, 0]] = vx;
                    vectors[[y, x, 1]] = vy;
                    has_vector[[y, x]] = true;
                }
                if let Some(r) = m.refs[k] {
                    refs[[y, x]] = r as i8;
                }
            }
        }
        let d = PyDict::new(py);
        d.set_item("type", f.frame_type.to_string())?;
        d.set_item("qp", f.qp)?;
        d.set_item("tool", f.tool)?;
        d.set_item("luma_filter", f.luma_filter)?;
        d.set_item("deblock", f.deblock)?;
        d.set_item("deblock_offsets", f.deblock_offsets)?;
        d.set_item("bytes", f.bytes)?;
        d.set_item("bits_header", f.bits.header)?;
        d.set_item("bits_motion", f.bits.motion)?;
        d.set_item("bits_residual", f.bits.residual)?;
        d.set_item("picture", frame_to_py(py, &f.picture)?)?;
        d.set_item("kind", kind.into_pyarray(py))?;
        d.set_item("partition", partition.into_pyarray(py))?;
        d.set_item("coded_blocks", coded.into_pyarray(py))?;
        d.set_item("bits", bits.into_pyarray(py))?;
        d.set_item("vectors", vectors.into_pyarray(py))?;
        d.set_item("has_vector", has_vector.into_pyarray(py))?;
        d.set_item("refs", refs.into_pyarray(py))?;
        let grid: Option<Bound<'py, PyArray3<i32>>> = f.grid.as_ref().map(|g| {
            let mut a = Array3::<i32>::zeros((g.rows(), g.cols(), 2));
            for row in 0..g.rows() {
                for col in 0..g.cols() {
                    let v = g.get(col, row);
                    a[[row, col, 0]] = v.x;
                    a[[row, col, 1]] = v.y;
                }
            }
            a.into_pyarray(py)
        });
        d.set_item("grid", grid)?;
        out.append(d)?;
    }
    Ok(out)
}
