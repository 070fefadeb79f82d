//! Where node workers run: one per core, pinned, when they fill the cores.
//!
//! Both the embedded renderer and the in-process cluster pin node worker *i* to the
//! *i*-th core this process may use ([`allowed_cores`]) when there are exactly as many
//! workers as cores, the default ([`worker_cores`]). Left to itself, the kernel
//! sometimes puts two busy workers on one core while another idles, for a scheduler
//! slice or more: a thread wakes where it last ran, a new one goes where the spawning
//! thread saw the least load, and an idle core pulls a thread that ran a moment ago only
//! at its next balancing tick. Measured on 2 cores (magg-paper): one node started the
//! light pass 1-4 ms late in 6 of 8 in-process renders, and the embedded renderer's two
//! light-pass threads shared one core for 9 ms while the other idled. Dynamic load
//! balancing (pairs and subscreens pulled on demand, redivision) keeps a pinned worker
//! on a core that something else wants from holding a render back.
//!
//! Fewer workers than cores are left to the kernel, which then has idle cores to put
//! them on (and two renders of a few nodes each, side by side on a big machine, do not
//! pile onto its first cores); more workers than cores cannot have one each.

/// The cores this thread may run on (its affinity mask: `taskset` and cgroup cpusets
/// narrow it), by id; empty where the platform does not tell.
pub fn allowed_cores() -> Vec<usize> {
    core_affinity::get_core_ids().unwrap_or_default().into_iter().map(|c| c.id).collect()
}

/// The core for each of `workers` workers when they are as many as the cores, else none
/// (then the kernel places them).
pub fn worker_cores(workers: usize) -> Vec<usize> {
    let cores = allowed_cores();
    if workers == cores.len() {
        cores
    } else {
        Vec::new()
    }
}

/// Pins the calling thread to core `id`; false where that is refused or unsupported
/// (the thread then runs wherever the kernel puts it).
pub fn pin_current(id: usize) -> bool {
    core_affinity::set_for_current(core_affinity::CoreId { id })
}

/// Pins the calling thread, worker `i`, to `cores[i % cores.len()]`; nothing to do (true)
/// with no cores, false where pinning was refused.
pub fn pin_worker(cores: &[usize], i: usize) -> bool {
    match cores.get(i % cores.len().max(1)) {
        Some(&c) => pin_current(c),
        None => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workers_that_fill_the_cores_get_one_each_others_none() {
        let cores = allowed_cores();
        let n = cores.len();
        if n == 0 {
            return; // a platform that does not tell: nothing is pinned
        }
        assert_eq!(worker_cores(n), cores);
        assert!(worker_cores(n + 1).is_empty(), "more workers than cores are pinned");
        if n > 1 {
            assert!(worker_cores(n - 1).is_empty(), "fewer workers than cores are pinned");
        }
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
