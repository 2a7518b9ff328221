//! Rate-distortion tooling: BD-rate, sweeps over QPs and predictors, plots.

pub mod bdrate;
