//! A fork's state for one render: its place among the forks, its shard of blocks, its
//! pair queue and the energy accumulated on its elements (paper §4.3–4.4).
//!
//! Everything here is synchronous, works on domain values ([`magg_core::cluster`]) and
//! checks its input before changing anything, so a refused request leaves the state as
//! it was. The jobs are done by the [`crate::state`] modules (block store, pair book,
//! ledger); this puts them together under the fork's placement. The gRPC layer
//! ([`crate::service`]) converts the messages and adds the peer calls (G-bus fetches,
//! pair stealing).

use crate::error::ForkError;
use crate::locks::lock;
use crate::peers::{PeerAccess, Peers};
use crate::state::ledger::Ledger;
use crate::state::pairs::{guided_batch, PairBook, PairQueue};
use crate::state::store::BlockStore;
use bytes::Bytes;
use magg_core::blocks::{fork_of_block, BLOCK_SIZE};
use magg_core::cluster::{DepositBatch, ForkReport, PairDeposit, ShardLoad};
use magg_core::header::SceneHeader;
use magg_core::pair::Pair;
use magg_plumbing::auth::NodeKey;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

pub use crate::state::pairs::GAPS_PER_LEASE;

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
/// Largest step of the replay epoch one `Replay` may take (epochs grow by one per lost
/// fork and rebuild).
pub const MAX_EPOCH_STEP: u64 = 1 << 16;
/// Memory a fork may give one shard's pair bookkeeping unless told otherwise
/// (`magg-fork --max-memory-mb`).
pub const DEFAULT_MAX_MEMORY_MB: u64 = 4096;

/// Bytes of a shard's pair bookkeeping at most, allocated at `LoadShard` or as the pass
/// goes: one bit per pair of the scene (deposits applied), and one bit per own pair for
/// the complete ones and for each other fork they may deposit on. The host's memory
/// estimate charges the same.
pub fn pair_state_bytes(pairs: u64, own_pairs: u64, forks: u64) -> u64 {
    pairs.div_ceil(8).saturating_add(own_pairs.div_ceil(8).saturating_mul(forks.max(1)))
}

/// Pair lease when `LoadShard` gives none: a node silent this long is taken for dead.
pub const DEFAULT_LEASE: Duration = Duration::from_secs(30);

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
    /// Unassigned pairs of this fork and those lent to nodes.
    pairs: PairBook,
    /// Applied deposits, complete pairs, element energy.
    ledger: Ledger,
}

/// One fork's share of a render.
#[derive(Debug)]
pub struct Shard {
    header: SceneHeader,
    place: Placement,
    /// Owned blocks (2 KB each, as received: served without a copy).
    store: BlockStore,
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
    /// Per light, the most fixed-point energy (r, g, b) one pair of it may deposit.
    flux_bound: Vec<[i128; 3]>,
    /// The render's node key: pairs go only to a node that shows its secret.
    node_key: NodeKey,
}

/// The most fixed-point energy per channel that one pair of each light source may
/// deposit in all: for a point light its whole flux, 4 pi I, for an emitting element
/// twice its power (what its rays can carry at most, `magg_core::lrt`'s area lights),
/// once for the first hit and once for each bounce after it (every surface reflects at
/// most what reaches it), plus a quantum of rounding for every ray at every bounce. A
/// node that deposits more is not tracing this scene.
fn flux_bounds(header: &SceneHeader) -> Vec<[i128; 3]> {
    let s = &header.settings;
    let hits = 1.0 + s.lrt_depth as f64 + s.diffuse_bounces as f64;
    let rounding = s.light_rays as f64 * (hits + 1.0);
    let q = header.energy_quantum;
    let bound = |flux: [f64; 3]| flux.map(|f| (f * hits / q + rounding).ceil().min(1e36) as i128);
    let points = header.lights.iter().map(|l| bound(l.intensity.0.map(|i| 4.0 * std::f64::consts::PI * i)));
    points.chain(header.emitters.iter().map(|e| bound(e.power.0.map(|p| 2.0 * p)))).collect()
}

impl Shard {
    /// Builds the shard of a render within [`DEFAULT_MAX_MEMORY_MB`] (see
    /// [`Shard::load_within`]).
    pub fn load(load: ShardLoad<Bytes>, access: PeerAccess) -> Result<Shard, ForkError> {
        Shard::load_within(load, access, DEFAULT_MAX_MEMORY_MB)
    }

