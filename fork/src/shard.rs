//! A fork's state for one render: its place among the forks, its shard of blocks, its
//! pair queue and the energy accumulated on its elements (paper §4.3–4.4).
//!
//! Everything here is synchronous and checks its input before changing anything, so a
//! refused request leaves the state as it was. The gRPC layer ([`crate::service`]) adds
//! the peer calls (G-bus fetches, pair stealing).

use crate::bits::Bitset;
use crate::error::ForkError;
use crate::locks::{lock, read, write};
use crate::pairs::PairQueue;
use crate::peers::Peers;
use magg_core::blocks::BLOCK_SIZE;
use magg_core::energy::Fixed;
use magg_core::header::SceneHeader;
use magg_proto::auth::Token;
use magg_proto::convert::block_bytes_from_wire;
use magg_proto::v1;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, RwLock};
use std::time::{Duration, Instant};

/// Most forks a cluster may have.
pub const MAX_FORKS: usize = 4096;
/// Most block ids in one `GetBlocks` / `PeerBlocks` request.
pub const MAX_IDS_PER_REQUEST: usize = 4096;
/// Most pairs handed out by one `TakePairs` / `StealPairs`.
pub const MAX_PAIRS_PER_REQUEST: u32 = 4096;
/// Most pairs in one `Deposit` request.
pub const MAX_DEPOSIT_PAIRS: usize = 65_536;
/// Most element deposits in one `Deposit` request.
pub const MAX_DEPOSITS: usize = 1 << 20;
/// Longest fork address accepted.
pub const MAX_ADDR_LEN: usize = 256;
/// Pair lease when `LoadShard` gives none: a node silent this long is taken for dead.
pub const DEFAULT_LEASE: Duration = Duration::from_secs(30);
/// A lease lasts at least this many times the longest gap seen between two requests of a
/// node that held pairs (a live node's gap is about one batch of pairs).
pub const GAPS_PER_LEASE: u32 = 4;

/// Which fork this is, and where the others are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Placement {
    /// This fork's index.
    pub index: u32,
    /// Every fork's address, by index.
    pub addrs: Vec<String>,
}

impl Placement {
    /// Number of forks.
    pub fn forks(&self) -> u32 {
        self.addrs.len() as u32
    }
}

/// Traffic this fork has served in the current render.
#[derive(Debug, Default)]
pub struct Traffic {
    /// Block bytes sent to nodes (the DMA path).
    pub dma_bytes: AtomicU64,
    /// Block bytes fetched from other forks (the G-bus path).
    pub gbus_bytes: AtomicU64,
    /// RPCs handled.
    pub rpcs: AtomicU64,
    /// Encoded bytes of pair and deposit messages with nodes (the link path).
    pub link_bytes: AtomicU64,
}

/// Pair and energy bookkeeping, under one lock.
#[derive(Debug)]
struct Work {
    /// Unassigned pairs of this fork.
    queue: PairQueue,
    /// Pairs of this fork handed out and not yet complete, with the node they went to
    /// and when (given back to the queue when the lease expires: node failure).
    leased: HashMap<u64, (u32, Instant)>,
    /// When each node last asked this fork for pairs (refreshes all its leases).
    seen: HashMap<u32, Instant>,
    /// Longest time a node holding pairs here took to ask again: leases last at least
    /// [`GAPS_PER_LEASE`] times this, so slow (e.g. throttled) batches do not expire.
    max_gap: Duration,
    /// Leases that expired so far.
    returned: u64,
    /// Replay epoch: completions of pairs handed out in an earlier epoch do not count.
    epoch: u64,
    /// Pairs (by id) whose deposits this fork has applied (exactly-once).
    applied: Bitset,
    /// Pairs of this fork reported complete, by local index (see [`Shard::local_pair`]).
    done: Bitset,
    /// For each other fork, the complete pairs of this fork (local index) that deposited
    /// on it: the pairs to trace again if it restarts and loses its energy.
    deposited_on: Vec<Option<Bitset>>,
    /// Fixed-point flux of each owned element, parallel to `Shard::owned`.
    energy: Vec<Fixed>,
}

