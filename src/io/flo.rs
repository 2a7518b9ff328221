//! Middlebury `.flo` flow files.
//!
//! Layout (little endian): the magic `PIEH` (the float 202021.25), width and
//! height as 32-bit integers, then `width * height` pairs of float32 `u, v`,
//! row after row. A component with magnitude above 1e9 (or NaN) marks the
//! pixel's flow as unknown: it is read as invalid in the [`Flow`]'s mask, and
//! invalid pixels are written as 1e10.
//!
//! The header's size is checked against the limits and against the data
//! actually present before the field is allocated.
//!
//! ```
//! use mocomp::flow::Flow;
//! use mocomp::io::flo;
//! let f = Flow::from_fn(3, 2, |x, y| (x as f32, -(y as f32)));
//! let mut bytes = Vec::new();
//! flo::write_flo_to(&mut bytes, &f).unwrap();
//! assert_eq!(bytes.len(), 12 + 3 * 2 * 8);
//! assert_eq!(flo::read_flo_from(&bytes[..]).unwrap(), f);
//! ```

use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::Path;

use ndarray::Array2;

use super::OutputFile;
use crate::codec::picture::{check_size, PictureError};
use crate::flow::Flow;

/// The first four bytes of a `.flo` file.
pub const MAGIC: [u8; 4] = *b"PIEH";

/// Components above this magnitude mark unknown flow.
pub const UNKNOWN_THRESHOLD: f32 = 1e9;

/// The value written for unknown flow.
pub const UNKNOWN_FLOW: f32 = 1e10;

const HEADER_LEN: u64 = 12;