    /// Builds the shard of a render: checks the placement, that its pair bookkeeping
    /// ([`pair_state_bytes`]) fits in `max_mb` MiB, and every block, then builds the pair
    /// queue. Other forks are reached as `access` says.
    pub fn load_within(load: ShardLoad<Bytes>, access: PeerAccess, max_mb: u64) -> Result<Shard, ForkError> {
        let forks = load.fork_addrs.len();
        if forks == 0 || forks > MAX_FORKS {
            return Err(ForkError::BadRequest(format!("fork_addrs has {forks} addresses, expected 1..={MAX_FORKS}")));
        }
        if let Some(a) = load.fork_addrs.iter().find(|a| a.is_empty() || a.len() > MAX_ADDR_LEN) {
            return Err(ForkError::BadRequest(format!("fork address {a:?} is empty or over {MAX_ADDR_LEN} bytes")));
        }
        if load.fork_index as usize >= forks {
            return Err(ForkError::BadRequest(format!("fork_index {} is not below {forks} forks", load.fork_index)));
        }
        let header = load.header;
        let place = Placement { index: load.fork_index, addrs: load.fork_addrs };
        let (index, f) = (place.index, place.forks());
        let owned: Vec<u32> = (0..header.counts.elements)
            .filter(|&e| fork_of_block(header.layout.element_slot(e).0, f) == index)
            .collect();
        let lights = header.light_sources();
        let pair_count = header.pair_count();
        let own_pairs = lights as u64 * owned.len() as u64;
        let need = pair_state_bytes(pair_count, own_pairs, forks as u64);
        if need > max_mb.saturating_mul(1 << 20) {
            return Err(ForkError::OverMemory {
                need,
                pairs: pair_count,
                lights: lights as u64,
                elements: header.counts.elements as u64,
                limit_mb: max_mb,
            });
        }
        let mut left_elsewhere = vec![0u64; forks];
        if header.plan.lrt {
            for e in 0..header.counts.elements {
                left_elsewhere[fork_of_block(header.layout.element_slot(e).0, f) as usize] += lights as u64;
            }
        }
        let work = Work {
            pairs: PairBook::new(PairQueue::new(lights, owned.len(), header.plan.lrt)),
            ledger: Ledger::new(index as usize, pair_count, own_pairs, forks, owned.len(), load.epoch),
        };
        let flux_bound = flux_bounds(&header);
        let shard = Shard {
            node_key: NodeKey::from_bytes(&load.node_key),
            flux_bound,
            store: BlockStore::new(index, f, header.layout.total),
            header,
            owned,
            work: Mutex::new(work),
            traffic: Traffic::default(),
            peers: Peers::new(place.addrs.clone(), access),
            place,
            nodes: load.nodes,
            left_elsewhere: Mutex::new(left_elsewhere),
            lease: load.lease.unwrap_or(DEFAULT_LEASE),
        };
        shard.put_blocks(load.blocks)?;
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
        lock(&self.work).pairs.total()
    }

    /// The fork holding block `id`.
    pub fn block_owner(&self, id: u32) -> u32 {
        self.store.owner(id)
    }

    /// The fork owning element `e` (the one holding its element block).
    pub fn element_owner(&self, e: u32) -> u32 {
        self.block_owner(self.header.layout.element_slot(e).0)
    }

    /// Refuses ids past the scene's last block.
    pub fn check_block_id(&self, id: u32) -> Result<(), ForkError> {
        self.store.check_id(id)
    }

    /// Refuses ids out of range or owned by another fork.
    pub fn check_owned_block(&self, id: u32) -> Result<(), ForkError> {
        self.store.check_owned(id)
    }

    /// Replaces owned blocks (id, 2 KB payload); all are checked before any is stored.
    /// Returns how many were stored.
    pub fn put_blocks(&self, blocks: Vec<(u32, Bytes)>) -> Result<u32, ForkError> {
        self.store.put(blocks)
    }

    /// Owned blocks supplied so far.
    pub fn stored_blocks(&self) -> u32 {
        self.store.stored()
    }

    /// Owned blocks by id, in request order (payloads shared, not copied).
    pub fn owned_blocks(&self, ids: &[u32]) -> Result<Vec<(u32, Bytes)>, ForkError> {
        self.store.get(ids)
    }

    /// Unassigned pairs of this fork's own queue.
    pub fn pairs_left(&self) -> u64 {
        lock(&self.work).pairs.remaining()
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
        guided_batch(max, self.pairs_left() + self.left_at_peers(), self.nodes)
    }

