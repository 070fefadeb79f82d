//! Where a batch's deposits go (paper §4.4): element `e`'s energy is accumulated by the
//! fork holding its element block, `layout.element_slot(e).0 % F`, so a traced pair's
//! deposits are split by fork, in two rounds. Round 1 carries a pair's deposits on the
//! forks other than its owner (the owner of its element); round 2, sent after every
//! round-1 message, carries the owner's own deposits, names the other forks it
//! deposited on and marks the pair complete, so that a pair counted as done has all its
//! energy in place.
//!
//! The split writes straight into the packed arrays of the wire format
//! ([`DepositWriter`]): one message per fork and round, no copy per deposit.
//!
//! ```
//! use magg_node::route::Rounds;
//! let owner_of = |e: u32| (e % 2) as usize; // two forks
//! let mut rounds = Rounds::new(2, 0);
//! rounds.add(7, 1, [(3, [1, 1, 1]), (4, [2, 2, 2])], owner_of);
//! let (round1, round2) = rounds.into_writers();
//! assert_eq!((round1[0].len(), round2[1].len()), (1, 1)); // element 4 on fork 0
//! ```

use magg_core::blocks::{fork_of_block, BlockLayout};
use magg_proto::deposits::DepositWriter;

/// The fork (of `forks`, at least 1) that accumulates element `e`'s energy.
pub fn element_owner(layout: &BlockLayout, forks: usize, e: u32) -> usize {
    fork_of_block(layout.element_slot(e).0, forks as u32) as usize
}

/// A batch's deposits split by fork: the messages of round 1 and of round 2, indexed by
/// fork.
#[derive(Clone, Debug)]
pub struct Rounds {
    round1: Vec<DepositWriter>,
    round2: Vec<DepositWriter>,
}

impl Rounds {
    /// Empty messages to `forks` forks (at least 1) for pairs handed out in replay
    /// `epoch`.
    pub fn new(forks: usize, epoch: u64) -> Rounds {
        let forks = forks.max(1);
        Rounds {
            round1: (0..forks).map(|_| DepositWriter::new(false, epoch)).collect(),
            round2: (0..forks).map(|_| DepositWriter::new(true, epoch)).collect(),
        }
    }

    /// Adds traced pair `pair`, whose element fork `owner` owns, with its `deposits`
    /// (element, r g b fixed point) routed by `owner_of` (below the number of forks,
    /// see [`element_owner`]). The pair's round-2 message is written even when it
    /// deposited nothing: it marks the pair complete.
    pub fn add(
        &mut self,
        pair: u64,
        owner: usize,
        deposits: impl IntoIterator<Item = (u32, [i64; 3])>,
        owner_of: impl Fn(u32) -> usize,
    ) {
        self.round2[owner].pair(pair);
        for (e, f) in deposits {
            let fork = owner_of(e);
            if fork == owner {
                self.round2[owner].deposit(e, f);
                continue;
            }
            if !self.round1[fork].last_pair_is(pair) {
                self.round1[fork].pair(pair);
                self.round2[owner].also_on(fork as u32);
            }
            self.round1[fork].deposit(e, f);
        }
    }

