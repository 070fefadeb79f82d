//! The queue of a fork's unassigned (light, element) pairs (paper §4.4).
//!
//! A fork's pairs are every (light, element) with an element the fork owns, handed out in
//! ascending pair id (`light * elements + element`, see [`magg_core::pair::Pair::id`]).
//! The queue is a cursor over that sequence, so it costs no memory per pair however large
//! the scene. Pairs whose lease expired (their node died or stalled) come back on a
//! second, explicit queue of returned pairs that is popped before the cursor.
//!
//! [`PairBook`] adds the pairs lent to nodes: each lease is renewed whenever its node asks
//! again, and a silent node's pairs go back to the queue (once) when it expires; a replay
//! after a lost fork recalls every lent pair.

use magg_core::idhash::IdMap;
use magg_core::pair::Pair;
use std::collections::BTreeSet;
use std::time::{Duration, Instant};

/// Unassigned pairs of one fork.
#[derive(Clone, Debug)]
pub struct PairQueue {
    /// Index of the next pair in the fork's sequence.
    next: u64,
    /// Pairs in the sequence: lights x owned elements (0 when LRT is off).
    total: u64,
    /// Pairs handed out once and given back (lease expired), ascending.
    returned: BTreeSet<u64>,
}

impl PairQueue {
    /// The queue of `lights` lights over `owned` elements; empty when `lrt` is false.
    pub fn new(lights: u32, owned: usize, lrt: bool) -> PairQueue {
        PairQueue { next: 0, total: if lrt { lights as u64 * owned as u64 } else { 0 }, returned: BTreeSet::new() }
    }

    /// Pairs of this fork in all (handed out or not).
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Pairs not handed out yet, or given back.
    pub fn remaining(&self) -> u64 {
        self.total - self.next + self.returned.len() as u64
    }

    /// Puts a pair that was handed out back on the queue (its lease expired).
    pub fn give_back(&mut self, pair: u64) {
        self.returned.insert(pair);
    }

    /// Takes up to `max` pairs: returned ones first, then the sequence, ascending. `owned`
    /// is the fork's owned elements in ascending order (the same slice the queue was built
    /// for), `elements` the scene's element count.
    pub fn pop(&mut self, max: usize, owned: &[u32], elements: u32) -> Vec<u64> {
        if owned.is_empty() {
            return Vec::new();
        }
        let mut out = Vec::with_capacity(max.min(self.remaining() as usize));
        while out.len() < max {
            match self.returned.pop_first() {
                Some(p) => out.push(p),
                None => break,
            }
        }
        let n = ((max - out.len()) as u64).min(self.total - self.next);
        let per_light = owned.len() as u64;
        out.extend(
            (self.next..self.next + n)
                .map(|k| Pair::new((k / per_light) as u32, owned[(k % per_light) as usize]).id(elements)),
        );
        self.next += n;
        out
    }
}

/// A lease lasts at least this many times the longest gap seen between two requests of a
/// node that held pairs (a live node's gap is about one batch of pairs).
pub const GAPS_PER_LEASE: u32 = 4;

/// A fork's pairs: those not handed out yet ([`PairQueue`]) and those lent to nodes, by
/// node and time, until they complete or their lease expires.
#[derive(Debug)]
pub struct PairBook {
    /// Unassigned pairs.
    queue: PairQueue,
    /// Pairs handed out and not yet complete, with the node they went to and when.
    leased: IdMap<u64, (u32, Instant)>,
    /// When each node last asked this fork for pairs (refreshes all its leases).
    seen: IdMap<u32, Instant>,
    /// Longest time a node holding pairs here took to ask again: leases last at least
    /// [`GAPS_PER_LEASE`] times this, so slow (e.g. throttled) batches do not expire.
    max_gap: Duration,
    /// Leases that expired so far.
    returned: u64,
}

