//! The embedded renderer: N node workers in this process, each with its own LRU block
//! cache over an in-memory store, running the phases LRT -> interpolation -> VRT with
//! barriers. Nodes pull pairs and subscreens from shared queues (dynamic load balancing
//! as in paper §4.4 and §4.6), so every core is busy; the result does not depend on the
//! number of nodes, the cache size or the order work completes in. When the nodes are as
//! many as the cores (the default), node i's threads are pinned to core i
//! ([`crate::placement`]), as the in-process cluster's nodes are.
//!
//! [`render_sequence`] reuses one light pass for several cameras (a camera path), or
//! skips it when the energies are given (a saved energy file).

use crate::blocks::{BlockCache, BlockError, BlockSource, MemStore};
use crate::camera::CameraRig;
use crate::energy::{interpolate, vertex_energy_blocks, Fixed};
use crate::frame::Frame;
use crate::lrt::{trace_pair, LrtTally};
use crate::math::Rgb;
use crate::preprocess::PreparedScene;
use crate::progress::Progress;
use crate::scene::Camera;
use crate::stats::*;
use crate::trace::TraceScratch;
use crate::view::SceneView;
use crate::vrt::{shade_pixel, Subscreen};
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// How to run the embedded renderer.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Node workers (threads); 0 = one per core.
    pub nodes: u32,
    /// Forks the blocks are interleaved over (for traffic accounting).
    pub forks: u32,
    /// Cache blocks per node; `None` = unlimited.
    pub cache_blocks: Option<u64>,
    /// Subscreen edge in pixels.
    pub subscreen: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { nodes: 0, forks: 5, cache_blocks: None, subscreen: 16 }
    }
}

impl RenderOptions {
    /// The node count to use (resolving 0 to the core count).
    pub fn node_count(&self) -> u32 {
        if self.nodes > 0 {
            self.nodes
        } else {
            std::thread::available_parallelism().map(|n| n.get() as u32).unwrap_or(1)
        }
    }
}

/// Why a render failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A block could not be read.
    #[error(transparent)]
    Block(#[from] BlockError),
    /// A worker thread died.
    #[error("a node worker panicked: {0}")]
    Worker(String),
    /// Given energies do not fit the scene.
    #[error("the energies do not fit the scene: {0}")]
    Energies(String),
    /// The frame sink refused a frame (e.g. an image could not be written).
    #[error("{0}")]
    Output(String),
}

/// What a render produces.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Linear image.
    pub frame: Frame,
    /// Flux per element, fixed point.
    pub element_flux: Vec<Fixed>,
    /// Irradiance per vertex.
    pub vertex_irradiance: Vec<Rgb>,
    /// Figures of the run.
    pub stats: RenderStats,
}

/// Splits the screen into subscreens of `edge` pixels, row by row.
pub fn subscreens(width: u32, height: u32, edge: u32) -> Vec<Subscreen> {
    let edge = edge.max(1);
    let mut v = Vec::new();
    let mut y = 0;
    while y < height {
        let mut x = 0;
        while x < width {
            v.push(Subscreen { x, y, w: edge.min(width - x), h: edge.min(height - y) });
            x += edge;
        }
        y += edge;
    }
    v
}

/// The result of a node worker thread; a panic becomes an error, not a crash.
fn join_worker<T>(h: std::thread::ScopedJoinHandle<'_, Result<T, BlockError>>) -> Result<T, RenderError> {
    match h.join() {
        Ok(r) => r.map_err(RenderError::from),
        Err(_) => Err(RenderError::Worker("a node worker thread panicked".into())),
    }
}

/// Energies of an earlier light pass (e.g. read back from a saved energy file): given
/// them, a render skips LRT and interpolation and goes straight to VRT.
#[derive(Clone, Debug, PartialEq)]
pub struct Energies {
    /// Flux per element, fixed point.
    pub element_flux: Vec<Fixed>,
    /// Irradiance per vertex (as interpolated from `element_flux`).
    pub vertex_irradiance: Vec<Rgb>,
}

