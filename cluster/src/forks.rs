//! The host's side of the forks: loading their shards, polling them, and bringing back a
//! fork that died.
//!
//! A fork that stops answering is polled until `--fork-timeout`; if it comes back on the
//! same address (empty: it says "no scene loaded"), the host loads its shard again, and
//! the vertex energies too once interpolation has put them there. Nodes meanwhile retry
//! their calls to it (an empty fork answers `UNAVAILABLE`). A fork that does not come
//! back in time stops the render with an error naming it.
//!
//! A fork that restarts during light ray tracing has lost the energy deposited on its
//! elements. The host then starts a replay epoch: the fork is loaded in the new epoch
//! (all of its own pairs queued, since the record of which were complete was on it too),
//! and every other fork queues again exactly its pairs that deposited on the lost fork
//! (each completion names the other forks the pair deposited on) and those still out
//! with nodes (`Replay` with `lost_fork`). Re-run pairs deposit the same values (seeded by
//! pair), the forks that kept their energy drop them as duplicates (keyed by pair), and
//! the restarted fork gets every deposit once: the result is bitwise that of a run
//! without the failure. Completions from before the epoch are not counted, so no pair
//! whose deposit the restarted fork lost is taken for done.
//!
//! Several forks lost together, or one lost again during its replay, are rebuilt one
//! after another, each in an epoch of its own ([`ForkSet::rebuild`]): a fork that
//! answers the `Replay` of another's loss with "no scene loaded" has restarted too, and
//! is loaded (in a later epoch) instead of failing the render. A fork loaded in an
//! epoch needs no replay for the losses before it: its ledger starts empty with every
//! own pair queued.
//!
//! The invariant the light pass ends on, checked by the host before it interpolates
//! ([`magg_core::cluster::check_ledgers`] on every fork's ledger digests): in the
//! current epoch, fork `j` applied the deposits of exactly those pairs of fork `k` that
//! `k`'s complete pairs say they deposited on `j` (and every own pair, for `j == k`).
//! A replay keeps it: a lost fork starts empty, and the others forget what they recorded
//! as deposited on it and trace those pairs again. A fork that fails the check (a
//! restart not seen, a load that replaced a loaded shard, a deposit no complete pair
//! made) is rebuilt as if it had been lost, and the check runs again; a render that
//! cannot pass it stops with an error naming the fork, never with a wrong image.

use crate::failure::ClusterError;
use crate::FaultPolicy;
use magg_core::prepared::PreparedScene;
use magg_plumbing::auth::{AddToken, Authed, NodeKey, Token};
use magg_plumbing::retry::{self, Backoff};
use magg_plumbing::transport::{InProcess, Sharing};
use magg_plumbing::with_message_limits;
use magg_proto::convert::scene_blocks_to_wire;
use magg_proto::v1::fork_client::ForkClient;
use magg_proto::v1::{self, GetEnergiesRequest, LoadShardRequest, PutBlocksRequest};
use magg_proto::PROTOCOL_VERSION;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tonic::{Code, Status};

type Result<T> = std::result::Result<T, ClusterError>;

/// What a poll of a fork's energies asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnergyPoll {
    /// Pair progress and the counters only (progress polls).
    Summary,
    /// The energies deposited so far too, for a watcher (the live view's preview): our
    /// monitoring, which costs the modelled machine nothing.
    Snapshot,
    /// The energies, collected as the paper's host does (over the G-bus, when throttled).
    Collect,
}

impl EnergyPoll {
    /// The request that asks for it.
    fn request(self) -> GetEnergiesRequest {
        GetEnergiesRequest { summary_only: self == EnergyPoll::Summary, monitor: self == EnergyPoll::Snapshot }
    }
}

/// Whether a fork answered "no scene loaded": it has started or restarted since.
fn not_loaded(status: &Status) -> bool {
    status.code() == Code::Unavailable && status.message() == magg_proto::NOT_LOADED
}

/// Longest wait for one poll of a fork (a stalled fork counts as down).
const POLL_TIMEOUT: Duration = Duration::from_secs(5);

/// Scenes with at least this many bytes of blocks upload their shards from parallel
/// tasks (see [`ForkSet::load_all`]).
const PARALLEL_UPLOAD_BYTES: usize = 4 << 20;

