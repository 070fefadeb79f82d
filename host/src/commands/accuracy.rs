//! `magg-host accuracy SCENE`: what accuracy costs in time (DESIGN §1). Renders the scene
//! with the embedded renderer over a grid of accuracy settings, measures each against a
//! converged reference at the same resolution, writes `accuracy.csv` and prints the
//! Pareto front of error against time as a markdown table.
//!
//! ```text
//! magg-host accuracy scenes/magg-paper.toml --seeds 2 --grid small   # about a minute
//! ```

use crate::accuracy::grid::{self, GridSize, Point, Setting};
use crate::accuracy::plot::{Plot, Series, PALETTE};
use crate::accuracy::{closed_form, metrics, pareto};
use crate::{cli::ImageFormat, images, scene_file};
use anyhow::{bail, Context};
use clap::Args;
use magg_core::frame::Frame;
use magg_core::math::Rgb;
use magg_core::progress::NoProgress;
use magg_core::scene::Scene;
use magg_core::{energy, preprocess, render};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Seed of the reference render, apart from the study's seeds 1..=N so that no setting
/// shares its random numbers with the reference.
pub const REFERENCE_SEED: u64 = 0x5eed_0000;

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

/// One measured row of the study.
#[derive(Clone, Debug)]
pub struct Row {
    /// The setting.
    pub setting: Setting,
    /// Effective `element_size` (the scene's times the multiplier).
    pub element_size: f64,
    /// Elements after preprocessing.
    pub elements: u32,
    /// Mean wall time of a render (stats `total_s`, preprocessing included).
    pub seconds: f64,
    /// Modelled time of the same work on one T800-20 of the 1993 machine (the
    /// `magg1993` profile's cost model: preprocessing plus every node's counted
    /// operations), seconds. Deterministic: it does not depend on this machine or its load.
    pub modelled_s: f64,
    /// RMSE of the linear image.
    pub image_rmse: Option<f64>,
    /// Relative MSE of the linear image.
    pub image_rel_mse: Option<f64>,
    /// PSNR of the tone-mapped 8-bit image, dB (capped).
    pub png_psnr: Option<f64>,
    /// RMSE of element irradiance (only at the reference's element size).
    pub element_rmse: Option<f64>,
    /// Relative RMSE of the vertex irradiance against the closed form I cos/r^2, where
    /// it holds (see [`crate::accuracy::closed_form`]).
    pub vertex_cf_rel_rmse: Option<f64>,
}

struct Measured {
    seconds: f64,
    modelled_s: f64,
    frame: Frame,
    irradiance: Vec<Rgb>,
    elements: u32,
    vertex_cf: Option<f64>,
}

fn render_point(scene: &Scene, point: &Point, seed: u64, nodes: u32) -> anyhow::Result<Measured> {
    let mut s = point.apply(scene);
    s.settings.seed = seed;
    let prepared = preprocess::prepare(&s)?;
    let opts = render::RenderOptions { nodes, ..Default::default() };
    let out = render::render(&prepared, &opts, &NoProgress)?;
    let irradiance = energy::element_irradiance(&prepared.elements, &out.element_flux, prepared.header.energy_quantum);
    let ops = out.stats.per_node.iter().fold(magg_core::view::OpCounters::default(), |a, n| a.add(n.ops));
    Ok(Measured {
        seconds: out.stats.stages.total_s,
        modelled_s: modelled_seconds(&prepared, &ops),
        frame: out.frame,
        irradiance,
        elements: prepared.header.counts.elements,
        vertex_cf: closed_form::vertex_rel_rmse(&prepared, &out.stats.light, &out.vertex_irradiance),
    })
}

/// Seconds the work of a render would take on one processor of the `magg1993` profile.
fn modelled_seconds(prepared: &preprocess::PreparedScene, ops: &magg_core::view::OpCounters) -> f64 {
    let Ok(profile) = magg_throttle::Profile::named("magg1993") else { return f64::NAN };
    let Some(cpu) = profile.cpu else { return f64::NAN };
    (magg_throttle::CpuCost(cpu).of(ops) + magg_throttle::preprocess_ops(&cpu, &prepared.ops, 1)).as_secs_f64()
}

