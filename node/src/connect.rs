//! Connecting to a peer with exponential backoff and jitter, naming the address on
//! failure; every call on the channel gets a deadline. A peer of this same process is
//! reached through the in-process transport ([`magg_proto::transport`]).

use crate::retry::jitter;
use crate::NodeError;
use magg_proto::transport::{self, Transport};
use std::time::Duration;

/// Retry policy of connections and of calls that failed for a transient reason, and the
/// deadline of every call.
#[derive(Clone, Copy, Debug)]
pub struct Backoff {
    /// First delay.
    pub initial: Duration,
    /// Longest delay.
    pub max: Duration,
    /// Give up after this long.
    pub deadline: Duration,
    /// Deadline of each call on a channel (a stalled peer fails the call with
    /// `DEADLINE_EXCEEDED` instead of hanging the caller).
    pub call_timeout: Duration,
}

/// Default deadline of one call: far above any healthy call (the largest, a
/// `GetBlocks` of 4096 blocks, is 8 MB), far below "hung".
pub const CALL_TIMEOUT: Duration = Duration::from_secs(60);

impl Default for Backoff {
    fn default() -> Self {
        Backoff {
            initial: Duration::from_millis(50),
            max: Duration::from_secs(2),
            deadline: Duration::from_secs(30),
            call_timeout: CALL_TIMEOUT,
        }
    }
}

/// Connects to `addr`, retrying with exponential backoff and jitter until
/// `backoff.deadline`; logs each failed attempt with the address.
pub async fn connect_with_backoff(addr: &str, backoff: Backoff) -> Result<Transport, NodeError> {
    let endpoint = magg_proto::tls::endpoint(addr)
        .map_err(|e| NodeError::Connect { addr: addr.to_string(), reason: e.to_string() })?
        .connect_timeout(Duration::from_secs(2))
        .timeout(backoff.call_timeout)
        .tcp_nodelay(true)
        // Block replies are up to 64 KB and more: windows large enough that HTTP/2 flow
        // control never stalls a reply waiting for a WINDOW_UPDATE round trip.
        .initial_stream_window_size(Some(4 << 20))
        .initial_connection_window_size(Some(16 << 20));
    let start = std::time::Instant::now();
    let mut delay = backoff.initial;
    let mut attempt = 0u64;
    loop {
        match transport::connect(endpoint.clone(), Some(backoff.call_timeout)).await {
            Ok(ch) => return Ok(ch),
            Err(e) => {
                attempt += 1;
                if start.elapsed() >= backoff.deadline {
                    return Err(NodeError::Connect {
                        addr: addr.to_string(),
                        reason: format!("{e} (after {attempt} attempts)"),
                    });
                }
                tracing::warn!("cannot reach {addr} (attempt {attempt}): {e}; retrying in {delay:?}");
                tokio::time::sleep(jitter(delay)).await;
                delay = (delay * 2).min(backoff.max);
            }
        }
    }
}
