//! A fork's exactly-once ledger (paper §4.4): which pairs' deposits it has applied (a
//! pair deposited twice, by a retry or by a node that lost its lease, counts once),
//! the energy accumulated on its elements, which of its own pairs are complete (in the
//! current replay epoch) and, for each other fork, which complete pairs deposited on it:
//! the pairs to trace again if that fork restarts and loses its energy.
//!
//! Beside the sets it keeps their digests ([`PairDigest`], by fork), which the host
//! compares across forks before it interpolates: what fork `j` applied of fork `k`'s
//! pairs must be what fork `k` recorded as deposited on `j` (see
//! [`Ledger::digest`]).

use crate::bits::Bitset;
use magg_core::cluster::{LedgerDigest, PairDigest};
use magg_core::fixed::Fixed;

/// The ledger of one fork. Own pairs are named by their local index (see
/// [`crate::shard::Shard::local_pair`]), every pair by its id.
#[derive(Debug)]
pub struct Ledger {
    /// This fork's index.
    me: usize,
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
    /// Digest of `applied`, split by the fork owning each pair.
    applied_from: Vec<PairDigest>,
    /// Digest of each `deposited_on` (by pair id); this fork's entry: of `done`.
    recorded: Vec<PairDigest>,
}

impl Ledger {
    /// An empty ledger of fork `me` in replay `epoch` for a scene of `pairs` pairs,
    /// `own_pairs` of them this fork's, `forks` forks and `elements` owned elements.
    pub fn new(me: usize, pairs: u64, own_pairs: u64, forks: usize, elements: usize, epoch: u64) -> Ledger {
        Ledger {
            me,
            epoch,
            applied: Bitset::new(pairs),
            done: Bitset::new(own_pairs),
            own_pairs,
            deposited_on: vec![None; forks],
            energy: vec![[0; 3]; elements],
            applied_from: vec![PairDigest::default(); forks],
            recorded: vec![PairDigest::default(); forks],
        }
    }