/// Runs the study.
pub fn run(args: &AccuracyArgs) -> anyhow::Result<()> {
    if args.seeds == 0 || args.seeds > 64 {
        bail!("--seeds {}: must be 1..=64", args.seeds);
    }
    for (name, v) in [("width", args.width), ("height", args.height)] {
        if v == 0 || v > 16384 {
            bail!("--{name} {v}: must be 1..=16384");
        }
    }
    let mut scene = scene_file::load(&args.scene)?;
    scene.settings.width = args.width;
    scene.settings.height = args.height;
    let out_dir = args.out_dir.clone().unwrap_or_else(|| {
        let stem = args.scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into());
        PathBuf::from(format!("accuracy-{stem}"))
    });
    std::fs::create_dir_all(&out_dir).with_context(|| format!("cannot create {}", out_dir.display()))?;

    let ref_point = Point::reference(&scene);
    let reference = render_point(&scene, &ref_point, REFERENCE_SEED, args.nodes)?;
    let scale = reference.frame.exposure_scale(scene.settings.exposure);
    let ref_srgb = reference.frame.to_srgb8(scale);
    images::write(&reference.frame, &out_dir.join("reference.png"), ImageFormat::Png, scene.settings.exposure)?;
    if !args.quiet {
        eprintln!(
            "reference: {} elements, {} light rays, {} pixel samples, {}x{}: {:.2}s",
            reference.elements,
            ref_point.light_rays,
            ref_point.pixel_samples,
            args.width,
            args.height,
            reference.seconds
        );
    }

    let settings = grid::settings(&scene, args.grid);
    let mut rows = Vec::with_capacity(settings.len());
    for setting in settings {
        let (mut secs, mut mse, mut rel, mut png, mut el) = (0.0, Some(0.0), Some(0.0), Some(0.0), Some(0.0));
        let mut modelled = 0.0;
        let mut vertex_cf = Some(0.0);
        let mut elements = 0;
        let comparable = setting.point.element_scale == ref_point.element_scale;
        for seed in 1..=args.seeds as u64 {
            let m = render_point(&scene, &setting.point, seed, args.nodes)?;
            secs += m.seconds;
            modelled += m.modelled_s;
            vertex_cf = vertex_cf.zip(m.vertex_cf).map(|(a, b)| a + b);
            elements = m.elements;
            let add = |acc: Option<f64>, x: Option<f64>| Some(acc? + x?);
            mse = add(mse, metrics::image_mse(&m.frame, &reference.frame));
            rel = add(rel, metrics::image_rel_mse(&m.frame, &reference.frame));
            png = add(png, metrics::srgb8_mse(&m.frame.to_srgb8(scale), &ref_srgb));
            el = if comparable { add(el, metrics::irradiance_mse(&m.irradiance, &reference.irradiance)) } else { None };
        }
        let n = args.seeds as f64;
        let row = Row {
            element_size: scene.settings.element_size * setting.point.element_scale,
            elements,
            seconds: secs / n,
            modelled_s: modelled / n,
            image_rmse: mse.map(|v| (v / n).sqrt()),
            image_rel_mse: rel.map(|v| v / n),
            png_psnr: png.map(|v| metrics::psnr_db(v / n)),
            element_rmse: el.map(|v| (v / n).sqrt()),
            vertex_cf_rel_rmse: vertex_cf.map(|v| v / n),
            setting,
        };
        if !args.quiet {
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
        rows.push(row);
    }

    let csv_path = out_dir.join("accuracy.csv");
    std::fs::write(&csv_path, csv(&rows)?).with_context(|| format!("cannot write {}", csv_path.display()))?;
    // The front is drawn on modelled time: wall time on a shared machine is noisy (the
    // same work measured 1.8 s and 3.2 s in one study), the cost model is not.
    let front = pareto::pareto_front(
        &rows.iter().map(|r| (r.modelled_s, r.image_rel_mse.unwrap_or(f64::NAN))).collect::<Vec<_>>(),
    );
    let plots = write_plots(&out_dir, &rows, &front)?;
    println!(
        "# Accuracy study: {} at {}x{}, {} seed(s), reference {} elements / {} light rays / {} pixel samples\n",
        args.scene.display(),
        args.width,
        args.height,
        args.seeds,
        reference.elements,
        ref_point.light_rays,
        ref_point.pixel_samples
    );
    println!("## All settings\n\n{}", markdown(&rows, 0..rows.len()));
    println!(
        "## Pareto front (cheapest setting in modelled time for each image_rel_mse level)\n\n{}",
        markdown(&rows, front)
    );
    if !args.quiet {
        eprintln!("-> {} and {}", csv_path.display(), out_dir.join("reference.png").display());
        for p in &plots {
            eprintln!("-> {}", p.display());
        }
    }
    Ok(())
}

