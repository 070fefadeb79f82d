//! Loading a scene file from disk (the core parses; this reads the files it names).

use anyhow::Context;
use magg_core::scene::{parse_scene_with_path, CameraPath, Scene};
use std::path::Path;

/// Reads and parses the scene at `path`; OBJ/MTL files are resolved next to it.
pub fn load(path: &Path) -> anyhow::Result<Scene> {
    load_with_path(path).map(|(scene, _)| scene)
}

/// Reads and parses the scene at `path` with its camera path, if it has one.
pub fn load_with_path(path: &Path) -> anyhow::Result<(Scene, Option<CameraPath>)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read scene file {}", path.display()))?;
    let base = path.parent().unwrap_or_else(|| Path::new("."));
    let label = path.display().to_string();
    Ok(parse_scene_with_path(&label, &text, base, &|p: &Path| std::fs::read_to_string(p))?)
}