/// One fork's share of a render.
#[derive(Debug)]
pub struct Shard {
    header: SceneHeader,
    place: Placement,
    /// Owned blocks by local index `id / forks` (2 KB each, as received: served without
    /// a copy); `None` until supplied.
    blocks: RwLock<Vec<Option<bytes::Bytes>>>,
    /// Elements whose element block this fork holds, ascending.
    owned: Vec<u32>,
    work: Mutex<Work>,
    traffic: Traffic,
    peers: Peers,
    /// Nodes the host expects (sizes guided pair batches; 0 = unknown).
    nodes: u32,
    /// Estimated unassigned pairs of every fork (this one's entry unused): each fork's
    /// pair count at first, then what its answers to this fork's steals said. A queue
    /// only shrinks (save for replays and expired leases), so a stale estimate is high.
    left_elsewhere: Mutex<Vec<u64>>,
    /// How long a node may stay silent before its pairs go back to the queue.
    lease: Duration,
}

impl Shard {
    /// Builds the shard from a `LoadShard` request: checks the protocol version, the
    /// placement, the header and every block, then builds the pair queue. Other forks
    /// are reached with the cluster `token`.
    pub fn load(req: v1::LoadShardRequest, token: Token) -> Result<Shard, ForkError> {
        if req.protocol_version != magg_proto::PROTOCOL_VERSION {
            return Err(ForkError::ProtocolVersion { got: req.protocol_version, want: magg_proto::PROTOCOL_VERSION });
        }
        let forks = req.fork_addrs.len();
        if forks == 0 || forks > MAX_FORKS {
            return Err(ForkError::BadRequest(format!("fork_addrs has {forks} addresses, expected 1..={MAX_FORKS}")));
        }
        if let Some(a) = req.fork_addrs.iter().find(|a| a.is_empty() || a.len() > MAX_ADDR_LEN) {
            return Err(ForkError::BadRequest(format!("fork address {a:?} is empty or over {MAX_ADDR_LEN} bytes")));
        }
        if req.fork_index as usize >= forks {
            return Err(ForkError::BadRequest(format!("fork_index {} is not below {forks} forks", req.fork_index)));
        }
        let header = req.header.ok_or_else(|| ForkError::BadRequest("header is missing".into()))?;
        let header = SceneHeader::try_from(header).map_err(ForkError::BadHeader)?;
        let place = Placement { index: req.fork_index, addrs: req.fork_addrs };
        let (index, f) = (place.index, place.forks());
        let total = header.layout.total;
        let local_blocks = (total.saturating_sub(index) as usize).div_ceil(f as usize);
        let owned: Vec<u32> =
            (0..header.counts.elements).filter(|&e| header.layout.element_slot(e).0 % f == index).collect();
        let lights = header.lights.len() as u32;
        let pair_count = lights as u64 * header.counts.elements as u64;
        let own_pairs = lights as u64 * owned.len() as u64;
        let lease = if req.lease_ms == 0 { DEFAULT_LEASE } else { Duration::from_millis(req.lease_ms as u64) };
        let mut left_elsewhere = vec![0u64; forks];
        if header.plan.lrt {
            for e in 0..header.counts.elements {
                left_elsewhere[(header.layout.element_slot(e).0 % f) as usize] += lights as u64;
            }
        }
        let work = Work {
            queue: PairQueue::new(lights, owned.len(), header.plan.lrt),
            leased: HashMap::new(),
            seen: HashMap::new(),
            max_gap: Duration::ZERO,
            returned: 0,
            epoch: req.epoch,
            applied: Bitset::new(pair_count),
            done: Bitset::new(own_pairs),
            deposited_on: vec![None; forks],
            energy: vec![[0; 3]; owned.len()],
        };
        let shard = Shard {
            header,
            blocks: RwLock::new(vec![None; local_blocks]),
            owned,
            work: Mutex::new(work),
            traffic: Traffic::default(),
            peers: Peers::new(place.addrs.clone(), token),
            place,
            nodes: req.nodes,
            left_elsewhere: Mutex::new(left_elsewhere),
            lease,
        };
        shard.put_blocks(req.blocks)?;
        Ok(shard)
    }

