//! Progress reporting hooks, so that front ends can show bars without the core doing I/O.

/// Receives progress of long stages.
pub trait Progress: Sync {
    /// A stage starts with `total` units of work.
    fn begin(&self, _stage: &str, _total: u64) {}
    /// `n` more units are done.
    fn advance(&self, _n: u64) {}
    /// The stage is over.
    fn end(&self) {}
}

/// Reports nothing.
pub struct NoProgress;
impl Progress for NoProgress {}