/// Every fork of the render, as the host drives them.
pub struct ForkSet {
    prepared: Arc<PreparedScene>,
    /// The scene's blocks for the wire, by id (sharing the scene's memory).
    wire_blocks: Arc<Vec<v1::Block>>,
    /// Which forks run in this process, and the blocks shared with them: their shards
    /// are loaded by reference, not encoded and decoded (`shared_blocks`).
    in_process: Vec<bool>,
    sharing: Option<Sharing>,
    addrs: Vec<String>,
    clients: Vec<ForkClient<Authed>>,
    lease_ms: u32,
    timeout: Duration,
    /// Vertex-energy blocks of each fork, once interpolation has made them.
    vertex_blocks: Option<Vec<Vec<v1::Block>>>,
    /// Since when each fork has not answered.
    down_since: Vec<Option<Instant>>,
    /// Forks reloaded after a restart.
    pub restarts: u64,
    /// Replay epoch (bumped when a fork restarts during light ray tracing).
    pub epoch: u64,
    /// Hardware profile sent with every shard (`Profile::to_wire`; empty: native).
    profile: String,
    /// Nodes the render expects (sizes the forks' guided pair batches).
    nodes: u32,
    /// The render's node key, sent with every shard.
    node_key: NodeKey,
}

/// Connects to the fork at `addr`, retrying until the fork timeout.
async fn connect(links: &InProcess, addr: &str, token: &Token, timeout: Duration) -> Result<ForkClient<Authed>> {
    let ch = retry::connect_with_backoff(links, addr, Backoff { deadline: timeout, ..Default::default() }).await?;
    Ok(with_message_limits!(ForkClient::with_interceptor(ch, AddToken(token.clone()))))
}

/// Sends `req` to the fork `name` behind `client`, retrying while it is unavailable: a
/// load replaces the last. A fork that has not answered within `timeout` (the fork
/// timeout; e.g. a listener that accepts connections and never speaks gRPC) is named.
async fn load_shard(client: ForkClient<Authed>, name: String, timeout: Duration, req: LoadShardRequest) -> Result<()> {
    let backoff = Backoff { deadline: timeout, ..Default::default() };
    let load = retry::retry("LoadShard", backoff, || {
        let (mut c, req) = (client.clone(), req.clone());
        async move { c.load_shard(req).await }
    });
    let Ok(answer) = tokio::time::timeout(timeout, load).await else {
        return Err(ClusterError::ForkSilent { fork: name, after: timeout, reason: "no answer to LoadShard".into() });
    };
    answer.map_err(|status| {
        let hint = magg_plumbing::tls::mismatch_hint(&status.to_string());
        ClusterError::Call { doing: "loading the shard of", fork: name, status, hint: hint.to_string() }
    })?;
    Ok(())
}

impl ForkSet {
    /// Connects to the forks at `addrs` (by index); those of this process through `links`.
    pub async fn connect(
        prepared: &Arc<PreparedScene>,
        addrs: &[String],
        faults: &FaultPolicy,
        links: &InProcess,
    ) -> Result<ForkSet> {
        let mut clients = Vec::with_capacity(addrs.len());
        for addr in addrs {
            clients.push(connect(links, addr, &faults.token, faults.fork_timeout).await?);
        }
        let wire_blocks = Arc::new(scene_blocks_to_wire(prepared));
        let in_process: Vec<bool> = addrs.iter().map(|a| links.get(a).is_some()).collect();
        let sharing = match in_process.contains(&true) {
            true => links.share(wire_blocks.clone()),
            false => None,
        };
        Ok(ForkSet {
            prepared: prepared.clone(),
            wire_blocks,
            in_process,
            sharing,
            addrs: addrs.to_vec(),
            clients,
            lease_ms: faults.lease.as_millis().clamp(1, u32::MAX as u128) as u32,
            timeout: faults.fork_timeout,
            vertex_blocks: None,
            down_since: vec![None; addrs.len()],
            restarts: 0,
            epoch: 0,
            profile: String::new(),
            nodes: 0,
            node_key: NodeKey::default(),
        })
    }

    /// Whether fork `i` runs in the host's process.
    pub fn in_process(&self, i: usize) -> bool {
        self.in_process.get(i) == Some(&true)
    }

