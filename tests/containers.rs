//! Containers on this machine's Docker engine, for real: `deploy/build-images.sh` builds the
//! FROM-scratch images, `deploy/docker-compose.yml` (compose: the host waits for healthy
//! forks and nodes) and `deploy/docker-stack.yml` (`docker stack deploy` on a
//! single-machine swarm) run five forks, eight nodes and a host, the image they render is
//! the embedded renderer's bit for bit, every process stops cleanly, and nothing the run
//! made is left behind. The host writes as the owner of the output folder (`MAGG_USER`). Without an engine (or a compose client, or a swarm) each
//! test prints a `SKIPPED: ...` line and returns.

use magg_tests::docker::*;
use magg_tests::*;
use std::path::Path;
use std::process::Command;
use std::sync::Mutex;
use std::time::Duration;

/// The two tests share the engine (and would share its CPU): one at a time.
static ENGINE: Mutex<()> = Mutex::new(());

const SCENE: &str = "magg-paper.toml";
const NODES: usize = 8;

/// The reference: the embedded renderer's image of `SCENE`, as RGB.
fn embedded_reference(dir: &Path) -> (u32, u32, Vec<u8>) {
    let out = dir.join("embedded.png");
    let run = run_host([
        "render".as_ref(),
        scene(SCENE).as_os_str(),
        "--embedded".as_ref(),
        "--quiet".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_success(&run, "embedded render");
    read_png_rgb(&out)
}

/// Checks what the cluster wrote into `out`: the reference image, bit for bit, and stats
/// from a five-fork cluster run.
fn check_outputs(out: &Path, reference: &(u32, u32, Vec<u8>), what: &str) {
    let image = read_png_rgb(&out.join("render.png"));
    assert_eq!((image.0, image.1), (reference.0, reference.1), "{what}: image size");
    assert!(image.2 == reference.2, "{what}: the image differs from the embedded renderer's");
    let stats = read_json(&out.join("stats.json"));
    assert_eq!(stats["mode"], "cluster", "{what}: stats {stats}");
    assert_eq!(stats["forks"], 5, "{what}: stats {stats}");
    assert_eq!(stats["profile"], "native", "{what}: stats {stats}");
    let nodes = stats["nodes"].as_u64().unwrap_or(0);
    // The host waits for every node (MAGG_MIN_NODES) before the light pass.
    assert_eq!(nodes, NODES as u64, "{what}: {nodes} nodes registered");
}

/// The environment of a compose or stack run; the host writes `out` as its owner.
fn settings(cmd: &mut Command, tag: &str, out: &Path) {
    use std::os::unix::fs::MetadataExt;
    let owner = std::fs::metadata(out).map(|m| format!("{}:{}", m.uid(), m.gid())).unwrap_or_default();
    cmd.current_dir(workspace_root())
        .env("MAGG_TAG", tag)
        .env("MAGG_OUT", out)
        .env("MAGG_SCENES", workspace_root().join("scenes"))
        .env("MAGG_SCENE", SCENE)
        .env("MAGG_PROFILE", "native")
        .env("MAGG_NODES", NODES.to_string())
        .env("MAGG_MIN_NODES", NODES.to_string())
        .env("MAGG_RENDER_FLAGS", "")
        .env("MAGG_USER", owner);
}

/// Takes a compose project down (containers, network, volumes) and removes its images,
/// also when the test fails half-way.
struct ComposeRun {
    client: Vec<String>,
    project: String,
    tag: String,
    out: std::path::PathBuf,
}

impl ComposeRun {
    fn cmd(&self, args: &[&str]) -> Command {
        let mut cmd = Command::new(&self.client[0]);
        cmd.args(&self.client[1..]).args(["-p", &self.project, "-f", "deploy/docker-compose.yml"]).args(args);
        settings(&mut cmd, &self.tag, &self.out);
        cmd
    }

    fn ids(&self, service: &str) -> Vec<String> {
        output(&mut self.cmd(&["ps", "-q", service]))
            .unwrap_or_default()
            .split_whitespace()
            .map(str::to_string)
            .collect()
    }
}

impl Drop for ComposeRun {
    fn drop(&mut self) {
        let _ = self.cmd(&["down", "-v", "--remove-orphans", "--timeout", "10"]).output();
        remove_images(&self.tag);
    }
}

#[test]
fn compose_cluster_renders_the_embedded_image_and_leaves_nothing() {
    const TEST: &str = "compose_cluster_renders_the_embedded_image_and_leaves_nothing";
    let _engine = ENGINE.lock().unwrap_or_else(|e| e.into_inner());
    let (Some(()), Some(client)) = (engine(TEST), compose_client(TEST)) else { return };
    let dir = tempfile::tempdir().unwrap();
    let reference = embedded_reference(dir.path());
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let run = ComposeRun { client, project: unique_name("maggtest"), tag: unique_name("test"), out: out.clone() };
    build_images(magg_bin("magg-host").parent().unwrap(), &run.tag);

    // One `up` of the host: compose starts the forks and nodes, waits until every one
    // reports SERVING on its health service (depends_on: service_healthy), then the host.
    let scale = format!("node={NODES}");
    let up = output(&mut run.cmd(&["up", "-d", "--scale", &scale, "host"]));
    up.unwrap_or_else(|e| panic!("compose up: {e}"));
    let label = format!("com.docker.compose.project={}", run.project);
    let healthy = inspect(&labelled("container", &label), "{{.Name}} {{.State.Status}} {{.State.Health.Status}}");
    let ready = healthy.iter().filter(|l| l.ends_with(" running healthy")).count();
    assert!(ready >= 5 + NODES, "the host started before every fork and node was healthy:\n{}", healthy.join("\n"));
    let host = run.ids("host");
    assert_eq!(host.len(), 1, "one host container");
    let code = output(&mut docker(["wait", &host[0]])).unwrap_or_else(|e| panic!("docker wait: {e}"));
    if code.trim() != "0" {
        let logs = docker(["logs", &host[0]]).output().map(|o| String::from_utf8_lossy(&o.stderr).into_owned());
        panic!("the host exited with {}: {}", code.trim(), logs.unwrap_or_default());
    }
    check_outputs(&out, &reference, "compose");

    // Graceful shutdown: SIGTERM, and every fork and node exits 0 well before the kill.
    output(&mut run.cmd(&["stop", "--timeout", "10"])).unwrap_or_else(|e| panic!("compose stop: {e}"));
    let exits = inspect(&labelled("container", &label), "{{.Name}} {{.State.ExitCode}}");
    assert_eq!(exits.len(), 5 + NODES + 1, "containers: {exits:?}");
    assert!(exits.iter().all(|l| l.ends_with(" 0")), "a process did not stop cleanly: {exits:?}");

    // Down, and nothing of the project is left.
    output(&mut run.cmd(&["down", "-v", "--remove-orphans", "--timeout", "10"]))
        .unwrap_or_else(|e| panic!("down: {e}"));
    for kind in ["container", "network", "volume"] {
        let left = labelled(kind, &label);
        assert!(left.is_empty(), "compose down left {kind}s behind: {left:?}");
    }
}

/// Leaves the swarm if this test initialised it; removes the stack and the images.
struct StackRun {
    stack: String,
    tag: String,
    joined_swarm: bool,
    /// Whether `docker_gwbridge` (which `docker swarm init` makes) was there before.
    had_gwbridge: bool,
}

impl Drop for StackRun {
    fn drop(&mut self) {
        let _ = docker(["stack", "rm", &self.stack]).output();
        let label = format!("com.docker.stack.namespace={}", self.stack);
        for _ in 0..60 {
            if labelled("container", &label).is_empty() && labelled("network", &label).is_empty() {
                break;
            }
            std::thread::sleep(Duration::from_millis(500));
        }
        remove_images(&self.tag);
        if self.joined_swarm {
            let _ = docker(["swarm", "leave", "--force"]).output();
            if !self.had_gwbridge {
                let _ = docker(["network", "rm", "docker_gwbridge"]).output();
            }
        }
    }
}

/// Joins a single-machine swarm if the engine is in none: `Some(true)` if this call
/// initialised it (and must leave), `Some(false)` if one was active; `None` (after a
/// SKIPPED line) if there is none and `docker swarm init` fails.
fn swarm(test: &str) -> Option<bool> {
    let state = output(&mut docker(["info", "--format", "{{.Swarm.LocalNodeState}}"])).unwrap_or_default();
    match state.trim() {
        "active" => return Some(false),
        "inactive" => {}
        other => {
            skipped(&format!("the engine's swarm is {other:?}, neither active nor inactive: {test} did not run"));
            return None;
        }
    }
    let plain = output(&mut docker(["swarm", "init"]));
    let init = plain.or_else(|_| output(&mut docker(["swarm", "init", "--advertise-addr", "127.0.0.1"])));
    match init {
        Ok(_) => Some(true),
        Err(e) => {
            skipped(&format!("docker swarm init failed ({}): {test} did not run", e.lines().last().unwrap_or("")));
            None
        }
    }
}

#[test]
fn swarm_stack_renders_the_embedded_image_and_leaves_nothing() {
    const TEST: &str = "swarm_stack_renders_the_embedded_image_and_leaves_nothing";
    let _engine = ENGINE.lock().unwrap_or_else(|e| e.into_inner());
    let Some(()) = engine(TEST) else { return };
    let dir = tempfile::tempdir().unwrap();
    let reference = embedded_reference(dir.path());
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let tag = unique_name("test");
    build_images(magg_bin("magg-host").parent().unwrap(), &tag);
    let had_gwbridge = output(&mut docker(["network", "inspect", "docker_gwbridge"])).is_ok();
    let Some(joined_swarm) = swarm(TEST) else {
        remove_images(&tag);
        return;
    };
    let run = StackRun { stack: unique_name("maggstack"), tag, joined_swarm, had_gwbridge };

    let mut deploy = docker(["stack", "deploy", "-c", "deploy/docker-stack.yml", &run.stack]);
    settings(&mut deploy, &run.tag, &out);
    output(&mut deploy).unwrap_or_else(|e| panic!("docker stack deploy: {e}"));
    let host = format!("{}_host", run.stack);
    let state =
        || output(&mut docker(["service", "ps", &host, "--no-trunc", "--format", "{{.CurrentState}} {{.Error}}"]));
    let done = wait_for(
        "the host's render task to end",
        Duration::from_secs(90),
        || state().ok().filter(|s| ["Complete", "Failed", "Rejected", "Shutdown"].iter().any(|w| s.starts_with(w))),
        || format!("{state:?}", state = state()),
    );
    assert!(done.starts_with("Complete"), "the host's task ended: {done}");
    check_outputs(&out, &reference, "swarm stack");

    output(&mut docker(["stack", "rm", &run.stack])).unwrap_or_else(|e| panic!("docker stack rm: {e}"));
    let label = format!("com.docker.stack.namespace={}", run.stack);
    let left = || [labelled("container", &label), labelled("network", &label), labelled("volume", &label)].concat();
    wait_for(
        "the stack to be gone",
        Duration::from_secs(30),
        || left().is_empty().then_some(()),
        || format!("{:?}", left()),
    );
}
