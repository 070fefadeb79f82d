//! Who may join: with a cluster token set, a node or host without it (or with another)
//! is refused with UNAUTHENTICATED and a clear error on both sides, and the render goes
//! on with the processes that have it; a server bound beyond loopback without a token
//! warns.

use magg_tests::*;
use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TINY: &[&str] = &["--width", "32", "--height", "32", "--light-rays", "2", "--pixel-samples", "1"];

fn node_output(host: &str, token: Option<&str>) -> std::process::Output {
    let mut c = Command::new(magg_bin("magg-node"));
    c.args(["--host", host, "--connect-timeout", "10"]).env_remove("MAGG_TOKEN");
    if let Some(t) = token {
        c.env("MAGG_TOKEN", t);
    }
    c.output().expect("run magg-node")
}

#[test]
fn nodes_without_the_token_are_refused_and_the_render_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let host_addr = format!("127.0.0.1:{}", free_port());
    let out = Rendered::at(dir.path(), "authed");
    let host = out
        .command(&scene("magg-paper.toml"))
        .args(TINY)
        .args(["--listen", &host_addr, "--external-nodes", "--forks", "2", "--token", "right-token"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut procs = Procs(vec![host]);
    for bad in [None, Some("wrong-token")] {
        let o = node_output(&host_addr, bad);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "a node with token {bad:?} was let in");
        assert!(err.contains("cluster token") && err.contains("--token"), "unclear refusal: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    let good = node_output(&host_addr, Some("right-token"));
    assert!(good.status.success(), "{}", String::from_utf8_lossy(&good.stderr));
    let mut host = procs.0.pop().unwrap();
    let st = host.wait().unwrap();
    let mut log = String::new();
    host.stderr.take().unwrap().read_to_string(&mut log).unwrap();
    assert!(st.success(), "{log}");
    assert!(log.contains("host refused a call") && log.contains("no cluster token"), "{log}");
    assert!(log.contains("wrong cluster token"), "{log}");
    assert!(out.png.is_file());
}

#[test]
fn a_host_without_the_forks_token_stops_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let (fork, fork_addr) = spawn_fork(0, &["--token", "fork-secret"], &dir.path().join("fork.log"));
    let _procs = Procs(vec![fork]);
    let o = magg_host()
        .arg("render")
        .arg(scene("magg-paper.toml"))
        .arg("--out")
        .arg(dir.path().join("x.png"))
        .args(TINY)
        .args(["--quiet", "--forks-at", &fork_addr, "--nodes", "1"])
        .env_remove("MAGG_TOKEN")
        .output()
        .unwrap();
    let line = assert_user_error(&o, "host without token");
    assert!(line.contains("fork refused the call") && line.contains("cluster token"), "{line}");
}

#[test]
fn a_fork_listening_beyond_loopback_without_a_token_warns() {
    let mut fork = Command::new(magg_bin("magg-fork"))
        .args(["--listen", "0.0.0.0:0"])
        .env_remove("MAGG_TOKEN")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = fork.stderr.take().unwrap();
    let _procs = Procs(vec![fork]);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut text = String::new();
    while !text.contains("fork listening") {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) => text.push_str(&(line + "\n")),
            Err(e) => panic!("the fork did not start ({e}): {text}"),
        }
    }
    assert!(text.contains("without a cluster token"), "no warning: {text}");
}
