//! The image and the energies do not depend on how the work is spread: node count, fork
//! count and cache size change the time and the traffic, never a byte of the output.
//! Nor does forcing every optional effect on (`--all-effects`) where the scene needs none.

use magg_tests::{read_json, render, scene, Rendered};
use serde_json::Value;
use std::path::Path;

/// Cornell box at a tiny size: mirror block and glass sphere, so specular light rays,
/// refraction and recursive viewing rays all run. On the embedded renderer, whose node
/// workers share memory: tiny caches here cost a memory copy per miss, where in the
/// cluster they cost a round trip (tests/cluster.rs checks the cluster's shapes).
const CORNELL: &[&str] = &[
    "--embedded",
    "--width",
    "48",
    "--height",
    "48",
    "--element-size",
    "0.25",
    "--light-rays",
    "4",
    "--pixel-samples",
    "2",
];

fn with<'a>(base: &[&'a str], more: &[&'a str]) -> Vec<&'a str> {
    base.iter().chain(more).copied().collect()
}

fn passes(stats: &Value) -> Vec<String> {
    stats["plan"]["passes"].as_array().expect("plan.passes").iter().map(|p| p.as_str().unwrap().to_string()).collect()
}

fn same_bytes(a: &Path, b: &Path) -> bool {
    std::fs::read(a).unwrap() == std::fs::read(b).unwrap()
}

fn assert_same_outputs(base: &Rendered, other: &Rendered, label: &str) {
    assert!(same_bytes(&base.png, &other.png), "{label}: PNG differs");
    assert!(same_bytes(&base.pfm, &other.pfm), "{label}: PFM differs");
    assert!(same_bytes(&base.energy, &other.energy), "{label}: energy CSV differs");
}

#[test]
fn cluster_shape_does_not_change_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene("cornell.toml");
    let base = render(&cornell, dir.path(), "n1f1", &with(CORNELL, &["--nodes", "1", "--forks", "1"]));

    let base_stats = read_json(&base.stats);
    let p = passes(&base_stats);
    for want in ["lrt_specular", "lrt_refraction", "vrt_specular"] {
        assert!(p.iter().any(|x| x == want), "cornell plan {p:?} lacks {want}");
    }

    let shapes: [(&str, &[&str]); 4] = [
        ("n4f5", &["--nodes", "4", "--forks", "5"]),
        ("n16f3c20", &["--nodes", "16", "--forks", "3", "--cache-blocks", "20"]),
        ("n3c7", &["--nodes", "3", "--cache-blocks", "7"]),
        ("n3", &["--nodes", "3", "--cache-blocks", "unlimited"]),
    ];
    let mut stats = Vec::new();
    for (label, flags) in shapes {
        let r = render(&cornell, dir.path(), label, &with(CORNELL, flags));
        assert_same_outputs(&base, &r, label);
        stats.push((label, read_json(&r.stats)));
    }

    let get = |label: &str| &stats.iter().find(|(l, _)| *l == label).unwrap().1;
    assert_eq!(get("n16f3c20")["nodes"].as_u64(), Some(16));
    assert_eq!(get("n16f3c20")["per_node"].as_array().unwrap().len(), 16);
    assert_eq!(get("n3c7")["cache_blocks"].as_u64(), Some(7));
    assert!(get("n3")["cache_blocks"].is_null(), "unlimited cache is null");

    // Same nodes, same work: a 7-block cache must miss more than an unlimited one.
    let small = get("n3c7")["cache"]["hit_ratio"].as_f64().unwrap();
    let unlimited = get("n3")["cache"]["hit_ratio"].as_f64().unwrap();
    assert!(small < unlimited, "hit ratio with 7 blocks ({small}) is not below unlimited ({unlimited})");
    // The work itself does not depend on the cluster shape.
    for (label, s) in &stats {
        assert_eq!(s["work"]["pairs"], base_stats["work"]["pairs"], "{label}: pairs");
        assert_eq!(s["work"]["light_rays"], base_stats["work"]["light_rays"], "{label}: light rays");
        assert_eq!(s["work"]["view_rays"], base_stats["work"]["view_rays"], "{label}: view rays");
    }
}

