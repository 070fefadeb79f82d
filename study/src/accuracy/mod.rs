//! What accuracy costs in time (docs/ACCURACY.md): the settings grid of the accuracy study, its
//! error metrics against a converged reference, the Pareto front of error against render
//! time, and the `--quality` presets of `magg-host render` that sit on that front.
//!
//! [`study`] runs it and writes its table and figures; `magg-host accuracy SCENE` drives
//! it; docs/ACCURACY.md has the measured tables.

pub mod closed_form;
pub mod grid;
pub mod metrics;
pub mod pareto;
pub mod preset;
pub mod study;
