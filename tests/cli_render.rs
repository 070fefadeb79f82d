//! `magg-host render` end to end on the paper's scene: the PNG, the stats JSON with every
//! key of docs/USER_GUIDE.md's stats file, the energy CSV, and the linear PFM and EXR outputs.

use magg_tests::{
    assert_success, magg_host, not_all_black, pfm_header, read_energy, read_json, read_pfm, read_png_rgb, render,
    scene, ENERGY_HEADER,
};
use serde_json::Value;

/// Small and fast: magg-paper fixes its subdivisions, so the element count stays 1664.
const SMALL: &[&str] = &["--width", "64", "--height", "64", "--light-rays", "4", "--pixel-samples", "1"];

/// Elements of magg-paper.toml: 2 * (3 * 16^2 + 8^2).
const PAPER_ELEMENTS: usize = 1664;

fn get<'a>(v: &'a Value, path: &str) -> &'a Value {
    path.split('.').fold(v, |v, k| v.get(k).unwrap_or_else(|| panic!("stats JSON lacks {path} (at {k:?}):\n{v:#}")))
}

#[test]
fn paper_scene_png_is_64x64_rgb_and_lit() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(&scene("magg-paper.toml"), dir.path(), "paper", SMALL);
    assert!(r.png.is_file());
    let (w, h, rgb) = read_png_rgb(&r.png);
    assert_eq!((w, h), (64, 64));
    assert_eq!(rgb.len(), 64 * 64 * 3);
    assert!(not_all_black(&rgb), "the paper scene rendered all black");
    // A lit room: a good share of pixels is clearly above black.
    let lit = rgb.chunks_exact(3).filter(|p| p.iter().any(|&c| c > 16)).count();
    assert!(lit > 64 * 64 / 2, "only {lit} of 4096 pixels are lit");
}

#[test]
fn stats_json_has_every_design_key() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = SMALL.to_vec();
    // Direct light by light rays, so that every pair traces its rays (counted below).
    args.extend(["--nodes", "3", "--forks", "2", "--cache-blocks", "40", "--direct", "lrt"]);
    let r = render(&scene("magg-paper.toml"), dir.path(), "paper", &args);
    let s = read_json(&r.stats);

    assert_eq!(get(&s, "nodes").as_u64(), Some(3));
    assert_eq!(get(&s, "forks").as_u64(), Some(2));
    assert_eq!(get(&s, "cache_blocks").as_u64(), Some(40));
    assert_eq!(get(&s, "profile").as_str(), Some("native"));
    for k in [
        "read_s",
        "stages.preprocess_s",
        "stages.lrt_s",
        "stages.interp_s",
        "stages.vrt_s",
        "stages.total_s",
        "cache.hit_ratio",
    ] {
        let x = get(&s, k).as_f64().unwrap_or_else(|| panic!("{k} is not a number"));
        assert!(x.is_finite() && x >= 0.0, "{k} = {x}");
    }
    let ratio = get(&s, "cache.hit_ratio").as_f64().unwrap();
    assert!(ratio <= 1.0, "hit ratio {ratio}");
    for k in [
        "cache.hits",
        "cache.misses",
        "traffic.link_bytes",
        "traffic.dma_bytes",
        "traffic.gbus_bytes",
        "traffic.rpcs",
        "work.pairs",
        "work.tiles",
        "work.redivisions",
        "work.light_rays",
        "work.view_rays",
    ] {
        assert!(get(&s, k).is_u64(), "{k} is not a count: {}", get(&s, k));
    }
    let hits = get(&s, "cache.hits").as_u64().unwrap();
    let misses = get(&s, "cache.misses").as_u64().unwrap();
    assert!(misses > 0, "a cold cache must miss");
    assert!(
        (ratio - hits as f64 / (hits + misses) as f64).abs() < 1e-12,
        "hit_ratio {ratio} != hits / (hits + misses)"
    );
    let total = get(&s, "stages.total_s").as_f64().unwrap();
    let lrt = get(&s, "stages.lrt_s").as_f64().unwrap();
    let vrt = get(&s, "stages.vrt_s").as_f64().unwrap();
    assert!(total >= lrt && total >= vrt, "total {total} < a stage");

    // One pair per (light, element): one light.
    assert_eq!(get(&s, "work.pairs").as_u64(), Some(PAPER_ELEMENTS as u64));
    assert!(get(&s, "work.light_rays").as_u64().unwrap() >= 4 * PAPER_ELEMENTS as u64);
    assert!(get(&s, "work.view_rays").as_u64().unwrap() >= 64 * 64);
    // 64 x 64 pixels in subscreens of 16: at least 16 tiles.
    assert!(get(&s, "work.tiles").as_u64().unwrap() >= 16);

    let passes = get(&s, "plan.passes").as_array().expect("plan.passes is an array");
    let passes: Vec<&str> = passes.iter().map(|p| p.as_str().unwrap()).collect();
    for p in ["preprocess", "lrt", "interp", "vrt"] {
        assert!(passes.contains(&p), "plan.passes {passes:?} lacks {p}");
    }
    let per_node = get(&s, "per_node").as_array().expect("per_node is an array");
    assert_eq!(per_node.len(), 3);
    let node_pairs: u64 = per_node.iter().map(|n| n["pairs"].as_u64().unwrap()).sum();
    assert_eq!(node_pairs, PAPER_ELEMENTS as u64, "per-node pairs do not add up");
}

