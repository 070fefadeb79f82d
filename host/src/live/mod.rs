//! The live view (`magg-host render --view ADDR`): a web page that shows a render as it
//! runs, the way the paper's frame buffer would have: the frame filling in, the subscreen
//! map coloured by the node that traced each part, redivisions as they happen, the stage
//! and its progress, and a table per node; the finished image downloads as PNG or EXR.
//!
//! The server runs on a runtime of its own (one thread), so it neither slows nor waits on
//! the render's. The page gets server-sent events; the cluster's host service feeds the
//! board through [`magg_cluster::events`], the embedded renderer through the
//! [`Progress`] hooks (there, per-node figures other than subscreens arrive at the end).
//! During the light pass, both machines hand the [`Progress`] hooks snapshots of the
//! element flux while a page is open, and the page shows a small preview traced from
//! them ([`preview`]); the stage message carries the times and units the page derives
//! elapsed time, ETA and rates (pairs, pixels and primary viewing rays per second) from.
//!
//! ```text
//! magg-host render scenes/cornell.toml --out c.png --view 127.0.0.1:8080 --view-linger 600
//! # open http://127.0.0.1:8080/
//! ```

mod board;
pub mod preview;
mod server;

use crate::frames::RunStats;
use anyhow::Context;
use board::Board;
use magg_cluster::events::EventSender;
use magg_core::color::Rgb;
use magg_core::fixed::Fixed;
use magg_core::frame::Frame;
use magg_core::prepared::PreparedScene;
use magg_core::progress::Progress;
use magg_core::scene::{Camera, Exposure};
use magg_core::subscreen::Subscreen;
use preview::{Preview, Previewer};
use serde_json::json;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A running live view.
pub struct LiveView {
    board: Arc<Board>,
    /// The light pass's preview thread, once [`LiveView::preview_light_pass`] started it.
    /// Declared before `rt`: stopped first.
    preview: Option<Preview>,
    rt: tokio::runtime::Runtime,
    addr: std::net::SocketAddr,
}

