//! How the cluster copes with lost processes, and who may join: the host's fault policy
//! (the `magg-host render` flags that fill it are the application's).

use magg_plumbing::auth::Token;
use std::time::Duration;

/// How the cluster copes with lost processes, and who may join: [`FaultArgs`] checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FaultPolicy {
    /// A node silent this long loses its pairs (on the forks) and its subscreen.
    pub lease: Duration,
    /// A fork unreachable this long stops the render.
    pub fork_timeout: Duration,
    /// Cluster token: presented to forks, required from nodes (none: no check).
    pub token: Token,
    /// TLS files, installed when the render reaches other processes.
    pub tls: magg_plumbing::tls::TlsFiles,
}

impl Default for FaultPolicy {
    fn default() -> Self {
        FaultPolicy {
            lease: Duration::from_secs(30),
            fork_timeout: Duration::from_secs(30),
            token: Token::default(),
            tls: Default::default(),
        }
    }
}

impl FaultPolicy {
    /// Installs the TLS files for this process when the render reaches other processes
    /// (`external`); a render wholly inside this process talks over 127.0.0.1 only and
    /// ignores them, saying so.
    pub fn install_tls(&self, external: bool) -> Result<(), magg_plumbing::tls::TlsError> {
        if external {
            magg_plumbing::tls::install_files(&self.tls)?;
        } else if !self.tls.is_empty() {
            tracing::warn!("TLS files ignored: forks and nodes run inside this process");
        }
        Ok(())
    }
}
