//! Chaos: real magg-fork, magg-node and magg-host processes on localhost, with a node
//! killed in the middle of light ray tracing, another in the middle of viewing ray
//! tracing (and a node joining late), and a fork killed and restarted on its address in
//! each phase. The image and the energies must be bitwise those of a
//! clean embedded run: leased pairs and subscreens of the dead nodes go to the others,
//! re-run pairs deposit exactly once, every pixel row is written once, a fork restarted
//! in LRT gets its energy rebuilt by a replay, and one restarted in VRT gets its shard and
//! vertex energies back. A fork that does not come back stops the
//! render with an error naming it, and every process exits.

use magg_tests::*;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};

const SMALL: &[&str] = &["--width", "48", "--height", "40", "--light-rays", "4", "--pixel-samples", "1"];

/// Lease of the chaos runs: short, so a dead node's work moves on quickly, and still
/// several batches of pairs long, so that live nodes keep theirs.
const LEASE: &str = "1.5";

/// A fork on `port` (0: any), logging to `DIR/LOG.log`; returns it and its address.
fn fork(dir: &Path, log: &str, port: u16) -> (Child, String) {
    // -v: the checks below read the fork's info lines (shard loaded, replay, leases).
    spawn_fork(port, &["-v"], &dir.join(format!("{log}.log")))
}

fn port_of(addr: &str) -> u16 {
    addr.rsplit(':').next().and_then(|p| p.parse().ok()).unwrap()
}

/// Kills fork process `k` and starts it again on `addr`, empty.
fn restart(procs: &mut Procs, k: usize, dir: &Path, log: &str, addr: &str) {
    procs.0[k].kill().unwrap();
    procs.0[k].wait().unwrap();
    std::thread::sleep(Duration::from_millis(200));
    procs.0[k] = fork(dir, log, port_of(addr)).0;
}