/// Pairs whose lease expired in one [`PairBook::expire`], for the log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Expired {
    /// How many went back to the queue.
    pub pairs: usize,
    /// The silent nodes that held them, ascending.
    pub nodes: Vec<u32>,
    /// The lease they outlived.
    pub lease: Duration,
}

impl PairBook {
    /// A book over `queue` with nothing lent.
    pub fn new(queue: PairQueue) -> PairBook {
        PairBook { queue, leased: IdMap::default(), seen: IdMap::default(), max_gap: Duration::ZERO, returned: 0 }
    }

    /// Pairs in all (handed out or not).
    pub fn total(&self) -> u64 {
        self.queue.total()
    }

    /// Pairs not handed out, or given back.
    pub fn remaining(&self) -> u64 {
        self.queue.remaining()
    }

    /// Leases that expired so far.
    pub fn returned(&self) -> u64 {
        self.returned
    }

    /// Pairs lent out now.
    pub fn lent(&self) -> usize {
        self.leased.len()
    }

    /// `node` asked for pairs at `now`: every lease it holds is renewed, and the gap
    /// since it last asked (while it held pairs) lengthens leases if it is the longest.
    pub fn heard_from(&mut self, node: u32, now: Instant) {
        if let Some(last) = self.seen.insert(node, now) {
            if self.leased.values().any(|l| l.0 == node) {
                self.max_gap = self.max_gap.max(now.saturating_duration_since(last));
            }
        }
    }

    /// Gives back to the queue the pairs of every node silent at `now` for longer than
    /// `lease` (or [`GAPS_PER_LEASE`] times the longest gap of a live node, if longer);
    /// `None` when no lease expired.
    pub fn expire(&mut self, lease: Duration, now: Instant) -> Option<Expired> {
        let lease = lease.max(self.max_gap * GAPS_PER_LEASE);
        let seen = &self.seen;
        let expired: Vec<(u64, u32)> = self
            .leased
            .iter()
            .filter(|(_, &(node, at))| {
                let last = seen.get(&node).map_or(at, |&s| s.max(at));
                now.saturating_duration_since(last) > lease
            })
            .map(|(&p, &(node, _))| (p, node))
            .collect();
        if expired.is_empty() {
            return None;
        }
        let mut nodes: Vec<u32> = expired.iter().map(|e| e.1).collect();
        nodes.sort_unstable();
        nodes.dedup();
        for (p, _) in &expired {
            self.leased.remove(p);
            self.queue.give_back(*p);
        }
        self.returned += expired.len() as u64;
        Some(Expired { pairs: expired.len(), nodes, lease })
    }

    /// Lends `node` up to `max` unassigned pairs at `now`, skipping those `keep` refuses
    /// (a given-back pair its first, slow node has completed since). `owned` and
    /// `elements` are as for [`PairQueue::pop`].
    pub fn take(
        &mut self,
        max: usize,
        node: u32,
        now: Instant,
        owned: &[u32],
        elements: u32,
        keep: impl Fn(u64) -> bool,
    ) -> Vec<u64> {
        let mut pairs = Vec::new();
        while pairs.len() < max {
            let got = self.queue.pop(max - pairs.len(), owned, elements);
            if got.is_empty() {
                break;
            }
            pairs.extend(got.into_iter().filter(|&p| keep(p)));
        }
        for &p in &pairs {
            self.leased.insert(p, (node, now));
        }
        pairs
    }

    /// `pair` is complete: its lease ends.
    pub fn complete(&mut self, pair: u64) {
        self.leased.remove(&pair);
    }

    /// Puts complete pairs back on the queue, to be traced again (a replay).
    pub fn requeue(&mut self, pairs: impl IntoIterator<Item = u64>) {
        for p in pairs {
            self.queue.give_back(p);
        }
    }

