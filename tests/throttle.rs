//! The throttling layer end to end (docs/ARCHITECTURE.md, the throttling layer): a throttled cluster gives the
//! embedded renderer's image bit for bit, its cost model gives the same modelled compute
//! whatever the cluster's shape, the native profile takes the layer out, a fork started
//! with another profile refuses the render, the small sweep writes its CSV and figures
//! with a hit ratio that rises with the cache size, and a sweep through both acceleration
//! structures gives one image and fewer DMA bytes per ray through the BVH.

use magg_tests::*;
use std::process::{Command, Stdio};

const SMALL: &[&str] = &["--width", "48", "--height", "48"];

fn with<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    [SMALL, extra].concat()
}

#[test]
fn magg1993_runs_give_the_embedded_image_and_the_same_modelled_compute() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("magg-paper.toml");
    // The paper scheme deposits direct light with light rays: so do the other two runs.
    let reference = render(&scene, dir.path(), "embedded", &with(&["--embedded", "--direct", "lrt"]));
    let a = render(
        &scene,
        dir.path(),
        "paper",
        &with(&["--profile", "magg1993", "--dilation", "0.25", "--scheme", "paper", "--nodes", "3"]),
    );
    let a = (a, "--forks 5 --nodes 3 paper scheme");
    let b = render(
        &scene,
        dir.path(),
        "magg",
        &with(&[
            "--profile",
            "magg1993",
            "--dilation",
            "0.25",
            "--nodes",
            "6",
            "--forks",
            "2",
            "--cache-blocks",
            "20",
            "--direct",
            "lrt",
        ]),
    );
    let b = (b, "--forks 2 --nodes 6 --cache-blocks 20 magg scheme");
    let mut cpu = Vec::new();
    for (r, what) in [&a, &b] {
        assert_eq!(std::fs::read(&r.pfm).unwrap(), std::fs::read(&reference.pfm).unwrap(), "{what}: image differs");
        assert_eq!(
            std::fs::read(&r.energy).unwrap(),
            std::fs::read(&reference.energy).unwrap(),
            "{what}: energies differ"
        );
        let s = read_json(&r.stats);
        assert_eq!(s["profile"], "magg1993", "{what}");
        let e = &s["emulation"];
        assert_eq!(e["dilation"].as_f64(), Some(0.25), "{what}");
        for k in ["node_cpu_s", "link_s", "dma_s", "fork_s", "preprocess_s"] {
            assert!(e["busy"][k].as_f64().unwrap() > 0.0, "{what}: busy.{k} = {}", e["busy"][k]);
        }
        // Modelled stage times: the run's wall time divided by the dilation, so at least
        // the modelled compute of the busiest node.
        let busiest =
            s["per_node"].as_array().unwrap().iter().map(|n| n["cpu_s"].as_f64().unwrap()).fold(0.0, f64::max);
        assert!(s["stages"]["total_s"].as_f64().unwrap() >= busiest, "{what}: total below the busiest node's compute");
        cpu.push(e["busy"]["node_cpu_s"].as_f64().unwrap());
    }
    assert_eq!(read_json(&a.0.stats)["scheme"], "paper");
    assert_eq!(read_json(&b.0.stats)["scheme"], "magg");
    // The cost model counts operations: the same work costs the same modelled time,
    // however it was spread over nodes, forks and caches.
    assert!((cpu[0] - cpu[1]).abs() <= 1e-9 * cpu[0], "modelled compute differs: {cpu:?}");
    // The paper's scheme preprocesses on one fork, ours on every fork: five times less.
    let pre = |r: &Rendered| read_json(&r.stats)["emulation"]["busy"]["preprocess_s"].as_f64().unwrap();
    assert!((pre(&a.0) / pre(&b.0) - 2.0).abs() < 1e-9, "paper {} vs magg on 2 forks {}", pre(&a.0), pre(&b.0));
}

#[test]
fn native_profile_takes_the_layer_out() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(&scene("magg-paper.toml"), dir.path(), "native", &with(&["--nodes", "2"]));
    let s = read_json(&r.stats);
    assert_eq!(s["profile"], "native");
    assert!(s.get("emulation").is_none(), "native run reports an emulation: {}", s["emulation"]);
    assert!(s["per_node"][0].get("cpu_s").is_none(), "native run reports modelled node time");
}

