//! The cluster: the in-process harness and real processes on localhost give the same
//! bits as the rendering core driven directly; a slow node's unstarted rows are
//! redivided; no process is left behind.

use magg_tests::*;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SMALL: &[&str] = &["--width", "48", "--height", "40", "--light-rays", "4", "--pixel-samples", "1"];
const SQUARE: &[&str] = &["--width", "64", "--height", "64", "--light-rays", "4", "--pixel-samples", "1"];

/// cornell.toml with two levels of refinement, on elements coarse enough to be quick.
const REFINED: &[&str] = &["--element-size", "0.25", "--set", "render.refine=2"];

fn with(extra: &[&str]) -> Vec<&'static str> {
    let mut v: Vec<&'static str> = SMALL.to_vec();
    for e in extra {
        v.push(Box::leak(e.to_string().into_boxed_str()));
    }
    v
}

fn same_files(a: &Rendered, b: &Rendered, what: &str) {
    assert_eq!(std::fs::read(&a.pfm).unwrap(), std::fs::read(&b.pfm).unwrap(), "{what}: image differs");
    assert_eq!(std::fs::read(&a.energy).unwrap(), std::fs::read(&b.energy).unwrap(), "{what}: energies differ");
    assert_eq!(std::fs::read(&a.png).unwrap(), std::fs::read(&b.png).unwrap(), "{what}: PNG differs");
}

#[test]
fn the_gathered_bounce_crosses_the_cluster_bit_for_bit() {
    // diffuse.toml: direct light at VRT and one diffuse bounce, so pixels beside the
    // boxes' contacts with the floor gather the bounce (their vertices are marked in the
    // vertex-energy blocks that travel through the forks).
    let dir = tempfile::tempdir().unwrap();
    let s = scene("diffuse.toml");
    let args = |extra: &[&str]| with(&[&["--element-size", "0.3"][..], extra].concat());
    let base = render(&s, dir.path(), "embedded", &args(&["--embedded"]));
    let flat = render(&s, dir.path(), "interpolated", &args(&["--embedded", "--gather-rays", "0"]));
    assert_ne!(std::fs::read(&base.pfm).unwrap(), std::fs::read(&flat.pfm).unwrap(), "nothing was gathered");
    let shapes: &[&[&str]] = &[
        &["--nodes", "3", "--forks", "2"],
        &["--nodes", "2", "--forks", "5", "--cache-blocks", "60", "--transport", "tcp"],
    ];
    for (i, shape) in shapes.iter().enumerate() {
        let r = render(&s, dir.path(), &format!("cluster{i}"), &args(shape));
        same_files(&base, &r, &format!("diffuse.toml {}", shape.join(" ")));
    }
}

#[test]
fn in_process_cluster_matches_the_embedded_core_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    // area.toml: light sources are emitting elements (area lights) after the point lights.
    for scene_name in ["magg-paper.toml", "cornell.toml", "area.toml"] {
        let s = scene(scene_name);
        let extra: &[&str] = if scene_name == "magg-paper.toml" { &[] } else { &["--element-size", "0.25"] };
        let base = render(&s, dir.path(), "embedded", &with(&[&["--embedded"][..], extra].concat()));
        // The shapes; the 20-block cache only on the paper's scene (on the
        // Cornell box it thrashes: every miss is a round trip, which is the point of the
        // paper's cache study, not of this test).
        let shapes: &[&[&str]] = if scene_name != "magg-paper.toml" {
            &[
                &["--nodes", "1", "--forks", "1"],
                &["--nodes", "4", "--forks", "5"],
                &["--nodes", "3", "--forks", "3", "--cache-blocks", "400"],
                // Every call over 127.0.0.1 sockets instead of the in-process transport.
                &["--nodes", "3", "--forks", "2", "--transport", "tcp"],
            ]
        } else {
            &[
                &["--nodes", "1", "--forks", "1"],
                &["--nodes", "4", "--forks", "5"],
                &["--nodes", "16", "--forks", "3", "--cache-blocks", "20"],
                &["--nodes", "4", "--forks", "5", "--transport", "tcp"],
            ]
        };
        for (i, shape) in shapes.iter().enumerate() {
            let args = with(&[*shape, extra].concat());
            let r = render(&s, dir.path(), &format!("cluster{i}"), &args);
            same_files(&base, &r, &format!("{scene_name} {}", shape.join(" ")));
            let stats = read_json(&r.stats);
            assert_eq!(stats["mode"], "cluster");
            assert_eq!(stats["work"]["pairs"], read_json(&base.stats)["work"]["pairs"]);
            assert_eq!(stats["nodes"].as_u64().unwrap(), shape[1].parse::<u64>().unwrap());
            assert!(stats["traffic"]["rpcs"].as_u64().unwrap() > 0);
            assert!(stats["traffic"]["dma_bytes"].as_u64().unwrap() > 0);
        }
    }
}

