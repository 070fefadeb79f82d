//! Where node workers run: one per core, pinned, when they fit.
//!
//! Both the embedded renderer and the in-process cluster pin node worker *i* to the
//! *i*-th core this process may use ([`allowed_cores`]) when there are no more workers
//! than cores ([`worker_cores`]). Left to itself, the kernel sometimes puts two of them
//! on one core while another idles, for a scheduler slice or more: a thread wakes where
//! it last ran, a new one goes where the spawning thread saw the least load, and an idle
//! core pulls a thread that ran a moment ago only at its next balancing tick. Measured
//! on 2 cores (magg-paper): one node started the light pass 1-4 ms late in 6 of 8
//! in-process renders, and the embedded renderer's two light-pass threads shared one
//! core for 9 ms while the other idled. Dynamic load balancing (pairs and subscreens
//! pulled on demand, redivision) keeps a pinned worker on a core that something else
//! wants from holding a render back.

/// The cores this thread may run on (its affinity mask: `taskset` and cgroup cpusets
/// narrow it), by id; empty where the platform does not tell.
pub fn allowed_cores() -> Vec<usize> {
    core_affinity::get_core_ids().unwrap_or_default().into_iter().map(|c| c.id).collect()
}

/// The core for each of `workers` workers, or none when they do not fit one per core
/// (then the kernel places them).
pub fn worker_cores(workers: usize) -> Vec<usize> {
    let cores = allowed_cores();
    if workers <= cores.len() {
        cores[..workers].to_vec()
    } else {
        Vec::new()
    }
}

/// Pins the calling thread to core `id`; false where that is refused or unsupported
/// (the thread then runs wherever the kernel puts it).
pub fn pin_current(id: usize) -> bool {
    core_affinity::set_for_current(core_affinity::CoreId { id })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workers_get_distinct_allowed_cores_or_none() {
        let cores = allowed_cores();
        let n = cores.len();
        if n == 0 {
            return; // a platform that does not tell: nothing is pinned
        }
        let w = worker_cores(n);
        assert_eq!(w, cores);
        assert_eq!(worker_cores(1), cores[..1].to_vec());
        assert!(worker_cores(n + 1).is_empty(), "more workers than cores are pinned");
    }

    #[test]
    fn a_pinned_thread_runs_only_on_its_core() {
        let Some(&c) = allowed_cores().last() else { return };
        let on = std::thread::spawn(move || {
            let pinned = pin_current(c);
            (pinned, allowed_cores())
        })
        .join()
        .unwrap();
        if on.0 {
            assert_eq!(on.1, vec![c]);
        }
    }
}
