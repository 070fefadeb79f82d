//! Rays traced together give, bit for bit, what each traced alone gives, and read far
//! fewer blocks through a small node cache: a pair's light rays a generation at a time,
//! a batch's deposits binned together, a subscreen's viewing rays in waves and stages;
//! and, through a cache that fetches ahead as a node's does, in far fewer requests.
//! (scenes/cornell.toml: a glass sphere and a mirror block, three levels of refinement.)

use magg_core::blocks::{Block, BlockCache, BlockError, BlockSource, MemStore};
use magg_core::camera::CameraRig;
use magg_core::color::Rgb;
use magg_core::energy::vertex_energy_blocks;
use magg_core::lrt::{bin, trace_pair, trace_pair_raw, trace_pairs, LrtTally};
use magg_core::pair::Pair;
use magg_core::prepared::PreparedScene;
use magg_core::scene::parse_scene_with_path;
use magg_core::subscreen::Subscreen;
use magg_core::trace::TraceScratch;
use magg_core::view::SceneView;
use magg_core::vrt::{shade_pixel, shade_pixels};
use magg_prepare::prepare;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// scenes/cornell.toml at 64 x 64, 8 light rays a pair, with made-up vertex energies
/// (so that the elements' light shows in every pixel).
fn cornell() -> PreparedScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let (mut s, _) = parse_scene_with_path("cornell.toml", &text, path.parent().unwrap(), &|p: &Path| std::fs::read(p))
        .unwrap_or_else(|e| panic!("{e}"));
    (s.settings.width, s.settings.height, s.settings.light_rays) = (64, 64, 8);
    let mut p = prepare(&s).unwrap();
    let n = p.vertex_positions.len();
    let irr: Vec<Rgb> = (0..n).map(|i| Rgb([(i % 7) as f64, (i % 11) as f64 * 0.5, 1.0 + (i % 3) as f64])).collect();
    for (id, block) in vertex_energy_blocks(&irr, &[], &p.header.layout) {
        p.blocks[id as usize] = block;
    }
    p
}

/// All the flux a tally accounts for.
fn accounted(t: &LrtTally) -> f64 {
    [t.reached, t.occluded, t.absorbed, t.diffuse_end, t.escaped, t.cut].iter().map(|c| c.0.iter().sum::<f64>()).sum()
}

fn view(p: &PreparedScene, cache: Option<usize>) -> SceneView {
    SceneView::new(p.header.clone(), BlockCache::new(Arc::new(MemStore::new(p.blocks.clone())), cache))
}

/// A scene's blocks that count the requests made of them (a node's fork answers a
/// request for many blocks at once).
struct Requests(MemStore, AtomicU64);

impl BlockSource for Requests {
    fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError> {
        self.1.fetch_add(1, Ordering::Relaxed);
        self.0.fetch(id, out)
    }
    fn fetch_batch(&self, ids: &[u32], out: &mut [Box<Block>]) -> Result<(), BlockError> {
        self.1.fetch_add(1, Ordering::Relaxed);
        ids.iter().zip(out.iter_mut()).try_for_each(|(&id, b)| self.0.fetch(id, b))
    }
}

/// A view through a cache of `blocks` blocks that counts its requests, fetching ahead
/// (as a node's cache does) or not (the paper's scheme: a block per request).
fn counted(p: &PreparedScene, blocks: usize, ahead: bool) -> (SceneView, Arc<Requests>) {
    let source = Arc::new(Requests(MemStore::new(p.blocks.clone()), AtomicU64::new(0)));
    let mut cache = BlockCache::new(source.clone(), Some(blocks));
    if ahead {
        cache = cache.with_prefetch(8, 1, vec![0, p.header.layout.total]);
    }
    (SceneView::new(p.header.clone(), cache), source)
}

/// The pairs of the scene's light with its mirror's and its glass's elements (the ones
/// a light pass traces when direct light is computed at VRT), and some others.
fn specular_pairs(p: &PreparedScene) -> Vec<Pair> {
    let mut v = view(p, None);
    let specular = |v: &mut SceneView, e: u32| {
        let patch = v.element(e).unwrap().patch;
        let m = v.patch(patch).unwrap().material;
        v.header.materials[m as usize].is_specular()
    };
    let all = p.elements.len() as u32;
    let mut pairs: Vec<Pair> = (0..all).filter(|&e| specular(&mut v, e)).step_by(3).map(|e| Pair::new(0, e)).collect();
    assert!(pairs.len() > 100, "{} specular pairs", pairs.len());
    pairs.extend((0..all).step_by(997).map(|e| Pair::new(0, e)));
    pairs
}

