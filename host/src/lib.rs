//! # magg-host: the host process of magg
//!
//! Reads a scene, preprocesses it, runs the render phases and writes the image, the
//! stats and the energies. `magg-host render SCENE --out IMAGE` runs the whole cluster
//! (forks, nodes and this host, over gRPC on 127.0.0.1) inside this process, so one
//! command renders a scene with no set-up ([`harness`]); the host library
//! (`magg-cluster`) also drives separate processes.

pub mod auto;
pub mod cli;
pub mod commands;
pub mod energy_csv;
pub mod faults;
pub mod frames;
pub mod framing;
pub mod harness;
pub mod image_diff;
pub mod images;
pub mod live;
pub mod memory;
pub mod mitsuba;
pub mod model_scene;
pub mod overrides;
pub mod partial;
pub mod progress;
pub mod saved_energy;
pub mod scene_file;

/// Runs a parsed command line. A render keeps its frame in progress in `partial`, which
/// the binary's signal handler saves (see [`partial`]).
pub fn run(cli: cli::Cli, partial: &partial::Slot) -> anyhow::Result<()> {
    let files = scene_file::SceneFiles::new(&cli.allow_path)?;
    match cli.command {
        cli::Command::Render(args) => commands::render::run(args.validate()?, &files, partial),
        cli::Command::Info(args) => commands::info::run(&args, &files),
        cli::Command::Accuracy(args) => commands::accuracy::run(&args, &files),
        cli::Command::Diff(args) => commands::diff::run(&args),
        cli::Command::Export(args) => commands::export::run(&args, &files),
        cli::Command::Sweep(args) => commands::sweep::run(&args, &cli.allow_path),
        cli::Command::Probe(p) => {
            magg_plumbing::health::probe_blocking(&p.addr)?;
            println!("{}: SERVING", p.addr);
            Ok(())
        }
    }
}
