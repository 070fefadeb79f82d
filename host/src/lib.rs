//! # magg-host: the host process of magg
//!
//! Reads a scene, preprocesses it, runs the render phases and writes the image, the
//! stats and the energies. `magg-host render SCENE --out IMAGE` runs the whole cluster
//! inside this process (the embedded renderer of `magg-core`), so one command renders a
//! scene with no set-up.

pub mod accuracy;
pub mod cli;
pub mod cluster;
pub mod commands;
pub mod energy_csv;
pub mod images;
pub mod logging;
pub mod progress;
pub mod scene_file;

/// Runs a parsed command line.
pub fn run(cli: cli::Cli) -> anyhow::Result<()> {
    match cli.command {
        cli::Command::Render(args) => commands::render::run(args.validate()?),
        cli::Command::Info(args) => commands::info::run(&args),
        cli::Command::Accuracy(args) => commands::accuracy::run(&args),
    }
}
