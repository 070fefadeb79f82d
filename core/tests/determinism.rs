//! The image and the energies are bitwise identical whatever the number of nodes, forks
//! and cache size.

mod common;
use common::*;
use magg_core::blocks::CacheSize;
use magg_core::render::{render, RenderOptions};
use magg_prepare::prepare;

#[test]
fn nodes_forks_and_cache_size_do_not_change_a_bit() {
    let mut patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 5, true);
    patches.extend(boxed(v(-0.6, 0.0, -0.5), v(-0.2, 0.9, -0.1), 1, 2, false));
    patches.extend(boxed(v(0.1, 0.0, 0.0), v(0.5, 0.4, 0.4), 2, 2, false));
    let mut s = scene(
        patches,
        vec![material("white", 0.7, 0.0, 0.0), material("mirror", 0.0, 0.9, 0.0), material("glass", 0.0, 0.0, 0.95)],
        vec![light(v(0.1, 1.7, 0.2), 1.0), light(v(-0.5, 1.2, 0.6), 0.5)],
    );
    s.settings.diffuse_bounces = 1;
    s.settings.pixel_samples = 2;
    let p = prepare(&s).unwrap();
    let base = run(&p, 1, None);
    for (nodes, forks, cache) in [(2, 5, None), (4, 3, Some(20)), (7, 1, Some(3)), (16, 2, Some(60))] {
        let o = render(
            &p,
            &RenderOptions { nodes, forks, cache_blocks: CacheSize::from_blocks(cache), subscreen: 5 },
            &magg_core::progress::NoProgress,
        )
        .unwrap();
        assert_eq!(
            o.element_flux, base.element_flux,
            "energies differ with {nodes} nodes, {forks} forks, cache {cache:?}"
        );
        assert_eq!(o.frame, base.frame, "image differs with {nodes} nodes, {forks} forks, cache {cache:?}");
    }
}

#[test]
fn a_small_cache_misses_more_than_an_unlimited_one() {
    let patches = boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 12, true);
    let s = scene(patches, vec![material("white", 0.7, 0.0, 0.0)], vec![light(v(0.1, 1.7, 0.2), 1.0)]);
    let p = prepare(&s).unwrap();
    let small = run(&p, 1, Some(4));
    let big = run(&p, 1, None);
    assert!(small.stats.cache.hit_ratio < big.stats.cache.hit_ratio);
    // Unlimited: each block is fetched at most once.
    assert!(big.stats.cache.misses <= p.header.layout.total as u64);
    assert!(small.stats.cache.misses > big.stats.cache.misses);
}