#[test]
fn energy_csv_has_every_element_and_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(&scene("magg-paper.toml"), dir.path(), "paper", SMALL);
    let text = std::fs::read_to_string(&r.energy).unwrap();
    assert_eq!(text.lines().next(), Some(ENERGY_HEADER));
    let rows = read_energy(&r.energy);
    let elements: Vec<_> = rows.iter().filter(|r| r.kind == "element").collect();
    let vertices: Vec<_> = rows.iter().filter(|r| r.kind == "vertex").collect();
    assert_eq!(elements.len(), PAPER_ELEMENTS);
    assert!(!vertices.is_empty(), "no vertex rows");
    assert_eq!(elements.len() + vertices.len(), rows.len(), "unknown row kinds");
    // Elements come first, then vertices, each numbered from 0.
    let first_vertex = rows.iter().position(|r| r.kind == "vertex").unwrap();
    assert_eq!(first_vertex, PAPER_ELEMENTS);
    for (i, e) in elements.iter().enumerate() {
        assert_eq!(e.values[0], Some(i as f64), "element row {i} id");
        assert!(e.values.iter().all(|v| v.is_some_and(f64::is_finite)), "element {i}: {e:?}");
        assert!(e.values[5].unwrap() > 0.0, "element {i}: area");
        assert!(e.values[6..].iter().all(|v| v.unwrap() >= 0.0), "element {i}: irradiance");
    }
    for (i, v) in vertices.iter().enumerate() {
        assert_eq!(v.values[0], Some(i as f64), "vertex row {i} id");
        assert_eq!((v.values[1], v.values[5]), (None, None), "vertex {i}: patch and area are empty");
        for (k, x) in v.values.iter().enumerate() {
            if k != 1 && k != 5 {
                assert!(x.is_some_and(f64::is_finite), "vertex {i}: field {k} = {x:?}");
            }
        }
    }
    // The elements tile the patches: their areas add up to the scene's surface,
    // 3 walls of 4 x 4, 4 x 3, 4 x 3 m and a 1.414 x 1.6 m mirror.
    let area: f64 = elements.iter().map(|e| e.values[5].unwrap()).sum();
    let expected = 16.0 + 12.0 + 12.0 + 2f64.sqrt() * 1.6;
    assert!((area - expected).abs() < 1e-6, "element areas sum to {area}, expected {expected}");
    // The light reaches the floor.
    assert!(elements.iter().any(|e| e.values[6].unwrap() > 0.0), "no element is lit");
}

