//! Reusing one light pass: saved energies (`--save-energy`, `--load-energy`) and camera
//! paths (`[camera_path]`), on the embedded renderer and the cluster. The light pass is
//! view-independent, so a reused pass must give the same image, bit for bit, as a render
//! that traced it.

use magg_tests::{assert_success, assert_user_error, magg_host, read_json, render, scene, workspace_root};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Small and fast: the diffuse room at 32 x 32 with big elements.
const SMALL: &[&str] =
    &["--width", "32", "--height", "32", "--light-rays", "4", "--pixel-samples", "1", "--element-size", "0.5"];

const CAMERA: &str = "[camera]\neye = [0.0, 1.5, 4.5]\nlook_at = [0.0, 1.0, 0.0]\nfov = 45.0\n";

/// scenes/diffuse.toml with its `[camera]` table replaced by `camera`, written to `dir`.
fn diffuse_with(dir: &Path, name: &str, camera: &str, edit: &dyn Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(scene("diffuse.toml")).unwrap();
    assert!(text.contains(CAMERA), "scenes/diffuse.toml changed its camera: update this test");
    let path = dir.join(name);
    std::fs::write(&path, edit(text.replace(CAMERA, camera))).unwrap();
    path
}

fn same(a: &Path, b: &Path) -> bool {
    std::fs::read(a).unwrap() == std::fs::read(b).unwrap()
}

fn num(v: &Value, path: &str) -> f64 {
    path.split('.').fold(v, |v, k| &v[k]).as_f64().unwrap_or_else(|| panic!("{path} missing in {v:#}"))
}

/// SMALL plus `extra`, where a flag of `extra` replaces the same flag of SMALL.
fn with(extra: &[&str]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for pair in SMALL.chunks(2) {
        if !extra.contains(&pair[0]) {
            out.extend(pair.iter().map(|s| s.to_string()));
        }
    }
    out.extend(extra.iter().map(|s| s.to_string()));
    out
}

fn render_s(scene: &Path, dir: &Path, stem: &str, extra: &[String]) -> magg_tests::Rendered {
    let extra: Vec<&str> = extra.iter().map(String::as_str).collect();
    render(scene, dir, stem, &extra)
}

#[test]
fn reloaded_energies_give_a_bitwise_identical_image_embedded_and_cluster() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene("diffuse.toml");
    let saved = d.join("room.energy");
    let save = with(&["--embedded", "--save-energy", saved.to_str().unwrap()]);
    let a = render_s(&s, d, "traced", &save);
    assert!(saved.is_file());
    let b = render_s(&s, d, "loaded", &with(&["--embedded", "--load-energy", saved.to_str().unwrap()]));
    let c =
        render_s(&s, d, "cluster", &with(&["--nodes", "2", "--forks", "2", "--load-energy", saved.to_str().unwrap()]));
    for (r, what) in [(&b, "embedded"), (&c, "cluster")] {
        assert!(same(&a.pfm, &r.pfm), "{what}: the image from loaded energies differs");
        assert!(same(&a.energy, &r.energy), "{what}: the energy CSV from loaded energies differs");
        let st = read_json(&r.stats);
        assert_eq!(num(&st, "stages.lrt_s"), 0.0, "{what}: LRT ran");
        assert_eq!(num(&st, "work.pairs"), 0.0, "{what}: pairs were traced");
        assert_eq!(st["energy"]["source"], "loaded", "{what}");
        assert_eq!(num(&st, "energy.light_passes"), 0.0, "{what}");
        assert!(st["energy"]["loaded_from"].as_str().unwrap().ends_with("room.energy"));
    }
    let st = read_json(&a.stats);
    assert!(num(&st, "work.pairs") > 0.0);
    assert_eq!(st["energy"]["source"], "traced");
}

#[test]
fn stale_energy_files_are_refused_and_a_new_camera_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = diffuse_with(d, "base.toml", CAMERA, &|t| t);
    let saved = d.join("base.energy");
    render_s(&base, d, "base", &with(&["--embedded", "--save-energy", saved.to_str().unwrap()]));
    let load = |scene: &Path, extra: &[&str]| {
        let mut cmd = magg_host();
        cmd.arg("render").arg(scene).arg("--out").arg(d.join("x.png")).arg("--quiet").arg("--embedded");
        cmd.args(with(extra)).arg("--load-energy").arg(&saved);
        cmd.output().unwrap()
    };
    // A brighter light: refused, naming the lights.
    let brighter = diffuse_with(d, "brighter.toml", CAMERA, &|t| t.replace("[6.0, 5.8, 5.4]", "[6.0, 5.8, 5.5]"));
    let e = assert_user_error(&load(&brighter, &[]), "load with a changed light");
    assert!(e.contains("base.energy was made for a different scene"), "{e}");
    assert!(e.contains("lights differ"), "{e}");
    // More light rays: refused, naming the setting and both values.
    let e = assert_user_error(&load(&base, &["--light-rays", "8"]), "load with other light rays");
    assert!(e.contains("light_rays 4 (file) vs 8 (now)"), "{e}");
    let e = assert_user_error(&load(&base, &["--seed", "7"]), "load with another seed");
    assert!(e.contains("seed 1 (file) vs 7 (now)"), "{e}");
    // Not an energy file at all.
    let mut cmd = magg_host();
    cmd.arg("render").arg(&base).arg("--out").arg(d.join("x.png")).arg("--quiet").arg("--load-energy").arg(&base);
    let e = assert_user_error(&cmd.output().unwrap(), "load a scene file as energies");
    assert!(e.contains("not a magg energy file"), "{e}");

    // Another camera, image size and pixel samples: accepted, and the image is the one a
    // full render of that view gives.
    let moved = "[camera]\neye = [1.0, 2.0, 4.0]\nlook_at = [0.0, 0.8, 0.0]\nfov = 50.0\n";
    let view = diffuse_with(d, "view.toml", moved, &|t| t);
    let extra = ["--width", "40", "--height", "24", "--pixel-samples", "2"];
    let reused = render_s(
        &view,
        d,
        "reused",
        &with(&[&["--embedded", "--load-energy", saved.to_str().unwrap()], &extra[..]].concat()),
    );
    let fresh = render_s(&view, d, "fresh", &with(&[&["--embedded"], &extra[..]].concat()));
    assert!(same(&reused.pfm, &fresh.pfm), "a new view from loaded energies differs from a full render");
}

