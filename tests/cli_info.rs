//! `magg-host info`: the counts of the paper's scene, as JSON and as text.

use magg_tests::{assert_success, magg_host};
use serde_json::Value;

#[test]
fn paper_scene_counts_as_json() {
    let out = magg_host().args(["info", "scenes/magg-paper.toml", "--json"]).output().unwrap();
    assert_success(&out, "magg-host info --json");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("info --json is not JSON: {e}"));
    let c = &v["counts"];
    assert_eq!(c["patches"].as_u64(), Some(8), "{v:#}");
    assert_eq!(c["elements"].as_u64(), Some(1664), "{v:#}");
    assert_eq!(c["subspaces"].as_u64(), Some(336), "{v:#}");
    assert_eq!(v["grid"], serde_json::json!([8, 7, 6]));
    assert_eq!(v["lights"].as_u64(), Some(1));
    // Reading and preparing are separate stages.
    for k in ["read_s", "preprocess_s"] {
        assert!(v[k].as_f64().is_some_and(|x| x.is_finite() && x >= 0.0), "{k}: {v:#}");
    }
    // The blocks of every kind add up to the total.
    let kinds: u64 = ["patch_blocks", "element_blocks", "vertex_blocks", "subspace_blocks"]
        .iter()
        .map(|k| c[k].as_u64().unwrap_or_else(|| panic!("counts.{k} missing")))
        .sum();
    assert!(kinds <= v["blocks"].as_u64().unwrap(), "{kinds} blocks of the kinds > total");
    let passes = v["plan"]["passes"].as_array().expect("plan.passes");
    assert!(passes.iter().any(|p| p == "lrt_specular"), "the mirror needs specular light rays");
}

#[test]
fn paper_scene_text_shows_counts_and_plan() {
    let out = magg_host().args(["info", "scenes/magg-paper.toml"]).output().unwrap();
    assert_success(&out, "magg-host info");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("effects plan"), "{text}");
    assert!(text.contains("1664"), "{text}");
    assert!(text.contains("grid 8x7x6"), "{text}");
    assert!(text.contains("\nread ") && text.contains("\npreprocess "), "{text}");
}

#[test]
fn large_scene_info_is_quick_and_consistent() {
    let out = magg_host().args(["info", "scenes/large.toml", "--json"]).output().unwrap();
    assert_success(&out, "magg-host info large.toml");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    // 39 560 mesh triangles (subdivisions = 1) plus the mirror's two halves.
    let patches = v["counts"]["patches"].as_u64().unwrap();
    assert_eq!(patches, 39_562, "{v:#}");
    assert!(v["counts"]["elements"].as_u64().unwrap() > patches);
    assert_eq!(v["lights"].as_u64(), Some(2));
}

/// The `chosen` lines of `magg-host info --json` on `scene` with `args`.
fn chosen(scene: &str, args: &[&str]) -> Vec<String> {
    let out = magg_host().args(["info", scene, "--json"]).args(args).output().unwrap();
    assert_success(&out, "magg-host info --json");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    v["chosen"].as_array().expect("chosen").iter().map(|l| l.as_str().unwrap().to_string()).collect()
}

#[test]
fn info_says_what_magg_chose_for_the_knobs_a_scene_leaves_unset() {
    // cornell-glass leaves the bounces and refinement to magg (coarse elements and few
    // rays keep the pilots quick).
    let quick = ["--set", "render.element_size=0.4", "--set", "render.light_rays=4"];
    let lines = chosen("scenes/cornell-glass.toml", &quick);
    let has = |s: &str| lines.iter().any(|l| l.starts_with(s));
    assert!(has("element_size = 0.4: the scene's"), "{lines:?}");
    assert!(has("diffuse_bounces = 7: the mean reflectance 0.60"), "{lines:?}");
    // Its lamp's direct light is computed at VRT; its glass sphere's caustic lands on the
    // elements.
    assert!(has("refine = 2: light via mirrors or glass"), "{lines:?}");
    // What --quality makes of them: final adds a level.
    let lines = chosen("scenes/cornell-glass.toml", &[&quick[..], &["--quality", "final"]].concat());
    assert!(lines.iter().any(|l| l.contains("--quality Final") && l.ends_with("refine 3")), "{lines:?}");
    // A scene that gives an ambient term keeps the paper's model; one that sets a knob
    // keeps it.
    let lines = chosen("scenes/area.toml", &[]);
    assert!(lines.iter().any(|l| l.starts_with("diffuse_bounces = 0: the scene gives an ambient term")), "{lines:?}");
    let lines = chosen("scenes/cornell-glass.toml", &[&quick[..], &["--set", "render.refine=0"]].concat());
    assert!(!lines.iter().any(|l| l.starts_with("refine")), "{lines:?}");
}
