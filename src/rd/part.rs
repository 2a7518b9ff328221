//! A sweep's CSV written a row at a time, durably, so that a study killed
//! part-way goes on where it stopped; and the merge of the parts that the
//! shards of one study wrote on different machines.

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::sweep::{csv_record, read_csv, CsvError, RdPoint, CSV_COLUMNS};

/// Why a part could not be opened, written or merged.
#[derive(Debug, thiserror::Error)]
pub enum PartError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// The file is not a CSV of this version's sweeps.
    #[error("{path}: {what}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
    /// The file holds rows of another study.
    #[error(
        "{path} holds rows of study {found}, not of this one ({expected}: other sequences, QPs, predictors or \
         settings); remove it or write elsewhere"
    )]
    OtherStudy {
        /// The file.
        path: PathBuf,
        /// The study its rows are of.
        found: String,
        /// This study.
        expected: String,
    },
    /// The file holds rows another shard of the study wrote.
    #[error(
        "{path} holds rows of shard {}/{}, not of shard {}/{}: a task's part is resumed only by the same shard \
         (rerun task I of N as --shard I/N; with rd_array.sh, the same SHARDS and sbatch --array=I)",
        found.0, found.1, expected.0, expected.1
    )]
    OtherShard {
        /// The file.
        path: PathBuf,
        /// The shard its rows are of.
        found: (usize, usize),
        /// This run's shard.
        expected: (usize, usize),
    },
    /// One job in two parts with different results.
    #[error(
        "job {job} is in {a} and in {b} with different rows (column {column}: {va} and {vb}): the parts are of \
         different runs; remove the wrong one"
    )]
    Conflict {
        /// The job.
        job: usize,
        /// One part.
        a: PathBuf,
        /// Another.
        b: PathBuf,
        /// The first column they differ in.
        column: &'static str,
        /// Its value in `a`.
        va: String,
        /// Its value in `b`.
        vb: String,
    },
    /// Parts of different studies were given to merge.
    #[error("{a} and {b} are parts of different studies ({sa} and {sb})")]
    Mixed {
        /// One part.
        a: PathBuf,
        /// Its study.
        sa: String,
        /// Another part.
        b: PathBuf,
        /// Its study.
        sb: String,
    },
    /// Jobs of the study are in none of the parts.
    #[error("{} of the study's {total} jobs are in no part: {}", missing.len(), list(missing))]
    Missing {
        /// The jobs' numbers.
        missing: Vec<usize>,
        /// The study's number of jobs.
        total: usize,
    },
}

/// The first numbers of `jobs`, for a message.
fn list(jobs: &[usize]) -> String {
    let mut s: Vec<String> = jobs.iter().take(12).map(usize::to_string).collect();
    if jobs.len() > 12 {
        s.push("...".into());
    }
    s.join(", ")
}

/// The header line of a sweep's CSV.
fn header_line() -> String {
    CSV_COLUMNS.join(",") + "\n"
}

/// A sweep's CSV open for appending rows.
pub struct PartFile {
    path: PathBuf,
    file: Mutex<File>,
}

impl PartFile {
    /// Opens `path` for shard `shard` (I, N) of study `study`: creates it
    /// with the header when it does not exist; else reads the rows already
    /// there (a last line cut short by a kill is dropped), which must be of
    /// this study and this shard, and returns them.
    pub fn open(
        path: &Path,
        study: &str,
        shard: (usize, usize),
    ) -> Result<(PartFile, Vec<RdPoint>), PartError> {
        let io = |source| PartError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut file = OpenOptions::new()
            .read(true)
            .append(true)
            .create(true)
            .open(path)
            .map_err(io)?;
        let mut text = Vec::new();
        file.read_to_end(&mut text).map_err(io)?;
        if text.is_empty() {
            file.write_all(header_line().as_bytes()).map_err(io)?;
            file.sync_data().map_err(io)?;
            let part = PartFile {
                path: path.to_path_buf(),
                file: Mutex::new(file),
            };
            return Ok((part, Vec::new()));
        }
        // Keep whole lines only: a row is written with its newline last.
        let whole = text.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        if whole < text.len() {
            file.set_len(whole as u64).map_err(io)?;
            file.seek(SeekFrom::End(0)).map_err(io)?;
            text.truncate(whole);
        }
        if !text.starts_with(header_line().as_bytes()) {
            return Err(PartError::Csv {
                path: path.to_path_buf(),
                what: format!(
                    "not a sweep CSV of this mocomp (its first line is not {})",
                    header_line().trim_end()
                ),
            });
        }
        let rows = parse(path, &text)?;
        if let Some(other) = rows.iter().find(|p| p.study != study) {
            return Err(PartError::OtherStudy {
                path: path.to_path_buf(),
                found: other.study.clone(),
                expected: study.to_string(),
            });
        }
        if let Some(found) = rows.iter().filter_map(|p| p.shard).find(|&s| s != shard) {
            return Err(PartError::OtherShard {
                path: path.to_path_buf(),
                found,
                expected: shard,
            });
        }
        let part = PartFile {
            path: path.to_path_buf(),
            file: Mutex::new(file),
        };
        Ok((part, rows))
    }

