//! The image so far, for a render stopped by Ctrl-C or SIGTERM: the pixels of the
//! subscreens traced (embedded renderer) or the rows received (cluster) of the frame in
//! progress, black elsewhere, written to `<stem>.partial.<ext>` beside the output.
//!
//! The partial image never goes to the output's own name: a script that waits for
//! `render.png` must not take a stopped render for a finished one. The host then exits
//! with the signal's status (130 for Ctrl-C, 143 for SIGTERM).
//!
//! ```text
//! magg-host render scenes/cornell.toml --out c.png --width 1600 --height 1200
//! ^C
//! magg-host: stopped by a signal after 41% of frame 0: the image so far is in c.partial.png
//! ```

use crate::frames;
use crate::images::{self, ImageFormat};
use magg_cluster::events::{ClusterEvent, EventSender};
use magg_core::color::Rgb;
use magg_core::frame::Frame;
use magg_core::progress::Progress;
use magg_core::scene::Exposure;
use magg_core::subscreen::Subscreen;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

/// `out` with `.partial` before its extension: `render.png` -> `render.partial.png`.
pub fn partial_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match out.extension() {
        Some(ext) => format!("{stem}.partial.{}", ext.to_string_lossy()),
        None => format!("{stem}.partial"),
    };
    out.with_file_name(name)
}

/// Where and how the frames of a render are written (what a partial image needs).
#[derive(Clone, Debug)]
pub struct Outputs {
    /// `--out` as given (before numbering).
    pub out: PathBuf,
    /// Its format.
    pub format: ImageFormat,
    /// The scene's exposure.
    pub exposure: Exposure,
    /// The crop window, if any.
    pub window: Option<Subscreen>,
    /// Number of the sequence's first frame in the whole camera path.
    pub first_number: usize,
    /// Frames in the whole camera path (1 without one).
    pub path_frames: usize,
}

/// The state behind [`PartialImage`].
struct State {
    /// The frame in progress (full size, before the crop window).
    frame: Frame,
    /// Its index in the sequence.
    index: usize,
    /// Whether it has been written in full (then there is nothing partial to save).
    written: bool,
    /// Pixels set since the frame began.
    filled: u64,
    /// Cluster: rectangle of each subscreen id of this frame.
    rects: HashMap<u64, Subscreen>,
}

/// The render's frame in progress, filled as pixels arrive. Cheap to share.
#[derive(Clone)]
pub struct PartialImage {
    state: Arc<Mutex<State>>,
    outputs: Arc<Outputs>,
}

