//! `magg-host diff A B`: error metrics of image A against the reference B (relMSE, MSE,
//! brightness ratio, largest difference, [`crate::image_diff`]), as a table or JSON, and an
//! optional heat map of where the error sits. Reads each file by its extension: linear
//! `.pfm`, `.exr`, `.hdr`, or `.png`, `.jpg`, `.tif` decoded from sRGB ([`images::read`]).
//!
//! ```text
//! magg-host diff magg.exr mitsuba.exr --heatmap error.png
//! magg-host diff a.pfm b.pfm --json --fail-above 0.01   # exit 2 when relMSE > 0.01
//! ```

use crate::image_diff::{self, Diff};
use crate::images;
use anyhow::{bail, Context};
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Arguments of `diff`.
#[derive(Debug, Args)]
pub struct DiffArgs {
    /// The image to measure: .pfm, .exr, .hdr (linear) or .png, .jpg, .tif (sRGB, decoded
    /// to linear).
    pub a: PathBuf,
    /// The reference, in any of the same formats and of the same size.
    pub b: PathBuf,
    /// Also write each pixel's relative error as a colour to this PNG: black at 1e-6 or
    /// less, red 1e-4, yellow 1e-2, white 1 or more (log scale).
    #[arg(long, value_name = "OUT.png")]
    pub heatmap: Option<PathBuf>,
    /// Compare only the pixels where this image (same size, any of the same formats) is
    /// above --mask-above in the mean of its channels, e.g. those a reference renderer can
    /// compute (deploy/ptracer-vs-mitsuba.sh).
    #[arg(long, value_name = "MASK")]
    pub mask: Option<PathBuf>,
    /// The mask's threshold: 0.5 keeps pixels mostly inside a region rendered with
    /// radiance 1, 0.999 those wholly inside it.
    #[arg(long, value_name = "T", default_value_t = 0.5, requires = "mask")]
    pub mask_above: f64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Exit with status 2 when relMSE is above X (for scripts); the metrics print first.
    #[arg(long, value_name = "X")]
    pub fail_above: Option<f64>,
}

/// relMSE above `--fail-above`: `main` exits with status 2 on this error.
#[derive(Debug, thiserror::Error)]
#[error("relMSE {rel_mse:.4e} is above --fail-above {limit}")]
pub struct AboveLimit {
    /// The measured relMSE.
    pub rel_mse: f64,
    /// The limit given.
    pub limit: f64,
}

/// What `--json` prints: the files and the metrics.
#[derive(Serialize)]
struct Report<'a> {
    a: &'a Path,
    b: &'a Path,
    rel_eps: f64,
    #[serde(flatten)]
    diff: &'a Diff,
    heatmap: Option<&'a Path>,
    mask: Option<&'a Path>,
}

/// Runs `magg-host diff`.
pub fn run(args: &DiffArgs) -> anyhow::Result<()> {
    if let Some(x) = args.fail_above {
        if !(x.is_finite() && x >= 0.0) {
            bail!("--fail-above {x}: expected a finite number >= 0");
        }
    }
    if let Some(out) = &args.heatmap {
        if !out.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            bail!("--heatmap {}: the heat map is a PNG; name it .png", out.display());
        }
    }
    let a = read(&args.a)?;
    let b = read(&args.b)?;
    let what = || format!("cannot compare {} with {}", args.a.display(), args.b.display());
    if !args.mask_above.is_finite() {
        bail!("--mask-above {}: expected a finite number", args.mask_above);
    }
    let mask = args.mask.as_deref().map(read).transpose()?;
    let mask = mask.as_ref().map(|image| image_diff::Mask { image, above: args.mask_above });
    let diff = image_diff::diff_where(&a, &b, mask).with_context(what)?;
    if diff.pixels == 0 {
        bail!("{}: the mask keeps no pixel", args.mask.as_deref().unwrap_or(Path::new("")).display());
    }
    if let Some(out) = &args.heatmap {
        image_diff::heatmap(&a, &b)
            .with_context(what)?
            .save_with_format(out, image::ImageFormat::Png)
            .with_context(|| format!("cannot write heat map {}", out.display()))?;
    }
    if args.json {
        let report = Report {
            a: &args.a,
            b: &args.b,
            rel_eps: image_diff::REL_EPS,
            diff: &diff,
            heatmap: args.heatmap.as_deref(),
            mask: args.mask.as_deref(),
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", table(args, &diff));
    }
    match args.fail_above {
        Some(limit) if diff.rel_mse > limit => Err(AboveLimit { rel_mse: diff.rel_mse, limit }.into()),
        _ => Ok(()),
    }
}

/// `path` as linear radiance with every pixel finite, or an error naming it.
fn read(path: &Path) -> anyhow::Result<magg_core::frame::Frame> {
    let frame = images::read(path)?;
    image_diff::check_finite(&frame).with_context(|| format!("{}", path.display()))?;
    Ok(frame)
}

/// The metrics as an aligned two-column table.
fn table(args: &DiffArgs, d: &Diff) -> String {
    let ratio = d.mean_ratio.map_or("n/a (B is black)".to_string(), |r| format!("{r:.6}"));
    let at = d.max_abs_diff_at.map_or(String::new(), |[x, y]| format!(" at ({x}, {y})"));
    let share = 100.0 * d.differing_pixels as f64 / d.pixels.max(1) as f64;
    let rows = [
        ("A", format!("{} ({} x {})", args.a.display(), d.width, d.height)),
        ("B (reference)", args.b.display().to_string()),
        ("relMSE", format!("{:.6e}  mean (a-b)^2 / (b^2 + {})", d.rel_mse, image_diff::REL_EPS)),
        ("MSE", format!("{:.6e}", d.mse)),
        ("RMSE", format!("{:.6e}", d.rmse)),
        ("mean A / mean B", format!("{ratio}  ({:.6} / {:.6})", d.mean_a, d.mean_b)),
        ("max |a-b|", format!("{:.6e}{at}", d.max_abs_diff)),
        ("differing pixels", format!("{} of {} ({share:.2}%)", d.differing_pixels, d.pixels)),
        ("mask", args.mask.as_ref().map_or("none (every pixel)".to_string(), |m| m.display().to_string())),
        ("identical", if d.identical { "yes (bitwise)" } else { "no" }.to_string()),
    ];
    let mut out: String = rows.iter().map(|(k, v)| format!("{k:<17} {v}\n")).collect();
    if let Some(h) = &args.heatmap {
        out += &format!("{:<17} {}\n", "heat map", h.display());
    }
    out
}
