//! This process's peak resident memory, for the stats of every process of a render.

/// The most memory this process has held resident so far (Linux's `VmHWM`), in bytes;
/// `None` where the platform does not tell.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.trim_start_matches("VmHWM:").trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_linux_process_knows_its_peak() {
        if cfg!(target_os = "linux") {
            let peak = super::peak_rss_bytes().expect("VmHWM on Linux");
            assert!(peak > 1 << 20, "{peak} bytes");
        }
    }
}
