//! Rate-distortion tooling: BD-rate, sweeps over QPs and predictors, plots.

pub mod bdrate;
#[cfg(feature = "plot")]
pub mod plot;
pub mod sweep;

pub use sweep::{
    compare, markdown, read_csv, sweep, write_csv, Comparison, CsvError, PsnrKind, RdPoint, Sequence,
    CSV_COLUMNS,
};
