//! The queue of a fork's unassigned (light, element) pairs (paper §4.4).
//!
//! A fork's pairs are every (light, element) with an element the fork owns, handed out in
//! ascending pair id (`light * elements + element`, see [`magg_core::lrt::pair_id`]).
//! The queue is a cursor over that sequence, so it costs no memory per pair however large
//! the scene. Pairs whose lease expired (their node died or stalled) come back on a
//! second, explicit queue of returned pairs that is popped before the cursor.

use magg_core::lrt::pair_id;
use std::collections::BTreeSet;

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
                .map(|k| pair_id((k / per_light) as u32, owned[(k % per_light) as usize], elements)),
        );
        self.next += n;
        out
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
