//! Progress reporting hooks, so that front ends can show bars without the core doing I/O.

use crate::fixed::Fixed;

/// The light pass's stage name, as [`Progress::begin`] gets it.
pub const LIGHT_PASS: &str = "light ray tracing";
/// The viewing pass's stage name, as [`Progress::begin`] gets it.
pub const VIEW_PASS: &str = "viewing ray tracing";

/// Receives progress of long stages.
pub trait Progress: Sync {
    /// A stage starts with `total` units of work.
    fn begin(&self, _stage: &str, _total: u64) {}
    /// `n` more units are done.
    fn advance(&self, _n: u64) {}
    /// The stage is over.
    fn end(&self) {}
    /// Frame `index` of `count` starts its viewing pass (more than one frame: a camera path).
    fn frame_begins(&self, _index: usize, _count: usize) {}
    /// Node `node` finished subscreen `t`; `px` holds its pixels row by row (for live views).
    fn subscreen_done(&self, _node: u32, _t: crate::subscreen::Subscreen, _px: &[crate::color::Rgb]) {}
    /// Whether a watcher wants a snapshot of the light pass's element flux now. Asked
    /// between batches of pairs, so it must be cheap; a true answer is a claim: the asker
    /// is expected to send [`Progress::light_snapshot`] next. Default: never.
    fn light_snapshot_due(&self) -> bool {
        false
    }
    /// The flux deposited on each element so far in the light pass (fixed point, by
    /// element id): a copy, read without stopping the pass, that nothing feeds back into
    /// the render (a live view draws a preview from it).
    fn light_snapshot(&self, _element_flux: Vec<Fixed>) {}
}

/// Reports nothing.
pub struct NoProgress;
impl Progress for NoProgress {}

/// `inner` with every stage shown under the name `stage` (refinement's pilot light
/// passes show as "refinement 1/3", not as the render's light pass). Only the stages'
/// progress is passed on: no frame, subscreen or light snapshot.
pub struct Renamed<'a> {
    /// Where the progress goes.
    pub inner: &'a dyn Progress,
    /// The name every stage takes.
    pub stage: String,
}

impl Progress for Renamed<'_> {
    fn begin(&self, _stage: &str, total: u64) {
        self.inner.begin(&self.stage, total);
    }

    fn advance(&self, n: u64) {
        self.inner.advance(n);
    }

    fn end(&self) {
        self.inner.end();
    }
}