#[test]
fn energy_vertex_rows_match_info_count() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(&scene("magg-paper.toml"), dir.path(), "paper", SMALL);
    let out = magg_host().args(["info", "scenes/magg-paper.toml", "--json"]).output().unwrap();
    assert_success(&out, "magg-host info");
    let info: Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = info["counts"]["vertices"].as_u64().unwrap() as usize;
    let rows = read_energy(&r.energy);
    assert_eq!(rows.iter().filter(|r| r.kind == "vertex").count(), n);
}

#[test]
fn pfm_output_has_header_and_exact_size() {
    let dir = tempfile::tempdir().unwrap();
    let pfm = dir.path().join("main.pfm");
    let out = magg_host()
        .args(["render", "scenes/magg-paper.toml", "--quiet", "--out"])
        .arg(&pfm)
        .args(SMALL)
        .output()
        .unwrap();
    assert_success(&out, "render to .pfm");
    let bytes = std::fs::read(&pfm).unwrap();
    let header = pfm_header(64, 64);
    assert_eq!(header, "PF\n64 64\n-1.0\n");
    assert!(bytes.starts_with(header.as_bytes()), "PFM header: {:?}", &bytes[..16]);
    assert_eq!(bytes.len(), header.len() + 64 * 64 * 12);
    let (w, h, px) = read_pfm(&pfm);
    assert_eq!((w, h), (64, 64));
    assert!(px.iter().all(|x| x.is_finite() && *x >= 0.0), "PFM has a negative or non-finite sample");
    assert!(px.iter().any(|&x| x > 0.0), "PFM is all black");
}

#[test]
fn pfm_as_main_output_equals_linear_side_output() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(&scene("magg-paper.toml"), dir.path(), "side", SMALL);
    let main = dir.path().join("main.pfm");
    let out = magg_host()
        .args(["render", "scenes/magg-paper.toml", "--quiet", "--out"])
        .arg(&main)
        .args(SMALL)
        .output()
        .unwrap();
    assert_success(&out, "render to .pfm");
    assert!(
        std::fs::read(&main).unwrap() == std::fs::read(&r.pfm).unwrap(),
        "--out x.pfm and --linear x.pfm differ for the same render"
    );
}

#[test]
fn exr_output_starts_with_openexr_magic() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("a.png");
    let exr = dir.path().join("a.exr");
    let out = magg_host()
        .args(["render", "scenes/magg-paper.toml", "--quiet", "--out"])
        .arg(&png)
        .arg("--linear")
        .arg(&exr)
        .args(SMALL)
        .output()
        .unwrap();
    assert_success(&out, "render with --linear .exr");
    let bytes = std::fs::read(&exr).unwrap();
    assert!(bytes.len() > 64 * 64 * 3, "EXR is only {} bytes", bytes.len());
    assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "not an OpenEXR file");

    // And as the main output.
    let exr2 = dir.path().join("b.exr");
    let out = magg_host()
        .args(["render", "scenes/magg-paper.toml", "--quiet", "--out"])
        .arg(&exr2)
        .args(SMALL)
        .output()
        .unwrap();
    assert_success(&out, "render to .exr");
    assert_eq!(&std::fs::read(&exr2).unwrap()[..4], &[0x76, 0x2f, 0x31, 0x01]);
}

#[test]
fn summary_goes_to_stderr_unless_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("a.png");
    let out = magg_host().args(["render", "scenes/magg-paper.toml", "--out"]).arg(&png).args(SMALL).output().unwrap();
    assert_success(&out, "render");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("effects plan:"), "no plan on stderr:\n{stderr}");
    assert!(stderr.contains("1664 elements"), "no summary on stderr:\n{stderr}");
    assert!(out.stdout.is_empty(), "render wrote to stdout");
}