impl Energies {
    /// Checks that the energies fit `header`'s element and vertex counts.
    pub fn check(&self, header: &crate::header::SceneHeader) -> Result<(), RenderError> {
        let (e, v) = (header.counts.elements as usize, header.counts.vertices as usize);
        if self.element_flux.len() != e || self.vertex_irradiance.len() != v {
            return Err(RenderError::Energies(format!(
                "{} elements and {} vertices given, the scene has {e} and {v}",
                self.element_flux.len(),
                self.vertex_irradiance.len()
            )));
        }
        Ok(())
    }
}

/// What a render runs beyond one frame of the scene's camera: energies computed before
/// (no light pass), and several cameras (one light pass, one viewing pass per camera).
#[derive(Clone, Debug, Default)]
pub struct Sequence {
    /// Energies to use instead of tracing the light pass.
    pub energies: Option<Arc<Energies>>,
    /// One frame per camera; empty means one frame of the scene's camera.
    pub cameras: Vec<Camera>,
}

impl Sequence {
    /// The cameras of the frames: `cameras`, or the scene's camera alone.
    pub fn frame_cameras(&self, scene_camera: &Camera) -> Vec<Camera> {
        if self.cameras.is_empty() {
            vec![scene_camera.clone()]
        } else {
            self.cameras.clone()
        }
    }
}

/// Receives every finished frame: its index, the frame, and the seconds its viewing pass
/// took. An error stops the render.
pub type FrameSink<'a> = dyn FnMut(usize, &Frame, f64) -> Result<(), String> + 'a;

/// Renders a prepared scene in this process: one frame of the scene's camera.
pub fn render(
    prepared: &PreparedScene,
    opts: &RenderOptions,
    progress: &dyn Progress,
) -> Result<RenderOutput, RenderError> {
    render_sequence(prepared, opts, progress, &Sequence::default(), &mut |_, _, _| Ok(()))
}

/// Light pass totals: flux per element, pairs per node, where the light went.
struct LightPass {
    flux: Vec<Fixed>,
    node_pairs: Vec<u64>,
    tally: LrtTally,
    pairs: u64,
}

/// LRT: nodes pull (light, element) pairs from a shared counter.
fn light_pass(
    views: &mut [SceneView],
    cores: &[usize],
    header: &crate::header::SceneHeader,
    progress: &dyn Progress,
) -> Result<LightPass, RenderError> {
    let n_el = header.counts.elements;
    let n_lights = header.lights.len() as u32;
    let flux: Vec<[AtomicI64; 3]> =
        (0..n_el).map(|_| [AtomicI64::new(0), AtomicI64::new(0), AtomicI64::new(0)]).collect();
    let total_pairs = if header.plan.lrt { n_lights as u64 * n_el as u64 } else { 0 };
    let next_pair = AtomicU64::new(0);
    const PAIR_BATCH: u64 = 8;
    progress.begin("light ray tracing", total_pairs);
    let lrt_results: Vec<Result<(u64, LrtTally), RenderError>> = std::thread::scope(|s| {
        let handles: Vec<_> = views
            .iter_mut()
            .enumerate()
            .map(|(node, view)| {
                let (flux, next_pair) = (&flux, &next_pair);
                s.spawn(move || -> Result<(u64, LrtTally), BlockError> {
                    crate::placement::pin_worker(cores, node);
                    let mut scratch = TraceScratch::default();
                    let mut tally = LrtTally::default();
                    let mut pairs = 0;
                    loop {
                        let start = next_pair.fetch_add(PAIR_BATCH, Ordering::Relaxed);
                        if start >= total_pairs {
                            break;
                        }
                        let end = (start + PAIR_BATCH).min(total_pairs);
                        for k in start..end {
                            let (light, element) = ((k / n_el as u64) as u32, (k % n_el as u64) as u32);
                            let r = trace_pair(view, &mut scratch, light, element)?;
                            for (e, f) in r.deposits {
                                if let Some(slot) = flux.get(e as usize) {
                                    for c in 0..3 {
                                        slot[c].fetch_add(f[c], Ordering::Relaxed);
                                    }
                                }
                            }
                            tally = tally.add(r.tally);
                            pairs += 1;
                        }
                        progress.advance(end - start);
                    }
                    Ok((pairs, tally))
                })
            })
            .collect();
        handles.into_iter().map(join_worker).collect()
    });
    progress.end();
    let mut node_pairs = Vec::with_capacity(views.len());
    let mut tally = LrtTally::default();
    for r in lrt_results {
        let (p, t) = r?;
        node_pairs.push(p);
        tally = tally.add(t);
    }
    let flux = flux
        .iter()
        .map(|a| [a[0].load(Ordering::Relaxed), a[1].load(Ordering::Relaxed), a[2].load(Ordering::Relaxed)])
        .collect();
    Ok(LightPass { flux, node_pairs, tally, pairs: total_pairs })
}

