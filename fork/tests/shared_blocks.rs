//! A host that loads a fork of its own process shares the scene's blocks with it
//! (`LoadShardRequest::shared_blocks`) instead of encoding them: the fork takes its own
//! from what is shared, and loads the same shard as from the blocks themselves. A key
//! its process does not share is refused.

mod common;
use common::load_request;
use magg_fork::service::{load_shard, with_shared_blocks};
use magg_fork::shard::DEFAULT_MAX_MEMORY_MB as MB;
use magg_fork::ForkError;
use magg_plumbing::transport::{InProcess, Mode};
use magg_proto::v1;
use std::sync::Arc;

#[test]
fn a_fork_takes_its_own_blocks_from_those_shared_and_loads_the_same_shard() {
    // load_request(): fork 0 of 2, the scene's even blocks.
    let full = load_request();
    let ids: Vec<u32> = full.blocks.iter().map(|b| b.id).collect();
    assert!(ids.iter().all(|id| id % 2 == 0) && ids.len() > 4);
    // Every block of the scene, odd ones too (as the host shares them), by id.
    let all: Vec<v1::Block> = (0..=*ids.last().unwrap())
        .map(|id| match full.blocks.iter().find(|b| b.id == id) {
            Some(b) => b.clone(),
            None => v1::Block { id, data: full.blocks[0].data.clone() },
        })
        .collect();
    let links = InProcess::new(Mode::InProcess);
    let guard = links.share(Arc::new(all)).unwrap();
    // One block of the request replaces the shared one with its id.
    let replaced = v1::Block { id: ids[1], data: full.blocks[2].data.clone() };
    let req = v1::LoadShardRequest { blocks: vec![replaced.clone()], shared_blocks: guard.key(), ..full.clone() };
    let merged = with_shared_blocks(req, &links).unwrap();
    assert_eq!(merged.shared_blocks, 0);
    let mut want = full.blocks.clone();
    want.push(replaced);
    assert_eq!(merged.blocks, want, "its own blocks in id order, then the request's");
    // The G-bus carries the bytes of the request with every block in it.
    assert_eq!(
        prost::Message::encoded_len(&merged),
        prost::Message::encoded_len(&v1::LoadShardRequest { blocks: want, ..full.clone() })
    );
    let shared = load_shard(
        with_shared_blocks(v1::LoadShardRequest { blocks: vec![], shared_blocks: guard.key(), ..full.clone() }, &links)
            .unwrap(),
        Default::default(),
        MB,
    )
    .unwrap();
    let sent = load_shard(full, Default::default(), MB).unwrap();
    assert_eq!((shared.stored_blocks(), shared.pairs_total()), (sent.stored_blocks(), sent.pairs_total()));
}

#[test]
fn a_key_the_process_does_not_share_is_refused() {
    let links = InProcess::new(Mode::InProcess);
    let guard = links.share(Arc::new(Vec::<v1::Block>::new())).unwrap();
    for (links, key) in [(InProcess::none(), 1), (links.clone(), guard.key() + 1)] {
        let req = v1::LoadShardRequest { shared_blocks: key, ..load_request() };
        match with_shared_blocks(req, &links) {
            Err(ForkError::BadRequest(m)) => assert!(m.contains("not in this fork's process"), "{m}"),
            other => panic!("key {key}: {other:?}"),
        }
    }
    // Withdrawn with its guard (the host's render is over).
    let key = guard.key();
    drop(guard);
    assert!(with_shared_blocks(v1::LoadShardRequest { shared_blocks: key, ..load_request() }, &links).is_err());
    // A fork index outside the forks is refused too.
    let guard = links.share(Arc::new(Vec::<v1::Block>::new())).unwrap();
    let req = v1::LoadShardRequest { shared_blocks: guard.key(), fork_index: 2, ..load_request() };
    assert!(matches!(with_shared_blocks(req, &links), Err(ForkError::BadRequest(_))));
}