#[test]
fn back_elements_give_the_same_bits_in_every_shape() {
    // panel.toml: light arrives on both faces of a thin panel, directly, via a mirror and
    // bounced, so back elements hold energy of their own.
    let dir = tempfile::tempdir().unwrap();
    let s = scene("panel.toml");
    let base = render(&s, dir.path(), "embedded", &with(&["--embedded"]));
    let rows = read_energy(&base.energy);
    // The panel (patches 0 and 1): its front elements, then (after every front element of
    // the scene) its back ones. The front holds the red light, the back the blue.
    let panel: Vec<_> = rows.iter().filter(|r| r.kind == "element" && r.values[1].is_some_and(|p| p < 2.0)).collect();
    let (front, back) = panel.split_at(panel.len() / 2);
    assert!(front.iter().all(|r| r.values[6].is_some_and(|red| red > 0.0)), "a front element without red light");
    assert!(back.iter().all(|r| r.values[8].is_some_and(|blue| blue > 0.0)), "a back element without blue light");
    for (i, shape) in [&["--nodes", "1", "--forks", "1"][..], &["--nodes", "3", "--forks", "5", "--cache-blocks", "30"]]
        .iter()
        .enumerate()
    {
        let r = render(&s, dir.path(), &format!("cluster{i}"), &with(shape));
        same_files(&base, &r, &format!("panel.toml {}", shape.join(" ")));
    }
}

#[test]
fn refined_elements_give_the_same_bits_in_every_shape() {
    // cornell.toml with two levels of refinement: the caustic's and the mirror light's
    // edges split into elements made after the lattice's, on every shape of the cluster.
    let dir = tempfile::tempdir().unwrap();
    let (s, refined) = (scene("cornell.toml"), REFINED);
    let base = render(&s, dir.path(), "embedded", &with(&[&["--embedded"][..], refined].concat()));
    let unrefined = [&["--embedded"][..], refined, &["--set", "render.refine=0"]].concat();
    let plain = render(&s, dir.path(), "plain", &with(&unrefined));
    let elements = |r: &Rendered| read_energy(&r.energy).iter().filter(|row| row.kind == "element").count();
    assert!(
        elements(&base) > elements(&plain),
        "refinement made no element: {} against {}",
        elements(&base),
        elements(&plain)
    );
    let mut light_rays = Vec::new();
    for (i, shape) in [
        &["--nodes", "1", "--forks", "1"][..],
        // Caches of 30 blocks fetch each level of the refined elements' records ahead,
        // in runs, in both passes.
        &["--nodes", "3", "--forks", "5", "--cache-blocks", "30"],
        // Over sockets the host shares nothing with its nodes: they trace the pairs that
        // the in-process nodes bin from the pilots' kept deposits.
        &["--nodes", "2", "--forks", "3", "--transport", "tcp", "--cache-blocks", "30"],
    ]
    .iter()
    .enumerate()
    {
        let r = render(&s, dir.path(), &format!("cluster{i}"), &with(&[*shape, refined].concat()));
        same_files(&base, &r, &format!("refined cornell.toml {}", shape.join(" ")));
        let stats = read_json(&r.stats);
        if shape.contains(&"--cache-blocks") {
            assert!(stats["cache"]["prefetched"].as_u64().unwrap() > 0, "{}: nothing fetched ahead", shape.join(" "));
        }
        assert_eq!(stats["refine"]["pilots_on"], "nodes", "{}: the pilots ran on the host", shape.join(" "));
        light_rays.push(stats["work"]["light_rays"].as_u64().unwrap());
    }
    // cornell's pairs (direct light at VRT) are the mirror's and the glass's, none split:
    // nodes of the host's process bin every one of them from the pilots' shared table.
    // (Over sockets each node bins those it traced in the pilots and traces the others:
    // how many depends on which node took which pair.)
    assert_eq!(light_rays[..2], [0, 0], "light rays traced: {light_rays:?}");
}

#[test]
fn eighty_nodes_on_five_forks_give_the_same_bits() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("magg-paper.toml");
    let base = render(&s, dir.path(), "embedded", &with(&["--embedded"]));
    let r = render(&s, dir.path(), "eighty", &with(&["--nodes", "80", "--forks", "5", "--cache-blocks", "40"]));
    same_files(&base, &r, "80 nodes, 5 forks, 40-block caches");
    assert_eq!(read_json(&r.stats)["nodes"].as_u64().unwrap(), 80);
}