/// VRT of one frame: nodes pull subscreens from a shared queue. Returns the frame and
/// the subscreens each node traced.
fn view_pass(
    views: &mut [SceneView],
    cores: &[usize],
    header: &crate::header::SceneHeader,
    camera: &Camera,
    tiles: &[Subscreen],
    progress: &dyn Progress,
) -> Result<(Frame, Vec<u64>), RenderError> {
    let s = &header.settings;
    let rig = CameraRig::new(camera, s.width, s.height);
    let queue = Mutex::new(tiles.iter().copied().rev().collect::<Vec<_>>());
    // Each worker copies a finished subscreen into the frame at once: the frame is
    // assembled while the others trace, not after the last of them.
    let frame = Mutex::new(Frame::new(s.width, s.height));
    progress.begin("viewing ray tracing", s.width as u64 * s.height as u64);
    let vrt_results: Vec<Result<u64, RenderError>> = std::thread::scope(|sc| {
        let handles: Vec<_> = views
            .iter_mut()
            .enumerate()
            .map(|(node, view)| {
                let (queue, rig, frame) = (&queue, &rig, &frame);
                sc.spawn(move || -> Result<u64, BlockError> {
                    crate::placement::pin_worker(cores, node);
                    let mut scratch = TraceScratch::default();
                    let mut done = 0;
                    let mut px = Vec::new();
                    loop {
                        let tile = match queue.lock() {
                            Ok(mut q) => q.pop(),
                            Err(_) => None,
                        };
                        let Some(t) = tile else { break };
                        px.clear();
                        for y in t.y..t.y + t.h {
                            for x in t.x..t.x + t.w {
                                px.push(shade_pixel(view, &mut scratch, rig, x, y)?);
                            }
                        }
                        progress.subscreen_done(node as u32, t, &px);
                        progress.advance(t.pixels());
                        let mut f = frame.lock().unwrap_or_else(|p| p.into_inner());
                        let mut it = px.iter();
                        for y in t.y..t.y + t.h {
                            for x in t.x..t.x + t.w {
                                if let Some(v) = it.next() {
                                    f.set(x, y, *v);
                                }
                            }
                        }
                        done += 1;
                    }
                    Ok(done)
                })
            })
            .collect();
        handles.into_iter().map(join_worker).collect()
    });
    progress.end();
    let node_tiles = vrt_results.into_iter().collect::<Result<Vec<u64>, RenderError>>()?;
    let frame = frame.into_inner().unwrap_or_else(|p| p.into_inner());
    Ok((frame, node_tiles))
}

