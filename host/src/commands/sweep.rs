//! `magg-host sweep`: the paper's experiments (paper §5, DESIGN.md §4): renders a scene
//! on the cluster under a hardware profile over nodes x cache blocks x forks x schedule,
//! writes `sweep.csv` (one row per run, from its stats) and the figures of
//! [`crate::sweep::figures`], and prints a table.
//!
//! ```text
//! magg-host sweep scenes/magg-paper.toml --out-dir sweep            # the paper's grid
//! magg-host sweep scenes/magg-paper.toml --nodes 5,20 --cache-blocks 20,40 -- --width 100 --height 100
//! ```
//!
//! The dilation of each run (real seconds per modelled second) grows with the node count,
//! so that the emulating machine's own work (gRPC, threads) stays small beside the
//! modelled work; a run whose real CPU share comes out above `--max-cpu-share` is run
//! again with a larger dilation, and the table says which dilation each row used.

use crate::sweep::figures;
use crate::sweep::run::{run_one, write_csv, Row, Runner, Shape};
use anyhow::{bail, Context};
use clap::Args;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Scene file.
    #[arg(default_value = "scenes/magg-paper.toml")]
    pub scene: PathBuf,
    /// Where sweep.csv, the figures and each run's stats go.
    #[arg(long, default_value = "sweep")]
    pub out_dir: PathBuf,
    /// Node counts (the paper's: 5,10,20,40,60,80).
    #[arg(long, value_delimiter = ',', default_value = "5,10,20,40,60,80")]
    pub nodes: Vec<u32>,
    /// Cache sizes per node in 2 KB blocks (the paper's: 20,40,60,80).
    #[arg(long, value_delimiter = ',', default_value = "20,40,60,80")]
    pub cache_blocks: Vec<u32>,
    /// Fork counts (the paper's machine had 5).
    #[arg(long, value_delimiter = ',', default_value = "5")]
    pub forks: Vec<u32>,
    /// Schedules: "paper" (the paper's choices) and/or "magg" (ours).
    #[arg(long, value_delimiter = ',', default_value = "paper,magg")]
    pub schemes: Vec<String>,
    /// Hardware profile (a built-in name or a file).
    #[arg(long, default_value = "magg1993")]
    pub profile: String,
    /// Real seconds per modelled second at 10 nodes or fewer; it grows in proportion to
    /// the node count beyond (default: the profile's).
    #[arg(long)]
    pub dilation: Option<f64>,
    /// Re-run a run whose real CPU share exceeds this, with a larger dilation.
    #[arg(long, default_value_t = 0.5)]
    pub max_cpu_share: f64,
    /// Run each render as a multi-process cluster (deploy/local-cluster.sh at this path)
    /// instead of the in-process harness.
    #[arg(long)]
    pub multi_process: Option<PathBuf>,
    /// Further `magg-host render` flags for every run (after `--`), e.g. `--width 200`.
    #[arg(last = true)]
    pub render_flags: Vec<String>,
}

/// Runs the sweep.
pub fn run(args: &SweepArgs) -> anyhow::Result<()> {
    for s in &args.schemes {
        if magg_throttle::Scheme::parse(s).is_none() {
            bail!("--schemes: {s:?} is not \"paper\" or \"magg\"");
        }
    }
    if args.nodes.iter().chain(&args.cache_blocks).chain(&args.forks).any(|&n| n == 0) {
        bail!("--nodes, --cache-blocks and --forks take positive numbers");
    }
    if !(args.max_cpu_share > 0.0 && args.max_cpu_share <= 1.0) {
        bail!("--max-cpu-share {}: must be in (0, 1]", args.max_cpu_share);
    }
    let profile = magg_throttle::Profile::named(&args.profile)?;
    let base = args.dilation.unwrap_or(profile.dilation);
    if !(base.is_finite() && base > 0.0) {
        bail!("--dilation {base}: must be a positive number");
    }
    let runner = match &args.multi_process {
        Some(script) => Runner::MultiProcess(script.clone()),
        None => Runner::InProcess,
    };
    let runs_dir = args.out_dir.join("runs");
    std::fs::create_dir_all(&runs_dir).with_context(|| format!("creating {}", runs_dir.display()))?;
    let total = args.schemes.len() * args.forks.len() * args.cache_blocks.len() * args.nodes.len();
    let mut rows = Vec::with_capacity(total);
    let mut k = 0;
    for scheme in &args.schemes {
        for &forks in &args.forks {
            for &cache in &args.cache_blocks {
                for &nodes in &args.nodes {
                    k += 1;
                    let mut shape = Shape {
                        scheme: scheme.clone(),
                        forks,
                        nodes,
                        cache_blocks: cache,
                        dilation: base * (nodes as f64 / 10.0).max(1.0),
                    };
                    let name = format!("{scheme}-f{forks}-c{cache}-n{nodes}");
                    let (image, stats) = (runs_dir.join(format!("{name}.png")), runs_dir.join(format!("{name}.json")));
                    let mut row =
                        run_one(&runner, &args.scene, &args.profile, &shape, &image, &stats, &args.render_flags)?;
                    // Faithful only while the emulating machine is mostly idle: else again,
                    // slower.
                    for _ in 0..2 {
                        let share = row.num("real_cpu_share");
                        if !(share > args.max_cpu_share) {
                            break;
                        }
                        shape.dilation *= share / (0.8 * args.max_cpu_share);
                        eprintln!("  {name}: real CPU share {share:.2}, again with dilation {:.1}", shape.dilation);
                        row = run_one(&runner, &args.scene, &args.profile, &shape, &image, &stats, &args.render_flags)?;
                    }
                    eprintln!(
                        "[{k}/{total}] {name}: total {:.3} s (LRT {:.3}, VRT {:.3}), hit ratio {:.4}, dilation {:.1}, real CPU share {:.2}",
                        row.num("total_s"),
                        row.num("lrt_s"),
                        row.num("vrt_s"),
                        row.num("hit_ratio"),
                        shape.dilation,
                        row.num("real_cpu_share"),
                    );
                    rows.push(row);
                }
            }
        }
    }
    let csv_path = args.out_dir.join("sweep.csv");
    write_csv(&csv_path, &rows)?;
    let figs = figures::write_all(&rows, &args.out_dir)?;
    print!("{}", table(&rows));
    eprintln!("wrote {} and {} figures in {}", csv_path.display(), figs.len(), args.out_dir.display());
    Ok(())
}

/// A markdown table of the runs, with the speed-up against the fewest nodes of the same
/// schedule, forks and cache.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| scheme | forks | cache | nodes | preprocess s | LRT s | VRT s | total s | speed-up total | LRT | VRT | hit ratio | dilation | real CPU |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for r in rows {
        let base = rows
            .iter()
            .filter(|b| {
                b.shape.scheme == r.shape.scheme
                    && b.shape.forks == r.shape.forks
                    && b.shape.cache_blocks == r.shape.cache_blocks
            })
            .min_by_key(|b| b.shape.nodes)
            .unwrap_or(r);
        let sp = |c: &str| base.num(c) / r.num(c);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.4} | {:.1} | {:.2} |",
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
            r.shape.dilation,
            r.num("real_cpu_share"),
        );
    }
    s
}
