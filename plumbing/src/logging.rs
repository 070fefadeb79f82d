//! Logging set-up, the same in the three binaries: one format (time, level, target,
//! message, on stderr), one default level, and colour only where a person reads it.
//!
//! The default is warnings and errors only, for every program: a host run from a shell
//! prints its progress and summary itself and must keep a user error to one line, and a
//! fork or node in a container should log what needs attention, not every request. `-v`
//! shows magg's info lines (a node's registration, the host's cluster address), `-vv`
//! its debug lines (stage timelines, where a node's time went), `-vvv` everything magg
//! traces; other crates (tonic, h2, hyper) stay at warnings. `RUST_LOG`, when set and
//! valid, replaces all of this (e.g. `RUST_LOG=magg_node=debug`): a comma-separated list
//! of `target=level` and a bare default `level`, targets matched by prefix (the
//! `Targets` filter; span and field filters are not taken, which keeps the regex engine
//! out of every binary).
//!
//! ANSI colour is used only when stderr is a terminal and `NO_COLOR` is unset or empty
//! (<https://no-color.org>): log files, pipes and container logs get plain text.
//!
//! ```no_run
//! let verbose = 1; // from `-v`
//! magg_plumbing::logging::init("magg-fork", verbose);
//! tracing::info!("shown with -v");
//! ```

use std::ffi::OsStr;
use std::io::IsTerminal;
use std::process::ExitCode;
use tracing_subscriber::filter::Targets;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;

/// Environment variable that, set to anything but the empty string, turns colour off.
pub const NO_COLOR_ENV: &str = "NO_COLOR";

/// The filter of `verbosity` (the count of `-v`) when `RUST_LOG` does not say: see the
/// module doc.
pub fn default_filter(verbosity: u8) -> String {
    match verbosity {
        0 => "warn".to_string(),
        1 => "warn,magg=info".to_string(),
        2 => "warn,magg=debug".to_string(),
        _ => "warn,magg=trace".to_string(),
    }
}

/// True when log lines may carry ANSI colour: stderr is a terminal and `NO_COLOR` (its
/// value `no_color`) is unset or empty.
pub fn use_colour(stderr_is_terminal: bool, no_color: Option<&OsStr>) -> bool {
    stderr_is_terminal && no_color.is_none_or(|v| v.is_empty())
}

/// Starts the tracing subscriber of `program` on stderr at `verbosity` (see the module
/// doc). A malformed `RUST_LOG` is reported on one line and the default used. A second
/// call (a test, the in-process harness) leaves the first subscriber in place.
pub fn init(program: &str, verbosity: u8) {
    let filter = match std::env::var("RUST_LOG") {
        Ok(spec) if !spec.is_empty() => spec.parse::<Targets>().unwrap_or_else(|e| {
            eprintln!("{program}: RUST_LOG={spec:?} ignored ({e})");
            default_targets(verbosity)
        }),
        _ => default_targets(verbosity),
    };
    let colour = use_colour(std::io::stderr().is_terminal(), std::env::var_os(NO_COLOR_ENV).as_deref());
    let format = tracing_subscriber::fmt::layer().with_ansi(colour).with_writer(std::io::stderr);
    let _ = tracing_subscriber::registry().with(format).with(filter).try_init();
}

/// [`default_filter`] parsed.
fn default_targets(verbosity: u8) -> Targets {
    default_filter(verbosity).parse().unwrap_or_default()
}

/// Prints `error` as a binary's one error line, `PROGRAM: error: ...`, and returns the
/// failure exit code: how every magg binary ends on an error.
pub fn fail(program: &str, error: impl std::fmt::Display) -> ExitCode {
    eprintln!("{program}: error: {error}");
    ExitCode::FAILURE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_only_on_a_terminal_without_no_color() {
        assert!(use_colour(true, None));
        assert!(use_colour(true, Some(OsStr::new(""))), "an empty NO_COLOR does not count");
        assert!(!use_colour(true, Some(OsStr::new("1"))));
        assert!(!use_colour(false, None), "a file or pipe gets no escapes");
        assert!(!use_colour(false, Some(OsStr::new("1"))));
    }

    #[test]
    fn every_default_filter_parses_and_only_magg_gets_louder() {
        for v in 0..5 {
            let f = default_filter(v);
            assert!(f.parse::<Targets>().is_ok(), "{f}");
            assert!(f.starts_with("warn"), "{f}");
        }
        assert_eq!(default_filter(0), "warn");
        assert_eq!(default_filter(2), "warn,magg=debug");
    }

    #[test]
    fn magg_targets_are_matched_by_prefix_and_others_stay_at_warnings() {
        use tracing::Level;
        let t = default_targets(2);
        assert!(t.would_enable("magg_node::work", &Level::DEBUG));
        assert!(!t.would_enable("magg_node::work", &Level::TRACE));
        assert!(!t.would_enable("h2::codec", &Level::INFO));
        assert!(t.would_enable("h2::codec", &Level::WARN));
        let spec: Targets = "magg_host=debug".parse().unwrap();
        assert!(spec.would_enable("magg_host::render", &Level::DEBUG));
        assert!(!spec.would_enable("magg_fork", &Level::ERROR), "a target not named is off");
    }
}
