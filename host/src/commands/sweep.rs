//! `magg-host sweep`: the paper's experiments (paper §5, docs/EXPERIMENTS.md). Parses the flags,
//! runs the grid of `magg_study::sweep::study` (the scene on the cluster under a hardware
//! profile over nodes x cache blocks x forks x schedule; `sweep.csv` and the figures),
//! and prints a table.
//!
//! ```text
//! magg-host sweep scenes/magg-paper.toml --out-dir sweep            # the paper's grid
//! magg-host sweep scenes/magg-paper.toml --nodes 5,20 --cache-blocks 20,40 -- --width 100 --height 100
//! ```

use anyhow::{bail, Context};
use clap::Args;
use magg_study::sweep::run::Runner;
use magg_study::sweep::study::{self, table, Event};
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
    /// Acceleration structures: "grid" (the paper's uniform grid of subspaces) and/or
    /// "bvh" (rows and figures of the BVH are named `<scheme>-bvh`).
    #[arg(long, value_delimiter = ',', default_value = "grid")]
    pub accel: Vec<String>,
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
pub fn run(args: &SweepArgs, allow_path: &[std::path::PathBuf]) -> anyhow::Result<()> {
    for s in &args.schemes {
        if magg_throttle::Scheme::parse(s).is_none() {
            bail!("--schemes: {s:?} is not \"paper\" or \"magg\"");
        }
    }
    for a in &args.accel {
        if magg_core::scene::Accel::parse(a).is_none() {
            bail!("--accel: {a:?} is not \"grid\" or \"bvh\"");
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
    // Every run is this binary's `render`.
    let host = std::env::current_exe().context("locating magg-host")?;
    let runner = match &args.multi_process {
        Some(script) => Runner::MultiProcess { script: script.clone(), host },
        None => Runner::InProcess { host },
    };
    let config = study::Config {
        scene: args.scene.clone(),
        out_dir: args.out_dir.clone(),
        nodes: args.nodes.clone(),
        cache_blocks: args.cache_blocks.clone(),
        forks: args.forks.clone(),
        schemes: args.schemes.clone(),
        accels: args.accel.clone(),
        profile: args.profile.clone(),
        dilation: Some(base),
        max_cpu_share: args.max_cpu_share,
        runner,
        // Every run reads the scene's meshes as this one would.
        render_flags: allow_path
            .iter()
            .flat_map(|d| ["--allow-path".to_string(), d.display().to_string()])
            .chain(args.render_flags.iter().cloned())
            .collect(),
    };
    let done = study::run(&config, &mut |event| {
        match event {
        Event::Again { name, share, dilation } => {
            eprintln!("  {name}: real CPU share {share:.2}, again with dilation {dilation:.1}")
        }
        Event::Done { k, total, name, row } => eprintln!(
            "[{k}/{total}] {name}: total {:.3} s (LRT {:.3}, VRT {:.3}), hit ratio {:.4}, dilation {:.1}, real CPU share {:.2}",
            row.num("total_s"),
            row.num("lrt_s"),
            row.num("vrt_s"),
            row.num("hit_ratio"),
            row.shape.dilation,
            row.num("real_cpu_share"),
        ),
    }
    })?;
    print!("{}", table(&done.rows));
    eprintln!("wrote {} and {} figures in {}", done.csv.display(), done.figures.len(), args.out_dir.display());
    Ok(())
}
