//! The accuracy study (docs/ACCURACY.md): renders a scene with the embedded renderer over a grid
//! of accuracy settings, measures each against a converged reference at the same
//! resolution, and writes `reference.png`, `accuracy.csv` and the figures; the rows, the
//! Pareto front of error against modelled time and their markdown table come back to
//! the caller (`magg-host accuracy`), which prints them.

use super::grid::{self, GridSize, Point, Setting};
use super::{closed_form, metrics, pareto};
use crate::error::{Result, StudyError};
use crate::plot::{Plot, Series, PALETTE};
use magg_core::color::Rgb;
use magg_core::frame::Frame;
use magg_core::progress::NoProgress;
use magg_core::scene::{Exposure, Scene};
use magg_core::{energy, render};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Seed of the reference render, apart from the study's seeds 1..=N so that no setting
/// shares its random numbers with the reference.
pub const REFERENCE_SEED: u64 = 0x5eed_0000;

/// How the study runs (the scene's own width and height are its resolution).
#[derive(Clone, Debug)]
pub struct Config {
    /// Independent seeds (1..=N) each error is averaged over.
    pub seeds: u32,
    /// How much of the grid to run.
    pub grid: GridSize,
    /// Node workers (0 = one per core).
    pub nodes: u32,
}

/// What the application lends the study: its image writer (the study has no image
/// formats of its own) and where the progress of each render goes.
pub trait Hooks {
    /// Writes `frame` as a PNG file at `path`, tone-mapped with `exposure`.
    fn write_png(
        &mut self,
        frame: &Frame,
        path: &Path,
        exposure: Exposure,
    ) -> std::result::Result<(), Box<dyn std::error::Error + Send + Sync>>;
    /// The reference is rendered.
    fn reference(&mut self, _reference: &Reference) {}
    /// A setting is measured.
    fn row(&mut self, _row: &Row) {}
}

/// The converged reference every setting is measured against.
#[derive(Clone, Debug)]
pub struct Reference {
    /// Its settings ([`Point::reference`]).
    pub point: Point,
    /// Elements after preprocessing.
    pub elements: u32,
    /// Wall time of its render (stats `total_s`).
    pub seconds: f64,
}

/// A finished study: the reference, one row per setting, the Pareto front (indices into
/// `rows`, on modelled time) and the files written.
#[derive(Clone, Debug)]
pub struct Study {
    /// The reference.
    pub reference: Reference,
    /// One row per setting, in grid order.
    pub rows: Vec<Row>,
    /// The rows on the Pareto front of image relative MSE against modelled time.
    pub front: Vec<usize>,
    /// `reference.png`.
    pub reference_png: PathBuf,
    /// `accuracy.csv`.
    pub csv: PathBuf,
    /// The figures ([`write_plots`]).
    pub plots: Vec<PathBuf>,
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
    /// it holds (see [`super::closed_form`]).
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

fn render_point(scene: &Scene, point: &Point, seed: u64, nodes: u32) -> Result<Measured> {
    let mut s = point.apply(scene);
    s.settings.seed = seed;
    let prepared = magg_prepare::refine::prepare(&s, magg_core::plan::EffectsPlan::for_scene(&s))?;
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
fn modelled_seconds(prepared: &magg_core::prepared::PreparedScene, ops: &magg_core::view::OpCounters) -> f64 {
    let Ok(profile) = magg_throttle::Profile::named("magg1993") else { return f64::NAN };
    let Some(cpu) = profile.cpu else { return f64::NAN };
    (magg_throttle::CpuCost(cpu).of(ops) + magg_throttle::preprocess_ops(&cpu, &prepared.ops, 1)).as_secs_f64()
}

/// Runs the study of `scene` at its own resolution, writing `reference.png` (through
/// `hooks`), `accuracy.csv` and the figures into `out_dir` (created if missing).
pub fn run(scene: &Scene, config: &Config, out_dir: &Path, hooks: &mut dyn Hooks) -> Result<Study> {
    std::fs::create_dir_all(out_dir).map_err(StudyError::io("create", out_dir))?;
    let ref_point = Point::reference(scene);
    let measured = render_point(scene, &ref_point, REFERENCE_SEED, config.nodes)?;
    let scale = measured.frame.exposure_scale(scene.settings.exposure);
    let ref_srgb = measured.frame.to_srgb8(scale);
    let reference_png = out_dir.join("reference.png");
    hooks
        .write_png(&measured.frame, &reference_png, scene.settings.exposure)
        .map_err(|e| StudyError::Image { path: reference_png.clone(), reason: e.to_string() })?;
    let reference = Reference { point: ref_point, elements: measured.elements, seconds: measured.seconds };
    hooks.reference(&reference);

    let settings = grid::settings(scene, config.grid);
    let mut rows = Vec::with_capacity(settings.len());
    for setting in settings {
        let (mut secs, mut mse, mut rel, mut png, mut el) = (0.0, Some(0.0), Some(0.0), Some(0.0), Some(0.0));
        let mut modelled = 0.0;
        let mut vertex_cf = Some(0.0);
        let mut elements = 0;
        let comparable = setting.point.element_scale == ref_point.element_scale;
        for seed in 1..=config.seeds as u64 {
            let m = render_point(scene, &setting.point, seed, config.nodes)?;
            secs += m.seconds;
            modelled += m.modelled_s;
            vertex_cf = vertex_cf.zip(m.vertex_cf).map(|(a, b)| a + b);
            elements = m.elements;
            let add = |acc: Option<f64>, x: Option<f64>| Some(acc? + x?);
            mse = add(mse, metrics::image_mse(&m.frame, &measured.frame));
            rel = add(rel, metrics::image_rel_mse(&m.frame, &measured.frame));
            png = add(png, metrics::srgb8_mse(&m.frame.to_srgb8(scale), &ref_srgb));
            el = if comparable { add(el, metrics::irradiance_mse(&m.irradiance, &measured.irradiance)) } else { None };
        }
        let n = config.seeds as f64;
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
        hooks.row(&row);
        rows.push(row);
    }

    let csv_path = out_dir.join("accuracy.csv");
    std::fs::write(&csv_path, csv(&rows)?).map_err(StudyError::io("write", &csv_path))?;
    // The front is drawn on modelled time: wall time on a shared machine is noisy (the
    // same work measured 1.8 s and 3.2 s in one study), the cost model is not.
    let front = pareto::pareto_front(
        &rows.iter().map(|r| (r.modelled_s, r.image_rel_mse.unwrap_or(f64::NAN))).collect::<Vec<_>>(),
    );
    let plots = write_plots(out_dir, &rows, &front)?;
    Ok(Study { reference, rows, front, reference_png, csv: csv_path, plots })
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
pub fn write_plots(out_dir: &Path, rows: &[Row], front: &[usize]) -> Result<Vec<PathBuf>> {
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
pub fn opt(v: Option<f64>, digits: usize) -> String {
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
pub fn csv(rows: &[Row]) -> Result<String> {
    let encoding = |reason| StudyError::Csv { path: PathBuf::new(), reason };
    let mut out = csv::Writer::from_writer(Vec::new());
    out.write_record(CSV_HEADER).map_err(encoding)?;
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
        ])
        .map_err(encoding)?;
    }
    let bytes = out.into_inner().map_err(|e| encoding(e.into_error().into()))?;
    // The writer was given only UTF-8 text.
    Ok(String::from_utf8_lossy(&bytes).into_owned())
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