#[test]
fn a_batch_of_pairs_deposits_what_each_pair_deposits_alone() {
    let p = cornell();
    let pairs = specular_pairs(&p);
    let mut scratch = TraceScratch::default();
    let mut v = view(&p, None);
    let alone: Vec<_> =
        pairs.iter().map(|&Pair { light: l, element: e }| trace_pair(&mut v, &mut scratch, l, e).unwrap()).collect();
    assert!(alone.iter().filter(|r| r.deposits.len() > 3).count() > 50, "the pairs deposit little");
    for batch in [1, 7, 64, pairs.len()] {
        // Through a bounded cache the rays go in waves (depth first with every block
        // resident): the deposits are the same bits. The tallies (diagnostics, summed
        // in tracing order) agree to rounding.
        let mut v = view(&p, Some(40));
        let together: Vec<_> =
            pairs.chunks(batch).flat_map(|c| trace_pairs(&mut v, &mut scratch, c).unwrap()).collect();
        assert_eq!(together.len(), alone.len());
        for (k, (t, a)) in together.iter().zip(&alone).enumerate() {
            assert_eq!(t.deposits, a.deposits, "pair {k} in batches of {batch}");
            let (t, a) = (accounted(&t.tally), accounted(&a.tally));
            assert!((t - a).abs() <= 1e-12 * a.abs().max(1e-30), "pair {k}: tally {t} against {a}");
        }
    }
}

#[test]
fn a_batch_of_pairs_misses_a_small_cache_far_less_than_its_pairs_one_by_one() {
    let p = cornell();
    let pairs = specular_pairs(&p);
    let mut scratch = TraceScratch::default();
    let mut one = view(&p, Some(40));
    for &Pair { light: l, element: e } in &pairs {
        trace_pair(&mut one, &mut scratch, l, e).unwrap();
    }
    let mut batched = view(&p, Some(40));
    for c in pairs.chunks(256) {
        trace_pairs(&mut batched, &mut scratch, c).unwrap();
    }
    let (one, batched) = (one.cache_stats().misses, batched.cache_stats().misses);
    assert!(batched * 3 < one * 2, "{batched} misses in batches against {one} one by one");
}

#[test]
fn a_subscreen_shaded_together_is_each_pixel_shaded_alone() {
    let p = cornell();
    let rig = CameraRig::new(&p.header.camera, 64, 64);
    let mut scratch = TraceScratch::default();
    // In waves through a bounded cache; depth first, pixel by pixel, with every block
    // resident.
    let (mut bounded, mut resident) = (view(&p, Some(40)), view(&p, None));
    // The glass sphere and the mirror block are in the image's lower half.
    for s in [Subscreen { x: 8, y: 30, w: 48, h: 30 }, Subscreen { x: 3, y: 5, w: 1, h: 7 }] {
        let mut together = Vec::new();
        shade_pixels(&mut bounded, &mut scratch, &rig, s, &mut together).unwrap();
        let mut alone = Vec::new();
        for y in s.y..s.y + s.h {
            for x in s.x..s.x + s.w {
                alone.push(shade_pixel(&mut resident, &mut scratch, &rig, x, y).unwrap());
                assert_eq!(shade_pixel(&mut bounded, &mut scratch, &rig, x, y).unwrap(), *alone.last().unwrap());
            }
        }
        assert_eq!(together, alone, "subscreen {s:?}");
    }
}

#[test]
fn a_subscreen_shaded_together_misses_a_small_cache_far_less_than_pixel_by_pixel() {
    let p = cornell();
    let rig = CameraRig::new(&p.header.camera, 64, 64);
    let mut scratch = TraceScratch::default();
    let s = Subscreen { x: 0, y: 0, w: 64, h: 64 };
    let mut one = view(&p, Some(40));
    for y in 0..64 {
        for x in 0..64 {
            shade_pixel(&mut one, &mut scratch, &rig, x, y).unwrap();
        }
    }
    let mut together = view(&p, Some(40));
    for band in (0..64).step_by(4) {
        shade_pixels(&mut together, &mut scratch, &rig, Subscreen { y: band, h: 4, ..s }, &mut Vec::new()).unwrap();
    }
    let (one, together) = (one.cache_stats().misses, together.cache_stats().misses);
    assert!(together * 2 < one, "{together} misses in bands against {one} pixel by pixel");
}

#[test]
fn fetched_ahead_the_light_and_viewing_passes_give_the_same_bits() {
    let p = cornell();
    let pairs = specular_pairs(&p);
    let rig = CameraRig::new(&p.header.camera, 64, 64);
    let mut scratch = TraceScratch::default();
    let mut resident = view(&p, None);
    let alone: Vec<_> = pairs
        .iter()
        .map(|&Pair { light: l, element: e }| trace_pair(&mut resident, &mut scratch, l, e).unwrap())
        .collect();
    let s = Subscreen { x: 8, y: 30, w: 48, h: 30 };
    let mut pixels = Vec::new();
    for y in s.y..s.y + s.h {
        for x in s.x..s.x + s.w {
            pixels.push(shade_pixel(&mut resident, &mut scratch, &rig, x, y).unwrap());
        }
    }
    // Down to a cache of two blocks, which fetches one ahead at a time.
    for blocks in [2, 7, 40] {
        let (mut v, requests) = counted(&p, blocks, true);
        let together: Vec<_> = pairs.chunks(64).flat_map(|c| trace_pairs(&mut v, &mut scratch, c).unwrap()).collect();
        for (k, (t, a)) in together.iter().zip(&alone).enumerate() {
            assert_eq!(t.deposits, a.deposits, "pair {k} through {blocks} blocks");
        }
        let mut shaded = Vec::new();
        shade_pixels(&mut v, &mut scratch, &rig, s, &mut shaded).unwrap();
        assert_eq!(shaded, pixels, "through {blocks} blocks");
        let stats = v.cache_stats();
        assert!(stats.prefetched > 0, "through {blocks} blocks nothing was fetched ahead");
        // Two blocks fetch one at a time; more fetch several in a request.
        let asked = requests.1.load(Ordering::Relaxed);
        assert!(asked <= stats.misses + stats.prefetched && (blocks == 2 || asked < stats.misses + stats.prefetched));
    }
}

