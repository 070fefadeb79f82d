//! Where a worker's time goes in each pass: waiting for work, tracing, and sending the
//! results, summed over the pass and logged at debug level when it ends
//! (`RUST_LOG=magg_node=debug`), beside the host's stage timeline
//! (`RUST_LOG=magg_host=debug`). A few clock readings per work unit, not per ray.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The three parts of a pass, summed.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassTimes {
    /// When the pass's first unit arrived.
    pub started: Option<Instant>,
    /// Asking for work (pair batches, subscreens) and waiting for it.
    pub asking: Duration,
    /// Tracing (block cache misses included: see `fetching`) and packing the results.
    pub tracing: Duration,
    /// Sending deposits or rows.
    pub sending: Duration,
    /// Work units handled (pair batches, subscreens).
    pub units: u64,
}

impl PassTimes {
    /// Adds the time since `t` to `part` and returns now (the start of the next part).
    pub fn lap(part: &mut Duration, t: Instant) -> Instant {
        let now = Instant::now();
        *part += now - t;
        now
    }

    /// Notes that a unit of work arrived at `t`.
    pub fn unit(&mut self, t: Instant) {
        self.started.get_or_insert(t);
        self.units += 1;
    }

    /// Logs the pass (`what`: "light pass", "viewing pass") at debug level, with the
    /// time the block cache spent fetching during it (`fetching`, nanoseconds since the
    /// worker started, taken back to zero), and starts the counts again.
    pub fn log(&mut self, node: u32, what: &str, fetching: &AtomicU64) {
        let ms = |d: Duration| format!("{:.2}", 1e3 * d.as_secs_f64());
        let fetched = Duration::from_nanos(fetching.swap(0, Ordering::Relaxed));
        if let Some(start) = self.started {
            tracing::debug!(
                node,
                units = self.units,
                asking_ms = ms(self.asking),
                tracing_ms = ms(self.tracing),
                fetching_ms = ms(fetched),
                sending_ms = ms(self.sending),
                wall_ms = ms(start.elapsed()),
                "{what} done"
            );
        }
        *self = PassTimes::default();
    }
}
