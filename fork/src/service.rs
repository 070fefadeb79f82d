//! The `Fork` gRPC service (paper §4.2–4.4): shard loading, block serving over the DMA
//! and G-bus paths, pair hand-out with stealing, exactly-once energy deposits.
//!
//! Each handler takes the current [`Shard`] (an `Arc`, so a concurrent `LoadShard` never
//! pulls state from under a running request), converts the request to the domain values
//! of [`magg_core::cluster`] (with the `From`/`TryFrom` of [`magg_proto::convert`]; a
//! batch of deposits is borrowed from the request, not copied), does its checks, and
//! maps every [`ForkError`] to a `Status` through the one mapping in [`crate::error`].
//! This is the only module of the fork's state that sees protobuf types; the peer
//! client ([`crate::peers`]) is the other.

use crate::error::ForkError;
use crate::hardware::ForkHardware;
use crate::locks::{read, write};
use crate::peers::PeerAccess;
use crate::shard::{Shard, MAX_IDS_PER_REQUEST, MAX_PAIRS_PER_REQUEST};
use bytes::Bytes;
use magg_core::cluster::{PairLease, ShardLoad};
use magg_core::pair::Pair;
use magg_plumbing::auth::Token;
use magg_plumbing::transport::InProcess;
use magg_proto::convert::block_bytes_from_wire;
use magg_proto::deposits::{self, Deposits};
use magg_proto::v1;
use magg_proto::v1::fork_server::Fork;
use magg_throttle::Profile;
use std::collections::BTreeMap;
use std::sync::{Arc, RwLock};
use tonic::{Request, Response, Status};

/// A fork process's service: the shard of the current render, if one is loaded, and
/// the fork's emulated hardware (throttling layer).
#[derive(Debug)]
pub struct ForkService {
    shard: RwLock<Option<Arc<Shard>>>,
    /// The shares of the scene this fork prepares (see [`crate::prepare`]).
    preparing: Arc<std::sync::Mutex<magg_prepare::shares::steps::Serving>>,
    hw: Arc<ForkHardware>,
    access: PeerAccess,
    /// Memory a shard's pair bookkeeping may take, in MiB.
    max_memory_mb: u64,
    /// A wait before each preparation step (tests only).
    slow_step: std::time::Duration,
}

impl Default for ForkService {
    fn default() -> ForkService {
        ForkService {
            shard: RwLock::default(),
            preparing: Arc::default(),
            hw: Arc::default(),
            access: PeerAccess::default(),
            max_memory_mb: crate::shard::DEFAULT_MAX_MEMORY_MB,
            slow_step: std::time::Duration::ZERO,
        }
    }
}

impl ForkService {
    /// A fork with no scene loaded and no cluster token.
    pub fn new() -> ForkService {
        ForkService::default()
    }

    /// A fork with no scene loaded that reaches the other forks with `token`.
    pub fn with_token(token: Token) -> ForkService {
        ForkService { access: PeerAccess::with_token(token), ..ForkService::default() }
    }

    /// The same fork reaching the forks of this process in `links` without sockets.
    pub fn with_links(mut self, links: InProcess) -> ForkService {
        self.access.links = links;
        self
    }

    /// The same fork on the given hardware (forks of one process share one G-bus this
    /// way).
    pub fn on_hardware(mut self, hw: ForkHardware) -> ForkService {
        self.hw = Arc::new(hw);
        self
    }

    /// The same fork refusing a `LoadShard` whose pair bookkeeping would take more than
    /// `mb` MiB (`RESOURCE_EXHAUSTED`, with the estimate).
    pub fn with_memory_limit(mut self, mb: u64) -> ForkService {
        self.max_memory_mb = mb;
        self
    }

    /// The same fork waiting `wait` before each preparation step (tests strike a fork in
    /// the middle of preparation with it).
    pub fn with_slow_steps(mut self, wait: std::time::Duration) -> ForkService {
        self.slow_step = wait;
        self
    }

    /// The loaded shard, counting the RPC against it.
    fn shard(&self) -> Result<Arc<Shard>, ForkError> {
        let shard = read(&self.shard).clone().ok_or(ForkError::NotLoaded)?;
        shard.count_rpc();
        Ok(shard)
    }

