//! Driving the machine's Docker engine from the container tests: whether there is one,
//! which compose client it has (`docker compose` or `docker-compose`), building the
//! images with `deploy/build-images.sh`, and waiting for and listing what a run left.
//!
//! Tests that need an engine call [`engine`] first and return when it gives `None`: it
//! has already printed the `SKIPPED: ...` line, so a missing engine never passes silently.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// Prints a `SKIPPED: ...` line straight to the process's stderr, past the test harness's
/// output capture, so that a skipped test shows in every `cargo test` log.
pub fn skipped(message: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIPPED: {message}");
}

/// Runs `cmd` and returns its stdout, or a message with its stderr when it fails.
pub fn output(cmd: &mut Command) -> Result<String, String> {
    let what = format!("{cmd:?}");
    let out: Output = cmd.output().map_err(|e| format!("{what}: cannot start: {e}"))?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    } else {
        Err(format!(
            "{what}: {}\n{}{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ))
    }
}

/// A `docker` command.
pub fn docker<I: IntoIterator<Item = S>, S: AsRef<std::ffi::OsStr>>(args: I) -> Command {
    let mut cmd = Command::new("docker");
    cmd.args(args);
    cmd
}

/// `Some(())` when `docker info` succeeds; otherwise prints, for the test named `test`,
/// `SKIPPED: no Docker engine (docker info failed: ...)` to stderr and gives `None`.
pub fn engine(test: &str) -> Option<()> {
    match output(&mut docker(["info", "--format", "{{.ServerVersion}}"])) {
        Ok(_) => Some(()),
        Err(e) => {
            let reason = e.lines().filter(|l| !l.trim().is_empty()).last().unwrap_or("").to_string();
            skipped(&format!("no Docker engine (docker info failed: {reason}): {test} did not run"));
            None
        }
    }
}

/// The compose client: `docker compose` (the v2 plugin) when it answers, else the
/// stand-alone `docker-compose`; `None` (after printing a SKIPPED line) when neither does.
pub fn compose_client(test: &str) -> Option<Vec<String>> {
    for client in [&["docker", "compose"][..], &["docker-compose"][..]] {
        let mut cmd = Command::new(client[0]);
        cmd.args(&client[1..]).arg("version");
        if output(&mut cmd).is_ok() {
            return Some(client.iter().map(|s| s.to_string()).collect());
        }
    }
    skipped(&format!("neither `docker compose` nor `docker-compose` runs: {test} did not run"));
    None
}

/// A name no other run on this engine uses: `prefix` with the process id and the clock.
pub fn unique_name(prefix: &str) -> String {
    let nanos =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.subsec_nanos()).unwrap_or(0);
    format!("{prefix}{}x{nanos}", std::process::id())
}

/// Builds the three images with `deploy/build-images.sh --bin-dir DIR --tag TAG` from the
/// binaries the tests use.
pub fn build_images(bin_dir: &Path, tag: &str) {
    let script = crate::workspace_root().join("deploy/build-images.sh");
    let mut cmd = Command::new("bash");
    cmd.arg(script).arg("--bin-dir").arg(bin_dir).args(["--tag", tag]);
    if let Err(e) = output(&mut cmd) {
        panic!("building the images failed: {e}");
    }
}

/// Removes the images of `tag` (best effort: for clean-up guards).
pub fn remove_images(tag: &str) {
    let names: Vec<String> = ["magg-fork", "magg-node", "magg-host"].iter().map(|n| format!("{n}:{tag}")).collect();
    let _ = docker(["rmi", "--force"]).args(&names).output();
}

/// Ids of the containers, networks or volumes (`kind`) that carry `label`.
pub fn labelled(kind: &str, label: &str) -> Vec<String> {
    let mut cmd = match kind {
        "container" => docker(["ps", "-a", "-q"]),
        "network" => docker(["network", "ls", "-q"]),
        _ => docker(["volume", "ls", "-q"]),
    };
    cmd.args(["--filter", &format!("label={label}")]);
    output(&mut cmd).unwrap_or_default().split_whitespace().map(str::to_string).collect()
}

/// Polls `done` every half second until it gives `Some`, or panics after `limit` with
/// `what` and the last answer of `state`.
pub fn wait_for<T>(what: &str, limit: Duration, mut done: impl FnMut() -> Option<T>, state: impl Fn() -> String) -> T {
    let start = Instant::now();
    loop {
        if let Some(v) = done() {
            return v;
        }
        if start.elapsed() > limit {
            panic!("timed out after {limit:?} waiting for {what}; last state:\n{}", state());
        }
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// `docker inspect` of `ids` with a Go template, one line per container.
pub fn inspect(ids: &[String], template: &str) -> Vec<String> {
    if ids.is_empty() {
        return Vec::new();
    }
    output(&mut docker(["inspect", "-f", template]).args(ids))
        .unwrap_or_default()
        .lines()
        .map(str::to_string)
        .filter(|l| !l.is_empty())
        .collect()
}
