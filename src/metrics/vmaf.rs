//! VMAF through an ffmpeg built with libvmaf, when the system has one.
//!
//! mocomp does not link libvmaf: it runs `ffmpeg` (or the program that
//! `MOCOMP_FFMPEG` names) with its `libvmaf` filter and the library's
//! built-in default model, and reads the per-frame scores from the filter's
//! CSV log. Nothing else in mocomp needs it; without such an ffmpeg, asking
//! for VMAF is an error that says so. (`pip install imageio-ffmpeg` brings
//! one: its binary is built with libvmaf.)

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use crate::codec::Frame;
use crate::io::y4m::{Y4mInfo, Y4mWriter};

/// Why VMAF could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum VmafError {
    /// No ffmpeg with the libvmaf filter was found.
    #[error(
        "VMAF needs an ffmpeg built with libvmaf (none found as $MOCOMP_FFMPEG or `ffmpeg` on the PATH; \
         `pip install imageio-ffmpeg` brings one, then MOCOMP_FFMPEG=$(python -c \
         'import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())'))"
    )]
    NoLibvmaf,
    /// Writing the temporary pictures or running ffmpeg failed.
    #[error("VMAF: {0}")]
    Io(#[from] std::io::Error),
    /// ffmpeg ran but did not give one score per frame.
    #[error("VMAF: {0}")]
    Failed(String),
}

/// The ffmpeg to use for VMAF, looked up once: `$MOCOMP_FFMPEG`, else
/// `ffmpeg` on the PATH, if its filter list has `libvmaf`.
pub fn ffmpeg_with_libvmaf() -> Option<&'static Path> {
    static FOUND: OnceLock<Option<PathBuf>> = OnceLock::new();
    FOUND
        .get_or_init(|| {
            let program = std::env::var_os("MOCOMP_FFMPEG")
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from("ffmpeg"));
            let out = Command::new(&program)
                .args(["-hide_banner", "-filters"])
                .output()
                .ok()?;
            let text = String::from_utf8_lossy(&out.stdout);
            text.lines()
                .any(|l| l.split_whitespace().nth(1) == Some("libvmaf"))
                .then_some(program)
        })
        .as_deref()
}

/// Per-frame VMAF of `test` against `reference` (frames of one size), as
/// many scores as the shorter list has frames.
pub fn vmaf(reference: &[Frame], test: &[Frame]) -> Result<Vec<f64>, VmafError> {
    let Some(first) = reference.first() else {
        return Ok(Vec::new());
    };
    let dir = tempfile::tempdir()?;
    let info = Y4mInfo::new(first.width(), first.height(), (25, 1));
    let write = |name: &str, frames: &[Frame]| -> Result<PathBuf, VmafError> {
        let path = dir.path().join(name);
        let file = std::io::BufWriter::new(std::fs::File::create(&path)?);
        let mut w = Y4mWriter::new(file, &info).map_err(|e| VmafError::Failed(e.to_string()))?;
        for f in frames {
            w.write_frame(f).map_err(|e| VmafError::Failed(e.to_string()))?;
        }
        // A write error must not pass for a shorter sequence.
        std::io::Write::flush(&mut w.into_inner())?;
        Ok(path)
    };
    let n = reference.len().min(test.len());
    let r = write("reference.y4m", &reference[..n])?;
    let t = write("test.y4m", &test[..n])?;
    let scores = vmaf_files(&r, &t)?;
    if scores.len() != n {
        return Err(VmafError::Failed(format!(
            "{} scores for {n} frames",
            scores.len()
        )));
    }
    Ok(scores)
}

/// Per-frame VMAF of the Y4M file `test` against the Y4M file `reference`.
pub fn vmaf_files(reference: &Path, test: &Path) -> Result<Vec<f64>, VmafError> {
    let ffmpeg = ffmpeg_with_libvmaf().ok_or(VmafError::NoLibvmaf)?;
    let dir = tempfile::tempdir()?;
    let log = dir.path().join("vmaf.csv");
    // The filter's first input is the distorted picture, the second the
    // reference. Colons in the path would end the option: the log goes
    // into a directory of our own whose name has none.
    let filter = format!("[0:v][1:v]libvmaf=log_fmt=csv:log_path={}", log.display());
    let out = Command::new(ffmpeg)
        .args(["-v", "error", "-nostdin", "-i"])
        .arg(test)
        .arg("-i")
        .arg(reference)
        .args(["-lavfi", &filter, "-f", "null", "-"])
        .output()?;
    if !out.status.success() {
        return Err(VmafError::Failed(
            String::from_utf8_lossy(&out.stderr).trim().to_string(),
        ));
    }
    read_log(&std::fs::read_to_string(&log)?)
}

/// The `vmaf` column of libvmaf's CSV log.
fn read_log(text: &str) -> Result<Vec<f64>, VmafError> {
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let headers = r.headers().map_err(|e| VmafError::Failed(e.to_string()))?.clone();
    let col = headers
        .iter()
        .position(|h| h == "vmaf")
        .ok_or_else(|| VmafError::Failed("libvmaf's log has no 'vmaf' column".into()))?;
    r.records()
        .map(|rec| {
            let rec = rec.map_err(|e| VmafError::Failed(e.to_string()))?;
            rec.get(col)
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| VmafError::Failed(format!("bad vmaf value in {rec:?}")))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_gives_the_vmaf_column() {
        let log = "Frame,integer_motion2,integer_adm2,vmaf\n0,0.000000,0.94,80.986206\n1,1.5,0.93,78.5\n";
        assert_eq!(read_log(log).unwrap(), vec![80.986206, 78.5]);
        assert!(read_log("Frame,psnr\n0,30\n").is_err());
    }
}