    /// The current replay epoch.
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// Applies `pair`'s deposits, (owned element position, r g b) each, unless the pair
    /// was applied before; the deposits are consumed either way. `owner` is the fork
    /// owning the pair (checked by the caller). True when applied.
    pub fn apply<'a>(&mut self, pair: u64, owner: usize, deposits: impl Iterator<Item = (usize, &'a [i64])>) -> bool {
        let fresh = self.applied.insert(pair);
        if fresh {
            if let Some(d) = self.applied_from.get_mut(owner) {
                d.add(pair);
            }
        }
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

    /// Own pair `local` (id `pair`) is complete, and also deposited on the forks
    /// `also_on` (checked by the caller to be other forks).
    pub fn complete(&mut self, local: u64, pair: u64, also_on: &[u32]) {
        if self.done.insert(local) {
            self.recorded[self.me].add(pair);
        }
        let bound = self.own_pairs;
        for &j in also_on {
            if let Some(on) = self.deposited_on.get_mut(j as usize) {
                if on.get_or_insert_with(|| Bitset::new(bound)).insert(local) {
                    self.recorded[j as usize].add(pair);
                }
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
    /// or all), no longer counted as done; `pair_of` names own pair `local` by id.
    /// Deposits applied here stay applied (the re-run ones are duplicates). An epoch not
    /// above the current one changes nothing and returns `None`.
    pub fn replay(&mut self, epoch: u64, lost: Option<u32>, pair_of: impl Fn(u64) -> u64) -> Option<Vec<u64>> {
        if epoch <= self.epoch {
            return None;
        }
        self.epoch = epoch;
        let again: Vec<u64> = match lost.map(|j| j as usize).filter(|&j| j < self.deposited_on.len()) {
            // No pair records this fork itself as another one it deposited on.
            Some(j) if j == self.me => Vec::new(),
            Some(j) => {
                self.recorded[j] = PairDigest::default();
                self.deposited_on[j].take().map_or_else(Vec::new, |on| on.iter().collect())
            }
            None => self.done.iter().collect(),
        };
        for &k in &again {
            if self.done.remove(k) {
                self.recorded[self.me].remove(pair_of(k));
            }
        }
        Some(again)
    }

    /// The ledger in digests: what this fork applied, by owning fork, and what its
    /// complete pairs recorded, by fork they deposited on (this fork's entry: every
    /// complete pair). See [`LedgerDigest`].
    pub fn digest(&self) -> LedgerDigest {
        LedgerDigest { epoch: self.epoch, applied: self.applied_from.clone(), recorded: self.recorded.clone() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use magg_core::cluster::{check_ledgers, LedgerMismatch};

    #[test]
    fn a_pair_deposited_twice_is_applied_once() {
        let mut l = Ledger::new(0, 10, 4, 2, 2, 0);
        let d: [i64; 6] = [1, 2, 3, 10, 20, 30];
        let deposits = || [0usize, 1].into_iter().zip(d.chunks_exact(3));
        assert!(l.apply(7, 1, deposits()));
        assert!(!l.apply(7, 1, deposits()), "a repeated pair was applied");
        assert!(l.apply(8, 1, deposits().take(1)));
        assert_eq!(l.energy(), &[[2, 4, 6], [10, 20, 30]]);
        assert_eq!(l.digest().applied[1].count, 2, "the duplicate was counted");
    }

    #[test]
    fn completions_count_in_their_epoch_only() {
        let mut l = Ledger::new(0, 10, 4, 2, 2, 3);
        assert!(l.counts(3) && !l.counts(2));
        l.complete(1, 1, &[]);
        assert_eq!(l.replay(4, None, |k| k), Some(vec![1]));
        assert!(!l.counts(3) && l.counts(4));
        assert_eq!(l.replay(4, None, |k| k), None, "a repeated replay changed something");
        assert_eq!(l.replay(2, Some(1), |k| k), None);
        assert_eq!(l.digest().recorded[0], PairDigest::default(), "a replayed pair still counts as done");
    }

    #[test]
    fn a_replay_for_a_lost_fork_names_exactly_the_pairs_that_deposited_on_it() {
        let mut l = Ledger::new(0, 20, 6, 3, 2, 0);
        l.complete(0, 0, &[1]);
        l.complete(1, 1, &[]);
        l.complete(2, 2, &[1, 2]);
        l.complete(3, 3, &[2]);
        assert_eq!(l.done(), 4);
        assert_eq!(l.replay(1, Some(1), |k| k), Some(vec![0, 2]));
        assert!(!l.is_done(0) && l.is_done(1) && !l.is_done(2) && l.is_done(3));
        // Fork 1 lost again: nothing complete has deposited on it since.
        assert_eq!(l.replay(2, Some(1), |k| k), Some(vec![]));
        // Pair 0 traced again deposits on the restarted fork 1: a second loss names it.
        l.complete(0, 0, &[1]);
        assert_eq!(l.replay(3, Some(1), |k| k), Some(vec![0]));
        // Pair 2 traced again: fork 2's list still names it once.
        l.complete(2, 2, &[2]);
        assert_eq!(l.replay(4, Some(2), |k| k), Some(vec![2, 3]));
        assert_eq!(l.done(), 1);
        // A replay naming this fork itself requeues nothing.
        assert_eq!(l.replay(5, Some(0), |k| k), Some(vec![]));
    }

    /// A cluster of ledgers driven the way forks and nodes drive them: pair `p` of `P`
    /// pairs is owned by fork `p % F` (its local index `p / F`) and deposits on the forks
    /// `reach(p)`, one unit of energy each; a node sends round 1 (the other forks), then
    /// round 2 (the owner, which completes the pair).
    struct Cluster {
        forks: Vec<Ledger>,
        epoch: u64,
    }

    const F: usize = 3;
    const P: u64 = 30;

    fn reach(p: u64) -> Vec<usize> {
        let mut on: Vec<usize> = vec![(p % 3) as usize];
        if p % 4 == 0 {
            on.push(((p + 1) % 3) as usize);
        }
        if p % 5 == 0 {
            on.push(((p + 2) % 3) as usize);
        }
        on
    }

    impl Cluster {
        fn new() -> Cluster {
            Cluster { forks: (0..F).map(|j| Ledger::new(j, P, P / F as u64, F, 1, 0)).collect(), epoch: 0 }
        }

        /// Round 1 of pair `p` (handed out in `epoch`) on every fork but its owner.
        fn round1(&mut self, p: u64) {
            let owner = (p % F as u64) as usize;
            for j in reach(p).into_iter().filter(|&j| j != owner) {
                self.forks[j].apply(p, owner, [(0usize, &[1i64, 1, 1][..])].into_iter());
            }
        }

        /// Round 2 of pair `p`, handed out in `epoch`.
        fn round2(&mut self, p: u64, epoch: u64) {
            let owner = (p % F as u64) as usize;
            let also: Vec<u32> = reach(p).into_iter().filter(|&j| j != owner).map(|j| j as u32).collect();
            let l = &mut self.forks[owner];
            l.apply(p, owner, [(0usize, &[1i64, 1, 1][..])].into_iter());
            if l.counts(epoch) {
                l.complete(p / F as u64, p, &also);
            }
        }

        fn trace(&mut self, p: u64) {
            self.round1(p);
            self.round2(p, self.epoch);
        }

        /// Fork `j` restarts: a fresh ledger in a new epoch, and every other fork replays
        /// for it. Returns the pairs to trace again (all of `j`'s, and those the others
        /// requeued).
        fn lose(&mut self, j: usize) -> Vec<u64> {
            self.epoch += 1;
            self.forks[j] = Ledger::new(j, P, P / F as u64, F, 1, self.epoch);
            let mut again: Vec<u64> = (0..P).filter(|p| (p % F as u64) as usize == j).collect();
            for k in (0..F).filter(|&k| k != j) {
                let pair_of = |local: u64| local * F as u64 + k as u64;
                let requeued = self.forks[k].replay(self.epoch, Some(j as u32), pair_of).unwrap();
                again.extend(requeued.into_iter().map(pair_of));
            }
            again
        }

        fn check(&self) -> Vec<LedgerMismatch> {
            assert!(self.forks.iter().all(|l| l.done() == P / F as u64), "not every pair is complete");
            check_ledgers(&self.forks.iter().map(Ledger::digest).collect::<Vec<_>>(), self.epoch)
        }

        /// Energy of fork `j`'s one element: one unit per pair reaching it.
        fn energy_is_right(&self) -> bool {
            (0..F).all(|j| self.forks[j].energy()[0][0] == (0..P).filter(|&p| reach(p).contains(&j)).count() as i64)
        }
    }

    #[test]
    fn a_clean_light_pass_passes_the_check() {
        let mut c = Cluster::new();
        (0..P).for_each(|p| c.trace(p));
        assert_eq!(c.check(), vec![]);
        assert!(c.energy_is_right());
    }

    #[test]
    fn the_check_catches_a_missing_deposit() {
        let mut c = Cluster::new();
        // Pair 4 deposits on forks 1 and 2; fork 2 takes its deposit for a new shard
        // (a load that replaced the last): its energy is gone, fork 1 says it is there.
        (0..P).for_each(|p| c.trace(p));
        c.forks[2] = Ledger::new(2, P, P / F as u64, F, 1, 0);
        (0..P).filter(|p| p % 3 == 2).for_each(|p| c.round2(p, 0));
        let bad = c.check();
        assert!(!bad.is_empty() && bad.iter().all(|m| m.fork() == 2), "{bad:?}");
        assert!(matches!(bad[0], LedgerMismatch::Deposits { on: 2, .. }), "{bad:?}");
        assert!(!c.energy_is_right());
    }

    #[test]
    fn the_check_catches_an_extra_deposit_and_ignores_a_duplicate() {
        let mut c = Cluster::new();
        (0..P).for_each(|p| c.trace(p));
        // A duplicate (a retry, a re-run pair) changes nothing.
        c.trace(8);
        c.round1(20);
        assert_eq!(c.check(), vec![]);
        // A deposit that no complete pair made (pair 1 does not reach fork 0).
        c.forks[0].apply(1, 1, [(0usize, &[1i64, 1, 1][..])].into_iter());
        let bad = c.check();
        assert_eq!(bad.len(), 1, "{bad:?}");
        assert!(matches!(bad[0], LedgerMismatch::Deposits { on: 0, owner: 1, .. }), "{bad:?}");
    }

    #[test]
    fn a_fork_lost_during_its_replay_is_rebuilt_exactly() {
        let mut c = Cluster::new();
        (0..20).for_each(|p| c.trace(p));
        // Fork 1 lost; a node still holds pair 20 of the old epoch (deposits arrive,
        // its completion does not count).
        let mut again = c.lose(1);
        c.round1(20);
        c.round2(20, 0);
        again.extend(20..P);
        // Half the replay done, then fork 1 lost again.
        let (first, rest) = again.split_at(again.len() / 2);
        first.iter().for_each(|&p| c.trace(p));
        let mut again2 = c.lose(1);
        // Whatever was not traced in the first replay is still queued on its fork.
        again2.extend(rest.iter().copied().filter(|&p| p % 3 != 1));
        again2.sort_unstable();
        again2.dedup();
        again2.iter().for_each(|&p| c.trace(p));
        assert_eq!(c.check(), vec![]);
        assert!(c.energy_is_right());
    }

    #[test]
    fn two_forks_lost_together_are_rebuilt_exactly() {
        let mut c = Cluster::new();
        (0..P).filter(|p| p % 2 == 0).for_each(|p| c.trace(p));
        let mut again = c.lose(0);
        again.extend(c.lose(2));
        again.extend((0..P).filter(|p| p % 2 == 1));
        again.sort_unstable();
        again.dedup();
        again.iter().for_each(|&p| c.trace(p));
        assert_eq!(c.check(), vec![]);
        assert!(c.energy_is_right());
    }

    #[test]
    fn the_check_catches_a_fork_rebuilt_without_a_replay() {
        let mut c = Cluster::new();
        (0..P).for_each(|p| c.trace(p));
        // Fork 1 restarts and is loaded again, but fork 0 never hears of it (no replay):
        // fork 1's own pairs come back, fork 0's deposits on it do not.
        c.epoch += 1;
        c.forks[1] = Ledger::new(1, P, P / F as u64, F, 1, c.epoch);
        (0..P).filter(|p| p % 3 == 1).for_each(|p| c.trace(p));
        let bad = c.check();
        assert!(bad.iter().any(|m| m.fork() == 1 || matches!(m, LedgerMismatch::Epoch { .. })), "{bad:?}");
        assert!(!c.energy_is_right());
    }
}