#[test]
fn same_seed_same_bytes_other_seed_other_energies() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = scene("cornell.toml");
    let a = render(&cornell, dir.path(), "a", &with(CORNELL, &["--nodes", "2"]));
    let b = render(&cornell, dir.path(), "b", &with(CORNELL, &["--nodes", "2"]));
    assert_same_outputs(&a, &b, "second run");
    let c = render(&cornell, dir.path(), "c", &with(CORNELL, &["--nodes", "2", "--seed", "7"]));
    assert!(!same_bytes(&a.energy, &c.energy), "--seed 7 gave the same energies as seed 1");
}

/// diffuse.toml sets lrt_depth = vrt_depth = 0; with depths of 2 the plan must still
/// leave the specular passes out (no mirror, no glass), and forcing them on must change
/// nothing but the time.
const DIFFUSE: &[&str] = &[
    "--width",
    "32",
    "--height",
    "32",
    "--element-size",
    "0.5",
    "--light-rays",
    "2",
    "--pixel-samples",
    "1",
    "--lrt-depth",
    "2",
    "--vrt-depth",
    "2",
    "--nodes",
    "2",
];

#[test]
fn all_effects_on_a_diffuse_scene_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let diffuse = scene("diffuse.toml");
    let plain = render(&diffuse, dir.path(), "plain", DIFFUSE);
    let forced = render(&diffuse, dir.path(), "forced", &with(DIFFUSE, &["--all-effects"]));

    assert!(same_bytes(&plain.pfm, &forced.pfm), "--all-effects changed the PFM");
    assert!(same_bytes(&plain.energy, &forced.energy), "--all-effects changed the energies");

    let p = passes(&read_json(&plain.stats));
    let f = passes(&read_json(&forced.stats));
    for pass in ["lrt_specular", "vrt_specular"] {
        assert!(!p.iter().any(|x| x == pass), "default plan {p:?} runs {pass}");
        assert!(f.iter().any(|x| x == pass), "forced plan {f:?} lacks {pass}");
    }
    assert!(p.iter().any(|x| x == "lrt_diffuse"), "diffuse.toml has a diffuse bounce: {p:?}");
}

/// Preparation in shares (one per fork, split in space: each fork's part of the scene
/// welded, numbered and given a BVH of its own) gives every shipped kind of scene the
/// bits of one share: meshes (the sphere), refinement (cornell's levels), textures and
/// area lights, embedded or in the cluster, for 1, 3, 5 and 7 forks.
#[test]
fn preparing_in_shares_does_not_change_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let small = ["--width", "40", "--height", "40", "--pixel-samples", "1", "--light-rays", "8"];
    let scenes: [(&str, &[&str]); 3] = [
        ("cornell.toml", &["--element-size", "0.25", "--set", "render.refine=2"]),
        ("textured.toml", &[]),
        ("area.toml", &["--element-size", "0.3"]),
    ];
    for (name, flags) in scenes {
        let path = scene(name);
        let base_flags = with(&with(&small, flags), &["--forks", "1"]);
        let base = render(&path, dir.path(), &format!("{name}-one"), &base_flags);
        for (label, more) in [
            ("f3", &["--forks", "3", "--share-patches", "16"][..]),
            ("f5", &["--forks", "5", "--share-patches", "16"]),
            ("f7", &["--forks", "7", "--share-patches", "8"]),
            ("embedded-f7", &["--embedded", "--forks", "7", "--share-patches", "8"]),
        ] {
            let r = render(&path, dir.path(), &format!("{name}-{label}"), &with(&with(&small, flags), more));
            assert_same_outputs(&base, &r, &format!("{name} {label}"));
        }
    }
}
