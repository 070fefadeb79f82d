//! The light pass's traffic between the host, the forks and the nodes, as domain values
//! (paper §4.2–4.4): a shard for a fork to load, pairs lent to a node, a batch of pair
//! deposits on one fork, a fork's report and a node's report.
//!
//! These are what the fork's and the node's state work on; the gRPC edges convert them
//! from and to the protocol's messages (`magg_proto::convert`), so no protobuf type
//! reaches that state. Nothing here checks values against a scene: the fork does that
//! before it changes anything.
//!
//! ```
//! use magg_core::cluster::{DepositBatch, PairDeposit};
//! let pairs = [PairDeposit { pair: 7, elements: &[3], energy: &[1, 2, 3], also_on: &[] }];
//! let batch = DepositBatch { complete: true, epoch: 0, deposits: 1, pairs: pairs.iter().copied() };
//! assert_eq!(batch.pairs.len(), 1);
//! ```

use crate::blocks::CacheStats;
use crate::fixed::Fixed;
use crate::header::SceneHeader;
use crate::lrt::LrtTally;
use crate::view::OpCounters;
use std::time::Duration;

/// A fork's share of a render as the host hands it over: where the fork stands among
/// the forks, the scene header, the blocks it holds (`B`: their payload, kept as
/// received) and how it leases pairs.
#[derive(Clone, Debug)]
pub struct ShardLoad<B> {
    /// This fork's index.
    pub fork_index: u32,
    /// Every fork's address, by index (their number is the cluster's fork count F).
    pub fork_addrs: Vec<String>,
    /// The resident scene header.
    pub header: SceneHeader,
    /// Owned blocks as (id, 2 KB payload); more may follow later.
    pub blocks: Vec<(u32, B)>,
    /// Nodes the host expects (sizes guided pair batches; 0 = unknown).
    pub nodes: u32,
    /// How long a silent node keeps its pairs; `None`: the fork's default.
    pub lease: Option<Duration>,
    /// Replay epoch the render starts in (above 0 when a fork is reloaded mid-pass).
    pub epoch: u64,
    /// The render's node key (empty: none): `TakePairs` under node i's id must carry the
    /// keyed hash of i under it.
    pub node_key: Vec<u8>,
}

/// Pairs a fork lends a node (its answer to `TakePairs` or to a peer's steal).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PairLease {
    /// Pair ids (`light * elements + element`).
    pub pairs: Vec<u64>,
    /// Replay epoch they are handed out in: their completion counts only in it.
    pub epoch: u64,
    /// No fork has pairs left to hand out (empty `pairs` without it: ask again).
    pub exhausted: bool,
    /// Unassigned pairs left on the fork that answered (0 when unknown).
    pub remaining: u64,
}

/// One pair's deposits on one fork, borrowed from the batch that carries them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairDeposit<'a> {
    /// The pair id (light * elements + element).
    pub pair: u64,
    /// Elements it deposited on.
    pub elements: &'a [u32],
    /// Three fixed-point values (r, g, b) per element.
    pub energy: &'a [i64],
    /// Other forks it deposited on (round 2, to the pair's owner).
    pub also_on: &'a [u32],
}

/// A batch's deposits on one fork: round 1 (`complete` false) carries deposits on a
/// fork other than the pairs' owner, round 2 the owner's own and marks the pairs done.
/// `P` yields the pairs (each once per batch; a repeated pair id is a duplicate).
#[derive(Clone, Debug)]
pub struct DepositBatch<P> {
    /// Round 2: the pairs are complete once these deposits are in.
    pub complete: bool,
    /// Replay epoch the pairs were handed out in.
    pub epoch: u64,
    /// Element deposits in all (the sum of the pairs' `elements`).
    pub deposits: usize,
    /// The pairs and their deposits.
    pub pairs: P,
}

/// What a fork reports to the host: the energy accumulated on its elements, pair
/// progress and the traffic it served.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForkReport {
    /// Owned elements, ascending (empty in a summary).
    pub elements: Vec<u32>,
    /// Fixed-point flux of each, parallel to `elements`.
    pub energy: Vec<Fixed>,
    /// Pairs of this fork in all.
    pub pairs_total: u64,
    /// Pairs of this fork complete.
    pub pairs_done: u64,
    /// Pairs whose lease expired and went back to the queue.
    pub pairs_returned: u64,
    /// Block bytes sent to nodes (the DMA path).
    pub dma_bytes: u64,
    /// Block bytes fetched from other forks (the G-bus path).
    pub gbus_bytes: u64,
    /// RPCs handled.
    pub rpcs: u64,
    /// Encoded bytes of pair and deposit messages with nodes (the link path).
    pub link_bytes: u64,
    /// What its exactly-once ledger holds, for the host's check before interpolation.
    pub ledger: LedgerDigest,
}

/// An order-independent digest of a set of pair ids: how many, and the wrapping sum of
/// a 64-bit mix of each. Two forks that name the same pairs have equal digests; a pair
/// missing or extra on one side changes both figures (the sum by a well-mixed value, so
/// a difference cancelling out is a 1 in 2^64 event, not a pattern a fault produces).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PairDigest {
    /// Pairs in the set.
    pub count: u64,
    /// Wrapping sum of [`PairDigest::mix`] of each.
    pub sum: u64,
}

