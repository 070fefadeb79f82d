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

impl Booking {
    /// Books `cost` at clock reading `now`: after everything booked so far, or, if the
    /// resource has been idle, from `now` less at most [`BURST`] of the idle time.
    /// Returns when the booking ends. A pure function of `now`, so that the pacing can be
    /// checked on a simulated clock.
    fn book(&mut self, now: Instant, cost: Duration) -> Instant {
        let earliest = now.checked_sub(BURST).unwrap_or(now);
        let start = match self.next_free {
            Some(t) => t.max(earliest),
            None => now,
        };
        let end = start + cost;
        self.next_free = Some(end);
        self.busy += cost;
        self.uses += 1;
        end
    }
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
        self.booking.lock().unwrap_or_else(|p| p.into_inner()).book(now, cost)
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

    /// A user on a simulated clock: books each message at its clock reading and, as
    /// [`wait`] and [`wait_blocking`] do, sleeps only when the booking ends more than
    /// [`SLACK`] ahead, waking `late(end)` instead of at `end`. Returns when the last
    /// booking ends (or the user's clock, if later), less the start.
    fn paced_stream(messages: u32, per: Duration, mut late: impl FnMut(Instant) -> Instant) -> Duration {
        let mut b = Booking::default();
        let t0 = Instant::now();
        let mut now = t0;
        let mut last = t0;
        for _ in 0..messages {
            last = b.book(now, per);
            if last > now + SLACK {
                now = late(last);
            }
        }
        now.max(last) - t0
    }

    /// Wake-ups late by a seeded pseudo-random amount below `max`, as sleeps on a timer of
    /// that granularity are.
    fn late_by_up_to(max: Duration) -> impl FnMut(Instant) -> Instant {
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        move |end: Instant| {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            end + Duration::from_nanos((x >> 33) % max.as_nanos() as u64)
        }
    }

    /// 2 MB in 2 KB messages at 20 MB/s: 102.4 us each, a tenth of the slack, add up to
    /// exactly 102.4 ms however the sleeps fall.
    #[test]
    fn small_messages_add_up_exactly() {
        let per = Duration::from_nanos(102_400);
        assert_eq!(paced_stream(1000, per, |end| end), per * 1000);
    }

    /// Sleeps that overshoot by up to a timer tick (less than [`BURST`]) are given back:
    /// the stream still gets its bandwidth, ending within one tick of 100 ms.
    #[test]
    fn late_wake_ups_are_given_back() {
        let per = Duration::from_micros(100);
        let want = per * 1000;
        let took = paced_stream(1000, per, late_by_up_to(Duration::from_millis(1)));
        assert!(took >= want && took <= want + Duration::from_millis(1), "took {took:?}, want {want:?}");
        // Overshoots beyond the burst allowance are lost (about 1 ms in each of some 25
        // sleeps here): idle time is not saved up.
        let slow = paced_stream(1000, per, |end| end + BURST + Duration::from_millis(1));
        assert!(slow > want + Duration::from_millis(10), "overshoots beyond BURST were given back: {slow:?}");
    }

    /// Two users of one resource each get half of it, in turns (messages longer than
    /// the slack: each user sleeps after every booking).
    #[test]
    fn shared_resource_is_split_between_its_users() {
        let per = Duration::from_millis(2);
        let mut b = Booking::default();
        let t0 = Instant::now();
        let stop = t0 + Duration::from_millis(400);
        let mut clocks = [t0, t0];
        let mut counts = [0u32; 2];
        loop {
            // The user whose clock is earliest books next (ties: the lower index).
            let i = if clocks[1] < clocks[0] { 1 } else { 0 };
            if clocks[i] >= stop {
                break;
            }
            let end = b.book(clocks[i], per);
            counts[i] += 1;
            if end > clocks[i] + SLACK {
                clocks[i] = end;
            }
        }
        // 400 ms at 2 ms each is 200 transfers in all, 100 each (give or take the one
        // booked when the other's turn ends at the stop).
        let total = counts[0] + counts[1];
        assert!((199..=201).contains(&total), "{counts:?}");
        assert!(counts[0].abs_diff(counts[1]) <= 1, "{counts:?}");
        assert_eq!(b.busy, per * total);
    }

    /// After an idle spell only [`BURST`] of it can be used to catch up.
    #[test]
    fn idle_time_is_not_saved_up() {
        let mut b = Booking::default();
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        assert_eq!(b.book(t0, ms(1)), t0 + ms(1));
        assert_eq!(b.book(t0 + ms(11), ms(1)), t0 + ms(11) - BURST + ms(1));
        // Within the burst allowance the booking chains on as if the user had been on time.
        assert_eq!(b.book(t0 + ms(11), ms(1)), t0 + ms(11) - BURST + ms(2));
        assert_eq!(b.uses, 3);
        assert_eq!(b.busy, ms(3));
    }

    /// On the real clock, a paced stream is never faster than its bandwidth (a sleep never
    /// ends early): blocking and async users alike.
    #[test]
    fn real_time_pacing_is_never_faster_than_the_bandwidth() {
        let per = Duration::from_micros(100);
        let r = Resource::new();
        let t0 = Instant::now();
        for _ in 0..200 {
            r.pay_blocking(per);
        }
        wait_final_blocking(&r);
        assert!(t0.elapsed() >= per * 200, "blocking: {:?}", t0.elapsed());
        assert_eq!((r.uses(), r.busy()), (201, per * 200));

        let rt = tokio::runtime::Builder::new_current_thread().enable_time().build().unwrap();
        let r = Resource::new();
        let t0 = Instant::now();
        rt.block_on(async {
            for _ in 0..200 {
                r.pay(per).await;
            }
            tokio::time::sleep_until(r.reserve(Duration::ZERO).into()).await;
        });
        assert!(t0.elapsed() >= per * 200, "async: {:?}", t0.elapsed());
    }

    fn wait_final_blocking(r: &Resource) {
        let end = r.reserve(Duration::ZERO);
        let now = Instant::now();
        if end > now {
            std::thread::sleep(end - now);
        }
    }
}
