//! The paper's experiments redone (paper §5, docs/EXPERIMENTS.md): a grid of cluster runs
//! over nodes x cache blocks x forks x schedule under a hardware profile, one CSV row per
//! run from its stats, and PNG figures that mirror the paper's figures 4-11.
//!
//! [`study`] runs the grid; `magg-host sweep` drives it; `deploy/sweep.sh` is the
//! documented full grid; docs/EXPERIMENTS.md reads the results.

pub mod figures;
pub mod run;
pub mod study;
