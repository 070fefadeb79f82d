//! Hard case: no NaN or infinity anywhere in an image or an energy file, on every scene
//! shipped in `scenes/`, rendered at tiny settings.

mod common;
#[path = "common/hard.rs"]
mod hard;

use hard::*;
use magg_core::blocks::CacheSize;
use magg_core::progress::NoProgress;
use magg_core::render::{render, RenderOptions};
use magg_core::scene::parse_scene_str;
use magg_prepare::prepare;
use std::path::{Path, PathBuf};

const SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes");

#[test]
fn every_shipped_scene_renders_finite_at_tiny_settings() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(SCENES)
        .expect("scenes/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 5, "expected the shipped scenes, found {files:?}");
    for path in &files {
        let label = path.file_name().unwrap().to_string_lossy().to_string();
        let text = std::fs::read_to_string(path).unwrap();
        let mut scene = parse_scene_str(&label, &text, Path::new(SCENES), &|p: &Path| std::fs::read(p))
            .unwrap_or_else(|e| panic!("{label}: {e}"));
        let s = &mut scene.settings;
        s.width = 24;
        s.height = 24;
        s.pixel_samples = 1;
        s.light_rays = 2;
        s.element_size = 0.3; // patches with fixed `subdivisions` keep theirs
        let prepared = prepare(&scene).unwrap_or_else(|e| panic!("{label}: {e}"));
        let out = render(
            &prepared,
            &RenderOptions { nodes: 2, forks: 5, cache_blocks: CacheSize::Unlimited, subscreen: 8 },
            &NoProgress,
        )
        .unwrap_or_else(|e| panic!("{label}: {e}"));
        assert_render_finite(&label, &out);
        assert_eq!(out.frame.pixels.len(), 24 * 24);
        // Something is lit, and the light pass balances.
        let t = out.stats.light;
        assert!(out.frame.pixels.iter().any(|p| p.iter().any(|c| *c > 0.0)), "{label}: black image");
        for c in 0..3 {
            let acc = t.absorbed.0[c] + t.diffuse_end.0[c] + t.escaped.0[c] + t.cut.0[c];
            assert!((acc - t.reached.0[c]).abs() <= 1e-9 * t.reached.0[c].max(1.0), "{label}: channel {c}: {t:?}");
        }
        for (e, info) in prepared.elements.iter().enumerate() {
            assert!(info.area.is_finite() && info.centroid.is_finite(), "{label}: element {e}");
        }
    }
}
