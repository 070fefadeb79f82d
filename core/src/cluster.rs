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
use crate::energy::Fixed;
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
