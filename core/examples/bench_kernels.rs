//! Rays per second of the LRT and VRT kernels on one core, printed as a markdown table.
//!
//! For each scene, the example prepares the scene, renders it once on all cores to get the
//! vertex energies that VRT interpolates, then times, on this thread alone, one node's
//! share of each pass through a fresh block cache (unlimited, then bounded):
//!
//! - **LRT**: the (light, element) pairs in the embedded renderer's order, in batches of 8
//!   consecutive pairs (the renderer's `PAIR_BATCH`), keeping every k-th batch;
//! - **VRT**: the 16 x 16 subscreens in row order, keeping every k-th subscreen.
//!
//! k is chosen so that about `--pairs` pairs and `--pixels` pixels are traced: the sample
//! is deterministic and spread over the whole scene, and each node-sized batch keeps the
//! locality that the cache sees in a real render. A sample that takes less than
//! `--min-time` seconds is run again, each time from a cold cache, until it has; the
//! table gives the sums. Rays are the kernels' own counts (`OpCounters::light_rays`,
//! `view_rays`: primary and secondary rays).
//!
//! ```text
//! cargo run --release -p magg-core --example bench_kernels                # both scenes
//! cargo run --release -p magg-core --example bench_kernels -- \
//!     --scenes scenes/magg-paper.toml --cache 40 --pairs 4000 --pixels 20000
//! ```
//! `deploy/bench-kernels.sh` wraps it; `docs/PERFORMANCE.md` records its figures.

use magg_core::blocks::{BlockCache, BlockSource, MemStore};
use magg_core::camera::CameraRig;
use magg_core::energy::vertex_energy_blocks;
use magg_core::pair::Pair;
use magg_core::prepared::PreparedScene;
use magg_core::progress::NoProgress;
use magg_core::render::{render, RenderOptions};
use magg_core::subscreen;
use magg_core::trace::TraceScratch;
use magg_core::view::SceneView;
use magg_core::{lrt, scene, vrt};
use magg_prepare::prepare;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

/// Pairs per batch, as the embedded renderer hands them out.
const PAIR_BATCH: u64 = 8;
/// Subscreen edge, as the embedded renderer's default.
const SUBSCREEN: u32 = 16;

struct Args {
    scenes: Vec<PathBuf>,
    cache: usize,
    pairs: u64,
    pixels: u64,
    min_time: f64,
    accel: Option<scene::Accel>,
}

fn usage() -> &'static str {
    "usage: bench_kernels [--scenes A.toml[,B.toml...]] [--cache BLOCKS] [--pairs N] [--pixels N] [--min-time S]\n\
     [--accel bvh|grid] (default: each scene's own)\n\
     defaults: scenes/magg-paper.toml,scenes/large.toml; cache 40; pairs 20000; pixels 60000;\n\
     min-time 1"
}

fn parse_args() -> Result<Args, String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut a = Args {
        scenes: vec![root.join("scenes/magg-paper.toml"), root.join("scenes/large.toml")],
        cache: 40,
        pairs: 20_000,
        pixels: 60_000,
        min_time: 1.0,
        accel: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or_else(|| format!("{flag} needs a value"));
        match flag.as_str() {
            "--scenes" => a.scenes = value()?.split(',').filter(|s| !s.is_empty()).map(PathBuf::from).collect(),
            "--cache" => a.cache = value()?.parse().map_err(|e| format!("--cache: {e}"))?,
            "--pairs" => a.pairs = value()?.parse().map_err(|e| format!("--pairs: {e}"))?,
            "--pixels" => a.pixels = value()?.parse().map_err(|e| format!("--pixels: {e}"))?,
            "--min-time" => a.min_time = value()?.parse().map_err(|e| format!("--min-time: {e}"))?,
            "--accel" => {
                let v = value()?;
                a.accel = Some(scene::Accel::parse(&v).ok_or_else(|| format!("--accel {v:?}: bvh or grid"))?);
            }
            "-h" | "--help" => return Err(usage().into()),
            other => return Err(format!("unknown argument {other}\n{}", usage())),
        }
    }
    Ok(a)
}