    /// The same forks, loaded for a render under hardware profile `profile` (wire form)
    /// with `nodes` expected nodes.
    pub fn for_render(mut self, profile: String, nodes: u32, node_key: NodeKey) -> ForkSet {
        self.profile = profile;
        self.nodes = nodes;
        self.node_key = node_key;
        self
    }

    /// Number of forks.
    pub fn len(&self) -> usize {
        self.clients.len()
    }

    /// True with no fork.
    pub fn is_empty(&self) -> bool {
        self.clients.is_empty()
    }

    /// "fork I at ADDR", for messages.
    pub fn name(&self, i: usize) -> String {
        format!("fork {i} at {}", self.addrs[i])
    }

    /// Loads fork `i`'s shard (every block `b` with `b mod F == i`), with its vertex
    /// energies in the same request if they exist already (so no node can read a block
    /// between the two). Retried while the fork is unavailable: a load replaces the last.
    pub async fn load(&mut self, i: usize) -> Result<()> {
        let req = self.shard_request(i);
        load_shard(self.clients[i].clone(), self.name(i), self.timeout, req).await
    }

    /// Loads every fork's shard, all at once. A fork of this process answers within the
    /// call, so where the calls run decides what runs in parallel: a large scene's shards
    /// are checked and set up on the runtime's threads side by side; a small one's are
    /// polled together in this task, where waking runtime threads would cost more than
    /// it saves (magg-paper, 350 KB: 1.0 ms, 1.2 spawned). Forks across sockets load
    /// concurrently either way.
    pub async fn load_all(&mut self) -> Result<()> {
        let requests: Vec<_> = (0..self.len()).map(|i| self.shard_request(i)).collect();
        let bytes = self.wire_blocks.len() * magg_core::blocks::BLOCK_SIZE;
        let loads = requests
            .into_iter()
            .enumerate()
            .map(|(i, req)| load_shard(self.clients[i].clone(), self.name(i), self.timeout, req));
        if bytes < PARALLEL_UPLOAD_BYTES {
            futures_util::future::try_join_all(loads).await?;
            return Ok(());
        }
        let tasks: Vec<_> = loads.map(tokio::spawn).collect();
        for t in tasks {
            t.await??;
        }
        Ok(())
    }

    /// Fork `i`'s `LoadShard` request; a fork of this process takes its blocks from
    /// those shared with it.
    fn shard_request(&self, i: usize) -> LoadShardRequest {
        let f = self.len();
        let shared = self.sharing.as_ref().filter(|_| self.in_process.get(i) == Some(&true)).map(Sharing::key);
        let mut blocks: Vec<v1::Block> = match shared {
            Some(_) => Vec::new(),
            None => self.wire_blocks.iter().skip(i).step_by(f).cloned().collect(),
        };
        // Later blocks of a request replace earlier ones with the same id.
        blocks.extend(self.vertex_blocks.as_ref().map(|v| v[i].clone()).unwrap_or_default());
        LoadShardRequest {
            protocol_version: PROTOCOL_VERSION,
            fork_index: i as u32,
            fork_addrs: self.addrs.clone(),
            header: Some(v1::SceneHeader::from(&*self.prepared.header)),
            blocks,
            lease_ms: self.lease_ms,
            epoch: self.epoch,
            profile: self.profile.clone(),
            nodes: self.nodes,
            node_key: self.node_key.as_bytes().to_vec().into(),
            shared_blocks: shared.unwrap_or(0),
        }
    }

    /// Stores the vertex-energy blocks on their forks (and keeps them, to reload a fork).
    /// A fork that restarted since its energies were collected is loaded again, with
    /// them.
    pub async fn put_vertex_blocks(&mut self, per_fork: Vec<Vec<v1::Block>>) -> Result<()> {
        self.vertex_blocks = Some(per_fork.clone());
        for (i, blocks) in per_fork.into_iter().enumerate() {
            let name = self.name(i);
            match self.clients[i].put_blocks(PutBlocksRequest { blocks }).await {
                Ok(_) => {}
                Err(s) if not_loaded(&s) => {
                    tracing::warn!("{name} restarted: loading its shard again, with its vertex energies");
                    self.load(i).await?;
                    self.restarts += 1;
                }
                Err(status) => {
                    let doing = "storing vertex energies on";
                    return Err(ClusterError::Call { doing, fork: name, status, hint: String::new() });
                }
            }
        }
        Ok(())
    }