/// The knobs varied one at a time, with their value of a row on a log axis (depths and
/// bounces plus one, since they can be 0) and the axis title.
pub const PLOT_KNOBS: [(&str, &str); 6] = [
    ("element_size", "Element size (m)"),
    ("light_rays", "Light rays per pair"),
    ("pixel_samples", "Pixel samples"),
    ("lrt_depth", "LRT depth + 1"),
    ("vrt_depth", "VRT depth + 1"),
    ("diffuse_bounces", "Diffuse bounces + 1"),
];

/// The value of `knob` in `row`, as plotted (see [`PLOT_KNOBS`]).
pub fn knob_value(row: &Row, knob: &str) -> f64 {
    let p = &row.setting.point;
    match knob {
        "element_size" => row.element_size,
        "light_rays" => p.light_rays as f64,
        "pixel_samples" => p.pixel_samples as f64,
        "lrt_depth" => p.lrt_depth as f64 + 1.0,
        "vrt_depth" => p.vrt_depth as f64 + 1.0,
        "diffuse_bounces" => p.diffuse_bounces as f64 + 1.0,
        _ => f64::NAN,
    }
}

/// Writes `error_vs_time.png` (image relative MSE against modelled T800 seconds: one series per knob,
/// each with the base point, and the Pareto `front` as a line) and `error_vs_<knob>.png`
/// for each knob of [`PLOT_KNOBS`] that `rows` vary. Returns the paths written.
pub fn write_plots(out_dir: &Path, rows: &[Row], front: &[usize]) -> anyhow::Result<Vec<PathBuf>> {
    let err = |r: &Row| r.image_rel_mse.unwrap_or(f64::NAN);
    let base: Vec<&Row> = rows.iter().filter(|r| r.setting.knob == "base").collect();
    let mut knobs: Vec<&str> = Vec::new();
    for r in rows {
        if r.setting.knob != "base" && !knobs.contains(&r.setting.knob.as_str()) {
            knobs.push(&r.setting.knob);
        }
    }
    let mut written = Vec::new();
    let mut plot = Plot::new("Error against modelled time", "Modelled T800 seconds", "Image relative MSE");
    let mut front_pts: Vec<(f64, f64)> = front.iter().map(|&i| (rows[i].modelled_s, err(&rows[i]))).collect();
    front_pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    plot.series.push(Series { markers: false, ..Series::new("pareto front", front_pts, [0, 0, 0]) });
    for (i, knob) in knobs.iter().enumerate() {
        let pts = rows.iter().filter(|r| r.setting.knob == *knob).chain(base.iter().copied());
        plot.series.push(Series::new(*knob, pts.map(|r| (r.modelled_s, err(r))).collect(), PALETTE[i % PALETTE.len()]));
    }
    plot.series.push(Series {
        lines: false,
        ..Series::new("base", base.iter().map(|r| (r.modelled_s, err(r))).collect(), [0, 0, 0])
    });
    let path = out_dir.join("error_vs_time.png");
    plot.write(&path)?;
    written.push(path);
    for (i, (knob, title)) in PLOT_KNOBS.iter().enumerate() {
        if !rows.iter().any(|r| r.setting.knob == *knob) {
            continue;
        }
        let pts = rows.iter().filter(|r| r.setting.knob == *knob).chain(base.iter().copied());
        let mut plot = Plot::new(format!("Error against {knob}"), *title, "Image relative MSE");
        plot.series.push(Series::new(*knob, pts.map(|r| (knob_value(r, knob), err(r))).collect(), PALETTE[i]));
        let path = out_dir.join(format!("error_vs_{knob}.png"));
        plot.write(&path)?;
        written.push(path);
    }
    Ok(written)
}

/// An optional figure in scientific notation with `digits` decimals, or empty.
fn opt(v: Option<f64>, digits: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.digits$e}"),
        _ => String::new(),
    }
}

/// The columns of accuracy.csv, in order.
pub const CSV_HEADER: [&str; 16] = [
    "knob",
    "value",
    "element_size",
    "light_rays",
    "pixel_samples",
    "lrt_depth",
    "vrt_depth",
    "diffuse_bounces",
    "seconds",
    "modelled_s",
    "image_rmse",
    "image_rel_mse",
    "png_psnr",
    "element_rmse",
    "elements",
    "vertex_cf_rel_rmse",
];

