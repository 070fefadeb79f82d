//! Flags of `magg-host render` about faults and access: how long a silent node keeps its
//! work, and the cluster token every process must present.
//!
//! Kept apart from [`crate::cli`] so these options read as one group in `--help` and in
//! the code.

use anyhow::{bail, Context};
use clap::Args;
use magg_proto::auth::Token;
use std::time::Duration;

/// Fault-handling and access flags of `render`.
#[derive(Debug, Args)]
pub struct FaultArgs {
    /// Cluster token: every process of the cluster must present it on every call (give
    /// the same to magg-fork and magg-node). Forks and nodes started in this process get
    /// it. Without one, any client is served: keep the default 127.0.0.1 addresses then.
    #[arg(long, env = "MAGG_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Seconds a node may stay silent before its leased (light, element) pairs and its
    /// subscreen are handed to other nodes (it died or stalled). Re-run pairs deposit
    /// exactly once and re-traced rows are written once, so the image is unchanged.
    #[arg(long, default_value_t = 30.0, value_name = "SECS")]
    pub lease_timeout: f64,
}

impl FaultArgs {
    /// The cluster token, checked.
    pub fn token(&self) -> anyhow::Result<Token> {
        Token::parse(self.token.clone()).context("--token")
    }

    /// The node lease, checked.
    pub fn lease(&self) -> anyhow::Result<Duration> {
        let s = self.lease_timeout;
        if !(s.is_finite() && (0.05..=86_400.0).contains(&s)) {
            bail!("--lease-timeout {s}: must be 0.05..=86400 seconds");
        }
        Ok(Duration::from_secs_f64(s))
    }
}
