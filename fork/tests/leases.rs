//! Pair leases: the pairs of a node that stops asking go back to the queue after the
//! lease, first in line for the next node; a node whose batches are slow keeps its pairs
//! (a lease lasts several of its gaps); a replay queues again the pairs that deposited on
//! the lost fork and those out with nodes, and ignores completions from before it.

mod common;

use common::load_request;
use magg_fork::service::{deposit, load_shard};
use magg_fork::shard::DEFAULT_MAX_MEMORY_MB as MB;
use magg_fork::{ForkError, Shard};
use magg_proto::deposits::DepositWriter;
use magg_proto::v1;
use std::time::Duration;

/// A completion (round 2) of `pairs`, handed out in `epoch`, each also deposited on the
/// forks listed beside it.
fn completions(pairs: &[(u64, Vec<u32>)], epoch: u64) -> v1::DepositRequest {
    let mut w = DepositWriter::new(true, epoch);
    for (p, also_on) in pairs {
        w.pair(*p);
        for &f in also_on {
            w.also_on(f);
        }
    }
    w.finish()
}

fn shard(lease_ms: u32) -> Shard {
    load_shard(v1::LoadShardRequest { lease_ms, ..load_request() }, Default::default(), MB).unwrap()
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
    assert!(s.replay(1, None).unwrap() > 0);
    let done = |p: u64, epoch: u64| completions(&[(p, vec![])], epoch);
    deposit(&s, &done(pairs[0], 0)).unwrap();
    assert_eq!(s.energies(true).pairs_done, 0, "a completion from before the replay counted");
    let (again, epoch) = s.take_own_pairs(4, 2);
    assert_eq!((again, epoch), (pairs.clone(), 1));
    deposit(&s, &done(pairs[0], 1)).unwrap();
    assert_eq!(s.energies(true).pairs_done, 1);
    assert_eq!(s.replay(1, None).unwrap(), 0, "a repeated replay changes nothing");
}

#[test]
fn a_replay_for_a_lost_fork_queues_exactly_the_pairs_that_deposited_on_it() {
    let s = shard(0);
    let (pairs, _) = s.take_own_pairs(6, 1);
    assert_eq!(pairs.len(), 6);
    // Pairs 0, 2 and 4 deposited on fork 1 as well; 1 and 3 only here; 5 is still out.
    let done: Vec<_> =
        pairs[..5].iter().enumerate().map(|(i, &p)| (p, if i % 2 == 0 { vec![1] } else { vec![] })).collect();
    deposit(&s, &completions(&done, 0)).unwrap();
    assert_eq!(s.energies(true).pairs_done, 5);
    assert_eq!(s.replay(1, Some(1)).unwrap(), 4, "three pairs on the lost fork and one out with a node");
    assert_eq!(s.energies(true).pairs_done, 2, "the pairs that never touched fork 1 stay done");
    let (again, epoch) = s.take_own_pairs(64, 2);
    let mut want = vec![pairs[0], pairs[2], pairs[4], pairs[5]];
    want.sort_unstable();
    assert_eq!((again[..4].to_vec(), epoch), (want, 1), "the queued-again pairs come first");
    assert!(!again.contains(&pairs[1]) && !again.contains(&pairs[3]));
}

#[test]
fn replays_naming_no_other_fork_or_jumping_epochs_are_refused() {
    let s = shard(0);
    let forks = s.placement().forks();
    for lost in [0, forks, u32::MAX] {
        assert!(matches!(s.replay(1, Some(lost)), Err(ForkError::BadRequest(_))), "lost fork {lost}");
    }
    assert!(matches!(s.replay(u64::MAX, Some(1)), Err(ForkError::BadRequest(_))));
    assert_eq!(s.energies(true).pairs_done, 0);
    assert!(s.replay(1, Some(1)).is_ok());
}

#[test]
fn a_completion_naming_a_fork_that_is_not_another_one_is_refused() {
    let s = shard(0);
    let (pairs, _) = s.take_own_pairs(1, 1);
    for bad in [0u32, 2, 99] {
        let d = completions(&[(pairs[0], vec![bad])], 0);
        assert!(deposit(&s, &d).is_err(), "also_on {bad} accepted");
    }
    assert_eq!(s.energies(true).pairs_done, 0, "a refused request changed the state");
}

