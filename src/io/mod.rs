//! Reading and writing what mocomp works on: Y4M video, PNG (and other
//! `image` formats) pictures, and Middlebury `.flo` flow fields.
//!
//! Paths named `-` mean standard input or output where a format streams
//! (Y4M). Files are written atomically: into a temporary file beside the
//! target, renamed over it only when everything was written, so a failed or
//! interrupted write never leaves a file that looks complete.

pub mod flo;
pub mod image;
mod output;
pub mod y4m;

pub use output::OutputFile;

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Opens `path` for reading, or standard input when `path` is `-`.
pub fn open_input(path: &Path) -> io::Result<Box<dyn Read + Send>> {
    if path.as_os_str() == "-" {
        Ok(Box::new(io::stdin()))
    } else {
        Ok(Box::new(File::open(path)?))
    }
}
