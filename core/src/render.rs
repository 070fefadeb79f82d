//! The embedded renderer: N node workers in this process, each with its own LRU block
//! cache over an in-memory store, running the phases LRT -> interpolation -> VRT with
//! barriers. Nodes pull pairs and subscreens from shared queues (dynamic load balancing
//! as in paper §4.4 and §4.6), so every core is busy; the result does not depend on the
//! number of nodes, the cache size or the order work completes in. When the nodes are as
//! many as the cores (the default), node i's threads are pinned to core i
//! ([`crate::placement`]), as the in-process cluster's nodes are.
//!
//! [`EmbeddedMachine`] is one of the two [`Machine`]s (the cluster is the other): the
//! phases themselves are sequenced by [`crate::phases::run`]; [`render`] and
//! [`render_sequence`] run them on an embedded machine.

use crate::blocks::{home_fork_of_node, BlockCache, BlockError, BlockSource, CacheSize, MemStore};
use crate::camera::CameraRig;
use crate::color::Rgb;
use crate::energy::vertex_energy_blocks;
use crate::fixed::Fixed;
use crate::frame::Frame;
use crate::lrt::{trace_pairs, LrtTally, PairResult};
use crate::machine::{
    self, FrameSink, Machine, MachineFigures, PhaseTimes, RenderError, RenderOutput, Sequence, ViewPass, ViewedFrame,
};
use crate::pair::Pair;
use crate::prepared::PreparedScene;
use crate::progress::Progress;
use crate::scene::Camera;
use crate::stats::{NodeStats, Stages, Traffic};
use crate::subscreen::{self, Subscreen};
use crate::trace::TraceScratch;
use crate::view::SceneView;
use crate::vrt::shade_pixels;
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
    /// Cache blocks per node.
    pub cache_blocks: CacheSize,
    /// Subscreen edge in pixels.
    pub subscreen: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions { nodes: 0, forks: 5, cache_blocks: CacheSize::Unlimited, subscreen: 16 }
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

/// The result of a node worker thread; a panic becomes an error, not a crash.
fn join_worker<T>(h: std::thread::ScopedJoinHandle<'_, Result<T, BlockError>>) -> Result<T, RenderError> {
    match h.join() {
        Ok(r) => r.map_err(RenderError::from),
        Err(_) => Err(RenderError::Worker("a node worker thread panicked".into())),
    }
}

/// Light pass totals: flux per element, pairs per node, where the light went.
struct LightPass {
    flux: Vec<Fixed>,
    node_pairs: Vec<u64>,
    tally: LrtTally,
    pairs: u64,
}

/// LRT: nodes pull (light, element) pairs from a shared counter (lights: the point
/// lights, then the emitting elements).
/// What traces a batch of (light, element) pairs in [`EmbeddedMachine::light_pass_with`]:
/// [`trace_pairs`], or a stand-in that gives the same results (refinement's pilots reuse
/// a pair's rays).
pub type PairTracer<'a> =
    dyn Fn(&mut SceneView, &mut TraceScratch, &[Pair]) -> Result<Vec<PairResult>, BlockError> + Sync + 'a;

