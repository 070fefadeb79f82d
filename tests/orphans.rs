//! A fork or node whose starter is gone (a script killed with SIGKILL) exits by itself
//! within seconds, saying why; with `--serve-on` it keeps serving. And a node pointed at
//! a listener that never answers gives up at its `--connect-timeout`, and a host at a
//! silent fork at its `--fork-timeout`, naming the address.

use magg_tests::{free_port, magg_bin};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn alive(pid: u32) -> bool {
    // A zombie (exited, not reaped by its new parent yet) counts as gone.
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .map(|s| s.rsplit(')').next().is_some_and(|rest| !rest.trim_start().starts_with('Z')))
        .unwrap_or(false)
}

/// Starts `bin ARGS` in the background of a shell, kills the shell with SIGKILL, and
/// returns the orphan's pid.
fn orphan(bin: &str, args: &str) -> u32 {
    let script = format!("{} {args} >/dev/null 2>&1 & echo $!; exec sleep 60", magg_bin(bin).display());
    let mut sh = Command::new("sh").arg("-c").arg(script).stdout(Stdio::piped()).spawn().unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(sh.stdout.take().unwrap()), &mut line).unwrap();
    let pid: u32 = line.trim().parse().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    assert!(alive(pid), "{bin} did not start");
    sh.kill().unwrap();
    sh.wait().unwrap();
    pid
}

fn gone_within(pid: u32, secs: u64) -> bool {
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(secs) {
        if !alive(pid) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    false
}

#[test]
fn forks_and_nodes_left_behind_exit_unless_told_to_serve_on() {
    let fork = orphan("magg-fork", &format!("--listen 127.0.0.1:{}", free_port()));
    let node = orphan("magg-node", &format!("--host 127.0.0.1:{} --connect-timeout 120", free_port()));
    assert!(gone_within(fork, 10), "the orphaned fork still serves");
    assert!(gone_within(node, 10), "the orphaned node still runs");

    let kept = orphan("magg-fork", &format!("--listen 127.0.0.1:{} --serve-on", free_port()));
    std::thread::sleep(Duration::from_secs(2));
    let still = alive(kept);
    let _ = Command::new("kill").arg(kept.to_string()).status();
    assert!(still, "--serve-on did not keep the fork");
}

#[test]
fn a_node_at_a_silent_listener_gives_up_at_its_connect_timeout_naming_it() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap(); // accepts, never answers
    let addr = listener.local_addr().unwrap().to_string();
    let t = Instant::now();
    let out = Command::new(magg_bin("magg-node")).args(["--host", &addr, "--connect-timeout", "2"]).output().unwrap();
    let took = t.elapsed();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&addr) && err.contains("Register"), "{err}");
    assert!(took < Duration::from_secs(20), "waited {took:?} with --connect-timeout 2");
    drop(listener);
}

#[test]
fn a_host_at_a_silent_fork_gives_up_at_its_fork_timeout_naming_it() {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap(); // accepts, never answers
    let addr = listener.local_addr().unwrap().to_string();
    let dir = tempfile::tempdir().unwrap();
    let t = Instant::now();
    let out = magg_tests::magg_host()
        .arg("render")
        .arg(magg_tests::scene("magg-paper.toml"))
        .args(["--out", &dir.path().join("x.png").display().to_string(), "--quiet"])
        .args(["--forks-at", &addr, "--fork-timeout", "2"])
        .output()
        .unwrap();
    let took = t.elapsed();
    let line = magg_tests::assert_user_error(&out, "a silent fork");
    assert!(line.contains(&addr) && line.contains("--fork-timeout"), "{line}");
    assert!(!line.contains("MetadataMap"), "a Debug dump: {line}");
    assert!(took < Duration::from_secs(20), "waited {took:?} with --fork-timeout 2");
    drop(listener);
}

#[test]
fn a_long_lived_node_waits_quietly_for_the_next_render() {
    let dir = tempfile::tempdir().unwrap();
    let host_addr = format!("127.0.0.1:{}", free_port());
    let mut node = Command::new(magg_bin("magg-node"))
        .args(["--host", &host_addr, "--repeat"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let out = magg_tests::magg_host()
        .arg("render")
        .arg(magg_tests::scene("magg-paper.toml"))
        .args(["--width", "16", "--height", "16", "--light-rays", "2", "--spp", "1", "--quiet"])
        .args(["--listen", &host_addr, "--external-nodes", "--forks", "2"])
        .arg("--out")
        .arg(dir.path().join("p.png"))
        .output()
        .unwrap();
    magg_tests::assert_success(&out, "a render with one external node");
    // The host is gone; the node waits for the next one.
    std::thread::sleep(Duration::from_secs(3));
    let _ = node.kill();
    let log = node.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&log.stderr);
    assert!(!log.contains("WARN") && !log.contains("cannot reach"), "the node warned while waiting:\n{log}");
}
