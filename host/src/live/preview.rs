//! The live view's preview of the light pass: while LRT runs (95% of a diffuse scene's
//! time), the page shows the scene lit by the energy deposited so far.
//!
//! The design is the cheapest honest one. The renderer already sums every element's flux
//! where the pass runs (the embedded renderer's atomics, the cluster's forks); a few times
//! a second, and only while a page is open, the pass hands a copy of those sums to
//! [`Progress::light_snapshot`](magg_core::progress::Progress::light_snapshot) (the
//! cluster's host asks the forks for them on its progress polls, as a monitoring
//! snapshot that costs the modelled machine nothing). This module's thread then does
//! what the render does after the pass, at a preview's size: interpolates the snapshot to
//! the vertices and traces one viewing ray per pixel of a frame [`PREVIEW_WIDTH`] pixels
//! wide with the render's own VRT kernel, over a block source of its own (the scene's
//! blocks with the snapshot's vertex-energy blocks in place). So the preview is the frame
//! as it would look were the light pass stopped now; it reads the render's sums and never
//! writes into the render's state, so the render's bits do not depend on it. One preview
//! is traced at a time: a snapshot is only asked for when the last one is drawn, and
//! after a pause of at least four times its tracing time, so the preview thread takes at
//! most a fifth of one core from the render (a 128 px preview of scenes/cornell.toml
//! traces in about 0.15 s on a shared 2-core machine: one every 0.8 s).

