//! `magg-host`: render a scene on the cluster (in this process by default), or describe it.
//!
//! ```text
//! magg-host render scenes/cornell.toml --out cornell.png
//! magg-host info scenes/magg-paper.toml
//! ```

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = magg_host::cli::Cli::parse();
    magg_host::logging::init(cli.verbose);
    match magg_host::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("magg-host: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
