//! Pair leases: the pairs of a node that stops asking go back to the queue after the
//! lease, first in line for the next node; a node whose batches are slow keeps its pairs
//! (a lease lasts several of its gaps); a replay queues every pair again and ignores
//! completions from before it.

mod common;

use common::load_request;
use magg_fork::Shard;
use magg_proto::v1;
use std::time::Duration;

fn shard(lease_ms: u32) -> Shard {
    Shard::load(v1::LoadShardRequest { lease_ms, ..load_request() }, Default::default()).unwrap()
}

#[test]
fn a_silent_nodes_pairs_go_to_the_next_node() {
    let s = shard(50);
    let (lost, _) = s.take_own_pairs(8, 1);
    std::thread::sleep(Duration::from_millis(120));
    assert_eq!(s.energies(true).pairs_returned, 8, "the lease expired");
    let (next, _) = s.take_own_pairs(8, 2);
    assert_eq!(next, lost, "given-back pairs come first");
}

#[test]
fn a_slow_but_live_node_keeps_its_pairs() {
    let s = shard(50);
    s.take_own_pairs(8, 1);
    std::thread::sleep(Duration::from_millis(40));
    s.take_own_pairs(8, 1); // a gap of 40 ms: leases now last at least 160 ms
    std::thread::sleep(Duration::from_millis(60));
    assert_eq!(s.energies(true).pairs_returned, 0, "a live node lost its pairs");
}

#[test]
fn a_replay_queues_every_pair_again_and_ignores_older_completions() {
    let s = shard(0);
    let (pairs, epoch) = s.take_own_pairs(4, 1);
    assert_eq!(epoch, 0);
    assert!(s.replay(1) > 0);
    let done = |p: u64, epoch: u64| v1::PairDeposits { pair: p, deposits: vec![], complete: true, epoch };
    s.deposit(&[done(pairs[0], 0)]).unwrap();
    assert_eq!(s.energies(true).pairs_done, 0, "a completion from before the replay counted");
    let (again, epoch) = s.take_own_pairs(4, 2);
    assert_eq!((again, epoch), (pairs.clone(), 1));
    s.deposit(&[done(pairs[0], 1)]).unwrap();
    assert_eq!(s.energies(true).pairs_done, 1);
    assert_eq!(s.replay(1), 0, "a repeated replay changes nothing");
}