    /// Fork `i`'s energies and counters; `None` while it does not answer (within the
    /// fork timeout). A fork that restarted empty is loaded again, and if `lrt_pending`
    /// (its energy is lost) a replay epoch starts: see the module doc.
    pub async fn poll(
        &mut self,
        i: usize,
        what: EnergyPoll,
        lrt_pending: bool,
    ) -> Result<Option<v1::GetEnergiesReply>> {
        let mut client = self.clients[i].clone();
        let call = client.get_energies(what.request());
        let status = match tokio::time::timeout(POLL_TIMEOUT, call).await {
            Ok(Ok(r)) => {
                if self.down_since[i].take().is_some() {
                    tracing::warn!("{} answers again", self.name(i));
                }
                return Ok(Some(r.into_inner()));
            }
            Ok(Err(s)) => s,
            Err(_) => tonic::Status::deadline_exceeded(format!("no answer within {POLL_TIMEOUT:?}")),
        };
        if not_loaded(&status) {
            tracing::warn!("{} restarted: loading its shard again", self.name(i));
            if lrt_pending {
                self.rebuild(i).await?;
            } else {
                self.load(i).await?;
            }
            self.restarts += 1;
            self.down_since[i] = None;
            return Ok(None);
        }
        let since = *self.down_since[i].get_or_insert_with(Instant::now);
        if since.elapsed() > self.timeout {
            return Err(ClusterError::ForkSilent {
                fork: self.name(i),
                after: self.timeout,
                reason: status.message().to_string(),
            });
        }
        tracing::warn!("{} does not answer ({}); waiting for it", self.name(i), status.message());
        Ok(None)
    }

    /// Fork `first` lost the energy on its elements during light ray tracing (it
    /// restarted, or failed the ledger check): each lost fork in turn gets a new replay
    /// epoch, is loaded in it (empty, every own pair queued), and every other fork is
    /// told to replay for it. A fork that answers that `Replay` with "no scene loaded"
    /// restarted too and is rebuilt next, in an epoch of its own.
    pub async fn rebuild(&mut self, first: usize) -> Result<()> {
        let mut lost = vec![first];
        while let Some(i) = lost.pop() {
            self.epoch += 1;
            tracing::warn!(
                "{}: its energy is lost: replay epoch {}, the pairs that deposited on it are traced again",
                self.name(i),
                self.epoch
            );
            self.load(i).await?;
            for j in (0..self.len()).filter(|&j| j != i) {
                if lost.contains(&j) {
                    continue;
                }
                if !self.replay_on(j, i).await? {
                    tracing::warn!("{} restarted too: it is loaded again after {}", self.name(j), self.name(i));
                    self.restarts += 1;
                    lost.push(j);
                }
            }
        }
        Ok(())
    }

    /// Tells fork `j` to start the current replay epoch because fork `lost` lost its
    /// energy; false when `j` has no scene loaded (it restarted too).
    async fn replay_on(&mut self, j: usize, lost: usize) -> Result<bool> {
        let req = v1::ReplayRequest { epoch: self.epoch, lost_fork: Some(lost as u32) };
        let backoff = Backoff { deadline: self.timeout, ..Default::default() };
        let reply = retry::retry("Replay", backoff, || {
            let (mut c, req) = (self.clients[j].clone(), req.clone());
            // Not retried: an empty fork is not coming back with a shard by itself.
            async move {
                c.replay(req)
                    .await
                    .map_err(|s| if not_loaded(&s) { Status::failed_precondition(s.message()) } else { s })
            }
        })
        .await;
        match reply {
            Ok(_) => Ok(true),
            Err(s) if s.code() == Code::FailedPrecondition && s.message() == magg_proto::NOT_LOADED => Ok(false),
            Err(status) => Err(ClusterError::Call {
                doing: "starting a replay on",
                fork: self.name(j),
                status,
                hint: String::new(),
            }),
        }
    }

    /// Polls fork `i` until it answers (loading it again if it restarted, see
    /// [`ForkSet::poll`]), or the fork timeout passes.
    pub async fn poll_until_up(
        &mut self,
        i: usize,
        what: EnergyPoll,
        lrt_pending: bool,
    ) -> Result<v1::GetEnergiesReply> {
        loop {
            if let Some(r) = self.poll(i, what, lrt_pending).await? {
                return Ok(r);
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }
}