impl PairDigest {
    /// The splitmix64 finaliser of `pair`: neighbouring ids give unrelated values.
    pub fn mix(pair: u64) -> u64 {
        let mut z = pair.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Adds `pair` (the caller adds each pair of the set once).
    pub fn add(&mut self, pair: u64) {
        self.count += 1;
        self.sum = self.sum.wrapping_add(Self::mix(pair));
    }

    /// Removes `pair` (one that was added).
    pub fn remove(&mut self, pair: u64) {
        self.count -= 1;
        self.sum = self.sum.wrapping_sub(Self::mix(pair));
    }
}

/// A fork's exactly-once ledger in digests, by fork index: the pairs whose deposits it
/// applied, grouped by the fork that owns each pair (`applied[k]`), and, for each other
/// fork `j`, its own complete pairs that said they deposited on `j` (`recorded[j]`;
/// `recorded[self]` is its complete own pairs). When light ray tracing is over and right,
/// fork `j`'s `applied[k]` equals fork `k`'s `recorded[j]` for every pair of forks.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LedgerDigest {
    /// Replay epoch of the ledger.
    pub epoch: u64,
    /// Applied pairs, by owning fork.
    pub applied: Vec<PairDigest>,
    /// Complete own pairs that deposited on each fork (on this one: all complete ones).
    pub recorded: Vec<PairDigest>,
}

/// Two forks' ledgers that disagree (see [`check_ledgers`]): the energy of fork `on`
/// cannot be trusted.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LedgerMismatch {
    /// A fork's ledger is of another replay epoch than the host's (it restarted, or was
    /// loaded again, unseen).
    #[error("fork {on}'s ledger is of replay epoch {got}, not {want}")]
    Epoch {
        /// The fork.
        on: usize,
        /// Its ledger's epoch.
        got: u64,
        /// The host's.
        want: u64,
    },
    /// A fork's ledger does not name every fork.
    #[error("fork {on}'s ledger names {got} forks, not {want}")]
    Shape {
        /// The fork.
        on: usize,
        /// Forks its digests cover.
        got: usize,
        /// Forks of the render.
        want: usize,
    },
    /// Fork `on` applied other deposits of fork `owner`'s pairs than `owner`'s complete
    /// pairs say they made there: some are missing, or extra.
    #[error(
        "fork {on} applied the deposits of {} pairs of fork {owner}, and fork {owner}'s complete pairs \
         made {} there (digests {:016x} and {:016x})",
        applied.count,
        recorded.count,
        applied.sum,
        recorded.sum
    )]
    Deposits {
        /// The fork the deposits went to.
        on: usize,
        /// The fork owning the pairs.
        owner: usize,
        /// What `on` applied of `owner`'s pairs.
        applied: PairDigest,
        /// What `owner` recorded as deposited on `on`.
        recorded: PairDigest,
    },
}

impl LedgerMismatch {
    /// The fork whose energy is in doubt.
    pub fn fork(&self) -> usize {
        match *self {
            LedgerMismatch::Epoch { on, .. }
            | LedgerMismatch::Shape { on, .. }
            | LedgerMismatch::Deposits { on, .. } => on,
        }
    }
}

/// Checks, once every fork's pairs are complete, that every pair's deposits were applied
/// exactly once on every fork they were made for: fork `j` applied of fork `k`'s pairs
/// exactly those that `k`'s complete pairs recorded as deposited on `j` (on `k` itself:
/// every complete pair, since a pair completes with its owner's deposits), all in replay
/// `epoch`. `ledgers` is by fork index. Returns every disagreement (none: the energies
/// are those of a run without failures).
pub fn check_ledgers(ledgers: &[LedgerDigest], epoch: u64) -> Vec<LedgerMismatch> {
    let forks = ledgers.len();
    let mut out = Vec::new();
    for (on, l) in ledgers.iter().enumerate() {
        if l.epoch != epoch {
            out.push(LedgerMismatch::Epoch { on, got: l.epoch, want: epoch });
        } else if l.applied.len() != forks || l.recorded.len() != forks {
            out.push(LedgerMismatch::Shape { on, got: l.applied.len().min(l.recorded.len()), want: forks });
        }
    }
    if out.iter().any(|m| matches!(m, LedgerMismatch::Shape { .. })) {
        return out;
    }
    for (on, l) in ledgers.iter().enumerate() {
        for (owner, k) in ledgers.iter().enumerate() {
            let (applied, recorded) = (l.applied[owner], k.recorded[on]);
            if applied != recorded {
                out.push(LedgerMismatch::Deposits { on, owner, applied, recorded });
            }
        }
    }
    out
}

/// What a node reports to the host: the sum over its workers so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeReport {
    /// Its block cache.
    pub cache: CacheStats,
    /// Its kernel operations.
    pub ops: OpCounters,
    /// Pairs traced.
    pub pairs: u64,
    /// Subscreens traced.
    pub tiles: u64,
    /// Where its light went.
    pub tally: LrtTally,
    /// Seconds its emulated link was busy (0 on the native profile).
    pub link_busy_s: f64,
    /// Seconds of emulated processor time (0 on the native profile).
    pub cpu_busy_s: f64,
}