/// Batches are sized by the pairs left in the whole cluster, as this fork has heard of
/// them: large while the other fork still holds its pairs, small once it said it has none.
#[test]
fn batches_shrink_with_the_pairs_left_in_the_cluster_not_only_here() {
    let s = load_shard(v1::LoadShardRequest { nodes: 2, ..load_request() }, Default::default(), MB).unwrap();
    let own = s.pairs_left();
    assert_eq!(own, 832, "magg-paper's 1664 pairs, half of them here");
    // Take all but 40 of this fork's pairs.
    while s.pairs_left() > 40 {
        s.take_own_pairs(8, 1);
    }
    // The other fork is thought to hold its 832: stealing, this one would ask for 64.
    assert_eq!(s.steal_batch(64), 64);
    // Its own 40 count twice (it cannot know the other was not drained as fast): 80 in
    // all, a quarter of a node's share is 10.
    let (pairs, _) = s.take_own_pairs(64, 1);
    assert_eq!(pairs.len(), 10);
    while s.pairs_left() > 0 {
        s.take_own_pairs(8, 1);
    }
    // The other says it has 160 left: 160 in all, a quarter of a node's share is 20.
    s.heard_pairs_left(1, 160);
    assert_eq!(s.steal_batch(64), 20);
    // Then 20: shared out at no fewer than 8 pairs while each node can have that many.
    s.heard_pairs_left(1, 20);
    assert_eq!(s.steal_batch(64), 8);
    s.heard_pairs_left(1, 10);
    assert_eq!(s.steal_batch(64), 5);
    assert_eq!(s.steal_order(), vec![1]);
}

#[test]
fn a_shard_whose_pairs_do_not_fit_is_refused_with_resource_exhausted_before_any_allocation() {
    // The paper's scene (1664 elements, one light) with 65,536 lights: 109 M pairs, over
    // 20 MB of bookkeeping on each of the 2 forks; the limit is 8 MB.
    let mut req = load_request();
    let header = req.header.as_mut().unwrap();
    let light = header.lights[0].clone();
    header.lights = vec![light; 65_536];
    let err = load_shard(req.clone(), Default::default(), 8).unwrap_err();
    let status = tonic::Status::from(err);
    assert_eq!(status.code(), tonic::Code::ResourceExhausted, "{status:?}");
    for part in
        ["pair bookkeeping needs about", "MB (109051904 pairs: 65536 lights x 1664 elements)", "--max-memory-mb 8"]
    {
        assert!(status.message().contains(part), "{part:?} not in {:?}", status.message());
    }
    assert!(load_shard(req, Default::default(), 64).is_ok(), "refused within the limit");
}

#[test]
fn deposits_no_tracing_of_the_scene_makes_are_refused() {
    let s = shard(0);
    let h = s.header();
    let forks = s.placement().forks();
    let e = (0..h.counts.elements)
        .find(|&e| magg_core::blocks::fork_of_block(h.layout.element_slot(e).0, forks) == 0)
        .expect("fork 0 owns an element");
    let one = |rgb: [i64; 3]| {
        let mut w = DepositWriter::new(false, 0);
        w.pair(e as u64); // light 0, element e
        w.deposit(e, rgb);
        w.finish()
    };
    for bad in [[-1, 0, 0], [0, 0, i64::MAX / 8]] {
        let r = deposit(&s, &one(bad));
        assert!(matches!(r, Err(ForkError::BadRequest(_))), "{bad:?}: {r:?}");
    }
    assert_eq!(s.energies(false).energy.iter().flatten().sum::<i64>(), 0, "a refused deposit changed the energy");
    deposit(&s, &one([5, 6, 7])).unwrap();
}

#[test]
fn pairs_go_only_to_the_node_that_shows_its_secret() {
    let key = magg_plumbing::auth::NodeKey::random();
    let req = v1::LoadShardRequest { node_key: key.as_bytes().to_vec().into(), ..load_request() };
    let s = load_shard(req, Default::default(), MB).unwrap();
    assert!(s.admit(3, key.secret(3)).is_ok());
    assert!(matches!(s.admit(3, key.secret(4)), Err(ForkError::NotThatNode(3))));
    assert!(matches!(s.admit(3, 0), Err(ForkError::NotThatNode(3))));
    // A shard loaded without a key (no host asked for one) checks nothing.
    assert!(shard(0).admit(3, 0).is_ok());
}
