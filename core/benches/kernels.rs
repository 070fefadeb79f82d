//! Criterion benchmark of the two kernels, in rays per second on one thread.
//!
//! Groups `lrt` and `vrt`, each over scene {magg-paper, large} x cache {unlimited, 40
//! blocks}. One iteration is a fixed batch of work:
//!
//! - `lrt`: 64 (light, element) pairs, as 8 batches of 8 consecutive pairs spread evenly
//!   over all pairs (what one node pulls from the renderer's queue);
//! - `vrt`: the 32 x 32 block of pixels at the centre of the image.
//!
//! The view and its cache live across iterations, so the figures are steady-state: the
//! unlimited cache is warm after the first iteration, the 40-block cache keeps evicting
//! whenever the batch touches more than 40 blocks. The throughput is the batch's ray
//! count (`OpCounters::light_rays` / `view_rays`, primary and secondary), so criterion
//! prints rays/s. Set-up renders each scene once on all cores for the vertex energies
//! that VRT interpolates.
//!
//! ```text
//! cargo bench -p magg-core --bench kernels
//! cargo bench -p magg-core --bench kernels -- 'vrt/magg-paper'   # a filter
//! ```
//! `core/examples/bench_kernels.rs` prints a table over a larger sample instead.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use magg_core::blocks::{BlockCache, BlockSource, MemStore};
use magg_core::camera::CameraRig;
use magg_core::energy::vertex_energy_blocks;
use magg_core::pair::Pair;
use magg_core::prepared::PreparedScene;
use magg_core::progress::NoProgress;
use magg_core::render::{render, RenderOptions};
use magg_core::trace::TraceScratch;
use magg_core::view::SceneView;
use magg_core::{lrt, scene, vrt};
use magg_prepare::prepare;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

const SCENES: [(&str, &str); 2] = [("magg-paper", "scenes/magg-paper.toml"), ("large", "scenes/large.toml")];
const CACHES: [(&str, Option<usize>); 2] = [("unlimited", None), ("40-blocks", Some(40))];
const PAIR_BATCH: u64 = 8;
const PAIR_BATCHES: u64 = 8;
const PIXEL_BLOCK: u32 = 32;

struct Fixture {
    name: &'static str,
    prepared: PreparedScene,
    store: Arc<MemStore>,
}

fn fixture(name: &'static str, rel: &str) -> Fixture {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let base = path.parent().unwrap_or(Path::new("."));
    let sc = scene::parse_scene_str(rel, &text, base, &|p: &Path| std::fs::read(p)).unwrap_or_else(|e| panic!("{e}"));
    let prepared = prepare(&sc).unwrap_or_else(|e| panic!("{rel}: {e}"));
    let out = render(&prepared, &RenderOptions::default(), &NoProgress).unwrap_or_else(|e| panic!("{rel}: {e}"));
    let store = Arc::new(MemStore::new(prepared.blocks.clone()));
    for (id, block) in vertex_energy_blocks(&out.vertex_irradiance, &[], &prepared.header.layout) {
        store.replace(id, block).unwrap_or_else(|e| panic!("{rel}: {e}"));
    }
    Fixture { name, prepared, store }
}

fn new_view(f: &Fixture, cache: Option<usize>) -> SceneView {
    let source: Arc<dyn BlockSource> = f.store.clone();
    SceneView::new(f.prepared.header.clone(), BlockCache::new(source, cache))
}

/// The 64 pairs of one LRT iteration.
fn pair_batch(f: &Fixture) -> Vec<Pair> {
    let h = &f.prepared.header;
    let n_el = h.counts.elements;
    let total = h.lights.len() as u64 * n_el as u64;
    let stride = (total / (PAIR_BATCH * PAIR_BATCHES)).max(1) * PAIR_BATCH;
    (0..PAIR_BATCHES)
        .flat_map(|b| (b * stride..b * stride + PAIR_BATCH).filter(move |&k| k < total))
        .map(|k| Pair::from_id(k, n_el))
        .collect()
}

fn lrt_batch(v: &mut SceneView, s: &mut TraceScratch, pairs: &[Pair]) -> u64 {
    let before = v.counters.light_rays;
    for &Pair { light, element } in pairs {
        let r = lrt::trace_pair(v, s, light, element).unwrap_or_else(|e| panic!("{e}"));
        std::hint::black_box(r);
    }
    v.counters.light_rays - before
}

fn vrt_batch(v: &mut SceneView, s: &mut TraceScratch, rig: &CameraRig, x0: u32, y0: u32) -> u64 {
    let before = v.counters.view_rays;
    let mut px = Vec::with_capacity((PIXEL_BLOCK * PIXEL_BLOCK) as usize);
    let block = magg_core::subscreen::Subscreen { x: x0, y: y0, w: PIXEL_BLOCK, h: PIXEL_BLOCK };
    vrt::shade_pixels(v, s, rig, block, &mut px).unwrap_or_else(|e| panic!("{e}"));
    std::hint::black_box(&px);
    v.counters.view_rays - before
}

fn kernels(c: &mut Criterion) {
    let fixtures: Vec<Fixture> = SCENES.iter().map(|&(n, p)| fixture(n, p)).collect();

    let mut g = c.benchmark_group("lrt");
    g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    for f in &fixtures {
        let pairs = pair_batch(f);
        for (cache_name, cache) in CACHES {
            let mut v = new_view(f, cache);
            let mut s = TraceScratch::default();
            let rays = lrt_batch(&mut v, &mut s, &pairs);
            g.throughput(Throughput::Elements(rays));
            g.bench_function(BenchmarkId::new(f.name, cache_name), |b| b.iter(|| lrt_batch(&mut v, &mut s, &pairs)));
        }
    }
    g.finish();

    let mut g = c.benchmark_group("vrt");
    g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    for f in &fixtures {
        let h = &f.prepared.header;
        let (w, hh) = (h.settings.width, h.settings.height);
        let rig = CameraRig::new(&h.camera, w, hh);
        let x0 = (w / 2).saturating_sub(PIXEL_BLOCK / 2);
        let y0 = (hh / 2).saturating_sub(PIXEL_BLOCK / 2);
        for (cache_name, cache) in CACHES {
            let mut v = new_view(f, cache);
            let mut s = TraceScratch::default();
            let rays = vrt_batch(&mut v, &mut s, &rig, x0, y0);
            g.throughput(Throughput::Elements(rays));
            g.bench_function(BenchmarkId::new(f.name, cache_name), |b| {
                b.iter(|| vrt_batch(&mut v, &mut s, &rig, x0, y0))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