    /// The scene header.
    pub fn header(&self) -> &SceneHeader {
        &self.header
    }

    /// This fork's place among the forks.
    pub fn placement(&self) -> &Placement {
        &self.place
    }

    /// Clients to the other forks.
    pub fn peers(&self) -> &Peers {
        &self.peers
    }

    /// Traffic counters of this render.
    pub fn traffic(&self) -> &Traffic {
        &self.traffic
    }

    /// Counts `bytes` of node <-> fork control messages (the link path).
    pub fn count_link(&self, bytes: usize) {
        self.traffic.link_bytes.fetch_add(bytes as u64, Ordering::Relaxed);
    }

    /// Elements owned by this fork, ascending.
    pub fn owned_elements(&self) -> &[u32] {
        &self.owned
    }

    /// Pairs of this fork in all.
    pub fn pairs_total(&self) -> u64 {
        lock(&self.work).queue.total()
    }

    /// The fork holding block `id`.
    pub fn block_owner(&self, id: u32) -> u32 {
        id % self.place.forks()
    }

    /// The fork owning element `e` (the one holding its element block).
    pub fn element_owner(&self, e: u32) -> u32 {
        self.block_owner(self.header.layout.element_slot(e).0)
    }

    /// Refuses ids past the scene's last block.
    pub fn check_block_id(&self, id: u32) -> Result<(), ForkError> {
        let total = self.header.layout.total;
        if id < total {
            Ok(())
        } else {
            Err(ForkError::BlockOutOfRange { id, total })
        }
    }

    /// Refuses ids out of range or owned by another fork.
    pub fn check_owned_block(&self, id: u32) -> Result<(), ForkError> {
        self.check_block_id(id)?;
        let owner = self.block_owner(id);
        if owner == self.place.index {
            Ok(())
        } else {
            Err(ForkError::BlockNotOwned { id, owner, fork: self.place.index })
        }
    }

    /// Replaces owned blocks; all are checked before any is stored. Returns how many
    /// were stored.
    pub fn put_blocks(&self, blocks: Vec<v1::Block>) -> Result<u32, ForkError> {
        let mut checked = Vec::with_capacity(blocks.len());
        for b in blocks {
            let (id, data) = block_bytes_from_wire(b).map_err(ForkError::BadBlock)?;
            self.check_owned_block(id)?;
            checked.push((id, data));
        }
        let n = checked.len() as u32;
        let f = self.place.forks();
        let mut store = write(&self.blocks);
        for (id, data) in checked {
            store[(id / f) as usize] = Some(data);
        }
        Ok(n)
    }

    /// Owned blocks supplied so far.
    pub fn stored_blocks(&self) -> u32 {
        read(&self.blocks).iter().filter(|b| b.is_some()).count() as u32
    }

    /// Owned blocks by id, in request order, ready for the wire.
    pub fn owned_blocks(&self, ids: &[u32]) -> Result<Vec<v1::Block>, ForkError> {
        for &id in ids {
            self.check_owned_block(id)?;
        }
        let f = self.place.forks();
        let store = read(&self.blocks);
        ids.iter()
            .map(|&id| match &store[(id / f) as usize] {
                Some(b) => Ok(v1::Block { id, data: b.clone() }),
                None => Err(ForkError::BlockNotLoaded { id, fork: self.place.index }),
            })
            .collect()
    }

    /// Unassigned pairs of this fork's own queue.
    pub fn pairs_left(&self) -> u64 {
        lock(&self.work).queue.remaining()
    }

    /// Estimated unassigned pairs of the other forks together.
    fn left_at_peers(&self) -> u64 {
        let me = self.place.index as usize;
        lock(&self.left_elsewhere).iter().enumerate().filter(|&(j, _)| j != me).map(|(_, &n)| n).sum()
    }

