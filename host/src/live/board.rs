//! What the live view shows, kept on the host: a log of the current frame's drawing events
//! (subscreens handed out, pixel rows, redivisions) that every page replays from the
//! start, and the latest stage, progress and per-node table.
//!
//! Messages are JSON objects with a type `t`: `hello`, `frame`, `tile`, `rows`, `split`,
//! `stage`, `nodes`, `preview`, `done` (see `page.html`, which draws them). Pixel rows and
//! previews travel as base64 of little-endian f32 linear RGB; the page tone-maps them
//! itself. The latest preview of the light pass is kept apart from the log (each replaces
//! the one before) and dropped when the viewing pass starts.

use base64::Engine;
use magg_cluster::events::ClusterEvent;
use magg_core::color::Rgb;
use magg_core::subscreen::Subscreen;
use serde::Serialize;
use serde_json::{json, Value};
use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

/// One row of the page's node table.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NodeRow {
    /// Node id.
    pub node: u32,
    /// Name it registered with (cluster) or `thread N` (embedded).
    pub name: String,
    /// Pairs traced.
    pub pairs: u64,
    /// Subscreens taken (redivided parts included).
    pub subscreens: u64,
    /// Light rays traced.
    pub light_rays: u64,
    /// Viewing rays traced.
    pub view_rays: u64,
    /// Cache hits.
    pub hits: u64,
    /// Cache misses (blocks over DMA or G-bus).
    pub misses: u64,
    /// Misses served from a fork other than the home fork (the G-bus path).
    pub remote_misses: u64,
    /// Bytes of its messages with the host (link path); unknown for the embedded renderer.
    pub link_bytes: Option<u64>,
}

/// A traced preview: linear RGB, row by row.
pub struct PreviewImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB, 3 floats per pixel.
    pub rgb: Vec<f32>,
}

/// The shared state, behind a lock, plus a version that wakes the pages' streams.
pub struct Board {
    inner: Mutex<Inner>,
    /// Bumped on every change.
    pub version: tokio::sync::watch::Sender<u64>,
    /// Event streams opened so far (pages that connected).
    pub viewers: std::sync::atomic::AtomicU32,
    /// Event streams open now (pages watching).
    pub watching: std::sync::atomic::AtomicU32,
}

/// The finished images.
#[derive(Clone, Default)]
pub struct Finals {
    /// Tone-mapped PNG.
    pub png: Option<Arc<Vec<u8>>>,
    /// Linear OpenEXR.
    pub exr: Option<Arc<Vec<u8>>>,
}

/// The lock-protected part of the board.
#[derive(Default)]
pub struct Inner {
    /// The `hello` message (scene, size, mode).
    hello: Value,
    /// Messages of the current frame, in order.
    pub log: Vec<Arc<str>>,
    /// Bumped when the log restarts (a new frame).
    pub epoch: u64,
    /// Subscreens of the current frame by id (cluster rows name only the id).
    rects: HashMap<u64, Subscreen>,
    /// Stage name, total and units done.
    pub stage: (String, u64, u64),
    /// When the stage began.
    pub stage_began: Option<Instant>,
    /// When the render began (after any wait for a page).
    pub started: Option<Instant>,
    /// Primary viewing rays per pixel of the viewing pass.
    pub pixel_samples: u64,
    /// The latest `preview` message of the light pass.
    pub preview: Option<Arc<str>>,
    /// Bumped when `preview` changes.
    pub preview_version: u64,
    /// A viewing pass began: the light pass is over, previews are dropped.
    pub viewing: bool,
    /// Per-node figures.
    pub nodes: BTreeMap<u32, NodeRow>,
    /// Bumped when `stage` or `nodes` change.
    pub stage_version: u64,
    /// Bumped when `nodes` change.
    pub nodes_version: u64,
    /// The render is over.
    pub finished: bool,
    /// The images to download.
    pub finals: Finals,
    /// The `done` message, once the render is over.
    pub done: Option<String>,
}