impl LiveView {
    /// Serves the page on `addr` (HOST:PORT; port 0 picks a free one).
    pub fn start(addr: &str) -> anyhow::Result<LiveView> {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("magg-live-view")
            .enable_all()
            .build()
            .context("starting the live view's runtime")?;
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(addr))
            .with_context(|| format!("--view {addr}: cannot listen there"))?;
        let addr = listener.local_addr()?;
        let board = Arc::new(Board::new());
        let app = server::router(board.clone());
        rt.spawn(async move {
            if let Err(e) = axum::serve(listener, app).await {
                tracing::warn!("live view server stopped: {e}");
            }
        });
        Ok(LiveView { board, preview: None, rt, addr })
    }

    /// The page's address.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Announces the render: scene label, image size, how it runs, frame count.
    /// `exposure` is the PNG's (`null` on the page for auto).
    pub fn begin(&self, scene: &str, width: u32, height: u32, exposure: Exposure, mode: &str, frames: usize) {
        let exposure = match exposure {
            Exposure::Fixed(s) => Some(s),
            Exposure::Auto => None,
        };
        let hello = json!({"t": "hello", "scene": scene, "width": width, "height": height,
                           "exposure": exposure, "mode": mode, "frames": frames});
        self.board.hello(hello, frames);
    }

    /// Previews the light pass of `scene` as seen by `camera` (the first frame's) while a
    /// page is open (see [`preview`]).
    pub fn preview_light_pass(&mut self, scene: Arc<PreparedScene>, camera: &Camera) -> anyhow::Result<()> {
        let previewer = Previewer::new(scene, camera);
        self.preview =
            Some(Preview::start(self.board.clone(), previewer).context("starting the live view's preview thread")?);
        Ok(())
    }

    /// The render begins now (after any wait for a page): the page's clock starts. A
    /// pixel casts `pixel_samples` primary viewing rays.
    pub fn rendering(&self, pixel_samples: u32) {
        self.board.update(|s| {
            s.started = Some(Instant::now());
            s.pixel_samples = pixel_samples as u64;
        });
    }

    /// A channel for the cluster's host service; its events are applied in order.
    pub fn cluster_events(&self) -> EventSender {
        let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
        let board = self.board.clone();
        self.rt.spawn(async move {
            while let Some(e) = rx.recv().await {
                board.update(|s| s.cluster(e));
            }
        });
        tx
    }

    /// Waits until a page has opened the event stream, at most `limit`; true if one did.
    pub fn wait_for_viewer(&self, limit: Duration) -> bool {
        let end = Instant::now() + limit;
        while Instant::now() < end {
            if self.board.viewers.load(Ordering::SeqCst) > 0 {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }

    /// The render is over: publishes the final frame (PNG and EXR to download) and the
    /// final per-node figures of `stats`.
    pub fn finish(&self, frame: &Frame, exposure: Exposure, stats: &RunStats<'_>) -> anyhow::Result<()> {
        let png = Arc::new(crate::images::encode_png(frame, exposure)?);
        let exr = Arc::new(crate::images::encode_exr(frame)?);
        let r = stats.render;
        self.board.update(|s| {
            for n in &r.per_node {
                let row = s.node(n.node);
                row.pairs = n.pairs;
                row.light_rays = n.ops.light_rays;
                row.view_rays = n.ops.view_rays;
                row.hits = n.cache.hits;
                row.misses = n.cache.misses;
            }
            s.finished = true;
            s.stage_version += 1;
            s.finals = board::Finals { png: Some(png), exr: Some(exr) };
            let done = json!({
                "t": "done",
                "png": "/image.png",
                "exr": "/image.exr",
                "stages": r.stages,
                "traffic": r.traffic,
                "work": r.work,
                "light_passes": stats.energy.light_passes,
                "frames": stats.frames.len(),
            });
            s.done = Some(done.to_string());
        });
        Ok(())
    }

    /// Keeps serving for `secs` seconds (the page stays up after the render).
    pub fn linger(&self, secs: u64) {
        if secs > 0 {
            std::thread::sleep(Duration::from_secs(secs));
        }
    }

    /// A [`Progress`] that feeds the board and forwards to `inner` (the terminal bars).
    /// With `cluster`, frames start through the cluster's events instead.
    pub fn progress<'a>(&'a self, inner: &'a dyn Progress, cluster: bool) -> LiveProgress<'a> {
        LiveProgress { inner, board: &self.board, preview: self.preview.as_ref(), cluster }
    }
}

/// Progress hooks that update the live view, then the terminal's.
pub struct LiveProgress<'a> {
    inner: &'a dyn Progress,
    board: &'a Board,
    preview: Option<&'a Preview>,
    cluster: bool,
}

impl Progress for LiveProgress<'_> {
    fn begin(&self, stage: &str, total: u64) {
        self.inner.begin(stage, total);
        self.board.update(|s| {
            s.stage = (stage.to_string(), total, 0);
            s.stage_began = Some(Instant::now());
            s.stage_version += 1;
        });
    }
    fn advance(&self, n: u64) {
        self.inner.advance(n);
        self.board.update(|s| {
            s.stage.2 += n;
            s.stage_version += 1;
        });
    }
    fn end(&self) {
        self.inner.end();
    }
    fn frame_begins(&self, index: usize, count: usize) {
        self.inner.frame_begins(index, count);
        if !self.cluster {
            self.board.update(|s| s.frame(index, count));
        }
    }
    fn subscreen_done(&self, node: u32, t: Subscreen, px: &[Rgb]) {
        self.inner.subscreen_done(node, t, px);
        self.board.update(|s| {
            let row = s.node(node);
            if row.name.is_empty() {
                row.name = format!("thread {node}");
            }
            s.subscreen_done(node, t, px)
        });
    }
    // The snapshots end here: the terminal's bars have no use for them.
    fn light_snapshot_due(&self) -> bool {
        self.preview.is_some_and(Preview::due)
    }
    fn light_snapshot(&self, element_flux: Vec<Fixed>) {
        if let Some(p) = self.preview {
            p.snapshot(element_flux);
        }
    }
}
