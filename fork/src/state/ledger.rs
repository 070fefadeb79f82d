//! A fork's exactly-once ledger (paper §4.4): which pairs' deposits it has applied (a
//! pair deposited twice, by a retry or by a node that lost its lease, counts once),
//! the energy accumulated on its elements, which of its own pairs are complete (in the
//! current replay epoch) and, for each other fork, which complete pairs deposited on it:
//! the pairs to trace again if that fork restarts and loses its energy.

use crate::bits::Bitset;
use magg_core::energy::Fixed;

/// The ledger of one fork. Own pairs are named by their local index (see
/// [`crate::shard::Shard::local_pair`]), every pair by its id.
#[derive(Debug)]
pub struct Ledger {
    /// Replay epoch: completions of pairs handed out in an earlier epoch do not count.
    epoch: u64,
    /// Pairs (by id) whose deposits were applied.
    applied: Bitset,
    /// Own pairs reported complete, by local index.
    done: Bitset,
    /// Own pairs in all (the bound of `done` and of each `deposited_on`).
    own_pairs: u64,
    /// For each fork, the complete own pairs that deposited on it (`None`: none yet).
    deposited_on: Vec<Option<Bitset>>,
    /// Fixed-point flux of each owned element, by position among the owned ones.
    energy: Vec<Fixed>,
}

impl Ledger {
    /// An empty ledger in replay `epoch` for a scene of `pairs` pairs, `own_pairs` of
    /// them this fork's, `forks` forks and `elements` owned elements.
    pub fn new(pairs: u64, own_pairs: u64, forks: usize, elements: usize, epoch: u64) -> Ledger {
        Ledger {
            epoch,
            applied: Bitset::new(pairs),
            done: Bitset::new(own_pairs),
            own_pairs,
            deposited_on: vec![None; forks],
            energy: vec![[0; 3]; elements],
        }
    }

    /// The current replay epoch.
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// Applies `pair`'s deposits, (owned element position, r g b) each, unless the pair
    /// was applied before; the deposits are consumed either way. True when applied.
    pub fn apply<'a>(&mut self, pair: u64, deposits: impl Iterator<Item = (usize, &'a [i64])>) -> bool {
        let fresh = self.applied.insert(pair);
        for (slot, d) in deposits {
            if fresh {
                let e = &mut self.energy[slot];
                e[0] = e[0].wrapping_add(d[0]);
                e[1] = e[1].wrapping_add(d[1]);
                e[2] = e[2].wrapping_add(d[2]);
            }
        }
        fresh
    }

    /// Whether a completion handed out in `epoch` counts (it is from the current one).
    pub fn counts(&self, epoch: u64) -> bool {
        epoch == self.epoch
    }

    /// Own pair `local` is complete, and also deposited on the forks `also_on` (checked
    /// by the caller to be other forks).
    pub fn complete(&mut self, local: u64, also_on: &[u32]) {
        self.done.insert(local);
        let bound = self.own_pairs;
        for &j in also_on {
            if let Some(on) = self.deposited_on.get_mut(j as usize) {
                on.get_or_insert_with(|| Bitset::new(bound)).insert(local);
            }
        }
    }

    /// Whether own pair `local` is complete.
    pub fn is_done(&self, local: u64) -> bool {
        self.done.contains(local)
    }

    /// Own pairs complete.
    pub fn done(&self) -> u64 {
        self.done.len()
    }

    /// The energy of each owned element, by position.
    pub fn energy(&self) -> &[Fixed] {
        &self.energy
    }

    /// Starts replay `epoch` because fork `lost` lost its energy (`None`: unknown):
    /// returns the complete own pairs to trace again (every one that deposited on `lost`,
    /// or all), no longer counted as done. Deposits applied here stay applied (the
    /// re-run ones are duplicates). An epoch not above the current one changes nothing
    /// and returns `None`.
    pub fn replay(&mut self, epoch: u64, lost: Option<u32>) -> Option<Vec<u64>> {
        if epoch <= self.epoch {
            return None;
        }
        self.epoch = epoch;
        let again: Vec<u64> = match lost.and_then(|j| self.deposited_on.get_mut(j as usize)) {
            Some(on_lost) => on_lost.take().map_or_else(Vec::new, |on| on.iter().collect()),
            None => self.done.iter().collect(),
        };
        for &k in &again {
            self.done.remove(k);
        }
        Some(again)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pair_deposited_twice_is_applied_once() {
        let mut l = Ledger::new(10, 4, 2, 2, 0);
        let d: [i64; 6] = [1, 2, 3, 10, 20, 30];
        let deposits = || [0usize, 1].into_iter().zip(d.chunks_exact(3));
        assert!(l.apply(7, deposits()));
        assert!(!l.apply(7, deposits()), "a repeated pair was applied");
        assert!(l.apply(8, deposits().take(1)));
        assert_eq!(l.energy(), &[[2, 4, 6], [10, 20, 30]]);
    }

    #[test]
    fn completions_count_in_their_epoch_only() {
        let mut l = Ledger::new(10, 4, 2, 2, 3);
        assert!(l.counts(3) && !l.counts(2));
        l.complete(1, &[]);
        assert_eq!(l.replay(4, None), Some(vec![1]));
        assert!(!l.counts(3) && l.counts(4));
        assert_eq!(l.replay(4, None), None, "a repeated replay changed something");
        assert_eq!(l.replay(2, Some(1)), None);
    }

    #[test]
    fn a_replay_for_a_lost_fork_names_exactly_the_pairs_that_deposited_on_it() {
        let mut l = Ledger::new(20, 6, 3, 2, 0);
        l.complete(0, &[1]);
        l.complete(1, &[]);
        l.complete(2, &[1, 2]);
        l.complete(3, &[2]);
        assert_eq!(l.done(), 4);
        assert_eq!(l.replay(1, Some(1)), Some(vec![0, 2]));
        assert!(!l.is_done(0) && l.is_done(1) && !l.is_done(2) && l.is_done(3));
        // Fork 1 lost again: nothing complete has deposited on it since.
        assert_eq!(l.replay(2, Some(1)), Some(vec![]));
        // Pair 0 traced again deposits on the restarted fork 1: a second loss names it.
        l.complete(0, &[1]);
        assert_eq!(l.replay(3, Some(1)), Some(vec![0]));
        // Pair 2 traced again: fork 2's list still names it once.
        l.complete(2, &[2]);
        assert_eq!(l.replay(4, Some(2)), Some(vec![2, 3]));
        assert_eq!(l.done(), 1);
    }
}
