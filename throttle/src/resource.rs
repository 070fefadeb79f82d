//! A resource that serialises its users: a link direction, a fork's DMA engine or
//! service, the G-bus, a node's processor.
//!
//! Token-debt accounting: [`Resource::reserve`] books the resource for a cost right after
//! what is already booked and returns when that booking ends; the caller sleeps only when
//! the end lies more than [`SLACK`] ahead. Costs far below the timer's granularity thus
//! add up exactly (the debt stays booked and the next caller starts after it), and a
//! sleep pays off the whole debt at once.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Debt a user may run up before it sleeps: about one tick of the async timer.
pub const SLACK: Duration = Duration::from_millis(1);

/// Idle time a resource may save up: what a late wake-up costs is given back, so that a
/// stream paced by sleeps that overshoot (by up to this much) still gets its bandwidth.
pub const BURST: Duration = Duration::from_millis(2);

#[derive(Debug, Default)]
struct Booking {
    next_free: Option<Instant>,
    busy: Duration,
    uses: u64,
}

/// A serial resource with a booking horizon.
#[derive(Debug, Default)]
pub struct Resource {
    booking: Mutex<Booking>,
}

impl Resource {
    /// An idle resource.
    pub fn new() -> Resource {
        Resource::default()
    }

    /// Books `cost` after everything booked so far (or, if the resource is idle, from
    /// now less at most [`BURST`] of the idle time) and returns when the booking ends.
    pub fn reserve(&self, cost: Duration) -> Instant {
        let now = Instant::now();
        let mut b = self.booking.lock().unwrap_or_else(|p| p.into_inner());
        let earliest = now.checked_sub(BURST).unwrap_or(now);
        let start = match b.next_free {
            Some(t) => t.max(earliest),
            None => now,
        };
        let end = start + cost;
        b.next_free = Some(end);
        b.busy += cost;
        b.uses += 1;
        end
    }

    /// Books `cost` and blocks the thread until the booking ends, if that is more than
    /// [`SLACK`] away.
    pub fn pay_blocking(&self, cost: Duration) {
        if !cost.is_zero() {
            wait_blocking(self.reserve(cost));
        }
    }

    /// Books `cost` and waits asynchronously until the booking ends, if that is more
    /// than [`SLACK`] away.
    pub async fn pay(&self, cost: Duration) {
        if !cost.is_zero() {
            wait(self.reserve(cost)).await;
        }
    }

    /// Total time booked so far (real time, i.e. dilated).
    pub fn busy(&self) -> Duration {
        self.booking.lock().unwrap_or_else(|p| p.into_inner()).busy
    }

    /// Starts the busy and use counts again from zero (a new render).
    pub fn reset_counts(&self) {
        let mut b = self.booking.lock().unwrap_or_else(|p| p.into_inner());
        b.busy = Duration::ZERO;
        b.uses = 0;
    }

    /// Bookings so far.
    pub fn uses(&self) -> u64 {
        self.booking.lock().unwrap_or_else(|p| p.into_inner()).uses
    }
}

/// Sleeps the thread until `end` if it is more than [`SLACK`] ahead.
pub fn wait_blocking(end: Instant) {
    let now = Instant::now();
    if end > now + SLACK {
        std::thread::sleep(end - now);
    }
}

/// Sleeps the task until about `end` if it is more than [`SLACK`] ahead. The async timer
/// rounds a deadline up to its next millisecond tick, so the task aims half a tick early
/// and wakes on average at `end`.
pub async fn wait(end: Instant) {
    let now = Instant::now();
    if end > now + SLACK {
        tokio::time::sleep_until((end - SLACK / 2).into()).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// 2 MB in 2 KB messages at 20 MB/s: 100 ms, paced within 5% although each message
    /// costs only 102 us, a tenth of the timer's tick.
    #[test]
    fn delivers_its_bandwidth_in_small_messages() {
        let r = Resource::new();
        let per = Duration::from_secs_f64(2048.0 / 20e6);
        let t0 = Instant::now();
        for _ in 0..1000 {
            r.pay_blocking(per);
        }
        wait_blocking_final(&r);
        let took = t0.elapsed().as_secs_f64();
        let want = per.as_secs_f64() * 1000.0;
        assert!((took - want).abs() < 0.05 * want, "took {took} s, want {want} s");
    }

    /// The same from async tasks.
    #[tokio::test]
    async fn delivers_its_bandwidth_from_async_tasks() {
        let r = Resource::new();
        let per = Duration::from_micros(100);
        let t0 = Instant::now();
        for _ in 0..1000 {
            r.pay(per).await;
        }
        tokio::time::sleep_until(r.reserve(Duration::ZERO).into()).await;
        let took = t0.elapsed().as_secs_f64();
        assert!((took - 0.1).abs() < 0.005, "took {took} s, want 0.1 s");
    }

    /// Two users of one resource each get about half of it (messages longer than the
    /// slack: below it, users share in turns of about one slack).
    #[test]
    fn shared_resource_is_split_between_its_users() {
        let r = Arc::new(Resource::new());
        let per = Duration::from_millis(2);
        let stop = Instant::now() + Duration::from_millis(400);
        let users: Vec<_> = (0..2)
            .map(|_| {
                let r = r.clone();
                std::thread::spawn(move || {
                    let mut n = 0u64;
                    while Instant::now() < stop {
                        r.pay_blocking(per);
                        n += 1;
                    }
                    n
                })
            })
            .collect();
        let counts: Vec<u64> = users.into_iter().map(|u| u.join().unwrap()).collect();
        let total = (counts[0] + counts[1]) as f64;
        // 400 ms at 2 ms each is 200 transfers in all, about 100 each.
        assert!((total - 200.0).abs() < 10.0, "{counts:?}");
        for c in &counts {
            assert!((*c as f64 / total - 0.5).abs() < 0.1, "{counts:?}");
        }
    }

    #[test]
    fn idle_time_is_not_saved_up() {
        let r = Resource::new();
        let a = r.reserve(Duration::from_millis(1));
        std::thread::sleep(Duration::from_millis(10));
        let b = r.reserve(Duration::from_millis(1));
        assert!(b > a + Duration::from_millis(10) - BURST);
        assert_eq!(r.uses(), 2);
        assert_eq!(r.busy(), Duration::from_millis(2));
    }

    fn wait_blocking_final(r: &Resource) {
        let end = r.reserve(Duration::ZERO);
        let now = Instant::now();
        if end > now {
            std::thread::sleep(end - now);
        }
    }
}
