//! Frames of a render and the stats that go with them: numbered image names for camera
//! paths, and the run's stats JSON (the core's [`RenderStats`] plus what the host knows:
//! where the energies came from and every frame written).
//!
//! Numbering: with more than one frame, `--out shot.png` becomes `shot_0000.png`,
//! `shot_0001.png`, ... (four digits, more when the path has over 10000 frames); a single
//! frame keeps the name as given.

use magg_core::stats::RenderStats;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The file of frame `index` of `count` for the output `path`.
pub fn numbered(path: &Path, index: usize, count: usize) -> PathBuf {
    if count <= 1 {
        return path.to_path_buf();
    }
    let digits = (count - 1).to_string().len().max(4);
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}_{index:0digits$}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{index:0digits$}"),
    };
    path.with_file_name(name)
}

/// One frame written.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRecord {
    /// Frame index.
    pub frame: usize,
    /// Image written.
    pub out: String,
    /// Seconds of its viewing pass.
    pub vrt_s: f64,
}

/// Where the energies of the run came from.
#[derive(Clone, Debug, Serialize)]
pub struct EnergyOrigin {
    /// Light passes run: 1, or 0 when the energies were loaded.
    pub light_passes: u32,
    /// `traced` or `loaded`.
    pub source: &'static str,
    /// The file they were loaded from.
    pub loaded_from: Option<String>,
    /// The file they were saved to.
    pub saved_to: Option<String>,
}

/// The stats file: the core's stats, flattened, plus `read_s`, `energy` and `frames`.
#[derive(Debug, Serialize)]
pub struct RunStats<'a> {
    /// The render's figures.
    #[serde(flatten)]
    pub render: &'a RenderStats,
    /// Seconds reading the scene (its TOML and every mesh file), a stage before
    /// `stages.preprocess_s` and not part of `stages.total_s`.
    pub read_s: f64,
    /// Where the energies came from.
    pub energy: EnergyOrigin,
    /// Every frame written, in order.
    pub frames: Vec<FrameRecord>,
}

impl<'a> RunStats<'a> {
    /// Stats of a run that loaded its energies from `loaded` (if any) and saved them to
    /// `saved` (if asked).
    pub fn new(
        render: &'a RenderStats,
        read_s: f64,
        loaded: Option<&Path>,
        saved: Option<&Path>,
        frames: Vec<FrameRecord>,
    ) -> Self {
        let show = |p: Option<&Path>| p.map(|p| p.display().to_string());
        RunStats {
            render,
            read_s,
            energy: EnergyOrigin {
                light_passes: if loaded.is_some() { 0 } else { 1 },
                source: if loaded.is_some() { "loaded" } else { "traced" },
                loaded_from: show(loaded),
                saved_to: show(saved),
            },
            frames,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_numbered_before_the_extension() {
        let p = Path::new("out/shot.png");
        assert_eq!(numbered(p, 3, 1), PathBuf::from("out/shot.png"));
        assert_eq!(numbered(p, 3, 10), PathBuf::from("out/shot_0003.png"));
        assert_eq!(numbered(p, 7, 20000), PathBuf::from("out/shot_00007.png"));
        assert_eq!(numbered(Path::new("x"), 1, 2), PathBuf::from("x_0001"));
    }
}