    /// Ends every lease and puts its pair back on the queue (a replay: completions from
    /// the old epoch will not count). Returns how many were out.
    pub fn recall(&mut self) -> usize {
        let n = self.leased.len();
        for (p, _) in self.leased.drain() {
            self.queue.give_back(p);
        }
        n
    }
}

/// Pairs to hand out for a request of `max` (guided self-scheduling, Polychronopoulos
/// and Kuck 1987): a quarter of each node's share of the pairs left in the whole cluster (`left`, this fork's estimate), so that
/// batches are large while there is much left and shrink towards the end (pairs of
/// neighbouring elements cost alike, so a late large batch would leave its node working
/// alone). They shrink to [`MIN_BATCH`] pairs, not to one: a batch costs a request and a
/// deposit per fork, as much as several pairs of tracing, so single-pair batches at the
/// end cost more than the imbalance they avoid. Fewer pairs than that per node are
/// shared out evenly, so that every one of `nodes` nodes gets work. `nodes == 0`
/// (unknown) hands out `max`.
///
/// The estimate must be the cluster's, not this fork's queue times the number of forks:
/// forks without a node of their own are emptied one after another by stealing, and
/// each would otherwise shrink its last batches to single pairs while others still hold
/// hundreds (46 batches instead of 26 for magg-paper on 2 nodes).
pub fn guided_batch(max: u32, left: u64, nodes: u32) -> u32 {
    if nodes == 0 {
        return max;
    }
    let share = left.div_ceil(GUIDED_PARTS * nodes as u64);
    let floor = MIN_BATCH.min(left.div_ceil(nodes as u64));
    (max as u64).min(share.max(floor).max(1)) as u32
}

/// Parts of a node's share of the remaining pairs handed out at once.
const GUIDED_PARTS: u64 = 4;

/// Smallest batch while each node has at least this many pairs left to share (the
/// embedded renderer's batch).
pub const MIN_BATCH: u64 = 8;

#[cfg(test)]
mod tests {
    use super::*;

    fn book(lights: u32, owned: &[u32]) -> PairBook {
        PairBook::new(PairQueue::new(lights, owned.len(), true))
    }

    #[test]
    fn an_expired_lease_puts_its_pairs_back_exactly_once() {
        let owned = [0u32, 1, 2, 3];
        let mut b = book(2, &owned);
        let t0 = Instant::now();
        let lease = Duration::from_millis(10);
        let lost = b.take(3, 7, t0, &owned, 4, |_| true);
        assert_eq!(lost, vec![0, 1, 2]);
        assert_eq!(b.expire(lease, t0 + Duration::from_millis(5)), None, "expired early");
        let later = t0 + Duration::from_millis(20);
        let e = b.expire(lease, later).expect("the lease expired");
        assert_eq!((e.pairs, e.nodes), (3, vec![7]));
        assert_eq!(b.expire(lease, later + Duration::from_secs(1)), None, "expired twice");
        assert_eq!((b.returned(), b.lent(), b.remaining()), (3, 0, 8));
        // Handed out again once, first in line.
        assert_eq!(b.take(3, 8, later, &owned, 4, |_| true), lost);
        assert_eq!(b.remaining(), 5);
    }

    #[test]
    fn a_node_that_keeps_asking_keeps_its_pairs() {
        let owned = [0u32, 1];
        let mut b = book(4, &owned);
        let t0 = Instant::now();
        let lease = Duration::from_millis(10);
        b.take(2, 1, t0, &owned, 2, |_| true);
        for k in 1..5 {
            b.heard_from(1, t0 + Duration::from_millis(8 * k));
        }
        assert_eq!(b.expire(lease, t0 + Duration::from_millis(40)), None);
        assert_eq!(b.lent(), 2);
        // Its longest gap was 8 ms: a lease now lasts 32 ms past its last request.
        assert_eq!(b.expire(lease, t0 + Duration::from_millis(60)), None);
        assert!(b.expire(lease, t0 + Duration::from_millis(80)).is_some());
    }