    /// Estimated unassigned pairs of the whole cluster, this fork holding `own`: the
    /// smaller of two estimates that both err high: `own` plus what the other forks last
    /// said they had (stale for a fork this one has not asked lately), and `own` times
    /// the number of forks (high while forks without a node of their own still hold all
    /// their pairs, right when every fork is drained by its own nodes).
    fn left_in_cluster(&self, own: u64) -> u64 {
        (own + self.left_at_peers()).min(own * self.place.forks() as u64)
    }

    /// Fork `fork` said it has `left` unassigned pairs.
    pub fn heard_pairs_left(&self, fork: u32, left: u64) {
        if let Some(n) = lock(&self.left_elsewhere).get_mut(fork as usize) {
            *n = left;
        }
    }

    /// The other forks in the order to ask them for pairs: most pairs left (as far as
    /// this fork knows) first, then nearest after this one (index + 1, + 2, ...).
    pub fn steal_order(&self) -> Vec<u32> {
        let (me, forks) = (self.place.index, self.place.forks());
        let left = lock(&self.left_elsewhere).clone();
        let mut order: Vec<u32> = (1..forks).map(|k| (me + k) % forks).collect();
        order.sort_by_key(|&j| std::cmp::Reverse(left.get(j as usize).copied().unwrap_or(0)));
        order
    }

    /// How many pairs to ask a peer for on behalf of a node that asked for `max`: the
    /// guided batch of the pairs left in the cluster, as this fork knows them.
    pub fn steal_batch(&self, max: u32) -> u32 {
        let max = max.clamp(1, MAX_PAIRS_PER_REQUEST);
        // This fork's queue is empty when it steals: what the others said is all it has.
        crate::pairs::guided_batch(max, self.pairs_left() + self.left_at_peers(), self.nodes)
    }

    /// Takes up to `max` unassigned pairs of this fork's own queue for `node` (first
    /// giving back the pairs of nodes whose lease expired), and renews `node`'s leases.
    /// Returns the pairs and the replay epoch they are handed out in.
    pub fn take_own_pairs(&self, max: u32, node: u32) -> (Vec<u64>, u64) {
        let max = max.clamp(1, MAX_PAIRS_PER_REQUEST);
        let now = Instant::now();
        let mut work = lock(&self.work);
        if let Some(last) = work.seen.insert(node, now) {
            if work.leased.values().any(|l| l.0 == node) {
                let gap = now.saturating_duration_since(last);
                work.max_gap = work.max_gap.max(gap);
            }
        }
        self.reclaim_expired(&mut work, now);
        let max = crate::pairs::guided_batch(max, self.left_in_cluster(work.queue.remaining()), self.nodes) as usize;
        let mut pairs = Vec::new();
        while pairs.len() < max {
            let got = work.queue.pop(max - pairs.len(), &self.owned, self.header.counts.elements);
            if got.is_empty() {
                break;
            }
            // A given-back pair may have been completed since by its first (slow) node.
            pairs.extend(got.into_iter().filter(|&p| self.local_pair(p).is_ok_and(|k| !work.done.contains(k))));
        }
        for &p in &pairs {
            work.leased.insert(p, (node, now));
        }
        (pairs, work.epoch)
    }

    /// Starts replay epoch `epoch` because fork `lost` restarted and lost the energy on
    /// its elements (`None`: unknown, replay everything). Goes back to the queue: every
    /// pair still out with a node (its completion, from the old epoch, will not count) and
    /// every complete pair that deposited on `lost`; the others stay done. Deposits already
    /// applied here stay (the re-run ones are duplicates). Returns the pairs queued again.
    /// An epoch not above the current one changes nothing (a repeated call).
    pub fn replay(&self, epoch: u64, lost: Option<u32>) -> u64 {
        let mut work = lock(&self.work);
        if epoch <= work.epoch {
            return 0;
        }
        work.epoch = epoch;
        let before = work.queue.remaining();
        let w = &mut *work;
        let again: Vec<u64> = match lost.and_then(|j| w.deposited_on.get(j as usize)) {
            Some(Some(on_lost)) => on_lost.iter().collect(),
            Some(None) => Vec::new(),
            None => w.done.iter().collect(),
        };
        for k in again {
            w.done.remove(k);
            w.queue.give_back(self.pair_of_local(k));
        }
        for (p, _) in w.leased.drain() {
            w.queue.give_back(p);
        }
        if let Some(Some(on_lost)) = lost.and_then(|j| w.deposited_on.get_mut(j as usize)) {
            *on_lost = Bitset::new(0);
        }
        let queued = work.queue.remaining() - before;
        tracing::warn!(
            fork = self.place.index,
            epoch,
            ?lost,
            pairs = queued,
            "replay: pairs that deposited on the lost fork, or were out with nodes, queued again"
        );
        queued
    }

