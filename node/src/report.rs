//! What a node tells the host about its work: cumulative counters over its workers.

use crate::pace::NodePace;
use magg_core::blocks::CacheStats;
use magg_core::lrt::LrtTally;
use magg_core::math::Rgb;
use magg_core::view::OpCounters;
use magg_proto::v1;
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

fn rgb(c: Rgb) -> Option<v1::Rgb> {
    Some(v1::Rgb { r: c.0[0], g: c.0[1], b: c.0[2] })
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
    /// The sum, as sent to the host.
    pub fn report(&self) -> v1::NodeReport {
        let s = self.sum();
        v1::NodeReport {
            cache_hits: s.cache.hits,
            cache_misses: s.cache.misses,
            cache_remote_misses: s.cache.remote_misses,
            grid_steps: s.ops.grid_steps,
            patch_tests: s.ops.patch_tests,
            light_rays: s.ops.light_rays,
            view_rays: s.ops.view_rays,
            shades: s.ops.shades,
            pairs: s.pairs,
            tiles: s.tiles,
            reached: rgb(s.tally.reached),
            occluded: rgb(s.tally.occluded),
            absorbed: rgb(s.tally.absorbed),
            diffuse_end: rgb(s.tally.diffuse_end),
            escaped: rgb(s.tally.escaped),
            cut: rgb(s.tally.cut),
            link_busy_s: self.pace.as_ref().map_or(0.0, |p| p.link_busy_s()),
            cpu_busy_s: self.pace.as_ref().map_or(0.0, |p| p.compute_cost(&s.ops).as_secs_f64()),
        }
    }
}