    /// Appends `point` as one line, written whole and synced before this
    /// returns.
    pub fn append(&self, point: &RdPoint) -> Result<(), PartError> {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        let line = w
            .write_record(csv_record(point))
            .map_err(|e| e.to_string())
            .and_then(|()| w.into_inner().map_err(|e| e.to_string()))
            .map_err(|what| PartError::Csv {
                path: self.path.clone(),
                what,
            })?;
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        let io = |source| PartError::Io {
            path: self.path.clone(),
            source,
        };
        file.write_all(&line).map_err(io)?;
        file.sync_data().map_err(io)
    }
}

/// The rows of a sweep CSV's text.
fn parse(path: &Path, text: &[u8]) -> Result<Vec<RdPoint>, PartError> {
    read_csv(text).map_err(|e: CsvError| PartError::Csv {
        path: path.to_path_buf(),
        what: e.to_string(),
    })
}

/// The columns two runs of one job may differ in: times and the shard.
const RUN_COLUMNS: [&str; 4] = ["encode_ms", "me_ms", "decode_ms", "shard"];

/// The first column in which two rows of one job differ beyond their
/// times and shard, with both values.
fn differing(a: &RdPoint, b: &RdPoint) -> Option<(&'static str, String, String)> {
    let (ra, rb) = (csv_record(a), csv_record(b));
    CSV_COLUMNS
        .iter()
        .zip(ra.into_iter().zip(rb))
        .find(|(c, (x, y))| !RUN_COLUMNS.contains(c) && x != y)
        .map(|(c, (x, y))| (*c, x, y))
}

/// Reads the parts of one study and returns its rows in job order: the
/// parts must be of the same study and hold every job between them; a job
/// found twice (a task run again) must have the same results in both.
pub fn merge(parts: &[PathBuf]) -> Result<Vec<RdPoint>, PartError> {
    let mut jobs: BTreeMap<usize, (RdPoint, PathBuf)> = BTreeMap::new();
    let mut first: Option<(PathBuf, String, usize)> = None;
    for path in parts {
        let text = std::fs::read(path).map_err(|source| PartError::Io {
            path: path.clone(),
            source,
        })?;
        for p in parse(path, &text)? {
            let Some((job, total)) = p.job else {
                return Err(PartError::Csv {
                    path: path.clone(),
                    what: "a row without a job number: not a part of a sweep".into(),
                });
            };
            match &first {
                None => first = Some((path.clone(), p.study.clone(), total)),
                Some((a, sa, n)) if *sa != p.study || *n != total => {
                    return Err(PartError::Mixed {
                        a: a.clone(),
                        sa: sa.clone(),
                        b: path.clone(),
                        sb: p.study.clone(),
                    })
                }
                Some(_) => {}
            }
            match jobs.get(&job) {
                None => {
                    jobs.insert(job, (p, path.clone()));
                }
                Some((q, qpath)) => {
                    if let Some((column, va, vb)) = differing(q, &p) {
                        return Err(PartError::Conflict {
                            job,
                            a: qpath.clone(),
                            b: path.clone(),
                            column,
                            va,
                            vb,
                        });
                    }
                }
            }
        }
    }
    let Some((_, _, total)) = first else {
        return Err(PartError::Csv {
            path: parts.first().cloned().unwrap_or_default(),
            what: "no rows to merge".into(),
        });
    };
    let missing: Vec<usize> = (0..total).filter(|j| !jobs.contains_key(j)).collect();
    if !missing.is_empty() {
        return Err(PartError::Missing { missing, total });
    }
    Ok(jobs.into_values().map(|(p, _)| p).collect())
}
