//! The sweep's grid (paper §5, docs/EXPERIMENTS.md): renders a scene on the cluster under a
//! hardware profile over nodes x cache blocks x forks x schedule, writes `sweep.csv`
//! (one row per run, from its stats) and the figures of [`super::figures`], and returns
//! the rows, whose [`table`] `magg-host sweep` prints.
//!
//! The dilation of each run (real seconds per modelled second) grows with the node count,
//! so that the emulating machine's own work (gRPC, threads) stays small beside the
//! modelled work; a run whose real CPU share comes out above [`Config::max_cpu_share`] is
//! run again with a larger dilation, and the table says which dilation each row used.

use super::figures;
use super::run::{run_one, write_csv, Row, Runner, Shape};
use crate::error::{Result, StudyError};
use std::fmt::Write as _;
use std::path::PathBuf;

/// The grid of a sweep and how each run is made.
#[derive(Clone, Debug)]
pub struct Config {
    /// Scene file.
    pub scene: PathBuf,
    /// Where sweep.csv, the figures and each run's stats (`runs/`) go.
    pub out_dir: PathBuf,
    /// Node counts.
    pub nodes: Vec<u32>,
    /// Cache sizes per node in 2 KB blocks.
    pub cache_blocks: Vec<u32>,
    /// Fork counts.
    pub forks: Vec<u32>,
    /// Schedules: "paper" and/or "magg".
    pub schemes: Vec<String>,
    /// Acceleration structures: "grid" (the paper's) and/or "bvh".
    pub accels: Vec<String>,
    /// Hardware profile (a built-in name or a file).
    pub profile: String,
    /// Real seconds per modelled second at 10 nodes or fewer; it grows in proportion to
    /// the node count beyond (`None`: the profile's).
    pub dilation: Option<f64>,
    /// Re-run a run whose real CPU share exceeds this, with a larger dilation.
    pub max_cpu_share: f64,
    /// Where each run happens.
    pub runner: Runner,
    /// Further `magg-host render` flags for every run, e.g. `--width 200`.
    pub render_flags: Vec<String>,
}

/// What the sweep tells its caller as it goes.
#[derive(Clone, Copy, Debug)]
pub enum Event<'a> {
    /// Run `name` used more than `share` of the real CPU: it runs again with `dilation`.
    Again {
        /// The run.
        name: &'a str,
        /// Its real CPU share.
        share: f64,
        /// The new dilation.
        dilation: f64,
    },
    /// Run `k` of `total` is measured.
    Done {
        /// Its 1-based index.
        k: usize,
        /// Runs in the grid.
        total: usize,
        /// The run.
        name: &'a str,
        /// Its row.
        row: &'a Row,
    },
}

/// A finished sweep: its rows, `sweep.csv` and the figures written.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// One row per run, in grid order (structure, scheme, forks, cache, nodes).
    pub rows: Vec<Row>,
    /// `sweep.csv`.
    pub csv: PathBuf,
    /// The figures.
    pub figures: Vec<PathBuf>,
}

/// Runs the sweep, telling `events` about each run.
pub fn run(config: &Config, events: &mut dyn FnMut(Event<'_>)) -> Result<Sweep> {
    let profile = magg_throttle::Profile::named(&config.profile)?;
    let base = config.dilation.unwrap_or(profile.dilation);
    let runs_dir = config.out_dir.join("runs");
    std::fs::create_dir_all(&runs_dir).map_err(StudyError::io("create", &runs_dir))?;
    let total = config.accels.len()
        * config.schemes.len()
        * config.forks.len()
        * config.cache_blocks.len()
        * config.nodes.len();
    let mut rows = Vec::with_capacity(total);
    let mut k = 0;
    for (accel, scheme) in config.accels.iter().flat_map(|a| config.schemes.iter().map(move |s| (a, s))) {
        for &forks in &config.forks {
            for &cache in &config.cache_blocks {
                for &nodes in &config.nodes {
                    k += 1;
                    let mut shape = Shape {
                        scheme: scheme.clone(),
                        forks,
                        nodes,
                        cache_blocks: cache,
                        dilation: base * (nodes as f64 / 10.0).max(1.0),
                        accel: accel.clone(),
                    };
                    let name = format!("{}-f{forks}-c{cache}-n{nodes}", shape.schedule());
                    let (image, stats) = (runs_dir.join(format!("{name}.png")), runs_dir.join(format!("{name}.json")));
                    let one = |shape: &Shape| {
                        run_one(
                            &config.runner,
                            &config.scene,
                            &config.profile,
                            shape,
                            &image,
                            &stats,
                            &config.render_flags,
                        )
                    };
                    let mut row = one(&shape)?;
                    // Faithful only while the emulating machine is mostly idle: else again,
                    // slower.
                    for _ in 0..2 {
                        let share = row.num("real_cpu_share");
                        if !(share > config.max_cpu_share) {
                            break;
                        }
                        shape.dilation *= share / (0.8 * config.max_cpu_share);
                        events(Event::Again { name: &name, share, dilation: shape.dilation });
                        row = one(&shape)?;
                    }
                    events(Event::Done { k, total, name: &name, row: &row });
                    rows.push(row);
                }
            }
        }
    }
    let csv = config.out_dir.join("sweep.csv");
    write_csv(&csv, &rows)?;
    let figures = figures::write_all(&rows, &config.out_dir)?;
    Ok(Sweep { rows, csv, figures })
}

/// A markdown table of the runs, with the speed-up against the fewest nodes of the same
/// schedule, forks and cache.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| scheme | forks | cache | nodes | preprocess s | LRT s | VRT s | total s | speed-up total | LRT | VRT | hit ratio | accel | DMA bytes per ray | dilation | real CPU |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: |\n",
    );
    for r in rows {
        let base = rows
            .iter()
            .filter(|b| {
                b.shape.scheme == r.shape.scheme
                    && b.shape.accel == r.shape.accel
                    && b.shape.forks == r.shape.forks
                    && b.shape.cache_blocks == r.shape.cache_blocks
            })
            .min_by_key(|b| b.shape.nodes)
            .unwrap_or(r);
        let sp = |c: &str| base.num(c) / r.num(c);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.4} | {} | {:.1} | {:.1} | {:.2} |",
            r.shape.scheme,
            r.shape.forks,
            r.shape.cache_blocks,
            r.shape.nodes,
            r.num("preprocess_s"),
            r.num("lrt_s"),
            r.num("vrt_s"),
            r.num("total_s"),
            sp("total_s"),
            sp("lrt_s"),
            sp("vrt_s"),
            r.num("hit_ratio"),
            r.shape.accel,
            r.dma_bytes_per_ray(),
            r.shape.dilation,
            r.num("real_cpu_share"),
        );
    }
    s
}
