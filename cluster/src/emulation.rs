//! The host's part of the throttling layer (docs/ARCHITECTURE.md, the throttling layer): preprocessing priced by the
//! cost model, stage times turned into modelled seconds, and the real CPU share that
//! tells whether an emulated run was faithful.

use magg_core::prepared::PreparedScene;
use magg_throttle::{preprocess_ops, Profile, Scheme};
use std::time::Duration;

/// Modelled time of preprocessing: on one fork processor in the paper's scheme (paper
/// §5.3: "Now only 1 FP does this"), spread over the `forks` fork processors in ours.
pub fn preprocess_time(profile: &Profile, scheme: Scheme, prepared: &PreparedScene, forks: u32) -> Duration {
    let processors = if scheme == Scheme::Paper { 1 } else { forks.max(1) };
    profile.cpu.map_or(Duration::ZERO, |c| preprocess_ops(&c, &prepared.ops, processors))
}

/// CPU seconds this process has used so far (user + system, all threads), where the
/// platform tells (Linux: /proc/self/stat, in clock ticks of 10 ms).
pub fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start after the last ')'.
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the whole line: 12 and 13 after ')'.
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// CPU used between two readings as a share of every core's wall time.
pub fn cpu_share(cpu0: Option<f64>, cpu1: Option<f64>, wall_s: f64) -> Option<f64> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
    match (cpu0, cpu1) {
        (Some(a), Some(b)) if wall_s > 0.0 => Some((b - a) / (wall_s * cores)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_time_grows_with_work() {
        let Some(a) = process_cpu_s() else { return };
        // Burn CPU until the reading moves by 50 ms (a loaded machine gives this thread
        // only part of a core), within a generous bound.
        let t = std::time::Instant::now();
        let mut x = 0u64;
        let mut b = a;
        while b - a < 0.05 && t.elapsed() < Duration::from_secs(20) {
            for _ in 0..1_000_000 {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            }
            b = process_cpu_s().unwrap();
        }
        std::hint::black_box(x);
        assert!(b - a >= 0.05, "{a} -> {b} after {:?}", t.elapsed());
    }
}
