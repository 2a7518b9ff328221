//! Rate-distortion tooling: BD-rate, sweeps over QPs and predictors, plots.

pub mod bdrate;
pub mod part;
#[cfg(feature = "plot")]
pub mod plot;
pub mod sweep;

pub use sweep::{
    compare, csv_record, markdown, read_csv, sweep, write_csv, Comparison, CsvError, PsnrKind, QualityAxis,
    RdPoint, Sequence, Study, CSV_COLUMNS,
};