    /// Takes up to `max` unassigned pairs of this fork's own queue for `node` (first
    /// giving back the pairs of nodes whose lease expired), and renews `node`'s leases.
    /// Returns the pairs and the replay epoch they are handed out in.
    pub fn take_own_pairs(&self, max: u32, node: u32) -> (Vec<u64>, u64) {
        let max = max.clamp(1, MAX_PAIRS_PER_REQUEST);
        let now = Instant::now();
        let mut work = lock(&self.work);
        work.pairs.heard_from(node, now);
        self.reclaim_expired(&mut work, now);
        let max = guided_batch(max, self.left_in_cluster(work.pairs.remaining()), self.nodes) as usize;
        let Work { pairs, ledger } = &mut *work;
        let elements = self.header.counts.elements;
        // A given-back pair may have been completed since by its first (slow) node.
        let keep = |p| self.local_pair(p).is_ok_and(|k| !ledger.is_done(k));
        (pairs.take(max, node, now, &self.owned, elements, keep), ledger.epoch())
    }

    /// Starts replay epoch `epoch` because fork `lost` restarted and lost the energy on
    /// its elements (`None`: unknown, replay everything). Goes back to the queue: every
    /// pair still out with a node (its completion, from the old epoch, will not count) and
    /// every complete pair that deposited on `lost`; the others stay done. Deposits already
    /// applied here stay (the re-run ones are duplicates). Returns the pairs queued again.
    /// An epoch not above the current one changes nothing (a repeated call).
    pub fn replay(&self, epoch: u64, lost: Option<u32>) -> Result<u64, ForkError> {
        let forks = self.place.forks();
        if let Some(l) = lost.filter(|&l| l >= forks || l == self.place.index) {
            return Err(ForkError::BadRequest(format!("lost_fork {l}: not another of the {forks} forks")));
        }
        let mut work = lock(&self.work);
        let now = work.ledger.epoch();
        // Epochs grow by one per lost fork: a jump past every fork losing its energy many
        // times over is not the host's.
        if epoch > now.saturating_add(MAX_EPOCH_STEP) {
            return Err(ForkError::BadRequest(format!(
                "replay epoch {epoch}: this fork is at epoch {now}, a jump of over {MAX_EPOCH_STEP}"
            )));
        }
        let Work { pairs, ledger } = &mut *work;
        let Some(again) = ledger.replay(epoch, lost, |k| self.pair_of_local(k)) else { return Ok(0) };
        let before = pairs.remaining();
        pairs.requeue(again.into_iter().map(|k| self.pair_of_local(k)));
        pairs.recall();
        let queued = pairs.remaining() - before;
        tracing::warn!(
            fork = self.place.index,
            epoch,
            ?lost,
            pairs = queued,
            "replay: pairs that deposited on the lost fork, or were out with nodes, queued again"
        );
        Ok(queued)
    }

    /// Gives back to the queue the pairs of every node silent for longer than the lease
    /// (or [`GAPS_PER_LEASE`] times the longest gap of a live node, if longer).
    fn reclaim_expired(&self, work: &mut Work, now: Instant) {
        if let Some(e) = work.pairs.expire(self.lease, now) {
            tracing::warn!(
                fork = self.place.index,
                pairs = e.pairs,
                nodes = ?e.nodes,
                "pair leases expired (node silent for over {:?}): pairs back on the queue",
                e.lease
            );
        }
    }

    /// The id range of pairs: `light sources * elements`.
    pub fn pair_count(&self) -> u64 {
        self.header.pair_count()
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
        let elements = self.header.counts.elements;
        let at = self.owned_index(Pair::element_of(pair, elements))?;
        Ok(Pair::light_of(pair, elements) * self.owned.len() as u64 + at as u64)
    }