/// Waits for `child` to exit, at most `secs` seconds.
fn wait_exit(child: &mut Child, secs: u64) -> Option<std::process::ExitStatus> {
    let deadline = Instant::now() + Duration::from_secs(secs);
    while Instant::now() < deadline {
        if let Some(st) = child.try_wait().unwrap() {
            return Some(st);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    None
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
/// after its `vrt_subscreens`-th subscreen began, and with `forks_too` restart a fork
/// right after each kill; compare with `base`.
/// `cache`: the nodes' cache size (`--cache-blocks`), unlimited for `None`.
fn chaos_run(
    dir: &Path,
    base: &Rendered,
    stem: &str,
    (lrt_batches, vrt_subscreens): (usize, usize),
    forks_too: bool,
    cache: Option<&str>,
) {
    let s = scene("magg-paper.toml");
    let mut procs = Procs(Vec::new());
    let mut fork_addrs = Vec::new();
    for i in 0..3 {
        let (c, a) = fork(dir, &format!("{stem}-fork{i}"), 0);
        procs.0.push(c);
        fork_addrs.push(a);
    }
    let host_addr = format!("127.0.0.1:{}", free_port());
    let out = Rendered::at(dir, stem);
    let forks_at = fork_addrs.join(",");
    let host_log = dir.join(format!("{stem}-host.log"));
    let mut host = out
        .command(&s)
        .args(["--subscreen", "16", "--forks-at", &forks_at, "--listen", &host_addr])
        .args(["--external-nodes", "--lease-timeout", LEASE, "--stall-timeout", "30"])
        .args(cache.map(|c| ["--cache-blocks", c]).iter().flatten())
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
    // Fork 2 dies in light ray tracing, losing the energy deposited on its elements, and
    // comes back empty on the same address.
    if forks_too {
        restart(&mut procs, 2, dir, &format!("{stem}-fork2-again"), &fork_addrs[2]);
    }
    // A node joining in the middle of the render gets work too; it is the one killed
    // in viewing ray tracing.
    let (vrt_victim, vrt_log) = node(&mut procs, &host_addr, "vrt-victim", &slow);
    wait_for(&vrt_log, "tracing a subscreen", vrt_subscreens);
    procs.0[vrt_victim].kill().unwrap();
    // Fork 1 dies in viewing ray tracing and comes back empty on the same address.
    if forks_too {
        restart(&mut procs, 1, dir, &format!("{stem}-fork1-again"), &fork_addrs[1]);
    }

    let Some(status) = wait_exit(&mut host, 60) else {
        let _ = host.kill();
        let _ = host.wait();
        panic!("{stem}: the host did not finish: {}", std::fs::read_to_string(&host_log).unwrap_or_default());
    };
    let host_text = std::fs::read_to_string(&host_log).unwrap();
    if forks_too {
        assert!(host_text.contains("fork 1 at") && host_text.contains("restarted"), "{stem}: fork 1: {host_text}");
        assert!(host_text.contains("replay epoch 1"), "{stem}: no replay after fork 2 restarted: {host_text}");
    }
    assert!(status.success(), "{stem}: host failed: {host_text}");
    assert!(host_text.contains("subscreens are back on the queue"), "{stem}: no subscreen was revoked: {host_text}");
    let forks_text: String =
        (0..3).map(|i| std::fs::read_to_string(dir.join(format!("{stem}-fork{i}.log"))).unwrap()).collect();
    // With a fork restarted in LRT, the replay may take the dead node's pairs back first.
    let taken_back = forks_text.contains("pair leases expired") || (forks_too && forks_text.contains("replay"));
    assert!(taken_back, "{stem}: the dead node's pairs were not taken back: {forks_text}");
    if forks_too {
        // The forks that kept their energy replay only their pairs that deposited on
        // fork 2 and those out with nodes, not all of them. One of them may have had
        // every pair out with nodes when fork 2 came back (a live node's batch can hold
        // a whole fork's queue), so the check is that not both replayed everything.
        let mut selective = false;
        for i in [0, 1] {
            let text = std::fs::read_to_string(dir.join(format!("{stem}-fork{i}.log"))).unwrap();
            let field = |line: &str, key: &str| -> Option<u64> {
                let at = line.find(&format!(" {key}="))? + key.len() + 2;
                line[at..].split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
            };
            let total = text.lines().find(|l| l.contains("shard loaded")).and_then(|l| field(l, "pairs"));
            let replayed = text.lines().find(|l| l.contains("replay:")).and_then(|l| field(l, "pairs"));
            let (Some(total), Some(replayed)) = (total, replayed) else {
                panic!("{stem}: fork {i} logged no shard or no replay: {text}");
            };
            assert!(replayed <= total, "{stem}: fork {i} replayed {replayed} of its {total} pairs: {text}");
            eprintln!("{stem}: fork {i} replayed {replayed} of its {total} pairs");
            selective |= replayed < total;
        }
        assert!(selective, "{stem}: forks 0 and 1 both replayed all their pairs: {forks_text}");
    }
    assert_eq!(std::fs::read(&base.pfm).unwrap(), std::fs::read(&out.pfm).unwrap(), "{stem}: image differs");
    assert_eq!(std::fs::read(&base.energy).unwrap(), std::fs::read(&out.energy).unwrap(), "{stem}: energies differ");
    assert_eq!(std::fs::read(&base.png).unwrap(), std::fs::read(&out.png).unwrap(), "{stem}: PNG differs");
    let stats = read_json(&out.stats);
    assert_eq!(stats["nodes"].as_u64().unwrap(), 3, "{stem}: three nodes registered");
    if cache.is_some() {
        assert!(stats["cache"]["prefetched"].as_u64().unwrap() > 0, "{stem}: nothing was fetched ahead");
    }
}

#[test]
fn killed_nodes_lose_nothing_and_the_bits_are_those_of_a_clean_run() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("magg-paper.toml");
    let base = render(&s, dir.path(), "embedded", &[SMALL, &["--embedded"]].concat());
    // Kill points: early in each phase, then later; forks restarted on two of the runs.
    chaos_run(dir.path(), &base, "early", (1, 1), false, None);
    chaos_run(dir.path(), &base, "mid", (2, 1), true, None);
    // Through 30-block caches, which fetch element records and vertex energies ahead
    // in runs: a fork lost in the viewing pass fails runs, not single blocks.
    chaos_run(dir.path(), &base, "later", (3, 2), true, Some("30"));
}

#[test]
fn a_fork_that_does_not_come_back_stops_the_render_naming_it_and_every_process_exits() {
    let dir = tempfile::tempdir().unwrap();
    let mut procs = Procs(Vec::new());
    let mut fork_addrs = Vec::new();
    for i in 0..2 {
        let (c, a) = fork(dir.path(), &format!("fork{i}"), 0);
        procs.0.push(c);
        fork_addrs.push(a);
    }
    let host_addr = format!("127.0.0.1:{}", free_port());
    let forks_at = fork_addrs.join(",");
    let mut host = Rendered::at(dir.path(), "lost")
        .command(&scene("magg-paper.toml"))
        .args(["--subscreen", "16", "--forks-at", &forks_at, "--listen", &host_addr, "--external-nodes"])
        .args(["--fork-timeout", "2"])
        .args(SMALL)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Nodes give up on an unreachable peer after 3 s of retries.
    let (n, log) = node(&mut procs, &host_addr, "n", &["--slow-row-ms", "20", "--connect-timeout", "3"]);
    wait_for(&log, "tracing a subscreen", 1);
    procs.0[1].kill().unwrap();
    let status = wait_exit(&mut host, 40).expect("the host did not stop");
    let mut err = String::new();
    std::io::Read::read_to_string(host.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(1), "{err}");
    let last = err.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("magg-host: error:") && last.contains(&format!("fork 1 at {}", fork_addrs[1])),
        "the error does not name the fork: {err}"
    );
    assert!(last.contains("--fork-timeout"), "{err}");
    assert!(wait_exit(&mut procs.0[n], 40).is_some(), "the node did not exit after the host stopped");
}

/// A fork-loss run in light ray tracing: 3 forks, a host and two nodes slowed so that
/// the pass lasts a few seconds. `procs.0[i]` is fork `i`.
struct LossRun {
    procs: Procs,
    forks: Vec<String>,
    host: Child,
    host_log: std::path::PathBuf,
    out: Rendered,
    /// A node's log lines (to strike at a chosen batch).
    node_log: Receiver<String>,
}

fn start_loss_run(dir: &Path, stem: &str) -> LossRun {
    start_loss_run_of(dir, stem, "magg-paper.toml", &[], &["--slow-pair-ms", "2"])
}

/// A loss run of `scene_name` with `extra` flags for the host; the second node runs
/// with `second`'s flags (the first, whose log is watched, is always slow).
fn start_loss_run_of(dir: &Path, stem: &str, scene_name: &str, extra: &[&str], second: &[&str]) -> LossRun {
    let mut procs = Procs(Vec::new());
    let mut forks = Vec::new();
    for i in 0..3 {
        let (c, a) = fork(dir, &format!("{stem}-fork{i}"), 0);
        procs.0.push(c);
        forks.push(a);
    }
    let host_addr = format!("127.0.0.1:{}", free_port());
    let out = Rendered::at(dir, stem);
    let host_log = dir.join(format!("{stem}-host.log"));
    let host = out
        .command(&scene(scene_name))
        .args(["--subscreen", "16", "--forks-at", &forks.join(","), "--listen", &host_addr])
        .args(extra)
        .args(["--external-nodes", "--lease-timeout", LEASE, "--stall-timeout", "30", "--fork-timeout", "10"])
        .args(SMALL)
        .stdout(Stdio::null())
        .stderr(File::create(&host_log).unwrap())
        .spawn()
        .unwrap();
    let (_, node_log) = node(&mut procs, &host_addr, "a", &["--slow-pair-ms", "2"]);
    node(&mut procs, &host_addr, "b", second);
    LossRun { procs, forks, host, host_log, out, node_log }
}

/// Waits until the file at `path` has a line containing `what`; panics after 30 s.
fn wait_in_file(path: &Path, what: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while !std::fs::read_to_string(path).unwrap_or_default().contains(what) {
        assert!(Instant::now() < deadline, "no {what:?} in {}", path.display());
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Waits for the host of `run` and checks that it finished with the bits of `base`;
/// returns its log.
fn finish_loss_run(mut run: LossRun, base: &Rendered, stem: &str) -> String {
    let status = wait_exit(&mut run.host, 90);
    let text = std::fs::read_to_string(&run.host_log).unwrap_or_default();
    let Some(status) = status else {
        let _ = run.host.kill();
        let _ = run.host.wait();
        panic!("{stem}: the host did not finish: {text}");
    };
    assert!(status.success(), "{stem}: host failed: {text}");
    assert_eq!(std::fs::read(&base.pfm).unwrap(), std::fs::read(&run.out.pfm).unwrap(), "{stem}: image differs");
    assert_eq!(
        std::fs::read(&base.energy).unwrap(),
        std::fs::read(&run.out.energy).unwrap(),
        "{stem}: energies differ"
    );
    text
}

#[test]
fn a_fork_killed_again_during_its_replay_gives_the_bits_of_a_clean_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = render(&scene("magg-paper.toml"), d, "embedded", &[SMALL, &["--embedded"]].concat());
    let mut run = start_loss_run(d, "again");
    wait_for(&run.node_log, "tracing a batch of pairs", 2);
    let addr = run.forks[2].clone();
    restart(&mut run.procs, 2, d, "again-fork2-second", &addr);
    // Loaded again: its replay is under way. Lost again in the middle of it.
    wait_in_file(&d.join("again-fork2-second.log"), "shard loaded");
    std::thread::sleep(Duration::from_millis(300));
    restart(&mut run.procs, 2, d, "again-fork2-third", &addr);
    let text = finish_loss_run(run, &base, "again");
    assert!(text.contains("replay epoch 2"), "fork 2's second loss started no replay: {text}");
}

#[test]
fn two_forks_lost_together_in_lrt_give_the_bits_of_a_clean_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = render(&scene("magg-paper.toml"), d, "embedded", &[SMALL, &["--embedded"]].concat());
    let mut run = start_loss_run(d, "two");
    wait_for(&run.node_log, "tracing a batch of pairs", 2);
    for k in [1, 2] {
        run.procs.0[k].kill().unwrap();
        run.procs.0[k].wait().unwrap();
    }
    std::thread::sleep(Duration::from_millis(200));
    for k in [1, 2] {
        run.procs.0[k] = fork(d, &format!("two-fork{k}-again"), port_of(&run.forks[k])).0;
    }
    let text = finish_loss_run(run, &base, "two");
    for k in [1, 2] {
        assert!(text.contains(&format!("fork {k} at")), "fork {k}'s loss is not in the log: {text}");
    }
    assert!(text.contains("replay epoch 2"), "not both forks were rebuilt: {text}");
}

#[test]
fn a_node_and_a_fork_lost_in_a_pilot_level_lose_nothing() {
    // Refinement's pilot levels run on the nodes, each a scene of the cluster's own: a
    // node killed in the first level's light pass and a fork lost there cost its pairs
    // a lease and a replay, as in the render's own light pass, and the image is the
    // embedded renderer's.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene("cornell.toml");
    let refined = ["--element-size", "0.5", "--set", "render.refine=2", "--min-nodes", "2"];
    let base = render(&s, d, "embedded", &[SMALL, &refined[..4], &["--embedded"]].concat());
    let mut run = start_loss_run_of(d, "pilot", "cornell.toml", &refined, &[]);
    wait_for(&run.node_log, "tracing a batch of pairs", 1);
    // Node "a" (after the three forks) dies in its first batch: the first pilot level.
    run.procs.0[3].kill().unwrap();
    let addr = run.forks[2].clone();
    restart(&mut run.procs, 2, d, "pilot-fork2-again", &addr);
    let stats_path = run.out.stats.clone();
    let text = finish_loss_run(run, &base, "pilot");
    assert!(text.contains("restarted"), "fork 2's loss in the pilot level went unseen: {text}");
    let stats = read_json(&stats_path);
    assert_eq!(stats["refine"]["pilots_on"], "nodes", "{}", stats["refine"]);
    assert_eq!(stats["refine"]["levels"], read_json(&base.stats)["refine"]["levels"]);
}

#[test]
fn a_fork_killed_while_the_forks_prepare_the_scene_has_its_share_prepared_again() {
    // The forks prepare the scene, each its shares of space; fork 1 dies after its
    // first step (slow steps give the test the time to strike). The host sees the loss,
    // prepares again in a new session on the forks as they are then (fork 1 restarted,
    // empty), and the render is the embedded renderer's, bit for bit.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene("cornell.toml");
    let base = render(&s, d, "embedded", &[SMALL, &["--embedded"]].concat());
    let mut procs = Procs(Vec::new());
    let mut forks = Vec::new();
    for i in 0..3 {
        let (c, a) = spawn_fork(0, &["-v", "--slow-step-ms", "300"], &d.join(format!("prep-fork{i}.log")));
        procs.0.push(c);
        forks.push(a);
    }
    let out = Rendered::at(d, "prep");
    let host_log = d.join("prep-host.log");
    let mut host = out
        .command(&s)
        .args(["--forks-at", &forks.join(","), "--share-patches", "1", "--fork-timeout", "10", "--nodes", "2"])
        .args(SMALL)
        .stdout(Stdio::null())
        .stderr(File::create(&host_log).unwrap())
        .spawn()
        .unwrap();
    wait_in_file(&d.join("prep-fork1.log"), "preparing a share");
    restart(&mut procs, 1, d, "prep-fork1-again", &forks[1]);
    let status = wait_exit(&mut host, 90);
    let text = std::fs::read_to_string(&host_log).unwrap_or_default();
    if status.is_none() {
        let _ = host.kill();
        let _ = host.wait();
    }
    assert!(status.is_some_and(|s| s.success()), "the host failed: {text}");
    assert!(text.contains("lost while preparing the scene"), "the loss went unseen: {text}");
    let stats = read_json(&out.stats);
    // Every process's peak memory: the host's and each fork's (separate processes).
    let memory = &stats["memory"];
    assert!(memory["host_bytes"].as_u64().is_some_and(|b| b > 0), "{memory}");
    let forks_peak = memory["fork_bytes"].as_array().expect("fork_bytes");
    assert_eq!(forks_peak.len(), 3, "{memory}");
    assert!(forks_peak.iter().all(|b| b.as_u64().is_some_and(|b| b > 0)), "{memory}");
    let prepare = &stats["prepare"];
    assert_eq!(prepare["shares"], 3, "{prepare}");
    assert!(prepare["attempts"].as_u64().is_some_and(|a| a >= 2), "{prepare}");
    assert!(prepare["place"].as_str().is_some_and(|p| p.contains(&forks[1])), "{prepare}");
    assert_eq!(std::fs::read(&base.pfm).unwrap(), std::fs::read(&out.pfm).unwrap(), "image differs");
    assert_eq!(std::fs::read(&base.energy).unwrap(), std::fs::read(&out.energy).unwrap(), "energies differ");
    // Every fork took part in the second session: each logged a share of it.
    let again = std::fs::read_to_string(d.join("prep-fork1-again.log")).unwrap();
    assert!(again.contains("preparing a share"), "the restarted fork prepared nothing: {again}");
}