fn spawn(bin: &str, args: &[String]) -> Child {
    Command::new(magg_bin(bin)).args(args).stdout(Stdio::null()).stderr(Stdio::null()).spawn().expect("spawn")
}

#[test]
fn separate_processes_on_localhost_give_the_same_bits_and_slow_nodes_are_redivided() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene("magg-paper.toml");
    let base = render(&s, dir.path(), "embedded", &[SQUARE, &["--embedded"]].concat());

    let mut procs = Procs(Vec::new());
    let fork_addrs: Vec<String> = (0..3).map(|_| format!("127.0.0.1:{}", free_port())).collect();
    for a in &fork_addrs {
        procs.0.push(spawn("magg-fork", &["--listen".into(), a.clone()]));
    }
    let host_addr = format!("127.0.0.1:{}", free_port());
    // A very slow node starts first and takes the only subscreen; a normal node joins
    // later and must get the unstarted rows by redivision.
    procs.0.push(spawn("magg-node", &["--host".into(), host_addr.clone(), "--slow-row-ms".into(), "40".into()]));
    let forks_at = fork_addrs.join(",");
    let args: Vec<&str> =
        [SQUARE, &["--subscreen", "64", "--forks-at", &forks_at, "--listen", &host_addr, "--external-nodes"]].concat();
    let multi = Rendered::at(dir.path(), "multi");
    let host = multi.command(&s).args(&args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    // The second node is fast but not instant (5 ms a row), so that whichever node holds
    // the subscreen when the other asks, there are unstarted rows to hand over.
    procs.0.push(spawn("magg-node", &["--host".into(), host_addr.clone(), "--slow-row-ms".into(), "5".into()]));
    let out = host.wait_with_output().unwrap();
    assert!(out.status.success(), "host failed: {}", String::from_utf8_lossy(&out.stderr));
    same_files(&base, &multi, "multi-process");
    let stats = read_json(&multi.stats);
    assert!(stats["work"]["redivisions"].as_u64().unwrap() > 0, "the slow node's rows were not redivided: {stats}");
    assert_eq!(stats["nodes"].as_u64().unwrap(), 2);
    // Both nodes exit by themselves once the host says done.
    exit_by_themselves(&mut procs.0[3..]);
}