/// A prepared scene and a store holding its blocks with the vertex energies published.
struct Fixture {
    name: String,
    prepared: PreparedScene,
    store: Arc<MemStore>,
}

fn load(path: &Path, accel: Option<scene::Accel>) -> Result<Fixture, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let label = path.display().to_string();
    let mut sc =
        scene::parse_scene_str(&label, &text, base, &|p: &Path| std::fs::read(p)).map_err(|e| e.to_string())?;
    if let Some(a) = accel {
        sc.settings.accel = a;
    }
    let prepared = prepare(&sc).map_err(|e| e.to_string())?;
    // One full render on all cores, only for the vertex energies VRT reads.
    let out = render(&prepared, &RenderOptions::default(), &NoProgress).map_err(|e| e.to_string())?;
    let store = Arc::new(MemStore::new(prepared.blocks.clone()));
    for (id, block) in vertex_energy_blocks(&out.vertex_irradiance, &[], &prepared.header.layout) {
        store.replace(id, block).map_err(|e| e.to_string())?;
    }
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or(label);
    Ok(Fixture { name, prepared, store })
}

/// One measurement: rays traced, seconds, cache hit ratio, work items, repetitions.
#[derive(Default)]
struct Measure {
    rays: u64,
    seconds: f64,
    hits: u64,
    accesses: u64,
    work: u64,
    runs: u32,
    grid_steps: u64,
    patch_tests: u64,
}

impl Measure {
    fn add(&mut self, o: Measure) {
        self.rays += o.rays;
        self.seconds += o.seconds;
        self.hits += o.hits;
        self.accesses += o.accesses;
        self.work = o.work;
        self.grid_steps += o.grid_steps;
        self.patch_tests += o.patch_tests;
        self.runs += 1;
    }
    fn hit_ratio(&self) -> f64 {
        if self.accesses == 0 {
            1.0
        } else {
            self.hits as f64 / self.accesses as f64
        }
    }
}

/// Runs `once` from a cold cache until `min_time` seconds have been measured.
fn repeat(min_time: f64, mut once: impl FnMut() -> Result<Measure, String>) -> Result<Measure, String> {
    let mut m = Measure::default();
    while m.runs == 0 || m.seconds < min_time {
        m.add(once()?);
    }
    Ok(m)
}

fn measure(v: &SceneView, t: Instant, rays: u64, work: u64) -> Measure {
    let c = v.cache_stats();
    Measure {
        seconds: t.elapsed().as_secs_f64(),
        rays,
        hits: c.hits,
        accesses: c.hits + c.misses,
        work,
        runs: 1,
        grid_steps: v.counters.grid_steps,
        patch_tests: v.counters.patch_tests,
    }
}

fn view(f: &Fixture, cache: Option<usize>) -> SceneView {
    let source: Arc<dyn BlockSource> = f.store.clone();
    SceneView::new(f.prepared.header.clone(), BlockCache::new(source, cache))
}

fn run_lrt(f: &Fixture, cache: Option<usize>, target_pairs: u64) -> Result<Measure, String> {
    let h = &f.prepared.header;
    let n_el = h.counts.elements;
    let total = h.lights.len() as u64 * n_el as u64;
    let batches = total.div_ceil(PAIR_BATCH);
    let keep_every = (batches * PAIR_BATCH / target_pairs.max(1)).max(1);
    let mut v = view(f, cache);
    let mut scratch = TraceScratch::default();
    let mut work = 0;
    let t = Instant::now();
    for b in (0..batches).step_by(keep_every as usize) {
        for k in b * PAIR_BATCH..((b + 1) * PAIR_BATCH).min(total) {
            let Pair { light, element } = Pair::from_id(k, n_el);
            let r = lrt::trace_pair(&mut v, &mut scratch, light, element).map_err(|e| e.to_string())?;
            std::hint::black_box(r);
            work += 1;
        }
    }
    Ok(measure(&v, t, v.counters.light_rays, work))
}

