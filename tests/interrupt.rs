//! Ctrl-C in the middle of a render: `magg-host render` writes the image so far to
//! `<stem>.partial.<ext>` beside `--out`, says where, never writes `--out` itself, and
//! exits with the signal's status (130 for SIGINT, 143 for SIGTERM); embedded and cluster.

use magg_tests::*;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// Big enough that the viewing pass takes seconds on two node threads of any machine.
const SIZE: &str = "1600";

/// Starts a slow render of `magg-paper.toml` into `dir/shot.png` with `extra` flags,
/// waits until its scene is preprocessed (the plan it prints) and a moment more, sends
/// `signal` (`INT`, `TERM`), and returns (exit code, stderr).
fn interrupted(dir: &Path, extra: &[&str], signal: &str) -> (Option<i32>, String) {
    let out = dir.join("shot.png");
    let mut child = magg_host()
        .arg("render")
        .arg(scene("magg-paper.toml"))
        .args(["--width", SIZE, "--height", SIZE, "--set", "render.pixel_samples=9", "--nodes", "2"])
        .args(extra)
        .arg("--out")
        .arg(&out)
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cannot start magg-host");
    let stderr = child.stderr.take().expect("piped stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(());
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    // The first line is the effects plan, printed once preprocessing is over.
    if rx.recv_timeout(Duration::from_secs(120)).is_err() {
        let _ = child.kill();
        panic!("magg-host printed nothing in 2 minutes: {}", reader.join().unwrap_or_default());
    }
    std::thread::sleep(Duration::from_millis(1000));
    let pid = child.id().to_string();
    let kill = Command::new("kill").args([&format!("-{signal}"), &pid]).status().expect("cannot run kill");
    assert!(kill.success(), "kill -{signal} {pid}");
    let status = child.wait().expect("waiting for magg-host");
    let text = reader.join().unwrap_or_default();
    (status.code(), text)
}

/// What an interrupted render must leave: the partial image, decodable, at the full size;
/// no `--out`; a line naming the partial file.
fn check_partial(dir: &Path, code: Option<i32>, stderr: &str, want: i32) {
    assert_eq!(code, Some(want), "exit status; stderr:\n{stderr}");
    assert!(!dir.join("shot.png").exists(), "a stopped render wrote --out itself");
    let partial = dir.join("shot.partial.png");
    assert!(stderr.contains(&partial.display().to_string()), "stderr does not name {}:\n{stderr}", partial.display());
    let (w, h, rgb) = read_png_rgb(&partial);
    assert_eq!((w.to_string(), h.to_string()), (SIZE.to_string(), SIZE.to_string()), "partial image size");
    assert_eq!(rgb.len(), (w * h * 3) as usize);
}

#[test]
fn ctrl_c_in_an_embedded_render_leaves_the_partial_image_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let (code, stderr) = interrupted(dir.path(), &["--embedded"], "INT");
    check_partial(dir.path(), code, &stderr, 130);
}

#[test]
fn ctrl_c_in_a_cluster_render_leaves_the_partial_image_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let (code, stderr) = interrupted(dir.path(), &[], "INT");
    check_partial(dir.path(), code, &stderr, 130);
}

#[test]
fn sigterm_in_a_cluster_render_leaves_the_partial_image_and_exits_143() {
    let dir = tempfile::tempdir().unwrap();
    let (code, stderr) = interrupted(dir.path(), &[], "TERM");
    check_partial(dir.path(), code, &stderr, 143);
}