fn b64(px: impl Iterator<Item = f32>) -> String {
    let bytes: Vec<u8> = px.flat_map(f32::to_le_bytes).collect();
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

impl Inner {
    fn push(&mut self, v: Value) {
        self.log.push(v.to_string().into());
    }

    /// Frame `index` of `count` starts its viewing pass: the light pass's preview goes.
    pub fn frame(&mut self, index: usize, count: usize) {
        self.viewing = true;
        self.preview = None;
        self.restart(index, count);
    }

    /// Whether previews of the light pass are still wanted (no viewing pass began).
    pub fn previewing(&self) -> bool {
        !self.viewing
    }

    /// A preview of the light pass, shown until the viewing pass starts.
    pub fn preview(&mut self, img: &PreviewImage) {
        if self.viewing {
            return; // traced from a snapshot taken just before the light pass ended
        }
        let (_, total, done) = &self.stage;
        let m = json!({"t": "preview", "w": img.width, "h": img.height, "pairs_done": done, "pairs_total": total,
                       "px": b64(img.rgb.iter().copied())});
        self.preview = Some(m.to_string().into());
        self.preview_version += 1;
    }

    /// Restarts the log for frame `index` of `count`.
    fn restart(&mut self, index: usize, count: usize) {
        self.epoch += 1;
        self.log.clear();
        self.rects.clear();
        let hello = self.hello.clone();
        self.push(hello);
        self.push(json!({"t": "frame", "index": index, "count": count}));
    }

    /// The row of `node` (created if new), marked changed.
    pub fn node(&mut self, node: u32) -> &mut NodeRow {
        self.nodes_version += 1;
        self.nodes.entry(node).or_insert_with(|| NodeRow { node, ..NodeRow::default() })
    }

    /// Node `node` took subscreen `id`.
    pub fn tile(&mut self, node: u32, id: u64, r: Subscreen) {
        self.rects.insert(id, r);
        self.node(node).subscreens += 1;
        self.push(json!({"t": "tile", "node": node, "x": r.x, "y": r.y, "w": r.w, "h": r.h}));
    }

    /// Rows `y..` of width `w` at `x`, traced by `node`.
    pub fn rows(&mut self, node: u32, x: u32, y: u32, w: u32, px: impl Iterator<Item = f32>) {
        let px: Vec<f32> = px.collect();
        let h = px.len() / (3 * w.max(1) as usize);
        self.push(json!({"t": "rows", "node": node, "x": x, "y": y, "w": w, "h": h, "px": b64(px.into_iter())}));
    }

    /// A subscreen of the embedded renderer, traced whole by `node`.
    pub fn subscreen_done(&mut self, node: u32, t: Subscreen, px: &[Rgb]) {
        let id = self.rects.len() as u64;
        self.tile(node, id, t);
        self.rows(node, t.x, t.y, t.w, px.iter().flat_map(|c| c.0.map(|v| v as f32)));
    }

    /// Applies an event of the host service.
    pub fn cluster(&mut self, e: ClusterEvent) {
        match e {
            ClusterEvent::FrameBegins { index, count } => self.frame(index, count),
            ClusterEvent::Registered { node, name } => self.node(node).name = name,
            ClusterEvent::Report { node, report: r, link_bytes } => {
                let n = self.node(node);
                n.pairs = r.pairs;
                n.light_rays = r.ops.light_rays;
                n.view_rays = r.ops.view_rays;
                n.hits = r.cache.hits;
                n.misses = r.cache.misses;
                n.remote_misses = r.cache.remote_misses;
                n.link_bytes = Some(link_bytes);
            }
            ClusterEvent::Assigned { node, id, rect } => self.tile(node, id, rect),
            ClusterEvent::Rows { node, id, rows } => {
                let (Some(r), Some(first)) = (self.rects.get(&id).copied(), rows.first()) else { return };
                let y = first.y;
                let px =
                    rows.iter().flat_map(|row| magg_proto::convert::pixels_from_wire(&row.rgb)).collect::<Vec<_>>();
                self.rows(node, r.x, y, r.w, px.into_iter());
            }
            ClusterEvent::Redivided { id, at } => {
                if let Some(r) = self.rects.get(&id).copied() {
                    self.push(json!({"t": "split", "x": r.x, "w": r.w, "y": at}));
                }
            }
        }
    }

    /// The `stage` message: the stage's progress, the seconds since the render and the
    /// stage began, the stage's unit of work and, where a unit's ray count is exact (a
    /// pixel casts `pixel_samples` primary viewing rays), its primary rays per unit; the
    /// page derives elapsed time, ETA and rates from them. A light pass pair has no such
    /// count (pairs the plan skips, or whose element the light cannot see, cast none):
    /// the page shows pairs per second there.
    pub fn stage_message(&self) -> String {
        let (name, total, done) = &self.stage;
        let secs = |t: Option<Instant>| t.map_or(0.0, |t| t.elapsed().as_secs_f64());
        let (unit, rays_per_unit) = match name.as_str() {
            magg_core::progress::LIGHT_PASS => ("pairs", 0),
            magg_core::progress::VIEW_PASS => ("pixels", self.pixel_samples),
            _ => ("units", 0),
        };
        json!({"t": "stage", "name": name, "total": total, "done": done, "finished": self.finished,
               "elapsed_s": secs(self.started), "stage_s": secs(self.stage_began), "unit": unit,
               "rays_per_unit": rays_per_unit})
        .to_string()
    }

    /// The `nodes` message.
    pub fn nodes_message(&self) -> String {
        json!({"t": "nodes", "rows": self.nodes.values().collect::<Vec<_>>()}).to_string()
    }
}

impl Board {
    /// An empty board.
    pub fn new() -> Self {
        Board {
            inner: Mutex::new(Inner::default()),
            version: tokio::sync::watch::channel(0).0,
            viewers: std::sync::atomic::AtomicU32::new(0),
            watching: std::sync::atomic::AtomicU32::new(0),
        }
    }

    /// Locks the state (a poisoned lock is recovered: every update is self-contained).
    pub fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Runs `f` on the state and wakes the pages.
    pub fn update(&self, f: impl FnOnce(&mut Inner)) {
        f(&mut self.lock());
        self.version.send_modify(|v| *v += 1);
    }

    /// Sets the `hello` message and starts frame 0.
    pub fn hello(&self, hello: Value, frames: usize) {
        self.update(|s| {
            s.hello = hello;
            s.restart(0, frames);
        });
    }
}

impl Default for Board {
    fn default() -> Self {
        Board::new()
    }
}