    /// Gives back to the queue the pairs of every node silent for longer than the lease
    /// (or [`GAPS_PER_LEASE`] times the longest gap of a live node, if longer).
    fn reclaim_expired(&self, work: &mut Work, now: Instant) {
        let lease = self.lease.max(work.max_gap * GAPS_PER_LEASE);
        let seen = &work.seen;
        let expired: Vec<u64> = work
            .leased
            .iter()
            .filter(|(_, &(node, at))| {
                let last = seen.get(&node).map_or(at, |&s| s.max(at));
                now.saturating_duration_since(last) > lease
            })
            .map(|(&p, _)| p)
            .collect();
        if expired.is_empty() {
            return;
        }
        let mut nodes: Vec<u32> = expired.iter().filter_map(|p| work.leased.get(p).map(|l| l.0)).collect();
        nodes.sort_unstable();
        nodes.dedup();
        for p in &expired {
            work.leased.remove(p);
            work.queue.give_back(*p);
        }
        work.returned += expired.len() as u64;
        tracing::warn!(
            fork = self.place.index,
            pairs = expired.len(),
            ?nodes,
            "pair leases expired (node silent for over {:?}): pairs back on the queue",
            lease
        );
    }

    /// The id range of pairs: `lights * elements`.
    pub fn pair_count(&self) -> u64 {
        self.header.lights.len() as u64 * self.header.counts.elements as u64
    }

    /// Refuses a pair id out of range or whose element another fork owns.
    pub fn check_own_pair(&self, pair: u64) -> Result<(), ForkError> {
        self.local_pair(pair).map(|_| ())
    }

    /// Index of own pair `pair` in this fork's sequence (`light * owned + position of the
    /// element among the owned ones`), or why it is not one of this fork's pairs.
    pub fn local_pair(&self, pair: u64) -> Result<u64, ForkError> {
        let pairs = self.pair_count();
        if pair >= pairs {
            return Err(ForkError::PairOutOfRange { pair, pairs });
        }
        let elements = self.header.counts.elements as u64;
        let at = self.owned_index((pair % elements) as u32)?;
        Ok(pair / elements * self.owned.len() as u64 + at as u64)
    }

    /// The pair id of local index `k` (inverse of [`Shard::local_pair`]).
    fn pair_of_local(&self, k: u64) -> u64 {
        let per_light = self.owned.len().max(1) as u64;
        magg_core::lrt::pair_id(
            (k / per_light) as u32,
            self.owned[(k % per_light) as usize],
            self.header.counts.elements,
        )
    }

    /// Position of element `e` in the owned list, or why it is not there.
    fn owned_index(&self, element: u32) -> Result<usize, ForkError> {
        let elements = self.header.counts.elements;
        if element >= elements {
            return Err(ForkError::ElementOutOfRange { element, elements });
        }
        self.owned.binary_search(&element).map_err(|_| ForkError::ElementNotOwned {
            element,
            owner: self.element_owner(element),
            fork: self.place.index,
        })
    }