/// `magg-host render magg-paper.toml --out <tmp>/x.png ARGS`, run to completion.
fn render_with(args: &[&str]) -> std::process::Output {
    let dir = tempfile::tempdir().unwrap();
    magg_host()
        .arg("render")
        .arg(scene("magg-paper.toml"))
        .arg("--out")
        .arg(dir.path().join("x.png"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn bad_profiles_and_schemes_are_refused_in_one_line() {
    for (args, needle) in [
        (vec!["--profile", "no-such-profile"], "no-such-profile"),
        (vec!["--profile", "magg1993", "--dilation", "0"], "--dilation"),
        (vec!["--scheme", "fast"], "--scheme"),
        (vec!["--profile", "magg1993", "--embedded"], "embedded"),
    ] {
        let out = render_with(&args);
        let line = assert_user_error(&out, &args.join(" "));
        assert!(line.contains(needle), "{args:?}: {line}");
    }
}

/// Children killed and reaped on drop.
struct Procs(Vec<std::process::Child>);
impl Drop for Procs {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

#[test]
fn a_fork_started_with_another_profile_refuses_the_render() {
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    let fork = Command::new(magg_bin("magg-fork"))
        .args(["--listen", &addr, "--profile", "magg1993"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _procs = Procs(vec![fork]);
    // Wait until the fork listens, so that the host's only line is the refusal.
    let t = std::time::Instant::now();
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(t.elapsed() < std::time::Duration::from_secs(20), "magg-fork never listened on {addr}");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let out = render_with(&with(&["--forks-at", &addr, "--nodes", "1", "--stall-timeout", "5", "-q"]));
    let line = assert_user_error(&out, "native host, magg1993 fork");
    assert!(line.contains("magg1993") && line.contains("native"), "{line}");
}

/// A sweep's CSV: its header and rows.
struct Csv {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Csv {
    /// Column `name` of `row`.
    fn get<'a>(&self, row: &'a [String], name: &str) -> &'a str {
        let at = self.header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
        &row[at]
    }
}

/// Runs `magg-host sweep` on magg-paper.toml over `grid` at 40 x 40 (timing shapes are
/// not judged here, so no re-runs for a busy machine); returns its folder, its table
/// (stdout) and its CSV.
fn small_sweep(grid: &[&str]) -> (tempfile::TempDir, String, Csv) {
    let dir = tempfile::tempdir().unwrap();
    let out = magg_host()
        .args(["sweep", "--out-dir"])
        .arg(dir.path())
        .arg(scene("magg-paper.toml"))
        .args(grid)
        .args(["--dilation", "0.1", "--max-cpu-share", "1"])
        .args(["--", "--width", "40", "--height", "40"])
        .output()
        .unwrap();
    assert_success(&out, &format!("magg-host sweep {grid:?}"));
    let text = std::fs::read_to_string(dir.path().join("sweep.csv")).unwrap();
    let split = |l: &str| l.split(',').map(String::from).collect::<Vec<_>>();
    let mut lines = text.lines();
    let header = split(lines.next().unwrap());
    let csv = Csv { header, rows: lines.map(split).collect() };
    (dir, String::from_utf8_lossy(&out.stdout).into_owned(), csv)
}

#[test]
fn small_sweep_writes_csv_and_figures_and_the_hit_ratio_rises_with_the_cache() {
    let (dir, table, csv) = small_sweep(&["--nodes", "2,4", "--cache-blocks", "3,60", "--schemes", "magg,paper"]);
    assert_eq!(csv.rows.len(), 8, "{:?}", csv.rows);
    for scheme in ["magg", "paper"] {
        let mut hits: Vec<(u32, f64)> = csv
            .rows
            .iter()
            .filter(|r| csv.get(r, "scheme") == scheme && csv.get(r, "nodes") == "4")
            .map(|r| (csv.get(r, "cache_blocks").parse().unwrap(), csv.get(r, "hit_ratio").parse().unwrap()))
            .collect();
        hits.sort_by_key(|h| h.0);
        assert_eq!(hits.len(), 2);
        assert!(hits[0].1 < hits[1].1, "{scheme}: hit ratio against cache size {hits:?}");
    }
    for fig in ["hit-ratio.png", "time-cache60-magg.png", "speedup-vrt-paper.png", "speedup-total-magg.png"] {
        let bytes = std::fs::read(dir.path().join(fig)).unwrap_or_else(|e| panic!("{fig}: {e}"));
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{fig} is not a PNG");
    }
    assert!(table.contains("| scheme | forks | cache | nodes |"), "{table}");
}

#[test]
fn a_sweep_over_both_structures_names_each_and_the_bvh_moves_fewer_bytes_per_ray() {
    let (dir, table, csv) =
        small_sweep(&["--nodes", "2", "--cache-blocks", "3", "--schemes", "magg", "--accel", "grid,bvh"]);
    let accels: Vec<&str> = csv.rows.iter().map(|r| csv.get(r, "accel")).collect();
    assert_eq!(accels, ["grid", "bvh"], "{:?}", csv.rows);
    let per_ray = |r: &[String]| {
        let n = |c: &str| csv.get(r, c).parse::<f64>().unwrap();
        n("dma_bytes") / (n("light_rays") + n("view_rays"))
    };
    assert!(per_ray(&csv.rows[1]) < per_ray(&csv.rows[0]), "DMA bytes per ray, grid then BVH: {:?}", csv.rows);
    // The same image whichever structure traced it, and figures of each.
    let runs = dir.path().join("runs");
    let grid = std::fs::read(runs.join("magg-f5-c3-n2.png")).unwrap();
    assert!(grid == std::fs::read(runs.join("magg-bvh-f5-c3-n2.png")).unwrap(), "the BVH run's image differs");
    for fig in ["time-cache3-magg.png", "time-cache3-magg-bvh.png"] {
        assert!(dir.path().join(fig).is_file(), "{fig} missing");
    }
    assert!(table.contains("| accel | DMA bytes per ray |") && table.contains("| bvh |"), "{table}");
}
