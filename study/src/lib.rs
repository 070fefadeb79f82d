//! # magg-study: the studies of magg and their figures
//!
//! Two studies, each a library the `magg-host` application drives (`magg-host accuracy`,
//! `magg-host sweep`), parsing the flags and printing what these return:
//!
//! - [`accuracy`]: what accuracy costs in time. The scene rendered by the embedded
//!   renderer over a grid of accuracy settings, each measured against a converged
//!   reference; the Pareto front of error against modelled time; the `--quality` presets
//!   that sit on it.
//! - [`sweep`]: the paper's experiments redone. A grid of cluster runs (nodes x cache
//!   blocks x forks x schedule) under a hardware profile, one CSV row per run, and the
//!   paper's figures 4-11.
//!
//! Both draw their log-log figures with [`plot`].
//!
//! ```no_run
//! use magg_study::accuracy::{grid::GridSize, study};
//! # fn f(scene: &magg_core::scene::Scene, hooks: &mut dyn study::Hooks) -> magg_study::Result<()> {
//! // `hooks` is the application's PNG writer and progress lines.
//! let config = study::Config { seeds: 2, grid: GridSize::Small, nodes: 0 };
//! let done = study::run(scene, &config, std::path::Path::new("accuracy-out"), hooks)?;
//! println!("{}", study::markdown(&done.rows, done.front.iter().copied()));
//! # Ok(()) }
//! ```

pub mod accuracy;
pub mod error;
pub mod plot;
pub mod sweep;

pub use error::{Result, StudyError};

/// The scene file `name` of the repository's `scenes/`, for the tests.
#[cfg(test)]
pub(crate) fn test_scene(name: &str) -> magg_core::scene::Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let read = |p: &std::path::Path| std::fs::read(p);
    magg_core::scene::parse_scene_with_path(name, &text, path.parent().unwrap(), &read).unwrap().0
}
