//! Fixtures shared by the fork's integration tests.

use magg_core::scene::parse_scene_str;
use magg_prepare::prepare;
use magg_proto::v1;

/// A valid `LoadShard` request of fork 0 of 2 for the paper's scene.
pub fn load_request() -> v1::LoadShardRequest {
    let text = include_str!("../../../scenes/magg-paper.toml");
    let read = |p: &std::path::Path| std::fs::read(p);
    let scene = prepare(&parse_scene_str("magg-paper.toml", text, "scenes".as_ref(), &read).unwrap()).unwrap();
    let blocks = (0..scene.blocks.len() as u32)
        .filter(|b| b % 2 == 0)
        .map(|b| magg_proto::convert::block_to_wire(b, &scene.blocks[b as usize]))
        .collect();
    v1::LoadShardRequest {
        protocol_version: magg_proto::PROTOCOL_VERSION,
        fork_index: 0,
        fork_addrs: vec!["127.0.0.1:1".into(), "127.0.0.1:2".into()],
        header: Some(v1::SceneHeader::from(&*scene.header)),
        blocks,
        ..Default::default()
    }
}
