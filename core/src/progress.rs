//! Progress reporting hooks, so that front ends can show bars without the core doing I/O.

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
    fn subscreen_done(&self, _node: u32, _t: crate::vrt::Subscreen, _px: &[crate::color::Rgb]) {}
}

/// Reports nothing.
pub struct NoProgress;
impl Progress for NoProgress {}
