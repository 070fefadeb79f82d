//! Every shipped scene (but the large one, which is for timing) renders at a tiny size
//! with finite, non-negative radiance and energies and a picture that is not black.

use magg_tests::{not_all_black, read_energy, read_json, read_pfm, read_png_rgb, render, workspace_root};
use std::path::PathBuf;

const TINY: &[&str] =
    &["--width", "24", "--height", "24", "--light-rays", "2", "--pixel-samples", "1", "--element-size", "0.3"];

/// `scenes/*.toml` except large.toml, sorted.
fn scenes() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(workspace_root().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .filter(|p| p.file_name().is_some_and(|n| n != "large.toml"))
        .collect();
    v.sort();
    v
}

#[test]
fn the_shipped_scenes_are_there() {
    let names: Vec<String> = scenes().iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    for want in ["area.toml", "cornell.toml", "diffuse.toml", "magg-paper.toml", "spot.toml"] {
        assert!(names.iter().any(|n| n == want), "scenes/{want} missing: {names:?}");
    }
}

#[test]
fn every_scene_renders_finite_and_lit() {
    let dir = tempfile::tempdir().unwrap();
    for path in scenes() {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let r = render(&path, dir.path(), &stem, TINY);

        let (w, h, px) = read_pfm(&r.pfm);
        assert_eq!((w, h), (24, 24), "{stem}: PFM size");
        if let Some(bad) = px.iter().find(|x| !x.is_finite() || **x < 0.0) {
            panic!("{stem}: PFM sample {bad}");
        }

        let rows = read_energy(&r.energy);
        let elements = rows.iter().filter(|r| r.kind == "element").count();
        assert!(elements > 0, "{stem}: no element rows");
        for (i, row) in rows.iter().enumerate() {
            assert!(row.kind == "element" || row.kind == "vertex", "{stem}: row {i} kind {:?}", row.kind);
            for x in row.values.iter().flatten() {
                assert!(x.is_finite(), "{stem}: energy row {i}: {row:?}");
            }
            assert!(
                row.values[6..].iter().all(|x| x.is_some_and(|x| x >= 0.0)),
                "{stem}: energy row {i} has a negative or missing irradiance: {row:?}"
            );
        }
        let stats = read_json(&r.stats);
        assert_eq!(
            stats["counts"]["elements"].as_u64(),
            Some(elements as u64),
            "{stem}: stats element count vs energy rows"
        );

        let (w, h, rgb) = read_png_rgb(&r.png);
        assert_eq!((w, h), (24, 24), "{stem}: PNG size");
        assert!(not_all_black(&rgb), "{stem}: the PNG is entirely black");
    }
}