    /// Applies a batch's deposits (see [`magg_proto::deposits`]) exactly once per pair
    /// id; returns (applied, duplicates). The whole request is checked before anything
    /// is applied.
    pub fn deposit(&self, req: &v1::DepositRequest) -> Result<(u32, u32), ForkError> {
        if req.pairs.len() > MAX_DEPOSIT_PAIRS {
            return Err(ForkError::TooMany {
                what: "pairs in a deposit",
                got: req.pairs.len() as u64,
                max: MAX_DEPOSIT_PAIRS as u64,
            });
        }
        if req.elements.len() > MAX_DEPOSITS {
            return Err(ForkError::TooMany {
                what: "element deposits in a request",
                got: req.elements.len() as u64,
                max: MAX_DEPOSITS as u64,
            });
        }
        let pairs = magg_proto::deposits::read(req).map_err(|e| ForkError::BadRequest(e.to_string()))?;
        let total_pairs = self.pair_count();
        let forks = self.place.forks();
        let mut slots = Vec::with_capacity(req.elements.len());
        let mut local = Vec::with_capacity(if req.complete { req.pairs.len() } else { 0 });
        for p in pairs.clone() {
            if p.pair >= total_pairs {
                return Err(ForkError::PairOutOfRange { pair: p.pair, pairs: total_pairs });
            }
            if req.complete {
                local.push(self.local_pair(p.pair)?);
            }
            if let Some(&j) = p.also_on.iter().find(|&&j| j >= forks || j == self.place.index) {
                return Err(ForkError::BadRequest(format!(
                    "pair {} deposited on fork {j}: not another of the {forks} forks",
                    p.pair
                )));
            }
            for &e in p.elements {
                slots.push(self.owned_index(e)?);
            }
        }
        let (mut applied, mut duplicates) = (0, 0);
        let mut slots = slots.into_iter();
        let mut work = lock(&self.work);
        let own_pairs = self.header.lights.len() as u64 * self.owned.len() as u64;
        let counts_done = req.complete && req.epoch == work.epoch;
        for (k, p) in pairs.enumerate() {
            let fresh = work.applied.insert(p.pair);
            for (d, slot) in p.energy.chunks_exact(3).zip(slots.by_ref()) {
                if fresh {
                    let e = &mut work.energy[slot];
                    e[0] = e[0].wrapping_add(d[0]);
                    e[1] = e[1].wrapping_add(d[1]);
                    e[2] = e[2].wrapping_add(d[2]);
                }
            }
            if fresh {
                applied += 1;
            } else {
                duplicates += 1;
            }
            if let (Some(&k), true) = (local.get(k), counts_done) {
                work.done.insert(k);
                work.leased.remove(&p.pair);
                for &j in p.also_on {
                    work.deposited_on[j as usize].get_or_insert_with(|| Bitset::new(own_pairs)).insert(k);
                }
            }
        }
        Ok((applied, duplicates))
    }

    /// Energies of every owned element (ascending id; none when `summary_only`), pair
    /// progress, and the traffic counters of [`Shard::traffic`].
    pub fn energies(&self, summary_only: bool) -> v1::GetEnergiesReply {
        let mut work = lock(&self.work);
        self.reclaim_expired(&mut work, Instant::now());
        let (elements, energy) = if summary_only {
            (Vec::new(), Vec::new())
        } else {
            (self.owned.clone(), work.energy.iter().flatten().copied().collect())
        };
        v1::GetEnergiesReply {
            elements,
            energy,
            pairs_total: work.queue.total(),
            pairs_done: work.done.len() as u64,
            dma_bytes: self.traffic.dma_bytes.load(Ordering::Relaxed),
            gbus_bytes: self.traffic.gbus_bytes.load(Ordering::Relaxed),
            rpcs: self.traffic.rpcs.load(Ordering::Relaxed),
            link_bytes: self.traffic.link_bytes.load(Ordering::Relaxed),
            pairs_returned: work.returned,
            ..Default::default()
        }
    }

    /// Counts one RPC handled.
    pub fn count_rpc(&self) {
        self.traffic.rpcs.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts `blocks` blocks sent to a node.
    pub fn count_dma(&self, blocks: usize) {
        self.traffic.dma_bytes.fetch_add((blocks * BLOCK_SIZE) as u64, Ordering::Relaxed);
    }

    /// Counts `blocks` blocks fetched from other forks.
    pub fn count_gbus(&self, blocks: usize) {
        self.traffic.gbus_bytes.fetch_add((blocks * BLOCK_SIZE) as u64, Ordering::Relaxed);
    }
}