    /// The loaded shard, if any (for an embedding process that wants to inspect it).
    pub fn current(&self) -> Option<Arc<Shard>> {
        read(&self.shard).clone()
    }
}

/// Longest single G-bus booking accepted (a whole shard at 1 KB/s would be far less).
const MAX_GBUS_BOOKING: std::time::Duration = std::time::Duration::from_secs(60);

fn too_many(what: &'static str, got: usize, max: usize) -> ForkError {
    ForkError::TooMany { what, got: got as u64, max: max as u64 }
}

/// A shard from a `LoadShard` request: the protocol version checked first, then the
/// request converted (header, 2 KB blocks) and the shard built (placement, ownership).
/// Its pair bookkeeping must fit in `max_mb` MiB.
pub fn load_shard(req: v1::LoadShardRequest, access: PeerAccess, max_mb: u64) -> Result<Shard, ForkError> {
    if req.protocol_version != magg_proto::PROTOCOL_VERSION {
        return Err(ForkError::ProtocolVersion { got: req.protocol_version, want: magg_proto::PROTOCOL_VERSION });
    }
    Shard::load_within(ShardLoad::try_from(req)?, access, max_mb)
}

/// `req` with the blocks its host shared in this process (`shared_blocks`, the
/// in-process harness) put back in: this fork's own (id mod forks = its index) first,
/// then the request's, which replace them. A key this process does not share (a fork of
/// a process of its own, or a host gone) is refused.
pub fn with_shared_blocks(
    mut req: v1::LoadShardRequest,
    links: &magg_plumbing::transport::InProcess,
) -> Result<v1::LoadShardRequest, ForkError> {
    if req.shared_blocks == 0 {
        return Ok(req);
    }
    let key = req.shared_blocks;
    let all = links.shared(key).and_then(|v| v.downcast::<Vec<v1::Block>>().ok()).ok_or_else(|| {
        ForkError::BadRequest(format!("shared blocks {key} are not in this fork's process: send the blocks"))
    })?;
    let (index, forks) = (req.fork_index as usize, req.fork_addrs.len());
    if forks == 0 || index >= forks {
        return Err(ForkError::BadRequest(format!("fork index {index} among {forks} forks")));
    }
    let own = all.iter().skip(index).step_by(forks).cloned();
    req.blocks = own.chain(std::mem::take(&mut req.blocks)).collect();
    req.shared_blocks = 0;
    Ok(req)
}

/// Blocks from the wire, each checked to be 2 KB (kept as received, no copy).
pub fn blocks_from_wire(blocks: Vec<v1::Block>) -> Result<Vec<(u32, Bytes)>, ForkError> {
    Ok(blocks.into_iter().map(block_bytes_from_wire).collect::<Result<_, _>>()?)
}

/// A `Deposit` request's packed arrays, decoded and checked to fit together.
pub fn read_deposits(req: &v1::DepositRequest) -> Result<Deposits<'_>, ForkError> {
    deposits::read(req).map_err(|e| ForkError::BadRequest(e.to_string()))
}

/// Applies a `Deposit` request's pairs; returns (applied, duplicates).
pub fn deposit(shard: &Shard, req: &v1::DepositRequest) -> Result<(u32, u32), ForkError> {
    shard.deposit(read_deposits(req)?.batch())
}

