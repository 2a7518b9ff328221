use std::fs;
use std::io::{self, BufWriter, Stdout, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

/// An output that becomes visible only when complete.
///
/// For a path, bytes go to a temporary file in the same directory, which
/// [`OutputFile::commit`] renames over the target; dropping the value without
/// committing removes the temporary file and leaves the target untouched.
/// For `-`, bytes go to standard output (which cannot be taken back), and
/// a target that exists and is not a regular file (`/dev/null`, a named
/// pipe) is written in place, as ffmpeg and x264 write it: renaming over
/// it would replace the device with a plain file.
///
/// ```
/// use std::io::Write;
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("out.txt");
/// let mut out = mocomp::io::OutputFile::create(&path).unwrap();
/// out.write_all(b"half").unwrap();
/// drop(out); // not committed: nothing appears
/// assert!(!path.exists());
/// let mut out = mocomp::io::OutputFile::create(&path).unwrap();
/// out.write_all(b"whole").unwrap();
/// out.commit().unwrap();
/// assert_eq!(std::fs::read(&path).unwrap(), b"whole");
/// ```
pub struct OutputFile {
    sink: Sink,
}

enum Sink {
    Stdout(BufWriter<Stdout>),
    /// A device or pipe, written as it is.
    Special(BufWriter<fs::File>),
    File {
        tmp: BufWriter<NamedTempFile>,
        target: PathBuf,
    },
}

impl OutputFile {
    /// Starts writing `path` (or standard output for `-`).
    pub fn create(path: &Path) -> io::Result<OutputFile> {
        if path.as_os_str() == "-" {
            return Ok(OutputFile {
                sink: Sink::Stdout(BufWriter::new(io::stdout())),
            });
        }
        if fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
            return Ok(OutputFile {
                sink: Sink::Special(BufWriter::new(fs::OpenOptions::new().write(true).open(path)?)),
            });
        }
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = path
            .file_name()
            .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".{}.", name.to_string_lossy()))
            .suffix(".partial")
            .tempfile_in(dir)?;
        Ok(OutputFile {
            sink: Sink::File {
                tmp: BufWriter::new(tmp),
                target: path.to_path_buf(),
            },
        })
    }

    /// Flushes everything and makes the file appear under its name.
    pub fn commit(self) -> io::Result<()> {
        match self.sink {
            Sink::Stdout(mut w) => w.flush(),
            Sink::Special(mut w) => w.flush(),
            Sink::File { tmp, target } => {
                let tmp = tmp.into_inner().map_err(|e| e.into_error())?;
                tmp.as_file().sync_all()?;
                let file = tmp.persist(&target).map_err(|e| e.error)?;
                // Temporary files are created 0600; give the result the usual mode.
                set_default_permissions(&file)?;
                Ok(())
            }
        }
    }
}

#[cfg(unix)]
fn set_default_permissions(file: &fs::File) -> io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    file.set_permissions(fs::Permissions::from_mode(0o644))
}

#[cfg(not(unix))]
fn set_default_permissions(_file: &fs::File) -> io::Result<()> {
    Ok(())
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.sink {
            Sink::Stdout(w) => w.write(buf),
            Sink::Special(w) => w.write(buf),
            Sink::File { tmp, .. } => tmp.write(buf),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match &mut self.sink {
            Sink::Stdout(w) => w.write_all(buf),
            Sink::Special(w) => w.write_all(buf),
            Sink::File { tmp, .. } => tmp.write_all(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.sink {
            Sink::Stdout(w) => w.flush(),
            Sink::Special(w) => w.flush(),
            Sink::File { tmp, .. } => tmp.flush(),
        }
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::os::unix::fs::FileTypeExt;

    #[test]
    fn a_device_is_written_in_place_not_replaced() {
        let null = Path::new("/dev/null");
        if !fs::metadata(null).is_ok_and(|m| m.file_type().is_char_device()) {
            // Not the device here to begin with: nothing to hold.
            return;
        }
        let mut out = OutputFile::create(null).unwrap();
        out.write_all(b"discarded").unwrap();
        out.commit().unwrap();
        assert!(fs::metadata(null).unwrap().file_type().is_char_device());
        // Nor is a temporary file left beside it.
        let leftovers = fs::read_dir("/dev")
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| e.file_name().to_string_lossy().starts_with(".null."))
            .count();
        assert_eq!(leftovers, 0);
    }
}