fn light_pass(
    views: &mut [SceneView],
    cores: &[usize],
    header: &crate::header::SceneHeader,
    progress: &dyn Progress,
    trace: &PairTracer,
) -> Result<LightPass, RenderError> {
    let n_el = header.counts.elements;
    let flux: Vec<[AtomicI64; 3]> =
        (0..n_el).map(|_| [AtomicI64::new(0), AtomicI64::new(0), AtomicI64::new(0)]).collect();
    let total_pairs = if header.plan.lrt { header.pair_count() } else { 0 };
    let next_pair = AtomicU64::new(0);
    const PAIR_BATCH: u64 = 8;
    progress.begin(crate::progress::LIGHT_PASS, total_pairs);
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
                        let batch: Vec<Pair> = (start..end).map(|k| Pair::from_id(k, n_el)).collect();
                        for r in trace(view, &mut scratch, &batch)? {
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
                        // A watcher's snapshot: relaxed loads of the sums, which the pass
                        // neither waits for nor sees.
                        if progress.light_snapshot_due() {
                            progress.light_snapshot(load_flux(flux));
                        }
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
    Ok(LightPass { flux: load_flux(&flux), node_pairs, tally, pairs: total_pairs })
}

/// The element sums of the light pass as they stand.
fn load_flux(flux: &[[AtomicI64; 3]]) -> Vec<Fixed> {
    flux.iter()
        .map(|a| [a[0].load(Ordering::Relaxed), a[1].load(Ordering::Relaxed), a[2].load(Ordering::Relaxed)])
        .collect()
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
    progress.begin(crate::progress::VIEW_PASS, subscreen::pixels(tiles));
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
                        shade_pixels(view, &mut scratch, rig, t, &mut px)?;
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

/// The embedded machine: `nodes` worker threads in this process, each a [`SceneView`]
/// with its own LRU block cache over one in-memory store of the scene's blocks.
pub struct EmbeddedMachine {
    store: Arc<MemStore>,
    header: Arc<crate::header::SceneHeader>,
    views: Vec<SceneView>,
    cores: Vec<usize>,
    opts: RenderOptions,
    forks: u32,
    tiles: Vec<Subscreen>,
    node_pairs: Vec<u64>,
    node_tiles: Vec<u64>,
    tally: LrtTally,
    preprocess_s: f64,
    started: Instant,
    /// Refinement's pilot pairs, binned instead of traced by the light pass (dropped
    /// after it).
    kept_pairs: Option<Arc<crate::kept::KeptPairs>>,
}

impl EmbeddedMachine {
    /// A machine for `prepared` shaped by `opts` (its clock starts now).
    pub fn new(prepared: &PreparedScene, opts: &RenderOptions) -> EmbeddedMachine {
        let started = Instant::now();
        let header = prepared.header.clone();
        let nodes = opts.node_count();
        let forks = opts.forks.max(1);
        let store = Arc::new(MemStore::new(prepared.blocks.clone()));
        let views = (0..nodes)
            .map(|node| {
                let source: Arc<dyn BlockSource> = store.clone();
                let cache = BlockCache::new(source, opts.cache_blocks.blocks().map(|c| c as usize))
                    .with_home(home_fork_of_node(node, forks), forks);
                SceneView::new(header.clone(), cache)
            })
            .collect();
        let s = &header.settings;
        let tiles = subscreen::tile(s.width, s.height, opts.subscreen);
        EmbeddedMachine {
            store,
            views,
            // Node i's threads run on core i when the nodes fill the cores.
            cores: crate::placement::worker_cores(nodes as usize),
            opts: opts.clone(),
            forks,
            tiles,
            node_pairs: vec![0; nodes as usize],
            node_tiles: vec![0; nodes as usize],
            tally: LrtTally::default(),
            preprocess_s: prepared.preprocess_s,
            started,
            header,
            kept_pairs: prepared.kept_pairs.take(),
        }
    }
}

impl EmbeddedMachine {
    /// The light pass with pairs traced by `trace` ([`Machine::light_pass`] uses
    /// [`trace_pairs`]).
    pub fn light_pass_with(
        &mut self,
        trace: &PairTracer,
        progress: &dyn Progress,
    ) -> Result<machine::LightPass, RenderError> {
        let light = light_pass(&mut self.views, &self.cores, &self.header, progress, trace)?;
        self.node_pairs = light.node_pairs;
        self.tally = light.tally;
        Ok(machine::LightPass { element_flux: light.flux, pairs: light.pairs, collect_s: 0.0 })
    }
}

impl Machine for EmbeddedMachine {
    fn light_pass(&mut self, progress: &dyn Progress) -> Result<machine::LightPass, RenderError> {
        match self.kept_pairs.take() {
            Some(kept) => {
                let trace = |view: &mut SceneView, scratch: &mut TraceScratch, batch: &[Pair]| {
                    let mut results = Vec::with_capacity(batch.len());
                    crate::kept::trace_pairs_kept(view, scratch, batch, Some(&kept), |_, r| results.push(r))?;
                    Ok(results)
                };
                self.light_pass_with(&trace, progress)
            }
            None => self.light_pass_with(&trace_pairs, progress),
        }
    }

    fn publish_vertex_energies(&mut self, vertex_irradiance: &[Rgb], gather: &[bool]) -> Result<(), RenderError> {
        for (id, block) in vertex_energy_blocks(vertex_irradiance, gather, &self.header.layout) {
            self.store.replace(id, block)?;
        }
        for v in self.views.iter_mut() {
            v.invalidate_vertex_energy();
        }
        Ok(())
    }

    fn view_pass(&mut self, pass: ViewPass<'_>, progress: &dyn Progress) -> Result<ViewedFrame, RenderError> {
        let tiles = pass.tiles(&self.tiles);
        let (frame, per_node) = view_pass(&mut self.views, &self.cores, &self.header, pass.camera, &tiles, progress)?;
        for (n, t) in self.node_tiles.iter_mut().zip(per_node) {
            *n += t;
        }
        Ok(ViewedFrame { frame, tiles: tiles.len() as u64, redivisions: 0 })
    }

    fn figures(&mut self, times: PhaseTimes) -> Result<MachineFigures, RenderError> {
        let per_node = self
            .views
            .iter()
            .enumerate()
            .map(|(node, view)| NodeStats {
                node: node as u32,
                home_fork: home_fork_of_node(node as u32, self.forks),
                pairs: self.node_pairs.get(node).copied().unwrap_or(0),
                tiles: self.node_tiles[node],
                cache: view.cache_stats().into(),
                ops: view.counters,
                ..Default::default()
            })
            .collect();
        let cache = self.views.iter().fold(crate::blocks::CacheStats::default(), |a, v| a.add(v.cache_stats()));
        Ok(MachineFigures {
            mode: "embedded".into(),
            nodes: self.views.len() as u32,
            forks: self.forks,
            cache_blocks: self.opts.cache_blocks,
            profile: "native".into(),
            scheme: "magg".into(),
            cache,
            traffic: Traffic {
                link_bytes: 0,
                dma_bytes: cache.misses * crate::blocks::BLOCK_SIZE as u64,
                gbus_bytes: cache.remote_misses * crate::blocks::BLOCK_SIZE as u64,
                rpcs: 0,
            },
            light: self.tally,
            per_node,
            emulation: None,
            stages: Stages::measured(self.preprocess_s, times.lrt_s, times.interp_s, times.vrt_s, self.started),
            fork_peak_bytes: Vec::new(),
        })
    }
}

/// Renders a prepared scene in this process: one frame of the scene's camera.
pub fn render(
    prepared: &PreparedScene,
    opts: &RenderOptions,
    progress: &dyn Progress,
) -> Result<RenderOutput, RenderError> {
    render_sequence(prepared, opts, progress, &Sequence::default(), &mut |_, _, _| Ok(()))
}

/// Renders a prepared scene in this process: the phases of [`crate::phases::run`] on an
/// [`EmbeddedMachine`] shaped by `opts`.
pub fn render_sequence(
    prepared: &PreparedScene,
    opts: &RenderOptions,
    progress: &dyn Progress,
    seq: &Sequence,
    sink: &mut FrameSink<'_>,
) -> Result<RenderOutput, RenderError> {
    let mut machine = EmbeddedMachine::new(prepared, opts);
    crate::phases::run(&mut machine, prepared, seq, progress, sink)
}