const KEYS: &str = "[camera_path]\nframes = 3\n\n[[camera_path.keys]]\neye = [0.0, 1.5, 4.5]\n\
                    look_at = [0.0, 1.0, 0.0]\nfov = 45.0\n\n[[camera_path.keys]]\neye = [1.0, 1.5, 4.5]\n\
                    look_at = [0.0, 1.0, 0.0]\nfov = 45.0\n\n";

#[test]
fn a_three_frame_path_matches_three_renders_with_one_light_pass() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path_scene = diffuse_with(d, "path.toml", KEYS, &|t| t);
    let png = d.join("frame.png");
    let (pfm, stats) = (d.join("frame.pfm"), d.join("frame.json"));
    let out = magg_host()
        .arg("render")
        .arg(&path_scene)
        .args(["--nodes", "2", "--forks", "2", "--quiet"])
        .args(SMALL)
        .arg("--out")
        .arg(&png)
        .arg("--linear")
        .arg(&pfm)
        .arg("--stats")
        .arg(&stats)
        .output()
        .unwrap();
    assert_success(&out, "render a camera path on the cluster");
    assert!(!png.exists(), "a path writes numbered frames, not {}", png.display());

    // Frame k's camera: eye x = 0, 0.5, 1 (keys at frames 0 and 2, the middle halfway).
    let single = |k: usize, x: &str| {
        let cam = format!("[camera]\neye = [{x}, 1.5, 4.5]\nlook_at = [0.0, 1.0, 0.0]\nfov = 45.0\n");
        let s = diffuse_with(d, &format!("single{k}.toml"), &cam, &|t| t);
        render_s(&s, d, &format!("single{k}"), &with(&["--embedded"]))
    };
    let mut pairs_single = 0.0;
    for (k, x) in ["0.0", "0.5", "1.0"].iter().enumerate() {
        let r = single(k, x);
        let frame = d.join(format!("frame_{k:04}.pfm"));
        assert!(d.join(format!("frame_{k:04}.png")).is_file(), "frame {k} PNG missing");
        assert!(same(&frame, &r.pfm), "frame {k} of the path differs from a render with its camera");
        pairs_single = num(&read_json(&r.stats), "work.pairs");
    }
    let st = read_json(&stats);
    assert_eq!(num(&st, "energy.light_passes"), 1.0);
    assert_eq!(num(&st, "work.pairs"), pairs_single, "the path traced more pairs than one light pass");
    let per_node_pairs: f64 = st["per_node"].as_array().unwrap().iter().map(|n| n["pairs"].as_f64().unwrap()).sum();
    assert_eq!(per_node_pairs, pairs_single, "nodes traced the pairs more than once");
    let frames = st["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 3);
    let vrt_sum: f64 = frames.iter().map(|f| f["vrt_s"].as_f64().unwrap()).sum();
    assert!((vrt_sum - num(&st, "stages.vrt_s")).abs() < 1e-9, "vrt_s is not the sum of the frames'");
    assert!(frames[2]["out"].as_str().unwrap().ends_with("frame_0002.png"));
}

#[test]
fn the_example_path_scene_renders_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = workspace_root().join("scenes/paths/diffuse-orbit.toml");
    let out = magg_host()
        .arg("render")
        .arg(&s)
        .args(["--embedded", "--quiet", "--width", "16", "--height", "16"])
        .args(&SMALL[4..])
        .arg("--out")
        .arg(d.join("orbit.png"))
        .output()
        .unwrap();
    assert_success(&out, "render scenes/paths/diffuse-orbit.toml");
    let mut frames: Vec<_> = std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name()).collect();
    frames.sort();
    assert_eq!(frames.len(), 24, "{frames:?}");
    assert_eq!(frames[0], "orbit_0000.png");
    assert_eq!(frames[23], "orbit_0023.png");
    // Different views: the first and last frames differ.
    assert!(!same(&d.join("orbit_0000.png"), &d.join("orbit_0023.png")));
}
