//! Retrying what failed for a transient reason, with exponential backoff and jitter, so
//! that many nodes retrying at once do not hit a recovering peer in lock-step:
//! connections ([`connect_with_backoff`]) and calls ([`retry`]; the peer is unreachable,
//! its connection broke, or it is restarting: see [`transient`]). One [`Backoff`] policy
//! serves both, and holds the deadline of every call on the channel.
//!
//! Only calls that are safe to repeat go through [`retry`]: reads (blocks, energies),
//! keyed writes (deposits, pixel rows: a repeat is acknowledged and ignored), and
//! hand-outs whose lost answer is recovered by a lease (pairs, subscreens).
//!
//! ```no_run
//! # async fn f(mut host: magg_proto::v1::host_client::HostClient<magg_plumbing::auth::Authed>) {
//! use magg_plumbing::retry::{retry, Backoff};
//! let req = magg_proto::v1::NextWorkRequest { node: 0, report: None, node_secret: 0 };
//! let reply = retry("NextWork", Backoff::default(), || {
//!     let (mut host, req) = (host.clone(), req.clone());
//!     async move { host.next_work(req).await }
//! })
//! .await;
//! # }
//! ```

use crate::transport::{InProcess, Transport};
use std::future::Future;
use std::time::{Duration, Instant};
use tonic::{Code, Status};

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
    /// The peer is expected to be away for a while (a long-lived node between renders,
    /// waiting for the next host): failed connection attempts are logged at debug level,
    /// not as warnings.
    pub expect_absence: bool,
}

/// Default deadline of one call: far above any healthy call (the largest, a
/// `GetBlocks` of 4096 blocks, is 8 MB), far below "hung".
pub const CALL_TIMEOUT: Duration = Duration::from_secs(60);

/// How long one connection attempt of [`connect_with_backoff`] may take.
pub const CONNECT_ATTEMPT_TIMEOUT: Duration = Duration::from_secs(2);

impl Default for Backoff {
    fn default() -> Self {
        Backoff {
            initial: Duration::from_millis(50),
            max: Duration::from_secs(2),
            deadline: Duration::from_secs(30),
            call_timeout: CALL_TIMEOUT,
            expect_absence: false,
        }
    }
}

/// A peer that could not be reached, even after retries.
#[derive(Debug, thiserror::Error)]
#[error("cannot reach {addr}: {reason}")]
pub struct ConnectError {
    /// Address tried.
    pub addr: String,
    /// Last error.
    pub reason: String,
}

/// Connects to `addr` ([`crate::net::endpoint`]: the cluster's limits, TLS when
/// installed; the in-process service when `links` holds it), retrying with
/// exponential backoff and jitter until `backoff.deadline`; logs each failed attempt with
/// the address. Every call on the channel gets `backoff.call_timeout` as its deadline.
pub async fn connect_with_backoff(links: &InProcess, addr: &str, backoff: Backoff) -> Result<Transport, ConnectError> {
    let endpoint = crate::net::endpoint(addr)
        .map_err(|e| ConnectError { addr: addr.to_string(), reason: e.to_string() })?
        .connect_timeout(CONNECT_ATTEMPT_TIMEOUT)
        .timeout(backoff.call_timeout);
    let start = Instant::now();
    let mut delay = backoff.initial;
    let mut attempt = 0u64;
    loop {
        match links.connect(endpoint.clone(), Some(backoff.call_timeout)).await {
            Ok(ch) => return Ok(ch),
            Err(e) => {
                attempt += 1;
                if start.elapsed() >= backoff.deadline {
                    return Err(ConnectError {
                        addr: addr.to_string(),
                        reason: format!("{e} (after {attempt} attempts)"),
                    });
                }
                if backoff.expect_absence {
                    tracing::debug!("{addr} not there yet (attempt {attempt}): {e}; retrying in {delay:?}");
                } else {
                    tracing::warn!("cannot reach {addr} (attempt {attempt}): {e}; retrying in {delay:?}");
                }
                tokio::time::sleep(jitter(delay)).await;
                delay = (delay * 2).min(backoff.max);
            }
        }
    }
}

/// `delay` scaled by a factor in [0.5, 1.5), from the clock's low bits (no RNG needed:
/// only spreading matters, not quality).
pub fn jitter(delay: Duration) -> Duration {
    let nanos =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.subsec_nanos()).unwrap_or(0);
    delay.mul_f64(0.5 + (nanos % 1000) as f64 / 1000.0)
}

/// True for the codes worth retrying: the peer could not be reached (`UNAVAILABLE`), or
/// the connection broke under a call in flight (tonic reports that as `UNKNOWN` or
/// `CANCELLED`; magg's servers never answer those codes themselves).
pub fn transient(status: &Status) -> bool {
    matches!(status.code(), Code::Unavailable | Code::Unknown | Code::Cancelled)
}

/// Runs `call` until it succeeds, fails for a non-transient reason, or `backoff.deadline`
/// has passed since the first attempt (then the last error is returned).
pub async fn retry<T, F, Fut>(what: &str, backoff: Backoff, mut call: F) -> Result<T, Status>
where
    F: FnMut() -> Fut,
    Fut: Future<Output = Result<T, Status>>,
{
    let start = Instant::now();
    let mut delay = backoff.initial;
    let mut attempt = 0u32;
    loop {
        match call().await {
            Ok(v) => return Ok(v),
            Err(s) if transient(&s) && start.elapsed() < backoff.deadline => {
                attempt += 1;
                tracing::warn!("{what} failed (attempt {attempt}): {}; retrying in about {delay:?}", s.message());
                tokio::time::sleep(jitter(delay)).await;
                delay = (delay * 2).min(backoff.max);
            }
            Err(s) => return Err(s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    fn quick() -> Backoff {
        Backoff { initial: Duration::from_millis(1), max: Duration::from_millis(4), ..Backoff::default() }
    }

    #[tokio::test]
    async fn unavailable_is_retried_until_it_succeeds() {
        let calls = AtomicU32::new(0);
        let r = retry("t", quick(), || {
            let n = calls.fetch_add(1, Ordering::SeqCst);
            async move {
                if n < 3 {
                    Err(Status::unavailable("down"))
                } else {
                    Ok(n)
                }
            }
        })
        .await;
        assert_eq!(r.unwrap(), 3);
    }

    #[test]
    fn broken_connections_are_transient_refusals_are_not() {
        assert!(transient(&Status::unknown("transport error")));
        assert!(transient(&Status::cancelled("connection reset")));
        assert!(!transient(&Status::unauthenticated("no token")));
        assert!(!transient(&Status::deadline_exceeded("slow")));
    }

    #[tokio::test]
    async fn other_errors_are_not_retried() {
        let calls = AtomicU32::new(0);
        let r: Result<(), _> = retry("t", quick(), || {
            calls.fetch_add(1, Ordering::SeqCst);
            async { Err(Status::invalid_argument("bad")) }
        })
        .await;
        assert_eq!(r.unwrap_err().code(), Code::InvalidArgument);
        assert_eq!(calls.load(Ordering::SeqCst), 1);
    }

    #[tokio::test]
    async fn retries_stop_at_the_deadline() {
        let b = Backoff { deadline: Duration::from_millis(20), ..quick() };
        let r: Result<(), _> = retry("t", b, || async { Err(Status::unavailable("down")) }).await;
        assert_eq!(r.unwrap_err().code(), Code::Unavailable);
    }
}