/// `GetBlocks`: owned blocks from memory, the others from their forks (one
/// `PeerBlocks` per owner over the G-bus, concurrently), in request order; the reply
/// goes to the node through the DMA engine. The peer calls run concurrently within this
/// call's task rather than as spawned tasks: a fork of the same process then answers on
/// the calling thread, with no hand-over to a runtime thread and back (which cost up to
/// a few milliseconds of wake-ups per light pass on a loaded machine).
async fn get_blocks(shard: Arc<Shard>, hw: Arc<ForkHardware>, ids: Vec<u32>) -> Result<Vec<v1::Block>, ForkError> {
    if ids.len() > MAX_IDS_PER_REQUEST {
        return Err(too_many("block ids in a request", ids.len(), MAX_IDS_PER_REQUEST));
    }
    for &id in &ids {
        shard.check_block_id(id)?;
    }
    let me = shard.placement().index;
    let mut out: Vec<Option<v1::Block>> = vec![None; ids.len()];
    let mut remote: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    let mut local = Vec::new();
    for (pos, &id) in ids.iter().enumerate() {
        match shard.block_owner(id) {
            owner if owner == me => local.push(pos),
            owner => remote.entry(owner).or_default().push(pos),
        }
    }
    let local_ids: Vec<u32> = local.iter().map(|&p| ids[p]).collect();
    for (pos, b) in local.into_iter().zip(shard.owned_blocks(&local_ids)?) {
        out[pos] = Some(v1::Block::from(b));
    }
    let calls = remote.into_iter().map(|(owner, positions)| {
        let (shard, hw) = (&shard, &hw);
        let wanted: Vec<u32> = positions.iter().map(|&p| ids[p]).collect();
        async move {
            hw.gbus(me, shard.peers(), wanted.len() * magg_core::blocks::BLOCK_SIZE).await;
            (positions, shard.peers().blocks(owner, wanted).await)
        }
    });
    let mut fetched = 0;
    for (positions, blocks) in futures_util::future::join_all(calls).await {
        let blocks = blocks?;
        fetched += blocks.len();
        for (pos, b) in positions.into_iter().zip(blocks) {
            out[pos] = Some(b);
        }
    }
    let blocks: Vec<v1::Block> = out.into_iter().flatten().collect();
    shard.count_gbus(fetched);
    shard.count_dma(blocks.len());
    hw.dma(blocks.len() * magg_core::blocks::BLOCK_SIZE).await;
    Ok(blocks)
}

/// `TakePairs`: the fork's own queue first; when it is empty, the other forks in turn
/// (index+1, index+2, ...) are asked to give some away (paper §4.4).
async fn take_pairs(
    shard: Arc<Shard>,
    hw: &ForkHardware,
    max: u32,
    node: u32,
    secret: u64,
) -> Result<PairLease, ForkError> {
    shard.admit(node, secret)?;
    let max = max.clamp(1, MAX_PAIRS_PER_REQUEST);
    let (pairs, epoch) = shard.take_own_pairs(max, node);
    if !pairs.is_empty() {
        return Ok(PairLease { pairs, exhausted: false, epoch, remaining: shard.pairs_left() });
    }
    let me = shard.placement().index;
    let ask = shard.steal_batch(max);
    let mut failure = None;
    for peer in shard.steal_order() {
        let stolen = shard.peers().steal(peer, ask, node, secret).await;
        // A request and a reply of pair ids cross the G-bus.
        hw.gbus(me, shard.peers(), 16 + 8 * stolen.as_ref().map_or(0, |r| r.pairs.len())).await;
        if let Ok(r) = &stolen {
            shard.heard_pairs_left(peer, r.remaining);
        }
        match stolen {
            Ok(r) if r.pairs.is_empty() => {}
            Ok(PairLease { pairs, epoch, .. }) => {
                check_stolen(&shard, peer, &pairs)?;
                tracing::debug!(fork = me, from = peer, pairs = pairs.len(), "stole pairs");
                return Ok(PairLease { pairs, exhausted: false, epoch, remaining: 0 });
            }
            Err(e) => {
                tracing::warn!(fork = me, peer, "pair stealing failed: {e}");
                failure.get_or_insert(e);
            }
        }
    }
    // A fork that could not be asked may still hold pairs: not exhausted.
    match failure {
        Some(e) => Err(e),
        None => Ok(PairLease { pairs: Vec::new(), exhausted: true, epoch: 0, remaining: 0 }),
    }
}

/// A node's take, alone or riding on a completion: [`take_pairs`], or with `own_only`
/// this fork's own pairs only ([`own_pairs`]), the G-bus booked as for the steal by the
/// node's home fork that it replaces.
async fn take(shard: Arc<Shard>, hw: &ForkHardware, t: &v1::TakePairsRequest) -> Result<PairLease, ForkError> {
    if !t.own_only {
        return take_pairs(shard, hw, t.max, t.node, t.node_secret).await;
    }
    let lease = own_pairs(&shard, t)?;
    hw.gbus(shard.placement().index, shard.peers(), 16 + 8 * lease.pairs.len()).await;
    Ok(lease)
}

