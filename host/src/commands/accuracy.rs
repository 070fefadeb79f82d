//! `magg-host accuracy SCENE`: what accuracy costs in time (docs/ACCURACY.md). Parses the flags,
//! runs the accuracy study of `magg_study::accuracy::study` (the scene rendered by the
//! embedded renderer over a grid of accuracy settings, each measured against a converged
//! reference), and prints the Pareto front of error against time as a markdown table.
//!
//! ```text
//! magg-host accuracy scenes/magg-paper.toml --seeds 2 --grid small   # about a minute
//! ```

use crate::{cli::ImageFormat, images, scene_file};
use anyhow::bail;
use clap::Args;
use magg_core::frame::Frame;
use magg_core::scene::Exposure;
use magg_study::accuracy::grid::GridSize;
use magg_study::accuracy::study::{self, markdown, opt, Hooks, Reference, Row};
use std::path::{Path, PathBuf};

/// Arguments of `accuracy`.
#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Scene file (TOML), e.g. scenes/magg-paper.toml.
    pub scene: PathBuf,
    /// Where accuracy.csv and reference.png go (default: accuracy-<scene stem>).
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// Independent seeds (1..=N) each error is averaged over.
    #[arg(long, default_value_t = 2)]
    pub seeds: u32,
    /// small: one knob at a time plus a few combined points; full: also every element
    /// size x light rays x pixel samples combination.
    #[arg(long, value_enum, default_value_t = GridSize::Small)]
    pub grid: GridSize,
    /// Image width of the study (and of the reference).
    #[arg(long, default_value_t = 128)]
    pub width: u32,
    /// Image height of the study (and of the reference).
    #[arg(long, default_value_t = 128)]
    pub height: u32,
    /// Node workers (0 = one per core).
    #[arg(long, default_value_t = 0)]
    pub nodes: u32,
    /// No per-setting lines on stderr.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The study's image writer and its progress lines on stderr.
struct Terminal<'a> {
    args: &'a AccuracyArgs,
}

impl Hooks for Terminal<'_> {
    fn write_png(
        &mut self,
        frame: &Frame,
        path: &Path,
        exposure: Exposure,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(images::write(frame, path, ImageFormat::Png, exposure)?)
    }

    fn reference(&mut self, r: &Reference) {
        if !self.args.quiet {
            eprintln!(
                "reference: {} elements, {} light rays, {} pixel samples, {}x{}: {:.2}s",
                r.elements, r.point.light_rays, r.point.pixel_samples, self.args.width, self.args.height, r.seconds
            );
        }
    }

    fn row(&mut self, row: &Row) {
        if !self.args.quiet {
            eprintln!(
                "{:>16} {:<24} {:>7} el  {:>8.3}s  rel_mse {}  psnr {}",
                row.setting.knob,
                row.setting.value,
                row.elements,
                row.seconds,
                opt(row.image_rel_mse, 3),
                row.png_psnr.map(|x| format!("{x:.2} dB")).unwrap_or_default()
            );
        }
    }
}

/// Runs the study.
pub fn run(args: &AccuracyArgs, files: &scene_file::SceneFiles) -> anyhow::Result<()> {
    if args.seeds == 0 || args.seeds > 64 {
        bail!("--seeds {}: must be 1..=64", args.seeds);
    }
    for (name, v) in [("width", args.width), ("height", args.height)] {
        if v == 0 || v > 16384 {
            bail!("--{name} {v}: must be 1..=16384");
        }
    }
    let mut scene = files.load(&args.scene, &[])?;
    scene.settings.width = args.width;
    scene.settings.height = args.height;
    let out_dir = args.out_dir.clone().unwrap_or_else(|| {
        let stem = args.scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into());
        PathBuf::from(format!("accuracy-{stem}"))
    });
    let config = study::Config { seeds: args.seeds, grid: args.grid, nodes: args.nodes };
    let done = study::run(&scene, &config, &out_dir, &mut Terminal { args })?;
    let (reference, rows) = (&done.reference, &done.rows);
    println!(
        "# Accuracy study: {} at {}x{}, {} seed(s), reference {} elements / {} light rays / {} pixel samples\n",
        args.scene.display(),
        args.width,
        args.height,
        args.seeds,
        reference.elements,
        reference.point.light_rays,
        reference.point.pixel_samples
    );
    println!("## All settings\n\n{}", markdown(rows, 0..rows.len()));
    println!(
        "## Pareto front (cheapest setting in modelled time for each image_rel_mse level)\n\n{}",
        markdown(rows, done.front.iter().copied())
    );
    if !args.quiet {
        eprintln!("-> {} and {}", done.csv.display(), done.reference_png.display());
        for p in &done.plots {
            eprintln!("-> {}", p.display());
        }
    }
    Ok(())
}