    /// The messages: round 1 and round 2, indexed by fork (empty ones are not sent).
    pub fn into_writers(self) -> (Vec<DepositWriter>, Vec<DepositWriter>) {
        (self.round1, self.round2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use magg_core::pair::Pair;
    use magg_proto::deposits::read;
    use std::collections::BTreeMap;

    /// Element blocks (64 elements each) from block 10: the owner of an element is not
    /// simply `e % F`.
    fn layout() -> BlockLayout {
        BlockLayout {
            bvh_base: 3,
            patch_base: 3,
            shading_base: 10,
            texture_base: 10,
            element_base: 10,
            vertex_base: 60,
            total: 70,
        }
    }

    /// A seeded batch: 40 pairs over 160 elements, up to 6 deposits each, some on one
    /// element twice (a pair may deposit on an element more than once).
    fn batch() -> Vec<(u64, Vec<(u32, [i64; 3])>)> {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        (0..40)
            .map(|k| {
                let n = next() % 7;
                let mut ds: Vec<_> = (0..n).map(|_| ((next() % 160) as u32, [next() as i64 % 1000, 1, -2])).collect();
                if n > 2 {
                    ds.push(ds[0]);
                }
                (3 * k + next() % 3, ds)
            })
            .collect()
    }

    #[test]
    fn deposits_go_to_the_fork_owning_their_element_none_lost_none_doubled() {
        let l = layout();
        for forks in [1usize, 2, 5] {
            let elements = 160;
            let owner_of = |e: u32| element_owner(&l, forks, e);
            let mut rounds = Rounds::new(forks, 3);
            let mut sent: BTreeMap<(u64, u32), Vec<[i64; 3]>> = BTreeMap::new();
            let mut also: BTreeMap<u64, Vec<u32>> = BTreeMap::new();
            for (pair, ds) in batch() {
                let owner = owner_of(Pair::element_of(pair, elements));
                for &(e, f) in &ds {
                    sent.entry((pair, e)).or_default().push(f);
                    if owner_of(e) != owner {
                        also.entry(pair).or_default().push(owner_of(e) as u32);
                    }
                }
                rounds.add(pair, owner, ds, owner_of);
            }
            let (round1, round2) = rounds.into_writers();
            assert_eq!((round1.len(), round2.len()), (forks, forks));
            let mut got: BTreeMap<(u64, u32), Vec<[i64; 3]>> = BTreeMap::new();
            let mut got_also: BTreeMap<u64, Vec<u32>> = BTreeMap::new();
            let mut completed = Vec::new();
            for (round, complete) in [(round1, false), (round2, true)] {
                for (fork, w) in round.into_iter().enumerate() {
                    let req = w.finish();
                    assert_eq!((req.complete, req.epoch), (complete, 3));
                    for p in read(&req).unwrap().pairs() {
                        let owner = owner_of(Pair::element_of(p.pair, elements));
                        assert_eq!(fork == owner, complete, "pair {} in the wrong round on fork {fork}", p.pair);
                        if complete {
                            completed.push(p.pair);
                            got_also.entry(p.pair).or_default().extend(p.also_on);
                        }
                        for (&e, f) in p.elements.iter().zip(p.energy.chunks_exact(3)) {
                            assert_eq!(owner_of(e), fork, "element {e} sent to fork {fork} of {forks}");
                            got.entry((p.pair, e)).or_default().push([f[0], f[1], f[2]]);
                        }
                    }
                }
            }
            assert_eq!(got, sent, "{forks} forks: deposits lost or doubled");
            let pairs: Vec<u64> = batch().iter().map(|b| b.0).collect();
            completed.sort_unstable();
            let mut want = pairs.clone();
            want.sort_unstable();
            assert_eq!(completed, want, "every pair completed once, on its owner");
            for (pair, mut forks_on) in also {
                forks_on.sort_unstable();
                forks_on.dedup();
                let mut named = got_also.remove(&pair).unwrap_or_default();
                named.sort_unstable();
                assert_eq!(named, forks_on, "pair {pair}: the other forks it deposited on");
            }
            assert!(got_also.values().all(|v| v.is_empty()));
            if forks == 1 {
                assert!(sent.len() > 20, "the batch deposits somewhere");
            }
        }
    }

    #[test]
    fn a_single_fork_gets_everything_in_round_two() {
        let (round1, round2) = {
            let mut r = Rounds::new(1, 0);
            r.add(5, 0, [(1, [1, 2, 3]), (9, [4, 5, 6])], |e| element_owner(&layout(), 1, e));
            r.into_writers()
        };
        assert!(round1[0].is_empty());
        let req = round2[0].clone().finish();
        let arrays = read(&req).unwrap();
        let p: Vec<_> = arrays.pairs().collect();
        assert_eq!((p.len(), p[0].pair, p[0].elements, p[0].also_on), (1, 5, &[1, 9][..], &[][..]));
    }

    #[test]
    fn elements_are_owned_by_their_element_blocks_fork() {
        let l = layout();
        // Elements 0..64 in block 10, 64..128 in block 11, ...
        assert_eq!(element_owner(&l, 5, 0), 0);
        assert_eq!(element_owner(&l, 5, 64), 1);
        assert_eq!(element_owner(&l, 2, 130), 0);
        assert_eq!(element_owner(&l, 3, 130), 0);
        assert_eq!(element_owner(&l, 3, 127), 2);
        assert_eq!(element_owner(&l, 1, 150), 0);
        assert_eq!(element_owner(&l, 0, 150), 0, "no forks is taken as one");
    }
}