/// Up to `t.max` of this fork's own unassigned pairs for node `t.node` (a `StealPairs`,
/// or a take with `own_only`); `exhausted` says that this fork has none left.
fn own_pairs(shard: &Shard, t: &v1::TakePairsRequest) -> Result<PairLease, ForkError> {
    shard.admit(t.node, t.node_secret)?;
    let (pairs, epoch) = shard.take_own_pairs(t.max, t.node);
    Ok(PairLease { exhausted: pairs.is_empty(), pairs, epoch, remaining: shard.pairs_left() })
}

/// Stolen pairs must be real pairs of the fork they came from.
fn check_stolen(shard: &Shard, peer: u32, pairs: &[u64]) -> Result<(), ForkError> {
    let elements = shard.header().counts.elements.max(1);
    for &p in pairs {
        if p >= shard.pair_count() || shard.element_owner(Pair::element_of(p, elements)) != peer {
            let addr = shard.peers().addr(peer).to_string();
            return Err(ForkError::PeerReply { fork: peer, addr, detail: format!("pair {p} is not one of its pairs") });
        }
    }
    Ok(())
}

#[tonic::async_trait]
impl Fork for ForkService {
    async fn load_shard(&self, req: Request<v1::LoadShardRequest>) -> Result<Response<v1::LoadShardReply>, Status> {
        let req = with_shared_blocks(req.into_inner(), &self.access.links)?;
        // (The request as it would have come with every block in it: the G-bus carries
        // the same bytes either way.)
        let bytes = prost::Message::encoded_len(&req);
        let profile = if req.profile.is_empty() {
            None
        } else {
            Some(Profile::from_wire(&req.profile).map_err(|e| ForkError::BadRequest(e.to_string()))?)
        };
        self.hw.check_profile(profile.as_ref())?;
        let shard = load_shard(req, self.access.clone(), self.max_memory_mb)?;
        shard.count_rpc();
        self.hw.set_profile(profile);
        // The host's upload crosses the G-bus.
        self.hw.gbus(shard.placement().index, shard.peers(), bytes).await;
        let (blocks, pairs) = (shard.stored_blocks(), shard.pairs_total());
        let place = shard.placement();
        tracing::info!(
            fork = place.index,
            forks = place.forks(),
            blocks,
            pairs,
            elements = shard.owned_elements().len(),
            "shard loaded"
        );
        *write(&self.shard) = Some(Arc::new(shard));
        Ok(Response::new(v1::LoadShardReply { blocks, pairs }))
    }

    async fn put_blocks(&self, req: Request<v1::PutBlocksRequest>) -> Result<Response<v1::PutBlocksReply>, Status> {
        let shard = self.shard()?;
        self.hw.serve(0).await;
        let req = req.into_inner();
        self.hw.gbus(shard.placement().index, shard.peers(), prost::Message::encoded_len(&req)).await;
        let stored = shard.put_blocks(blocks_from_wire(req.blocks)?)?;
        Ok(Response::new(v1::PutBlocksReply { stored }))
    }

    async fn get_blocks(&self, req: Request<v1::GetBlocksRequest>) -> Result<Response<v1::GetBlocksReply>, Status> {
        let shard = self.shard()?;
        self.hw.serve(0).await;
        let blocks = get_blocks(shard, self.hw.clone(), req.into_inner().ids).await?;
        Ok(Response::new(v1::GetBlocksReply { blocks }))
    }

    async fn peer_blocks(&self, req: Request<v1::GetBlocksRequest>) -> Result<Response<v1::GetBlocksReply>, Status> {
        let shard = self.shard()?;
        self.hw.serve(0).await;
        let ids = req.into_inner().ids;
        if ids.len() > MAX_IDS_PER_REQUEST {
            return Err(too_many("block ids in a request", ids.len(), MAX_IDS_PER_REQUEST).into());
        }
        let blocks = shard.owned_blocks(&ids)?.into_iter().map(v1::Block::from).collect();
        Ok(Response::new(v1::GetBlocksReply { blocks }))
    }