impl PartialImage {
    /// A black `width` x `height` frame 0, written per `outputs`.
    pub fn new(width: u32, height: u32, outputs: Outputs) -> Self {
        let state =
            State { frame: Frame::new(width, height), index: 0, written: false, filled: 0, rects: HashMap::new() };
        PartialImage { state: Arc::new(Mutex::new(state)), outputs: Arc::new(outputs) }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic elsewhere must not keep the partial image from being written.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Frame `index` of the sequence starts: black again.
    pub fn frame_begins(&self, index: usize) {
        let mut s = self.lock();
        s.frame.pixels.fill([0.0; 3]);
        s.index = index;
        s.written = false;
        s.filled = 0;
        s.rects.clear();
    }

    /// Frame `index` has been written to its own file.
    pub fn frame_written(&self, index: usize) {
        let mut s = self.lock();
        if s.index == index {
            s.written = true;
        }
    }

    /// The pixels of subscreen `t`, row by row (the embedded renderer).
    pub fn subscreen(&self, t: Subscreen, px: &[Rgb]) {
        let mut s = self.lock();
        for (row, chunk) in px.chunks(t.w.max(1) as usize).enumerate() {
            let Some(dst) = s.frame.row_mut(t.x, t.y + row as u32, chunk.len() as u32) else { continue };
            for (d, c) in dst.iter_mut().zip(chunk) {
                *d = [c.0[0] as f32, c.0[1] as f32, c.0[2] as f32];
            }
            s.filled += chunk.len() as u64;
        }
    }

    /// An event of the cluster's host service: frames begin, subscreens are handed out,
    /// rows arrive.
    pub fn cluster_event(&self, e: &ClusterEvent) {
        match e {
            ClusterEvent::FrameBegins { index, .. } => self.frame_begins(*index),
            ClusterEvent::Assigned { id, rect, .. } => {
                self.lock().rects.insert(*id, *rect);
            }
            ClusterEvent::Rows { id, rows, .. } => {
                let mut s = self.lock();
                let Some(r) = s.rects.get(id).copied() else { return };
                for row in rows {
                    let Some(dst) = s.frame.row_mut(r.x, row.y, r.w) else { continue };
                    magg_proto::convert::pixels_into(&row.rgb, dst);
                    s.filled += r.w as u64;
                }
            }
            ClusterEvent::Registered { .. } | ClusterEvent::Report { .. } | ClusterEvent::Redivided { .. } => {}
        }
    }

    /// An event channel for the cluster that fills this image and hands every event on
    /// to `then` (the live view's), in order. Its thread ends when the cluster drops the
    /// sender.
    pub fn cluster_events(&self, then: Option<EventSender>) -> std::io::Result<EventSender> {
        let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<ClusterEvent>();
        let me = self.clone();
        std::thread::Builder::new().name("magg-partial-image".into()).spawn(move || {
            while let Some(e) = rx.blocking_recv() {
                me.cluster_event(&e);
                if let Some(then) = &then {
                    let _ = then.send(e);
                }
            }
        })?;
        Ok(tx)
    }

    /// Writes the frame in progress to its partial file and returns a line saying
    /// where; `Ok(None)` when there is nothing partial (the frame was written in full).
    pub fn save(&self) -> anyhow::Result<Option<String>> {
        let (frame, index, filled) = {
            let s = self.lock();
            if s.written {
                return Ok(None);
            }
            (s.frame.clone(), s.index, s.filled)
        };
        let o = &self.outputs;
        let number = o.first_number + index;
        let path = partial_path(&frames::numbered(&o.out, number, o.path_frames));
        let frame = match o.window {
            Some(w) => frame.crop(w.x, w.y, w.w, w.h),
            None => frame,
        };
        let total = (frame.width as u64 * frame.height as u64).max(1);
        images::write(&frame, &path, o.format, o.exposure)?;
        let share = (filled.min(total) * 100) / total;
        Ok(Some(format!("{share}% of frame {number} traced: the image so far is in {}", path.display())))
    }

    /// Saves the partial image and says so on stderr: the host's last words on a
    /// signal. Returns the exit code for `stop`.
    pub fn last_words(&self, stop: magg_plumbing::lifecycle::Stop) -> i32 {
        match self.save() {
            Ok(Some(line)) => eprintln!("magg-host: stopped by a signal after {line}"),
            Ok(None) => eprintln!("magg-host: stopped by a signal (the image was already written)"),
            Err(e) => eprintln!("magg-host: stopped by a signal; the partial image could not be written: {e:#}"),
        }
        stop.exit_code()
    }

    /// [`Progress`] hooks that fill this image from the embedded renderer's subscreens
    /// and forward everything to `inner`. With `cluster`, frames and pixels come through
    /// [`PartialImage::cluster_events`] instead.
    pub fn progress<'a>(&'a self, inner: &'a dyn Progress, cluster: bool) -> PartialProgress<'a> {
        PartialProgress { image: self, inner, cluster }
    }
}

/// Where the binary's signal handler finds the render's [`PartialImage`]: empty until a
/// render has loaded its scene (and for every other command). Cheap to clone.
#[derive(Clone, Default)]
pub struct Slot(Arc<Mutex<Option<PartialImage>>>);

impl Slot {
    /// From now on a signal saves `image`.
    pub fn fill(&self, image: PartialImage) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(image);
    }

    /// Saves the partial image if there is one, says what happened on stderr, and gives
    /// the exit code for `stop`.
    pub fn last_words(&self, stop: magg_plumbing::lifecycle::Stop) -> i32 {
        let image = self.0.lock().unwrap_or_else(|e| e.into_inner()).clone();
        match image {
            Some(image) => image.last_words(stop),
            None => {
                eprintln!("magg-host: stopped by a signal");
                stop.exit_code()
            }
        }
    }
}

/// See [`PartialImage::progress`].
pub struct PartialProgress<'a> {
    image: &'a PartialImage,
    inner: &'a dyn Progress,
    cluster: bool,
}