#[test]
fn fetching_ahead_asks_the_source_far_less_often() {
    let p = cornell();
    let pairs = specular_pairs(&p);
    let rig = CameraRig::new(&p.header.camera, 64, 64);
    let mut scratch = TraceScratch::default();
    // The pairs' deposits as the pilots keep them, binned to the leaves again (what
    // the light pass does with the pilots' pairs), then the viewing pass.
    let mut resident = view(&p, None);
    let raw: Vec<_> = pairs
        .iter()
        .map(|&Pair { light: l, element: e }| trace_pair_raw(&mut resident, &mut scratch, l, e).unwrap())
        .collect();
    let mut requests = Vec::new();
    for ahead in [false, true] {
        let (mut v, source) = counted(&p, 40, ahead);
        for (&Pair { element: e, .. }, r) in pairs.iter().zip(&raw) {
            bin(&mut v, e, r).unwrap();
        }
        let light = source.1.load(Ordering::Relaxed);
        for band in (0..64).step_by(4) {
            let s = Subscreen { x: 0, y: band, w: 64, h: 4 };
            shade_pixels(&mut v, &mut scratch, &rig, s, &mut Vec::new()).unwrap();
        }
        requests.push((light, source.1.load(Ordering::Relaxed) - light));
    }
    let [(light, view), (light_ahead, view_ahead)] = requests[..] else { unreachable!() };
    assert!(light_ahead * 2 < light, "binning: {light_ahead} requests fetching ahead against {light}");
    assert!(view_ahead * 3 < view * 2, "viewing pass: {view_ahead} requests fetching ahead against {view}");
}

/// A pilot level's batch through a bounded cache (its raw deposits gathered first, then
/// binned together) gives what each of its pairs gives traced alone through such a
/// cache, bit for bit, and the deposits of each pair alone with every block at hand
/// (the tallies, summed in tracing order, to rounding); and so does the next level's
/// batch, whose pairs are all kept already.
#[test]
fn a_pilot_batch_through_a_small_cache_gives_what_each_pair_gives_alone() {
    use magg_core::kept::KeptPairs;
    let p = cornell();
    let pairs = specular_pairs(&p);
    let mut scratch = TraceScratch::default();
    let alone = |cache: Option<usize>, scratch: &mut TraceScratch| {
        let (kept, mut v) = (KeptPairs::default(), view(&p, cache));
        pairs
            .iter()
            .map(|&Pair { light: l, element: e }| kept.trace(&mut v, scratch, l, e).unwrap())
            .collect::<Vec<_>>()
    };
    let (resident, small_alone) = (alone(None, &mut scratch), alone(Some(40), &mut scratch));
    assert!(resident.iter().filter(|r| r.deposits.len() > 3).count() > 50, "the pairs deposit little");
    let (kept, (mut small, _)) = (KeptPairs::default(), counted(&p, 40, true));
    for level in ["first level (traced and kept)", "next level (binned from the kept)"] {
        let mut together = Vec::new();
        for batch in pairs.chunks(64) {
            kept.trace_each(&mut small, &mut scratch, batch, |_, r| together.push(r)).unwrap();
        }
        assert!(together == small_alone, "{level}: a batch's results differ from its pairs' alone");
        for (k, (t, a)) in together.iter().zip(&resident).enumerate() {
            assert_eq!(t.deposits, a.deposits, "{level}, pair {k}");
            let (t, a) = (accounted(&t.tally), accounted(&a.tally));
            assert!((t - a).abs() <= 1e-12 * a.abs().max(1e-30), "{level}, pair {k}: tally {t} against {a}");
        }
    }
    assert!(small.cache_stats().misses > 0, "the cache held every block");
    // A batch that names a pair twice gets its result twice.
    let (kept, (mut small, _)) = (KeptPairs::default(), counted(&p, 40, true));
    let (mut twice, batch) = (Vec::new(), [pairs[0], pairs[1], pairs[0]]);
    kept.trace_each(&mut small, &mut scratch, &batch, |_, r| twice.push(r)).unwrap();
    assert!(twice == [small_alone[0].clone(), small_alone[1].clone(), small_alone[0].clone()], "a repeated pair");
}