/// The CSV text of `rows`: one line per setting; a missing error is an empty field.
pub fn csv(rows: &[Row]) -> anyhow::Result<String> {
    let mut out = csv::Writer::from_writer(Vec::new());
    out.write_record(CSV_HEADER)?;
    for r in rows {
        let p = &r.setting.point;
        out.write_record([
            r.setting.knob.clone(),
            r.setting.value.clone(),
            r.element_size.to_string(),
            p.light_rays.to_string(),
            p.pixel_samples.to_string(),
            p.lrt_depth.to_string(),
            p.vrt_depth.to_string(),
            p.diffuse_bounces.to_string(),
            format!("{:.6}", r.seconds),
            format!("{:.4}", r.modelled_s),
            opt(r.image_rmse, 6),
            opt(r.image_rel_mse, 6),
            r.png_psnr.filter(|x| x.is_finite()).map(|x| format!("{x:.3}")).unwrap_or_default(),
            opt(r.element_rmse, 6),
            r.elements.to_string(),
            opt(r.vertex_cf_rel_rmse, 6),
        ])?;
    }
    Ok(String::from_utf8(out.into_inner()?)?)
}

/// A markdown table of the rows at `idx`, in that order.
pub fn markdown(rows: &[Row], idx: impl IntoIterator<Item = usize>) -> String {
    let mut s = String::from(
        "| knob | value | elements | light rays | pixel samples | lrt/vrt depth | diffuse | seconds | T800 s | image RMSE | image rel. MSE | PNG PSNR (dB) | element RMSE | vertex vs closed form |\n\
         | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for i in idx {
        let r = &rows[i];
        let p = &r.setting.point;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {}/{} | {} | {:.3} | {:.2} | {} | {} | {} | {} | {} |",
            r.setting.knob,
            r.setting.value,
            r.elements,
            p.light_rays,
            p.pixel_samples,
            p.lrt_depth,
            p.vrt_depth,
            p.diffuse_bounces,
            r.seconds,
            r.modelled_s,
            opt(r.image_rmse, 2),
            opt(r.image_rel_mse, 2),
            r.png_psnr.map(|x| format!("{x:.2}")).unwrap_or_default(),
            opt(r.element_rmse, 2),
            opt(r.vertex_cf_rel_rmse, 2)
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(knob: &str, value: &str, rel: Option<f64>) -> Row {
        Row {
            setting: Setting {
                knob: knob.into(),
                value: value.into(),
                point: Point {
                    element_scale: 1.0,
                    light_rays: 16,
                    pixel_samples: 1,
                    lrt_depth: 1,
                    vrt_depth: 1,
                    diffuse_bounces: 0,
                },
            },
            element_size: 0.1,
            elements: 1664,
            seconds: 0.5,
            modelled_s: 60.0,
            image_rmse: rel,
            image_rel_mse: rel,
            png_psnr: Some(metrics::psnr_db(0.0)),
            element_rmse: None,
            vertex_cf_rel_rmse: None,
        }
    }

    #[test]
    fn csv_has_no_nan_and_quotes_commas() {
        let text = csv(&[row("combined", "x0.5, 16 rays", Some(0.25)), row("base", "scene", Some(f64::NAN))]).unwrap();
        assert!(!text.to_ascii_lowercase().contains("nan"), "{text}");
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[1].starts_with("combined,\"x0.5, 16 rays\",0.1,16,1,1,1,0,0.500000,"));
        assert!(lines[2].contains(",100.000,,1664"), "{}", lines[2]);
        let cols = lines[0].split(',').count();
        assert_eq!(lines[2].split(',').count(), cols);
    }

    #[test]
    fn plots_are_written_per_varied_knob() {
        let dir = std::env::temp_dir().join(format!("magg-accuracy-plots-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut depth = row("lrt_depth", "0", Some(0.5));
        depth.setting.point.lrt_depth = 0;
        assert_eq!(knob_value(&depth, "lrt_depth"), 1.0);
        let rows = [row("base", "scene", Some(0.1)), row("light_rays", "64", Some(0.05)), depth, row("x", "y", None)];
        let written = write_plots(&dir, &rows, &[0]).unwrap();
        let names: Vec<String> =
            written.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["error_vs_time.png", "error_vs_light_rays.png", "error_vs_lrt_depth.png"]);
        assert!(written.iter().all(|p| p.exists()));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn markdown_lists_the_rows_asked_for() {
        let rows = [row("base", "scene", Some(1.0)), row("light_rays", "64", Some(0.5))];
        let t = markdown(&rows, [1]);
        assert_eq!(t.lines().count(), 3);
        assert!(t.contains("| light_rays | 64 |"));
    }
}
