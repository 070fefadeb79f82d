//! Chaos: real magg-fork, magg-node and magg-host processes on localhost, with a node
//! killed in the middle of light ray tracing and another in the middle of viewing ray
//! tracing (and a node joining late). The image and the energies must be bitwise those of
//! a clean embedded run: leased pairs and subscreens of the dead nodes go to the others,
//! re-run pairs deposit exactly once, and every pixel row is written once.

use magg_tests::*;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};

const SMALL: &[&str] = &["--width", "48", "--height", "40", "--light-rays", "4", "--pixel-samples", "1"];

/// Lease of the chaos runs: short, so a dead node's work moves on quickly, and still
/// several batches of pairs long, so that live nodes keep theirs.
const LEASE: &str = "1.5";

fn log_file(dir: &Path, name: &str) -> File {
    File::create(dir.join(format!("{name}.log"))).unwrap()
}

/// A node whose debug log lines come back on a channel (to kill it at a chosen moment).
fn node(procs: &mut Procs, host: &str, name: &str, extra: &[&str]) -> (usize, Receiver<String>) {
    let mut child = Command::new(magg_bin("magg-node"))
        .args(["--host", host, "--name", name])
        .args(extra)
        .env("RUST_LOG", "magg_node=debug")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn magg-node");
    let (tx, rx) = channel();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    procs.0.push(child);
    (procs.0.len() - 1, rx)
}

/// Waits for the `n`-th log line containing `what`; panics after a bound.
fn wait_for(rx: &Receiver<String>, what: &str, n: usize) {
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut seen = 0;
    while seen < n {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) if line.contains(what) => seen += 1,
            Ok(_) => {}
            Err(e) => panic!("no {n}th {what:?} line from the node ({seen} seen): {e}"),
        }
    }
}

/// One chaos run: kill a node after its `lrt_batches`-th batch of pairs began, another
/// after its `vrt_subscreens`-th subscreen began; compare with `base`.
fn chaos_run(dir: &Path, base: &Rendered, stem: &str, lrt_batches: usize, vrt_subscreens: usize) {
    let s = scene("magg-paper.toml");
    let mut procs = Procs(Vec::new());
    let fork_addrs: Vec<String> = (0..3).map(|_| format!("127.0.0.1:{}", free_port())).collect();
    for (i, a) in fork_addrs.iter().enumerate() {
        let log = log_file(dir, &format!("{stem}-fork{i}"));
        let c = Command::new(magg_bin("magg-fork")).args(["--listen", a]).stdout(Stdio::null()).stderr(log).spawn();
        procs.0.push(c.expect("spawn magg-fork"));
    }
    let host_addr = format!("127.0.0.1:{}", free_port());
    let out = Rendered::at(dir, stem);
    let forks_at = fork_addrs.join(",");
    let host_log = dir.join(format!("{stem}-host.log"));
    let mut host = out
        .command(&s)
        .args(["--subscreen", "16", "--forks-at", &forks_at, "--listen", &host_addr])
        .args(["--external-nodes", "--lease-timeout", LEASE, "--stall-timeout", "30"])
        .args(SMALL)
        .stdout(Stdio::null())
        .stderr(File::create(&host_log).unwrap())
        .spawn()
        .unwrap();
    let slow = ["--slow-pair-ms", "1", "--slow-row-ms", "10"];
    let (lrt_victim, lrt_log) = node(&mut procs, &host_addr, "lrt-victim", &slow);
    let (_, _keep1) = node(&mut procs, &host_addr, "survivor", &slow);

    wait_for(&lrt_log, "tracing a batch of pairs", lrt_batches);
    procs.0[lrt_victim].kill().unwrap();
    // A node joining in the middle of the render gets work too; it is the one killed
    // in viewing ray tracing.
    let (vrt_victim, vrt_log) = node(&mut procs, &host_addr, "vrt-victim", &slow);
    wait_for(&vrt_log, "tracing a subscreen", vrt_subscreens);
    procs.0[vrt_victim].kill().unwrap();

    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(st) = host.try_wait().unwrap() {
            break st;
        }
        if Instant::now() > deadline {
            let _ = host.kill();
            let _ = host.wait();
            panic!("{stem}: the host did not finish: {}", std::fs::read_to_string(&host_log).unwrap_or_default());
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let host_text = std::fs::read_to_string(&host_log).unwrap();
    assert!(status.success(), "{stem}: host failed: {host_text}");
    assert!(host_text.contains("subscreens are back on the queue"), "{stem}: no subscreen was revoked: {host_text}");
    let forks_text: String =
        (0..3).map(|i| std::fs::read_to_string(dir.join(format!("{stem}-fork{i}.log"))).unwrap()).collect();
    assert!(forks_text.contains("pair leases expired"), "{stem}: no pair lease expired: {forks_text}");
    assert_eq!(std::fs::read(&base.pfm).unwrap(), std::fs::read(&out.pfm).unwrap(), "{stem}: image differs");
    assert_eq!(std::fs::read(&base.energy).unwrap(), std::fs::read(&out.energy).unwrap(), "{stem}: energies differ");
    assert_eq!(std::fs::read(&base.png).unwrap(), std::fs::read(&out.png).unwrap(), "{stem}: PNG differs");
    assert_eq!(read_json(&out.stats)["nodes"].as_u64().unwrap(), 3, "{stem}: three nodes registered");
}

#[test]
fn killed_nodes_lose_nothing_and_the_bits_are_those_of_a_clean_run() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("magg-paper.toml");
    let base = render(&s, dir.path(), "embedded", &[SMALL, &["--embedded"]].concat());
    // Kill points: early in each phase, then later.
    chaos_run(dir.path(), &base, "early", 1, 1);
    chaos_run(dir.path(), &base, "later", 3, 2);
}
