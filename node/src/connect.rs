//! Reaching a peer: [`magg_plumbing::retry::connect_with_backoff`] (the cluster's limits,
//! backoff with jitter, a deadline on every call, the in-process transport for a peer of
//! this process), its failure as a [`NodeError`].

use crate::NodeError;
use magg_plumbing::retry::{self, Backoff};
use magg_plumbing::transport::{InProcess, Transport};

/// Connects to `addr`, retrying with `backoff`; a peer still unreachable at its deadline
/// is [`NodeError::Connect`], naming the address.
pub async fn connect_with_backoff(links: &InProcess, addr: &str, backoff: Backoff) -> Result<Transport, NodeError> {
    retry::connect_with_backoff(links, addr, backoff)
        .await
        .map_err(|retry::ConnectError { addr, reason }| NodeError::Connect { addr, reason })
}
