//! Where node threads that share their machine's cores with the host (the
//! single-process harness behind `magg-host render`) run, and how they wait.
//!
//! **Placement.** The harness pins node *i*'s worker to core *i* when there are no more
//! nodes than cores ([`allowed_cores`], [`pin_current`]). Left to itself, the kernel
//! sometimes starts two node threads on one core (each wakes where it last ran, and an
//! idle core pulls a thread that ran recently only at its next balancing tick): one
//! node then traces while the other waits for a slice, 1-4 ms at the start of a pass
//! (measured on magg-paper, 2 cores). The embedded renderer spawns fresh threads per
//! pass, which the kernel places on idle cores. Dynamic load balancing (pairs and
//! subscreens pulled on demand, redivision) keeps a pinned node on a busy core from
//! holding the render back.
//!
//! **Waiting.** A node told to wait (its `NextWork` held by the host until the phase changes) would
//! park its thread. When the phase changes, the host wakes it, but the kernel queues the
//! woken thread on the core it last ran on, and when that core is busy with the other
//! node's tracing, the thread may sit there for a scheduler slice (measured: 1-3.4 ms,
//! at the start of the light pass in 6 of 8 renders of magg-paper on 2 cores, and at the
//! start of the viewing pass in 3 of 8) while another core idles. The embedded renderer
//! never meets this: it spawns fresh threads per pass, and a new thread goes to an idle
//! core. So for a bounded time a waiting node stays runnable instead: it polls its call
//! again after each `sched_yield`, which hands the core to any thread that wants it (the
//! host's), and parks only when the wait lasts longer. OpenMP runtimes wait the same way
//! (`OMP_WAIT_POLICY=active`, `GOMP_SPINCOUNT`).

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

/// The cores this thread may run on (its affinity mask: `taskset` and cgroup cpusets
/// narrow it), by id; empty where the platform does not tell.
pub fn allowed_cores() -> Vec<usize> {
    core_affinity::get_core_ids().unwrap_or_default().into_iter().map(|c| c.id).collect()
}

/// Pins the calling thread to core `id`; false where that is refused or unsupported
/// (the thread then runs wherever the kernel puts it).
pub fn pin_current(id: usize) -> bool {
    core_affinity::set_for_current(core_affinity::CoreId { id })
}

/// Polls `inner` until it is ready, yielding the core between polls for up to `spin`
/// (from the first poll); after that it waits as any future does. `spin` zero: no
/// spinning at all.
pub fn spin_then_park<F: Future>(spin: Duration, inner: F) -> SpinThenPark<F> {
    SpinThenPark { inner: Box::pin(inner), spin, until: None }
}

/// The future of [`spin_then_park`].
pub struct SpinThenPark<F> {
    inner: Pin<Box<F>>,
    spin: Duration,
    until: Option<Instant>,
}

impl<F: Future> Future for SpinThenPark<F> {
    type Output = F::Output;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        if let Poll::Ready(v) = self.inner.as_mut().poll(cx) {
            return Poll::Ready(v);
        }
        if self.spin.is_zero() {
            return Poll::Pending;
        }
        let (now, spin) = (Instant::now(), self.spin);
        let until = *self.until.get_or_insert(now + spin);
        if now < until {
            std::thread::yield_now();
            // Asks to be polled again at once: the executor does not park the thread.
            cx.waker().wake_by_ref();
        }
        Poll::Pending
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};
    use std::sync::Arc;

    /// A future that is ready after `n` polls and never wakes its task itself.
    struct ReadyAfter(Arc<AtomicU32>, u32);

    impl Future for ReadyAfter {
        type Output = u32;
        fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<u32> {
            let polls = self.0.fetch_add(1, Ordering::Relaxed) + 1;
            if polls >= self.1 {
                Poll::Ready(polls)
            } else {
                Poll::Pending
            }
        }
    }

    fn runtime() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap()
    }

    /// While spinning, the future is polled again without anyone waking it: a future
    /// that never wakes its task still completes.
    #[test]
    fn spinning_polls_again_without_a_wake_up() {
        let polls = Arc::new(AtomicU32::new(0));
        let got = runtime().block_on(spin_then_park(Duration::from_secs(10), ReadyAfter(polls.clone(), 50)));
        assert_eq!(got, 50);
    }

    /// A future that is not ready within the spin time is still pending after it (here
    /// the timeout's wake-up ends the wait), and with no spin time it is polled only when
    /// woken.
    #[test]
    fn spinning_is_bounded_and_optional() {
        let polls = Arc::new(AtomicU32::new(0));
        let rt = runtime();
        let spun = rt.block_on(async {
            tokio::time::timeout(
                Duration::from_millis(50),
                spin_then_park(Duration::from_millis(5), ReadyAfter(polls.clone(), u32::MAX)),
            )
            .await
        });
        assert!(spun.is_err(), "a future that is never ready completed");
        let after_spin = polls.load(Ordering::Relaxed);
        assert!(after_spin > 1, "it did not spin: {after_spin} polls");

        let polls = Arc::new(AtomicU32::new(0));
        let parked = rt.block_on(async {
            tokio::time::timeout(
                Duration::from_millis(20),
                spin_then_park(Duration::ZERO, ReadyAfter(polls.clone(), 3)),
            )
            .await
        });
        assert!(parked.is_err());
        // Once at the start and once when the timeout's timer woke the task.
        assert_eq!(polls.load(Ordering::Relaxed), 2, "polled without a wake-up");
    }
}