fn run_vrt(f: &Fixture, cache: Option<usize>, target_pixels: u64) -> Result<Measure, String> {
    let h = &f.prepared.header;
    let s = &h.settings;
    let rig = CameraRig::new(&h.camera, s.width, s.height);
    let tiles = subscreen::tile(s.width, s.height, SUBSCREEN);
    let per_tile = (SUBSCREEN * SUBSCREEN) as u64;
    let keep_every = (tiles.len() as u64 * per_tile / target_pixels.max(1)).max(1);
    let mut v = view(f, cache);
    let mut scratch = TraceScratch::default();
    let mut work = 0;
    let t = Instant::now();
    for tile in tiles.iter().step_by(keep_every as usize) {
        let mut px = Vec::with_capacity(tile.pixels() as usize);
        vrt::shade_pixels(&mut v, &mut scratch, &rig, *tile, &mut px).map_err(|e| e.to_string())?;
        std::hint::black_box(&px);
        work += tile.pixels();
    }
    Ok(measure(&v, t, v.counters.view_rays, work))
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for path in &args.scenes {
        let t = Instant::now();
        let f = match load(path, args.accel) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("bench_kernels: {e}");
                return ExitCode::FAILURE;
            }
        };
        let h = &f.prepared.header;
        eprintln!(
            "{}: {} elements, {} blocks, {} lights, {}x{} pixels; set up in {:.1} s",
            f.name,
            h.counts.elements,
            h.layout.total,
            h.lights.len(),
            h.settings.width,
            h.settings.height,
            t.elapsed().as_secs_f64()
        );
        let mut sampled = (0, 0);
        let mut runs = Vec::new();
        for (cache_label, cache) in
            [("unlimited".to_string(), None), (format!("{} blocks", args.cache), Some(args.cache))]
        {
            for kernel in ["LRT", "VRT"] {
                let m = repeat(args.min_time, || {
                    if kernel == "LRT" {
                        run_lrt(&f, cache, args.pairs)
                    } else {
                        run_vrt(&f, cache, args.pixels)
                    }
                });
                let m = match m {
                    Ok(m) => m,
                    Err(e) => {
                        eprintln!("bench_kernels: {}: {kernel}: {e}", f.name);
                        return ExitCode::FAILURE;
                    }
                };
                runs.push(format!("{kernel} {cache_label} {}", m.runs));
                if kernel == "LRT" {
                    sampled.0 = m.work;
                } else {
                    sampled.1 = m.work;
                }
                eprintln!(
                    "  {kernel} {cache_label}: {} rays in {:.2} s ({} runs); per ray: {:.1} \
                     subspaces, {:.1} patch tests",
                    m.rays,
                    m.seconds,
                    m.runs,
                    m.grid_steps as f64 / m.rays.max(1) as f64,
                    m.patch_tests as f64 / m.rays.max(1) as f64
                );
                rows.push(format!(
                    "| {} | {kernel} | {cache_label} | {} | {:.2} | {:.0} | {:.4} |",
                    f.name,
                    m.rays,
                    m.seconds,
                    m.rays as f64 / m.seconds.max(1e-9),
                    m.hit_ratio()
                ));
            }
        }
        let total_pairs = h.lights.len() as u64 * h.counts.elements as u64;
        let total_pixels = h.settings.width as u64 * h.settings.height as u64;
        notes.push(format!(
            "- {}: {} blocks in all; one run traces {} of {} LRT pairs and {} of {} VRT \
             pixels ({} samples per pixel); runs: {}.",
            f.name,
            h.layout.total,
            sampled.0,
            total_pairs,
            sampled.1,
            total_pixels,
            h.plan.pixel_samples.max(1),
            runs.join(", ")
        ));
    }
    println!("| scene | kernel | cache | rays | seconds | rays/s per core | hit ratio |");
    println!("|---|---|---|---:|---:|---:|---:|");
    for r in rows {
        println!("{r}");
    }
    println!();
    for n in notes {
        println!("{n}");
    }
    ExitCode::SUCCESS
}