impl Progress for PartialProgress<'_> {
    fn begin(&self, stage: &str, total: u64) {
        self.inner.begin(stage, total);
    }
    fn advance(&self, n: u64) {
        self.inner.advance(n);
    }
    fn end(&self) {
        self.inner.end();
    }
    fn frame_begins(&self, index: usize, count: usize) {
        if !self.cluster {
            self.image.frame_begins(index);
        }
        self.inner.frame_begins(index, count);
    }
    fn subscreen_done(&self, node: u32, t: Subscreen, px: &[Rgb]) {
        if !self.cluster {
            self.image.subscreen(t, px);
        }
        self.inner.subscreen_done(node, t, px);
    }
    fn light_snapshot_due(&self) -> bool {
        self.inner.light_snapshot_due()
    }
    fn light_snapshot(&self, element_flux: Vec<magg_core::fixed::Fixed>) {
        self.inner.light_snapshot(element_flux);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outputs(dir: &Path, path_frames: usize) -> Outputs {
        Outputs {
            out: dir.join("shot.png"),
            format: ImageFormat::Png,
            exposure: Exposure::Fixed(1.0),
            window: None,
            first_number: 0,
            path_frames,
        }
    }

    #[test]
    fn the_partial_name_keeps_the_extension_and_never_is_the_output() {
        assert_eq!(partial_path(Path::new("out/render.png")), PathBuf::from("out/render.partial.png"));
        assert_eq!(partial_path(Path::new("a.b.exr")), PathBuf::from("a.b.partial.exr"));
        assert_eq!(partial_path(Path::new("x")), PathBuf::from("x.partial"));
    }

    #[test]
    fn subscreens_fill_the_frame_and_the_rest_stays_black() {
        let dir = tempfile::tempdir().unwrap();
        let p = PartialImage::new(4, 2, outputs(dir.path(), 1));
        p.subscreen(Subscreen { x: 2, y: 0, w: 2, h: 2 }, &[Rgb([1.0, 0.5, 0.25]); 4]);
        let line = p.save().unwrap().unwrap();
        assert!(line.contains("50% of frame 0"), "{line}");
        assert!(line.contains("shot.partial.png"), "{line}");
        assert!(!dir.path().join("shot.png").exists());
        let s = p.lock();
        assert_eq!(s.frame.get(0, 1), [0.0; 3]);
        assert_eq!(s.frame.get(3, 1), [1.0, 0.5, 0.25]);
    }

    #[test]
    fn a_written_frame_leaves_nothing_partial_and_the_next_one_is_numbered() {
        let dir = tempfile::tempdir().unwrap();
        let p = PartialImage::new(2, 2, outputs(dir.path(), 3));
        p.frame_written(0);
        assert!(p.save().unwrap().is_none());
        p.frame_begins(1);
        let line = p.save().unwrap().unwrap();
        assert!(line.contains("shot_0001.partial.png"), "{line}");
        assert!(dir.path().join("shot_0001.partial.png").is_file());
    }

    #[test]
    fn cluster_rows_land_in_their_subscreen() {
        let dir = tempfile::tempdir().unwrap();
        let p = PartialImage::new(3, 3, outputs(dir.path(), 1));
        p.cluster_event(&ClusterEvent::Assigned { node: 0, id: 7, rect: Subscreen { x: 1, y: 1, w: 2, h: 2 } });
        let rgb = magg_proto::convert::pixels_to_wire([2.0, 2.0, 2.0, 3.0, 3.0, 3.0]);
        let row = magg_proto::v1::Row { y: 2, rgb };
        p.cluster_event(&ClusterEvent::Rows { node: 0, id: 7, rows: vec![row.clone()] });
        // Rows of a subscreen never assigned are ignored, not a panic.
        p.cluster_event(&ClusterEvent::Rows { node: 0, id: 8, rows: vec![row] });
        let s = p.lock();
        assert_eq!(s.frame.get(1, 2), [2.0; 3]);
        assert_eq!(s.frame.get(2, 2), [3.0; 3]);
        assert_eq!(s.frame.get(1, 1), [0.0; 3]);
        assert_eq!(s.filled, 2);
    }
}