    async fn take_pairs(&self, req: Request<v1::TakePairsRequest>) -> Result<Response<v1::TakePairsReply>, Status> {
        let shard = self.shard()?;
        self.hw.serve(0).await;
        let r = req.into_inner();
        let reply = v1::TakePairsReply::from(take(shard.clone(), &self.hw, &r).await?);
        shard.count_link(prost::Message::encoded_len(&r) + prost::Message::encoded_len(&reply));
        Ok(Response::new(reply))
    }

    async fn steal_pairs(&self, req: Request<v1::TakePairsRequest>) -> Result<Response<v1::TakePairsReply>, Status> {
        let shard = self.shard()?;
        self.hw.serve(0).await;
        Ok(Response::new(own_pairs(&shard, &req.into_inner())?.into()))
    }

    async fn deposit(&self, req: Request<v1::DepositRequest>) -> Result<Response<v1::DepositReply>, Status> {
        let shard = self.shard()?;
        let r = req.into_inner();
        let arrays = read_deposits(&r)?;
        self.hw.serve(arrays.deposits()).await;
        let (applied, duplicates) = shard.deposit(arrays.batch())?;
        // The node's next batch, asked for in the same call.
        let taken = match &r.take {
            Some(t) => {
                self.hw.serve(0).await;
                Some(take(shard.clone(), &self.hw, t).await?.into())
            }
            None => None,
        };
        let reply = v1::DepositReply { applied, duplicates, taken };
        shard.count_link(prost::Message::encoded_len(&r) + prost::Message::encoded_len(&reply));
        Ok(Response::new(reply))
    }

    async fn prepare(&self, req: Request<v1::PrepareRequest>) -> Result<Response<v1::PrepareReply>, Status> {
        if !self.slow_step.is_zero() {
            tokio::time::sleep(self.slow_step).await;
        }
        let payload = crate::prepare::step(self.preparing.clone(), req.into_inner()).await?;
        Ok(Response::new(v1::PrepareReply { payload }))
    }

    async fn replay(&self, req: Request<v1::ReplayRequest>) -> Result<Response<v1::ReplayReply>, Status> {
        let shard = self.shard()?;
        let r = req.into_inner();
        Ok(Response::new(v1::ReplayReply { pairs: shard.replay(r.epoch, r.lost_fork)? }))
    }

    async fn get_energies(
        &self,
        req: Request<v1::GetEnergiesRequest>,
    ) -> Result<Response<v1::GetEnergiesReply>, Status> {
        let shard = self.shard()?;
        let r = req.into_inner();
        let mut reply = v1::GetEnergiesReply::from(shard.energies(r.summary_only));
        // The energies go back to the host over the G-bus. The host's progress polls
        // (summaries) and a watcher's snapshots are our monitoring, not the paper's
        // protocol: they cost nothing.
        if !r.summary_only && !r.monitor {
            self.hw.serve(0).await;
            self.hw.gbus(shard.placement().index, shard.peers(), prost::Message::encoded_len(&reply)).await;
        }
        (reply.service_busy_s, reply.dma_busy_s, reply.gbus_busy_s) = self.hw.busy_s();
        reply.peak_rss_bytes = magg_plumbing::memory::peak_rss_bytes().unwrap_or(0);
        Ok(Response::new(reply))
    }

    async fn reserve_gbus(
        &self,
        req: Request<v1::ReserveGbusRequest>,
    ) -> Result<Response<v1::ReserveGbusReply>, Status> {
        let cost_ns = req.into_inner().cost_ns;
        if cost_ns > MAX_GBUS_BOOKING.as_nanos() as u64 {
            return Err(ForkError::BadRequest(format!(
                "cost_ns {cost_ns}: a G-bus booking is at most {} s",
                MAX_GBUS_BOOKING.as_secs()
            ))
            .into());
        }
        let wait = self.hw.reserve_gbus(std::time::Duration::from_nanos(cost_ns));
        Ok(Response::new(v1::ReserveGbusReply { wait_ns: wait.as_nanos() as u64 }))
    }
}
