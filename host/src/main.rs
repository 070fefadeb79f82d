//! `magg-host`: render a scene on the cluster (in this process by default), describe it, or compare two images.
//!
//! ```text
//! magg-host render scenes/cornell.toml --out cornell.png
//! magg-host info scenes/magg-paper.toml
//! magg-host diff magg.exr reference.exr --heatmap error.png
//! magg-host probe 127.0.0.1:7000
//! ```

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    magg_plumbing::allocator::keep_freed_memory();
    let cli = magg_host::cli::Cli::parse();
    if let magg_host::cli::Command::Probe(p) = &cli.command {
        return magg_plumbing::health::probe_command("magg-host", p);
    }
    magg_plumbing::logging::init("magg-host", cli.verbose);
    // In a container the host is PID 1, which has no default action for SIGTERM. A
    // render stopped by a signal leaves its image so far beside --out (never as --out).
    let partial = magg_host::partial::Slot::default();
    let last_words = {
        let partial = partial.clone();
        move |stop| partial.last_words(stop)
    };
    if let Err(e) = magg_plumbing::lifecycle::on_signal("magg-host", last_words) {
        eprintln!("magg-host: cannot watch for signals: {e}");
    }
    match magg_host::run(cli, &partial) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<magg_host::commands::diff::AboveLimit>() => {
            eprintln!("magg-host: {e}");
            ExitCode::from(2)
        }
        Err(e) => magg_plumbing::logging::fail("magg-host", format_args!("{e:#}")),
    }
}