    /// The pair id of local index `k` (inverse of [`Shard::local_pair`]).
    fn pair_of_local(&self, k: u64) -> u64 {
        let per_light = self.owned.len().max(1) as u64;
        Pair::new((k / per_light) as u32, self.owned[(k % per_light) as usize]).id(self.header.counts.elements)
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

    /// Applies a batch's deposits exactly once per pair id; returns (applied,
    /// duplicates). The whole batch is checked before anything is applied.
    pub fn deposit<'a, P>(&self, batch: DepositBatch<P>) -> Result<(u32, u32), ForkError>
    where
        P: ExactSizeIterator<Item = PairDeposit<'a>> + Clone,
    {
        let n = batch.pairs.len();
        if n > MAX_DEPOSIT_PAIRS {
            return Err(ForkError::TooMany {
                what: "pairs in a deposit",
                got: n as u64,
                max: MAX_DEPOSIT_PAIRS as u64,
            });
        }
        if batch.deposits > MAX_DEPOSITS {
            return Err(ForkError::TooMany {
                what: "element deposits in a request",
                got: batch.deposits as u64,
                max: MAX_DEPOSITS as u64,
            });
        }
        let total_pairs = self.pair_count();
        let forks = self.place.forks();
        let mut slots = Vec::with_capacity(batch.deposits);
        let mut local = Vec::with_capacity(if batch.complete { n } else { 0 });
        let mut owners = Vec::with_capacity(n);
        let elements = self.header.counts.elements.max(1);
        for p in batch.pairs.clone() {
            if p.pair >= total_pairs {
                return Err(ForkError::PairOutOfRange { pair: p.pair, pairs: total_pairs });
            }
            owners.push(self.element_owner(Pair::element_of(p.pair, elements)) as usize);
            if batch.complete {
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
            self.check_flux(Pair::light_of(p.pair, elements), &p)?;
        }
        let (mut applied, mut duplicates) = (0, 0);
        let mut slots = slots.into_iter();
        let mut work = lock(&self.work);
        let Work { pairs, ledger } = &mut *work;
        let counts_done = batch.complete && ledger.counts(batch.epoch);
        for (k, p) in batch.pairs.enumerate() {
            let deposits = p.energy.chunks_exact(3).zip(slots.by_ref()).map(|(d, slot)| (slot, d));
            if ledger.apply(p.pair, owners[k], deposits) {
                applied += 1;
            } else {
                duplicates += 1;
            }
            if let (Some(&k), true) = (local.get(k), counts_done) {
                ledger.complete(k, p.pair, p.also_on);
                pairs.complete(p.pair);
            }
        }
        Ok((applied, duplicates))
    }

    /// Refuses a request under node `node`'s id that does not carry its secret.
    pub fn admit(&self, node: u32, secret: u64) -> Result<(), ForkError> {
        if self.node_key.admits(node, secret) {
            Ok(())
        } else {
            Err(ForkError::NotThatNode(node))
        }
    }

    /// Refuses a pair's deposits that no tracing of this scene makes: a negative value, or
    /// more in all than its light can give ([`flux_bounds`]).
    fn check_flux(&self, light: u64, p: &PairDeposit<'_>) -> Result<(), ForkError> {
        let Some(bound) = self.flux_bound.get(light as usize) else {
            return Err(ForkError::PairOutOfRange { pair: p.pair, pairs: self.pair_count() });
        };
        let mut sum = [0i128; 3];
        for d in p.energy.chunks_exact(3) {
            for c in 0..3 {
                if d[c] < 0 {
                    return Err(ForkError::BadRequest(format!("pair {}: a negative deposit ({})", p.pair, d[c])));
                }
                sum[c] += d[c] as i128;
            }
        }
        if let Some(c) = (0..3).find(|&c| sum[c] > bound[c]) {
            return Err(ForkError::BadRequest(format!(
                "pair {} deposits {} quanta in channel {c}, more than its light can give ({})",
                p.pair, sum[c], bound[c]
            )));
        }
        Ok(())
    }

    /// Energies of every owned element (ascending id; none when `summary_only`), pair
    /// progress, and the traffic counters of [`Shard::traffic`].
    pub fn energies(&self, summary_only: bool) -> ForkReport {
        let mut work = lock(&self.work);
        self.reclaim_expired(&mut work, Instant::now());
        let (elements, energy) =
            if summary_only { (Vec::new(), Vec::new()) } else { (self.owned.clone(), work.ledger.energy().to_vec()) };
        ForkReport {
            elements,
            energy,
            pairs_total: work.pairs.total(),
            pairs_done: work.ledger.done(),
            pairs_returned: work.pairs.returned(),
            dma_bytes: self.traffic.dma_bytes.load(Ordering::Relaxed),
            gbus_bytes: self.traffic.gbus_bytes.load(Ordering::Relaxed),
            rpcs: self.traffic.rpcs.load(Ordering::Relaxed),
            link_bytes: self.traffic.link_bytes.load(Ordering::Relaxed),
            ledger: work.ledger.digest(),
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