    #[test]
    fn a_replay_requeues_exactly_what_was_lent_or_named() {
        let owned = [0u32, 1, 2];
        let mut b = book(2, &owned);
        let t0 = Instant::now();
        let lent = b.take(4, 1, t0, &owned, 3, |_| true);
        for &p in &lent[..2] {
            b.complete(p);
        }
        assert_eq!(b.remaining(), 2);
        assert_eq!(b.recall(), 2, "the two pairs still out");
        b.requeue([lent[0]]); // a complete pair that deposited on the lost fork
        assert_eq!(b.remaining(), 5);
        let mut again = b.take(6, 2, t0, &owned, 3, |_| true);
        again.sort_unstable();
        assert_eq!(again, vec![0, 2, 3, 4, 5], "pair 1 stayed done");
        assert_eq!(b.recall(), 5);
    }

    #[test]
    fn stealing_and_taking_hand_out_each_pair_once() {
        let owned = [1u32, 3, 4, 6, 9];
        let mut b = book(7, &owned);
        let t0 = Instant::now();
        let mut seen = std::collections::HashSet::new();
        // Own nodes and peers stealing for theirs, in turn, in batches of several sizes.
        for round in 0.. {
            let node = round % 3;
            let got = b.take(1 + round % 4, node as u32, t0, &owned, 10, |_| true);
            if got.is_empty() {
                break;
            }
            for p in got {
                assert!(seen.insert(p), "pair {p} handed out twice");
            }
        }
        assert_eq!(seen.len(), 35);
        assert!(seen.iter().all(|p| owned.contains(&((p % 10) as u32))));
        // A pair `keep` refuses (done since) is not handed out again.
        b.requeue([1, 3]);
        assert_eq!(b.take(5, 0, t0, &owned, 10, |p| p != 1), vec![3]);
    }

    #[test]
    fn guided_batches_shrink_and_spread_over_nodes() {
        // 1664 pairs left and 80 nodes: a quarter of a node's share is 6, raised to 8.
        assert_eq!(guided_batch(128, 1664, 80), 8);
        assert_eq!(guided_batch(128, 3200, 80), 10);
        assert_eq!(guided_batch(128, 500_000, 80), 128);
        // Down to 8 pairs, while every node can still have 8.
        assert_eq!(guided_batch(128, 80, 2), 10);
        assert_eq!(guided_batch(128, 20, 2), 8);
        // Fewer: shared out, so that all nodes get some.
        assert_eq!(guided_batch(128, 300, 80), 4);
        assert_eq!(guided_batch(128, 1, 80), 1);
        assert_eq!(guided_batch(128, 0, 80), 1);
        assert_eq!(guided_batch(7, 5000, 0), 7);
    }

    #[test]
    fn pops_every_pair_once_in_ascending_order() {
        let owned = [0u32, 1, 4, 5];
        let mut q = PairQueue::new(2, owned.len(), true);
        let mut all = Vec::new();
        loop {
            let got = q.pop(3, &owned, 6);
            if got.is_empty() {
                break;
            }
            all.extend(got);
        }
        assert_eq!(all, vec![0, 1, 4, 5, 6, 7, 10, 11]);
        assert_eq!((q.total(), q.remaining()), (8, 0));
    }

    #[test]
    fn returned_pairs_come_first() {
        let owned = [0u32, 1];
        let mut q = PairQueue::new(1, owned.len(), true);
        assert_eq!(q.pop(1, &owned, 2), vec![0]);
        q.give_back(0);
        assert_eq!(q.remaining(), 2);
        assert_eq!(q.pop(5, &owned, 2), vec![0, 1]);
        assert_eq!(q.remaining(), 0);
    }

    #[test]
    fn no_pairs_without_lrt() {
        let mut q = PairQueue::new(3, 10, false);
        assert!(q.pop(100, &[0; 10], 10).is_empty());
        assert_eq!(q.total(), 0);
    }
}
