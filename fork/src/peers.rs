//! Clients to the other forks (the paper's G-bus): block fetches and pair stealing.
//!
//! Connections are made on first use and cached; a connection that fails is dropped
//! from the cache so that the next call reconnects. [`connect`] is also what nodes and
//! the host use to reach a fork, with the cluster's limits ([`magg_plumbing::net`]).

use crate::error::ForkError;
use crate::locks::lock;
use magg_core::cluster::PairLease;
use magg_plumbing::auth::{AddToken, Authed, Token};
use magg_plumbing::transport::InProcess;
use magg_plumbing::{net, retry, with_message_limits};
use magg_proto::v1;
use magg_proto::v1::fork_client::ForkClient;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Duration;
use tonic::Code;

/// How long a connection attempt to a fork may take.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);
/// How long one fork-to-fork call may take.
pub const PEER_CALL_TIMEOUT: Duration = Duration::from_secs(60);

/// How a fork is reached: the cluster token presented on every call, and the servers of
/// this process reached without sockets (none for a process of its own).
#[derive(Clone, Debug, Default)]
pub struct PeerAccess {
    /// Presented on every call.
    pub token: Token,
    /// Forks of this process (the in-process harness).
    pub links: InProcess,
}

impl PeerAccess {
    /// Reaching forks over sockets with `token`.
    pub fn with_token(token: Token) -> PeerAccess {
        PeerAccess { token, links: InProcess::none() }
    }
}

/// Connects to the fork at `addr` (`HOST:PORT`) as `access` says, with the cluster's
/// limits ([`net::endpoint`], [`net::MAX_MESSAGE_BYTES`] both ways). Errors are
/// [`ForkError::PeerUnavailable`] naming the address.
pub async fn connect(addr: &str, access: &PeerAccess) -> Result<ForkClient<Authed>, ForkError> {
    let unavailable = |reason: String| ForkError::PeerUnavailable { addr: addr.to_string(), reason };
    let endpoint = net::endpoint(addr)
        .map_err(|e| unavailable(format!("bad address: {e}")))?
        .connect_timeout(CONNECT_TIMEOUT)
        .timeout(PEER_CALL_TIMEOUT);
    let channel = access
        .links
        .connect(endpoint, Some(PEER_CALL_TIMEOUT))
        .await
        .map_err(|e| unavailable(magg_plumbing::error_chain(&e)))?;
    Ok(with_message_limits!(ForkClient::with_interceptor(channel, AddToken(access.token.clone()))))
}

/// Cached clients to the other forks of one render.
#[derive(Debug)]
pub struct Peers {
    addrs: Vec<String>,
    access: PeerAccess,
    clients: Mutex<HashMap<u32, ForkClient<Authed>>>,
}

impl Peers {
    /// Peers at `addrs` (by fork index), reached as `access` says; nothing is connected
    /// yet.
    pub fn new(addrs: Vec<String>, access: PeerAccess) -> Peers {
        Peers { addrs, access, clients: Mutex::new(HashMap::new()) }
    }

    /// Address of fork `fork`.
    pub fn addr(&self, fork: u32) -> &str {
        self.addrs.get(fork as usize).map(String::as_str).unwrap_or("<no such fork>")
    }

    async fn client(&self, fork: u32) -> Result<ForkClient<Authed>, ForkError> {
        if let Some(c) = lock(&self.clients).get(&fork) {
            return Ok(c.clone());
        }
        let c = connect(self.addr(fork), &self.access).await?;
        lock(&self.clients).insert(fork, c.clone());
        Ok(c)
    }

    /// Turns a peer's error status into a [`ForkError`], dropping the cached connection
    /// when the transport failed.
    fn failed(&self, fork: u32, status: tonic::Status) -> ForkError {
        let addr = self.addr(fork).to_string();
        if retry::transient(&status) || status.code() == Code::DeadlineExceeded {
            lock(&self.clients).remove(&fork);
        }
        // A peer unreachable, or whose connection broke under the call: the caller may retry.
        if retry::transient(&status) {
            return ForkError::PeerUnavailable { addr, reason: status.message().to_string() };
        }
        ForkError::Peer { fork, addr, status }
    }

    /// Blocks `ids`, all owned by fork `fork`, in request order (checked: same ids, 2 KB
    /// each).
    pub async fn blocks(&self, fork: u32, ids: Vec<u32>) -> Result<Vec<v1::Block>, ForkError> {
        let mut client = self.client(fork).await?;
        let reply = client
            .peer_blocks(v1::GetBlocksRequest { ids: ids.clone() })
            .await
            .map_err(|s| self.failed(fork, s))?
            .into_inner();
        let wrong = |detail: String| ForkError::PeerReply { fork, addr: self.addr(fork).to_string(), detail };
        if reply.blocks.len() != ids.len() {
            return Err(wrong(format!("{} blocks for {} ids", reply.blocks.len(), ids.len())));
        }
        for (b, &id) in reply.blocks.iter().zip(&ids) {
            if b.id != id || b.data.len() != magg_core::blocks::BLOCK_SIZE {
                return Err(wrong(format!("block {} of {} bytes where block {id} was asked for", b.id, b.data.len())));
            }
        }
        Ok(reply.blocks)
    }

    /// Books the G-bus at fork 0, the arbiter, for a transfer of `cost` (real time);
    /// returns how long to wait until the transfer has ended.
    pub async fn reserve_gbus(&self, cost: Duration) -> Result<Duration, ForkError> {
        let mut client = self.client(0).await?;
        let reply = client
            .reserve_gbus(v1::ReserveGbusRequest { cost_ns: cost.as_nanos() as u64 })
            .await
            .map_err(|s| self.failed(0, s))?
            .into_inner();
        Ok(Duration::from_nanos(reply.wait_ns))
    }

    /// Up to `max` unassigned pairs of fork `fork`, taken on behalf of `node` (with its
    /// secret, which that fork checks too), with the
    /// replay epoch they were handed out in and the pairs the fork has left.
    pub async fn steal(&self, fork: u32, max: u32, node: u32, secret: u64) -> Result<PairLease, ForkError> {
        let mut client = self.client(fork).await?;
        let reply = client
            .steal_pairs(v1::TakePairsRequest { max, node, node_secret: secret, own_only: true })
            .await
            .map_err(|s| self.failed(fork, s))?
            .into_inner();
        let reply = PairLease::try_from(reply).map_err(|e| ForkError::PeerReply {
            fork,
            addr: self.addr(fork).to_string(),
            detail: e.to_string(),
        })?;
        if reply.pairs.len() > max as usize {
            let detail = format!("{} pairs where at most {max} were asked for", reply.pairs.len());
            return Err(ForkError::PeerReply { fork, addr: self.addr(fork).to_string(), detail });
        }
        Ok(reply)
    }
}
