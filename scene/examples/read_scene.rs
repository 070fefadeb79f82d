//! Times reading a scene (its TOML and every mesh it names) through the public API, as
//! `magg-host` reads it, and prints one line: seconds, patches, patches per second and
//! the process's peak resident memory (docs/PERFORMANCE.md, "Start-up on a large mesh").
//!
//! ```text
//! cargo run --release -p magg-scene --example read_scene -- scenes/large.toml
//! ```

use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: read_scene SCENE.toml");
        std::process::exit(2);
    };
    let start = std::time::Instant::now();
    let text = std::fs::read_to_string(&path)?;
    let dir = Path::new(&path).parent().unwrap_or(Path::new("."));
    let scene = magg_scene::parse_scene_str(&path, &text, dir, &|p: &Path| std::fs::read(p))?;
    let secs = start.elapsed().as_secs_f64();
    // Peak resident set (VmHWM) of this process, where /proc has it.
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let peak_kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0);
    let n = scene.patches.len();
    println!("{secs:.3} s  {n} patches  {:.0} patches/s  peak {} MB", n as f64 / secs, peak_kb / 1024);
    Ok(())
}
