//! Why a render on the cluster stopped: the host's own failures, as the phase sequence
//! reports them ([`magg_core::machine::RenderError::Machine`] holds one). A fork that is
//! lost for a while is not one of them (it is reloaded and its pairs replayed); a fork
//! silent past `--fork-timeout`, a pass that stalls, or a reply that does not fit the
//! scene is.

use magg_plumbing::retry::ConnectError;
use magg_plumbing::tls::TlsError;
use magg_proto::convert::ConvertError;
use std::time::Duration;

/// A cluster render that cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// The render was given no fork address.
    #[error("no fork to render with")]
    NoForks,
    /// A fork (or the host's own address) could not be reached, even after retries.
    #[error(transparent)]
    Connect(#[from] ConnectError),
    /// A fork refused a call, or failed it for longer than the retries allow.
    #[error("{doing} {fork}: {} ({:?}){hint}", status.message(), status.code())]
    Call {
        /// What the host was doing ("loading the shard of").
        doing: &'static str,
        /// Which fork: `fork I at ADDR`.
        fork: String,
        /// The fork's answer.
        status: tonic::Status,
        /// A hint at the likely cause (e.g. TLS on one side only), or empty.
        hint: String,
    },
    /// A fork that has not answered for the whole fork timeout.
    #[error("{fork} has not answered for {after:?} (--fork-timeout): {reason}")]
    ForkSilent {
        /// Which fork.
        fork: String,
        /// The fork timeout.
        after: Duration,
        /// Its last error.
        reason: String,
    },
    /// A task of the host's runtime died.
    #[error("a shard upload task failed: {0}")]
    Task(#[from] tokio::task::JoinError),
    /// A fork's energies do not convert.
    #[error("the energies of fork {fork}: {source}")]
    Energies {
        /// Fork index.
        fork: usize,
        /// What was wrong.
        source: ConvertError,
    },
    /// A fork sent energy for an element the scene does not have.
    #[error("fork {fork} sent energy for element {element} of {elements}")]
    NoSuchElement {
        /// Fork index.
        fork: usize,
        /// The element it named.
        element: u32,
        /// Elements in the scene.
        elements: usize,
    },
    /// The forks' exactly-once ledgers still disagreed after rebuilding the forks in
    /// doubt: the energy on `fork` cannot be trusted.
    #[error("the energy on {fork} could not be verified after {rebuilds} rebuilds: {mismatch}")]
    Unverified {
        /// The fork in doubt ("fork I at ADDR").
        fork: String,
        /// The last disagreement found.
        mismatch: magg_core::cluster::LedgerMismatch,
        /// Rebuilds tried.
        rebuilds: u32,
    },
    /// No pair finished for the stall timeout.
    #[error("light ray tracing stalled at {done} of {total} pairs for {after:?} (are nodes connected?)")]
    LightStalled {
        /// Pairs done.
        done: u64,
        /// Pairs in all.
        total: u64,
        /// The stall timeout.
        after: Duration,
    },
    /// No pixel row came in for the stall timeout.
    #[error("viewing ray tracing stalled at {pixels} pixels for {after:?}")]
    ViewStalled {
        /// Pixels done.
        pixels: u64,
        /// The stall timeout.
        after: Duration,
    },
    /// The subscreen queue went away under a running viewing pass.
    #[error("the viewing pass lost its schedule")]
    LostSchedule,
    /// The host's listener has no local address.
    #[error("the host listener's address: {0}")]
    Listener(#[source] std::io::Error),
    /// The host's server could not be built with the installed TLS identity.
    #[error("host server TLS: {0}")]
    ServerTls(#[source] tonic::transport::Error),
    /// The TLS files could not be installed.
    #[error(transparent)]
    Tls(#[from] TlsError),
}
