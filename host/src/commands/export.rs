//! `magg-host export --mitsuba SCENE --out DIR`: the scene written for Mitsuba 3
//! ([`crate::mitsuba`]), after `--set`, `--quality` and the knob flags, so that the
//! reference is of exactly the scene magg renders.
//!
//! ```text
//! magg-host export --mitsuba scenes/diffuse.toml --out /tmp/diffuse-mitsuba
//! python3 deploy/mitsuba-reference.py /tmp/diffuse-mitsuba --spp 1024 --out ref.exr
//! ```

use crate::scene_file;
use anyhow::bail;
use clap::Args;
use std::path::PathBuf;

/// Arguments of `export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Scene file (TOML) or model file.
    pub scene: PathBuf,
    /// Write Mitsuba 3's scene format (scene.xml and meshes/*.ply): the only target so far.
    #[arg(long)]
    pub mitsuba: bool,
    /// Directory to write into (created when missing).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Overrides of any scene value (`--set KEY=VALUE`).
    #[command(flatten)]
    pub set: crate::overrides::SetArgs,
    /// Quality preset applied first, as `render --quality` does.
    #[arg(long, value_enum)]
    pub quality: Option<magg_study::accuracy::preset::Quality>,
    /// The accuracy knobs, as `render` takes them (resolution, samples, ...).
    #[command(flatten)]
    pub knobs: crate::cli::Knobs,
}

/// Writes the scene and prints what the export could not carry.
pub fn run(args: &ExportArgs, files: &scene_file::SceneFiles) -> anyhow::Result<()> {
    if !args.mitsuba {
        bail!("export: say which format to write (--mitsuba)");
    }
    let mut scene = files.load(&args.scene, &args.set.overrides()?)?;
    if let Some(q) = args.quality {
        q.apply(&mut scene);
    }
    args.knobs.apply(&mut scene.settings)?;
    let notes = crate::mitsuba::write(&scene, &args.out)?;
    println!("wrote {}", args.out.join("scene.xml").display());
    for line in notes.lines {
        println!("note: {line}");
    }
    Ok(())
}
