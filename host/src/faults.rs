//! Flags of `magg-host render` about faults and access: how long a silent node keeps its
//! work, and the cluster token every process must present.
//!
//! Kept apart from [`crate::cli`] so these options read as one group in `--help` and in
//! the code.

use anyhow::{bail, Context};
use clap::Args;
use magg_cluster::FaultPolicy;
use magg_plumbing::auth::Token;
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
    /// Seconds a fork may stay unreachable before the render stops with an error naming
    /// it. A fork restarted on the same address within this time (after light ray
    /// tracing) gets its shard back and the render goes on.
    #[arg(long, default_value_t = 30.0, value_name = "SECS")]
    pub fork_timeout: f64,
    /// Refuse, before preprocessing, a scene whose render would need more than this many
    /// MiB (estimated from its element count and image size; the estimate is printed).
    #[arg(long, default_value_t = crate::memory::DEFAULT_MAX_MEMORY_MB, value_name = "MB")]
    pub max_memory_mb: u64,
    /// TLS for the cluster's channels (with --forks-at or --external-nodes; a render
    /// wholly inside this process ignores them): the host's certificate and key, served
    /// to nodes, and the CA that forks' certificates chain to.
    #[command(flatten)]
    pub tls: magg_plumbing::tls::TlsFiles,
}

impl FaultArgs {
    /// The checked policy ([`FaultPolicy`], the host library's).
    pub fn policy(&self) -> anyhow::Result<FaultPolicy> {
        Ok(FaultPolicy {
            lease: self.lease()?,
            fork_timeout: self.fork_timeout()?,
            token: self.token()?,
            tls: self.tls.clone(),
        })
    }

    /// The cluster token, checked.
    pub fn token(&self) -> anyhow::Result<Token> {
        Token::parse(self.token.clone()).context("--token")
    }

    /// The node lease, checked.
    pub fn lease(&self) -> anyhow::Result<Duration> {
        seconds("lease-timeout", self.lease_timeout)
    }

    /// The fork timeout, checked.
    pub fn fork_timeout(&self) -> anyhow::Result<Duration> {
        seconds("fork-timeout", self.fork_timeout)
    }
}

fn seconds(flag: &str, s: f64) -> anyhow::Result<Duration> {
    if !(s.is_finite() && (0.05..=86_400.0).contains(&s)) {
        bail!("--{flag} {s}: must be 0.05..=86400 seconds");
    }
    Ok(Duration::from_secs_f64(s))
}
