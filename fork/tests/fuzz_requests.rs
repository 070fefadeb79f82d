//! Fuzzing what a fork decodes from the wire, with proptest (fixed seed, bounded cases,
//! seconds in CI): arbitrary bytes as every request message of the protocol, mutated
//! `LoadShard` requests (scene header and block conversion, placement checks), and
//! arbitrary `Deposit`, `GetBlocks`, `PutBlocks` and `TakePairs` contents on a loaded
//! shard. Nothing panics; refusals are errors, and a refused request changes nothing.

mod common;

use common::load_request;
use magg_fork::service::{blocks_from_wire, load_shard};
use magg_fork::shard::DEFAULT_MAX_MEMORY_MB as MB;
use magg_proto::deposits::DepositWriter;
use magg_proto::v1;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use prost::Message;

fn runner(seed: u8, cases: u32) -> TestRunner {
    let config = Config { cases, failure_persistence: None, rng_algorithm: RngAlgorithm::ChaCha, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[seed; 32]))
}

/// Decodes `bytes` as every request message; a message that decodes is re-encoded.
fn decode_all(bytes: &[u8]) {
    macro_rules! each {
        ($($t:ty),*) => {$(
            if let Ok(m) = <$t>::decode(bytes) {
                let _ = m.encode_to_vec();
            }
        )*};
    }
    each!(
        v1::LoadShardRequest,
        v1::PutBlocksRequest,
        v1::GetBlocksRequest,
        v1::TakePairsRequest,
        v1::DepositRequest,
        v1::GetEnergiesRequest,
        v1::RegisterRequest,
        v1::NextWorkRequest,
        v1::SubmitRowsRequest
    );
}

#[test]
fn arbitrary_bytes_decode_or_fail_cleanly_as_every_request() {
    runner(1, 1024).run(&proptest::collection::vec(any::<u8>(), 0..256), |b| Ok(decode_all(&b))).unwrap();
}

#[test]
fn mutated_load_shard_requests_load_or_are_refused() {
    let good = load_request().encode_to_vec();
    // Header fields come first in the encoding: mutate there most of the time.
    let head = good.len().min(4096);
    let edits = proptest::collection::vec((0..head, any::<u8>()), 1..6);
    runner(2, 256)
        .run(&(edits, 0..good.len() + 1), |(edits, cut)| {
            let mut bytes = good.clone();
            for (at, v) in edits {
                bytes[at] = v;
            }
            bytes.truncate(cut.max(head));
            decode_all(&bytes);
            if let Ok(req) = v1::LoadShardRequest::decode(bytes.as_slice()) {
                let _ = load_shard(req, Default::default(), MB);
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn arbitrary_requests_on_a_loaded_shard_are_served_or_refused() {
    let shard = load_shard(load_request(), Default::default(), MB).unwrap();
    let pairs = shard.pair_count();
    let blocks = shard.header().layout.total;
    let elements = shard.header().counts.elements;
    // A batch of pairs, written as a node writes it, then now and then one array cut or
    // stretched by one entry: a malformed request.
    let pair = (
        0..pairs + 4,
        proptest::collection::vec((0..elements + 4, any::<i64>()), 0..8),
        proptest::collection::vec(0u32..4, 0..3),
    );
    let deposit = (proptest::collection::vec(pair, 0..6), any::<bool>(), 0u8..12).prop_map(|(ps, complete, cut)| {
        let mut w = DepositWriter::new(complete, 0);
        for (pair, ds, also_on) in ps {
            w.pair(pair);
            for (e, v) in ds {
                w.deposit(e, [v, -v, v / 3]);
            }
            if complete {
                for f in also_on {
                    w.also_on(f);
                }
            }
        }
        let mut r = w.finish();
        // The packed arrays' bytes: one value (or one byte) less, one varint more.
        let cut_to = |b: &bytes::Bytes, less: usize| b.slice(..b.len().saturating_sub(less));
        match cut {
            0 => r.energy = cut_to(&r.energy, 8),
            1 => r.counts = [&r.counts[..], &[1]].concat().into(),
            2 => r.elements = cut_to(&r.elements, 1),
            3 => r.also_on.push(1),
            4 => r.also_on_counts.push(0),
            5 => r.energy = cut_to(&r.energy, 1),
            6 => r.pairs = [&r.pairs[..], &[0x80]].concat().into(),
            _ => {}
        }
        r
    });
    let request = (
        deposit,
        proptest::collection::vec(0..blocks + 4, 0..8),
        proptest::collection::vec((0..blocks + 4, 0..2100usize), 0..3),
        any::<u32>(),
        any::<u32>(),
    );
    runner(3, 512)
        .run(&request, |(deposits, ids, puts, max, node)| {
            let before = shard.energies(false);
            if magg_fork::service::deposit(&shard, &deposits).is_err() {
                prop_assert_eq!(before.energy, shard.energies(false).energy, "a refused deposit changed energy");
            }
            let _ = shard.owned_blocks(&ids);
            let puts = puts.into_iter().map(|(id, len)| v1::Block { id, data: vec![0; len].into() }).collect();
            let _ = blocks_from_wire(puts).and_then(|b| shard.put_blocks(b));
            let (got, _) = shard.take_own_pairs(max, node);
            prop_assert!(got.len() <= magg_fork::shard::MAX_PAIRS_PER_REQUEST as usize);
            Ok(())
        })
        .unwrap();
}
