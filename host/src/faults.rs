//! Flags of `magg-host render` about faults: how long a silent node keeps its work.
//!
//! Kept apart from [`crate::cli`] so the fault-handling options read as one group in
//! `--help` and in the code.

use anyhow::bail;
use clap::Args;
use std::time::Duration;

/// Fault-handling flags of `render`.
#[derive(Debug, Args)]
pub struct FaultArgs {
    /// Seconds a node may stay silent before its leased (light, element) pairs and its
    /// subscreen are handed to other nodes (it died or stalled). Re-run pairs deposit
    /// exactly once and re-traced rows are written once, so the image is unchanged.
    #[arg(long, default_value_t = 30.0, value_name = "SECS")]
    pub lease_timeout: f64,
}

impl FaultArgs {
    /// The node lease, checked.
    pub fn lease(&self) -> anyhow::Result<Duration> {
        let s = self.lease_timeout;
        if !(s.is_finite() && (0.05..=86_400.0).contains(&s)) {
            bail!("--lease-timeout {s}: must be 0.05..=86400 seconds");
        }
        Ok(Duration::from_secs_f64(s))
    }
}