/// Waits (up to 10 s) for the node processes `nodes` to exit, successfully.
fn exit_by_themselves(nodes: &mut [Child]) {
    let deadline = Instant::now() + Duration::from_secs(10);
    for c in nodes {
        loop {
            if let Some(st) = c.try_wait().unwrap() {
                assert!(st.success(), "a node exited with {st}");
                break;
            }
            assert!(Instant::now() < deadline, "a node did not stop after the render");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// The first of `n` consecutive ports on 127.0.0.1 that are free now, below the range
/// the system hands out for port 0 (32768 and up on Linux), so that no other test's
/// listener, bound to port 0 while this one runs, can take one of them: a run of ports
/// chosen from `free_port()` could collide with one (the host then fails to bind).
fn free_port_run(n: u16) -> u16 {
    let seed = std::process::id() as u64
        ^ std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos() as u64);
    for attempt in 0..200u64 {
        let base = 20_000
            + ((seed.wrapping_mul(6364136223846793005).wrapping_add(attempt * 1442695040888963407) >> 33) % 12_000)
                as u16;
        if (0..n).all(|k| std::net::TcpListener::bind(("127.0.0.1", base + k)).is_ok()) {
            return base;
        }
    }
    panic!("no run of {n} free ports between 20000 and 32000 on 127.0.0.1");
}

#[test]
fn local_cluster_script_renders_and_leaves_no_process_behind() {
    let dir = tempfile::tempdir().unwrap();
    let base_port = free_port_run(3);
    let bin_dir = magg_bin("magg-fork").parent().unwrap().to_path_buf();
    let out_png = dir.path().join("script.png");
    let out = Command::new("bash")
        .current_dir(workspace_root())
        .arg("deploy/local-cluster.sh")
        .arg("scenes/magg-paper.toml")
        .arg(&out_png)
        .args(["--forks", "2", "--nodes", "3", "--base-port", &base_port.to_string(), "--"])
        .args(SMALL)
        .arg("--quiet")
        .env("MAGG_BIN", &bin_dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "script failed: {}", String::from_utf8_lossy(&out.stderr));
    assert!(out_png.is_file());
    // No magg-fork or magg-node of this run is alive.
    std::thread::sleep(Duration::from_millis(200));
    let ps = Command::new("ps").args(["-eo", "args"]).output().unwrap();
    let listing = String::from_utf8_lossy(&ps.stdout);
    let leftovers: Vec<&str> = listing
        .lines()
        .filter(|l| {
            (l.contains("magg-fork") || l.contains("magg-node"))
                && (0..=2).any(|k| l.split_whitespace().any(|w| w == format!("127.0.0.1:{}", base_port + k)))
        })
        .collect();
    assert!(leftovers.is_empty(), "processes left behind: {leftovers:?}");
}

#[test]
fn a_repeat_node_waits_for_the_next_host_without_warnings() {
    // Regression: after a finished render a --repeat node logged "no host yet: cannot reach
    // ..." as a warning once its host had exited (the first absence it met).
    let dir = tempfile::tempdir().unwrap();
    let host_addr = format!("127.0.0.1:{}", free_port());
    let log = dir.path().join("node.log");
    let node = Command::new(magg_bin("magg-node"))
        .args(["--host", &host_addr, "--repeat", "--connect-timeout", "1", "-v"])
        .env("NO_COLOR", "1")
        .env_remove("RUST_LOG")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .expect("spawn magg-node");
    let mut procs = Procs(vec![node]);
    let args: Vec<&str> = [SMALL, &["--listen", &host_addr, "--external-nodes", "--min-nodes", "1"]].concat();
    let r = Rendered::at(dir.path(), "once");
    let out = r.command(&scene("cornell.toml")).args(&args).output().unwrap();
    assert_success(&out, "render with an external --repeat node");
    // The host is gone: the node's next connection attempts fail for longer than its
    // --connect-timeout (after its one-second pause between renders).
    std::thread::sleep(Duration::from_millis(3500));
    assert!(procs.0[0].try_wait().unwrap().is_none(), "the --repeat node exited");
    let _ = procs.0[0].kill();
    let _ = procs.0[0].wait();
    let text = std::fs::read_to_string(&log).unwrap();
    let done = text.find(" done: ").unwrap_or_else(|| panic!("the node never finished a render:\n{text}"));
    let after = &text[done..];
    assert!(after.contains("no host yet"), "the node did not try the next host within the wait:\n{text}");
    assert!(!after.contains("WARN"), "a warning after the render:\n{after}");
}

#[test]
fn external_nodes_run_the_pilot_levels_of_a_refined_scene() {
    // Refinement's pilot light passes run on the cluster's nodes, each level a scene of
    // its own on the same host and forks: two magg-node processes register for each
    // level, then for the render, and the image is the embedded renderer's.
    let dir = tempfile::tempdir().unwrap();
    let (s, refined) = (scene("cornell.toml"), REFINED);
    let base = render(&s, dir.path(), "embedded", &with(&[&["--embedded"][..], refined].concat()));
    let host_addr = format!("127.0.0.1:{}", free_port());
    let mut procs = Procs(Vec::new());
    for i in 0..2 {
        let args = ["--host".into(), host_addr.clone(), "--name".into(), format!("pilot-{i}")];
        procs.0.push(spawn("magg-node", &args));
    }
    let external = ["--listen", &host_addr, "--external-nodes", "--min-nodes", "2"];
    let multi = render(&s, dir.path(), "external", &with(&[refined, &external[..]].concat()));
    same_files(&base, &multi, "refined cornell.toml on two magg-node processes");
    let stats = read_json(&multi.stats);
    let refine = &stats["refine"];
    assert_eq!(refine["pilots_on"], "nodes", "{refine}");
    assert_eq!(refine["levels"].as_u64().unwrap(), 2, "{refine}");
    assert_eq!(refine["pilot_nodes"].as_u64().unwrap(), 2, "both nodes traced pilot pairs: {refine}");
    assert!(refine["split"].as_u64().unwrap() > 0 && refine["pilot_pairs"].as_u64().unwrap() > 0, "{refine}");
    let embedded = read_json(&base.stats);
    assert_eq!(embedded["refine"]["pilots_on"], "embedded");
    for key in ["levels", "split", "pilot_pairs", "kept"] {
        assert_eq!(embedded["refine"][key], refine[key], "{key}: the same pilots wherever they run");
    }
    assert_eq!(stats["nodes"].as_u64().unwrap(), 2);
    // The nodes went through every scene and exit by themselves at the render's end.
    exit_by_themselves(&mut procs.0);
}
