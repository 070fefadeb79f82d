//! What a node tells the host about its work: cumulative counters over its workers, as a
//! [`NodeReport`] (converted to the wire at the call that carries it).

use crate::pace::NodePace;
use magg_core::blocks::CacheStats;
use magg_core::cluster::NodeReport;
use magg_core::lrt::LrtTally;
use magg_core::view::OpCounters;
use std::sync::{Arc, Mutex};

/// One worker's totals.
#[derive(Clone, Copy, Debug, Default)]
pub struct WorkerTotals {
    /// Its cache.
    pub cache: CacheStats,
    /// Its kernel operations.
    pub ops: OpCounters,
    /// Pairs traced.
    pub pairs: u64,
    /// Subscreens traced (redivided parts count once each).
    pub tiles: u64,
    /// Where its light went.
    pub tally: LrtTally,
}

/// Totals of every worker of the node, by worker index.
#[derive(Debug, Default)]
pub struct Totals {
    workers: Mutex<Vec<WorkerTotals>>,
    pace: Option<Arc<NodePace>>,
}

impl Totals {
    /// Room for `n` workers.
    pub fn new(n: usize) -> Self {
        Totals { workers: Mutex::new(vec![WorkerTotals::default(); n]), pace: None }
    }

    /// The same, reporting the link and processor time of `pace`.
    pub fn paced(mut self, pace: Option<Arc<NodePace>>) -> Self {
        self.pace = pace;
        self
    }
    /// Records worker `i`'s totals.
    pub fn set(&self, i: usize, t: WorkerTotals) {
        let mut g = self.workers.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(slot) = g.get_mut(i) {
            *slot = t;
        }
    }
    /// The sum over workers.
    pub fn sum(&self) -> WorkerTotals {
        let g = self.workers.lock().unwrap_or_else(|e| e.into_inner());
        g.iter().fold(WorkerTotals::default(), |a, w| WorkerTotals {
            cache: a.cache.add(w.cache),
            ops: a.ops.add(w.ops),
            pairs: a.pairs + w.pairs,
            tiles: a.tiles + w.tiles,
            tally: a.tally.add(w.tally),
        })
    }
    /// The sum, with the link and processor time, as reported to the host.
    pub fn report(&self) -> NodeReport {
        let s = self.sum();
        NodeReport {
            cache: s.cache,
            ops: s.ops,
            pairs: s.pairs,
            tiles: s.tiles,
            tally: s.tally,
            link_busy_s: self.pace.as_ref().map_or(0.0, |p| p.link_busy_s()),
            cpu_busy_s: self.pace.as_ref().map_or(0.0, |p| p.compute_cost(&s.ops).as_secs_f64()),
        }
    }
}