use super::board::{Board, PreviewImage};
use magg_core::blocks::{Block, BlockCache, BlockError, BlockSource};
use magg_core::camera::CameraRig;
use magg_core::energy::{interpolate, vertex_energy_blocks};
use magg_core::fixed::Fixed;
use magg_core::prepared::PreparedScene;
use magg_core::scene::Camera;
use magg_core::subscreen::Subscreen;
use magg_core::trace::TraceScratch;
use magg_core::view::SceneView;
use magg_core::vrt::shade_pixels;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Width of a preview in pixels (at most the frame's; the height keeps its aspect).
pub const PREVIEW_WIDTH: u32 = 128;
/// Shortest time between two snapshots (a few previews a second); after a preview that
/// took t to trace, the next snapshot waits at least 4 t.
pub const PREVIEW_PERIOD: Duration = Duration::from_millis(250);
/// `next_due` while a snapshot is claimed and its preview not yet drawn.
const BUSY: u64 = u64::MAX;

/// The scene's blocks with the vertex-energy blocks of a snapshot in their place.
struct SnapshotBlocks {
    scene: Arc<PreparedScene>,
    vertex: HashMap<u32, Box<Block>>,
}

impl BlockSource for SnapshotBlocks {
    fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError> {
        let block = match self.vertex.get(&id) {
            Some(b) => b,
            None => self
                .scene
                .blocks
                .get(id as usize)
                .ok_or(BlockError::OutOfRange { id, total: self.scene.blocks.len() as u32 })?,
        };
        out.copy_from_slice(&block[..]);
        Ok(())
    }
}

/// Traces previews of `scene` seen by `camera` (see the module doc).
pub struct Previewer {
    scene: Arc<PreparedScene>,
    /// The scene's header with one viewing ray per pixel.
    header: Arc<magg_core::header::SceneHeader>,
    rig: CameraRig,
    width: u32,
    height: u32,
}

impl Previewer {
    /// A previewer for frames of `scene` seen by `camera`.
    pub fn new(scene: Arc<PreparedScene>, camera: &Camera) -> Previewer {
        let s = &scene.header.settings;
        let width = PREVIEW_WIDTH.min(s.width).max(1);
        let height = ((s.height as u64 * width as u64 + s.width as u64 / 2) / s.width.max(1) as u64).max(1) as u32;
        let mut header = (*scene.header).clone();
        header.plan.pixel_samples = 1;
        Previewer { rig: CameraRig::new(camera, width, height), header: Arc::new(header), scene, width, height }
    }

    /// The preview of the light pass's element flux `flux` (by element id).
    pub fn trace(&self, flux: &[Fixed]) -> Result<PreviewImage, BlockError> {
        let h = &self.scene.header;
        let vertex = interpolate(
            &self.scene.elements,
            &self.scene.t_junctions,
            flux,
            h.counts.vertices as usize,
            h.energy_quantum,
        );
        let blocks = SnapshotBlocks {
            scene: self.scene.clone(),
            vertex: vertex_energy_blocks(&vertex, &[], &h.layout).into_iter().collect(),
        };
        let mut view = SceneView::new(self.header.clone(), BlockCache::new(Arc::new(blocks), None));
        let mut scratch = TraceScratch::default();
        let mut rgb = Vec::with_capacity(3 * (self.width * self.height) as usize);
        let mut row = Vec::with_capacity(self.width as usize);
        for y in 0..self.height {
            row.clear();
            shade_pixels(&mut view, &mut scratch, &self.rig, Subscreen { x: 0, y, w: self.width, h: 1 }, &mut row)?;
            rgb.extend(row.iter().flat_map(|c| c.0.map(|v| v as f32)));
        }
        Ok(PreviewImage { width: self.width, height: self.height, rgb })
    }
}

/// The snapshot handed to the preview thread, and whether it should stop.
#[derive(Default)]
struct Slot {
    flux: Option<Vec<Fixed>>,
    stop: bool,
}

/// The preview thread of a live view and the claim on its next snapshot.
pub struct Preview {
    board: Arc<Board>,
    slot: Arc<(Mutex<Slot>, Condvar)>,
    /// Milliseconds since `clock` when the next snapshot is due ([`BUSY`]: one is out).
    next_due: Arc<AtomicU64>,
    clock: Instant,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Preview {
    /// Starts the preview thread, which draws on `board`.
    pub fn start(board: Arc<Board>, previewer: Previewer) -> std::io::Result<Preview> {
        let slot: Arc<(Mutex<Slot>, Condvar)> = Arc::default();
        let next_due = Arc::new(AtomicU64::new(0));
        let clock = Instant::now();
        let thread = {
            let (board, slot, next_due) = (board.clone(), slot.clone(), next_due.clone());
            std::thread::Builder::new().name("magg-live-preview".into()).spawn(move || loop {
                let flux = {
                    let (lock, wake) = &*slot;
                    let mut s = lock.lock().unwrap_or_else(|e| e.into_inner());
                    loop {
                        if s.stop {
                            return;
                        }
                        if let Some(f) = s.flux.take() {
                            break f;
                        }
                        s = wake.wait(s).unwrap_or_else(|e| e.into_inner());
                    }
                };
                let t = Instant::now();
                match previewer.trace(&flux) {
                    Ok(img) => {
                        tracing::debug!(
                            ms = format!("{:.1}", 1e3 * t.elapsed().as_secs_f64()),
                            "live view: preview traced"
                        );
                        board.update(|s| s.preview(&img))
                    }
                    Err(e) => tracing::warn!("live view: the light pass preview failed: {e}"),
                }
                // The next snapshot after the period, or later if tracing took long: the
                // preview keeps to a fifth of one core, whatever the scene.
                let wait = PREVIEW_PERIOD.max(4 * t.elapsed());
                next_due.store(clock.elapsed().as_millis() as u64 + wait.as_millis() as u64, Ordering::SeqCst);
            })?
        };
        Ok(Preview { board, slot, next_due, clock, thread: Some(thread) })
    }

    /// Whether a snapshot is wanted now: a page is open, the light pass is on, the last
    /// preview is drawn and [`PREVIEW_PERIOD`] old. A true answer claims the snapshot.
    pub fn due(&self) -> bool {
        if self.board.watching.load(Ordering::SeqCst) == 0 {
            return false;
        }
        let next = self.next_due.load(Ordering::SeqCst);
        if next == BUSY || (self.clock.elapsed().as_millis() as u64) < next || !self.board.lock().previewing() {
            return false;
        }
        self.next_due.compare_exchange(next, BUSY, Ordering::SeqCst, Ordering::SeqCst).is_ok()
    }

    /// Hands a claimed snapshot to the preview thread.
    pub fn snapshot(&self, flux: Vec<Fixed>) {
        let (lock, wake) = &*self.slot;
        lock.lock().unwrap_or_else(|e| e.into_inner()).flux = Some(flux);
        wake.notify_one();
    }
}

impl Drop for Preview {
    fn drop(&mut self) {
        let (lock, wake) = &*self.slot;
        lock.lock().unwrap_or_else(|e| e.into_inner()).stop = true;
        wake.notify_one();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use magg_core::scene::parse_scene_str;

    /// scenes/plane.toml (a lit floor) at 40 x 20 pixels.
    fn scene() -> Arc<PreparedScene> {
        let text = include_str!("../../../scenes/plane.toml");
        let read = |p: &std::path::Path| std::fs::read(p);
        let mut scene = parse_scene_str("plane.toml", text, std::path::Path::new("."), &read).expect("scene");
        (scene.settings.width, scene.settings.height) = (40, 20);
        Arc::new(magg_prepare::prepare(&scene).expect("prepare"))
    }

    #[test]
    fn a_preview_keeps_the_aspect_and_shows_the_deposited_energy() {
        let scene = scene();
        let p = Previewer::new(scene.clone(), &scene.header.camera);
        let dark = p.trace(&vec![[0; 3]; scene.elements.len()]).unwrap();
        assert_eq!((dark.width, dark.height), (40, 20), "a frame narrower than the preview width keeps its size");
        assert_eq!(dark.rgb.len(), 3 * 40 * 20);
        // Some flux on every element: the floor is lit in the preview.
        let lit = p.trace(&vec![[1 << 20; 3]; scene.elements.len()]).unwrap();
        let sum = |img: &PreviewImage| img.rgb.iter().map(|&v| v as f64).sum::<f64>();
        assert!(sum(&lit) > sum(&dark), "deposited energy does not show: {} vs {}", sum(&lit), sum(&dark));
    }
}