/// What can go wrong with a `.flo` file.
#[derive(Debug, thiserror::Error)]
pub enum FloError {
    /// The underlying file failed.
    #[error(transparent)]
    Io(#[from] io::Error),
    /// The first four bytes are not `PIEH`.
    #[error("not a .flo file: magic is {found:?}, expected \"PIEH\" (202021.25)")]
    BadMagic {
        /// The bytes found.
        found: String,
    },
    /// Shorter than the 12-byte header.
    #[error("not a .flo file: {got} bytes, shorter than the 12-byte header")]
    ShortHeader {
        /// Bytes present.
        got: u64,
    },
    /// Width or height out of range.
    #[error("bad .flo size {width}x{height}: {reason}")]
    BadSize {
        /// Width from the header.
        width: i64,
        /// Height from the header.
        height: i64,
        /// Why it is refused.
        reason: String,
    },
    /// The data does not match the header's size.
    #[error(".flo file of {width}x{height} needs {expected} bytes, it has {actual}")]
    Length {
        /// Width from the header.
        width: usize,
        /// Height from the header.
        height: usize,
        /// `12 + 8 * width * height`.
        expected: u64,
        /// The file's length.
        actual: u64,
    },
}

fn check_header(header: &[u8; 12]) -> Result<(usize, usize), FloError> {
    if header[..4] != MAGIC {
        return Err(FloError::BadMagic {
            found: String::from_utf8_lossy(&header[..4]).into_owned(),
        });
    }
    let width = i32::from_le_bytes([header[4], header[5], header[6], header[7]]) as i64;
    let height = i32::from_le_bytes([header[8], header[9], header[10], header[11]]) as i64;
    let bad = |reason: String| FloError::BadSize {
        width,
        height,
        reason,
    };
    if width <= 0 || height <= 0 {
        return Err(bad("width and height must be positive".into()));
    }
    check_size(width as usize, height as usize).map_err(|e: PictureError| bad(e.to_string()))?;
    Ok((width as usize, height as usize))
}

fn expected_len(width: usize, height: usize) -> u64 {
    HEADER_LEN + 8 * (width as u64) * (height as u64)
}

/// The length a `width x height` file must have, or the error saying so.
fn check_length(width: usize, height: usize, actual: u64) -> Result<u64, FloError> {
    let expected = expected_len(width, height);
    if actual != expected {
        return Err(FloError::Length {
            width,
            height,
            expected,
            actual,
        });
    }
    Ok(expected)
}

/// Reads a `.flo` file, checking its length against its header first.
pub fn read_flo(path: &Path) -> Result<Flow, FloError> {
    let file = File::open(path)?;
    let actual = file.metadata()?.len();
    let mut reader = BufReader::new(file);
    let (width, height) = read_header(&mut reader)?;
    let expected = check_length(width, height, actual)?;
    read_body(&mut reader, width, height, expected)
}

/// Reads a `.flo` stream of unknown length. Memory grows only with the data
/// actually present, so a lying header cannot force a large allocation.
pub fn read_flo_from(reader: impl Read) -> Result<Flow, FloError> {
    let mut reader = BufReader::new(reader);
    let (width, height) = read_header(&mut reader)?;
    let expected = expected_len(width, height);
    let mut body = Vec::new();
    (&mut reader)
        .take(expected - HEADER_LEN + 1)
        .read_to_end(&mut body)?;
    check_length(width, height, HEADER_LEN + body.len() as u64)?;
    read_body(&mut &body[..], width, height, expected)
}

fn read_header(reader: &mut impl Read) -> Result<(usize, usize), FloError> {
    let mut header = [0u8; 12];
    let mut got = 0;
    while got < header.len() {
        match reader.read(&mut header[got..])? {
            0 => break,
            n => got += n,
        }
    }
    if got < header.len() {
        return Err(FloError::ShortHeader { got: got as u64 });
    }
    check_header(&header)
}

fn read_body(reader: &mut impl Read, width: usize, height: usize, expected: u64) -> Result<Flow, FloError> {
    let mut u = Array2::zeros((height, width));
    let mut v = Array2::zeros((height, width));
    let mut valid = Array2::from_elem((height, width), true);
    let mut row = vec![0u8; 8 * width];
    for y in 0..height {
        reader.read_exact(&mut row).map_err(|e| match e.kind() {
            io::ErrorKind::UnexpectedEof => FloError::Length {
                width,
                height,
                expected,
                actual: HEADER_LEN + 8 * (y * width) as u64,
            },
            _ => FloError::Io(e),
        })?;
        for (x, px) in row.chunks_exact(8).enumerate() {
            let a = f32::from_le_bytes([px[0], px[1], px[2], px[3]]);
            let b = f32::from_le_bytes([px[4], px[5], px[6], px[7]]);
            // NaN fails both comparisons, so it is unknown too.
            if a.abs() <= UNKNOWN_THRESHOLD && b.abs() <= UNKNOWN_THRESHOLD {
                u[[y, x]] = a;
                v[[y, x]] = b;
            } else {
                valid[[y, x]] = false;
            }
        }
    }
    Ok(Flow::from_parts(u, v, valid))
}

/// Writes a `.flo` file atomically; invalid pixels are written as unknown.
pub fn write_flo(path: &Path, flow: &Flow) -> Result<(), FloError> {
    let mut out = OutputFile::create(path)?;
    write_flo_to(&mut out, flow)?;
    out.commit()?;
    Ok(())
}

/// Writes `.flo` bytes to any writer.
pub fn write_flo_to(writer: impl Write, flow: &Flow) -> Result<(), FloError> {
    let (width, height) = (flow.width(), flow.height());
    check_size(width, height).map_err(|e| FloError::BadSize {
        width: width as i64,
        height: height as i64,
        reason: e.to_string(),
    })?;
    let mut w = BufWriter::new(writer);
    w.write_all(&MAGIC)?;
    w.write_all(&(width as i32).to_le_bytes())?;
    w.write_all(&(height as i32).to_le_bytes())?;
    let mut row = Vec::with_capacity(8 * width);
    for y in 0..height {
        row.clear();
        for x in 0..width {
            let (a, b) = if flow.is_valid(x, y) {
                flow.get(x, y)
            } else {
                (UNKNOWN_FLOW, UNKNOWN_FLOW)
            };
            row.extend_from_slice(&a.to_le_bytes());
            row.extend_from_slice(&b.to_le_bytes());
        }
        w.write_all(&row)?;
    }
    w.flush()?;
    Ok(())
}