/// Renders a prepared scene in this process: the light pass once (or not at all when
/// `seq` brings energies), then one viewing pass per camera of `seq`, each frame handed
/// to `sink` as it is done. The output's frame is the last one.
pub fn render_sequence(
    prepared: &PreparedScene,
    opts: &RenderOptions,
    progress: &dyn Progress,
    seq: &Sequence,
    sink: &mut FrameSink<'_>,
) -> Result<RenderOutput, RenderError> {
    let t_start = Instant::now();
    let header = prepared.header.clone();
    let nodes = opts.node_count();
    let forks = opts.forks.max(1);
    let store = Arc::new(MemStore::new(prepared.blocks.clone()));
    let make_view = |node: u32| {
        let source: Arc<dyn BlockSource> = store.clone();
        let cache = BlockCache::new(source, opts.cache_blocks.map(|c| c as usize)).with_home(node % forks, forks);
        SceneView::new(header.clone(), cache)
    };
    let mut views: Vec<SceneView> = (0..nodes).map(make_view).collect();
    // Node i's threads run on core i when the nodes fill the cores.
    let cores = crate::placement::worker_cores(nodes as usize);

    // --- LRT, unless the energies are given.
    let t_lrt = Instant::now();
    let light = match &seq.energies {
        Some(e) => {
            e.check(&header)?;
            LightPass {
                flux: e.element_flux.clone(),
                node_pairs: vec![0; nodes as usize],
                tally: LrtTally::default(),
                pairs: 0,
            }
        }
        None => light_pass(&mut views, &cores, &header, progress)?,
    };
    let lrt_s = if seq.energies.is_some() { 0.0 } else { t_lrt.elapsed().as_secs_f64() };

    // --- Energy interpolation (the given energies carry theirs).
    let t_interp = Instant::now();
    let element_flux = light.flux;
    let vertex_irradiance = match &seq.energies {
        Some(e) => e.vertex_irradiance.clone(),
        None => interpolate(&prepared.elements, &element_flux, header.counts.vertices as usize, header.energy_quantum),
    };
    for (id, block) in vertex_energy_blocks(&vertex_irradiance, &header.layout) {
        store.replace(id, block)?;
    }
    for v in views.iter_mut() {
        v.invalidate_vertex_energy();
    }
    let interp_s = t_interp.elapsed().as_secs_f64();

    // --- VRT: one viewing pass per camera.
    let s = &header.settings;
    let tiles = subscreens(s.width, s.height, opts.subscreen);
    let cameras = seq.frame_cameras(&header.camera);
    let mut node_tiles = vec![0u64; nodes as usize];
    let mut vrt_s = 0.0;
    let mut frame = Frame::new(s.width, s.height);
    for (index, camera) in cameras.iter().enumerate() {
        progress.frame_begins(index, cameras.len());
        let t_vrt = Instant::now();
        let (f, per_node) = view_pass(&mut views, &cores, &header, camera, &tiles, progress)?;
        let frame_s = t_vrt.elapsed().as_secs_f64();
        vrt_s += frame_s;
        for (n, t) in node_tiles.iter_mut().zip(per_node) {
            *n += t;
        }
        sink(index, &f, frame_s).map_err(RenderError::Output)?;
        frame = f;
    }

    let per_node = views
        .iter()
        .enumerate()
        .map(|(node, view)| NodeStats {
            node: node as u32,
            home_fork: node as u32 % forks,
            pairs: light.node_pairs.get(node).copied().unwrap_or(0),
            tiles: node_tiles[node],
            cache: view.cache_stats().into(),
            ops: view.counters,
            ..Default::default()
        })
        .collect();
    let cache_total = views.iter().fold(crate::blocks::CacheStats::default(), |a, v| a.add(v.cache_stats()));
    let ops = views.iter().fold(crate::view::OpCounters::default(), |a, v| a.add(v.counters));
    let stats = RenderStats {
        scene: prepared.name.clone(),
        mode: "embedded".into(),
        nodes,
        forks,
        cache_blocks: opts.cache_blocks,
        profile: "native".into(),
        scheme: "magg".into(),
        stages: Stages::measured(prepared.preprocess_s, lrt_s, interp_s, vrt_s, t_start),
        cache: cache_total.into(),
        traffic: Traffic {
            link_bytes: 0,
            dma_bytes: cache_total.misses * crate::blocks::BLOCK_SIZE as u64,
            gbus_bytes: cache_total.remote_misses * crate::blocks::BLOCK_SIZE as u64,
            rpcs: 0,
        },
        work: Work {
            pairs: light.pairs,
            tiles: tiles.len() as u64 * cameras.len() as u64,
            redivisions: 0,
            light_rays: ops.light_rays,
            view_rays: ops.view_rays,
        },
        plan: (&header.plan).into(),
        counts: header.counts,
        light: light.tally,
        per_node,
        emulation: None,
    };
    Ok(RenderOutput { frame, element_flux, vertex_irradiance, stats })
}
