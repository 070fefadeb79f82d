//! How every magg process starts and stops, the same in all three binaries: first it
//! keeps the memory it frees, loads its TLS files and, asked to `probe ADDR`, probes
//! ([`start`]); it stops on Ctrl-C or SIGTERM (in a container the binary is PID 1, which
//! the kernel gives no default signal action: without a handler, `docker stop` would wait
//! and then kill).
//!
//! ```no_run
//! # async fn f() {
//! // Serve until Ctrl-C or SIGTERM:
//! magg_plumbing::lifecycle::shutdown_signal().await;
//! # }
//! ```

use crate::flags::{ClusterArgs, ProbeCommand};
use std::process::ExitCode;

/// What a cluster process does first: keeps the memory it frees
/// ([`crate::allocator`]), puts its TLS files in force and, when asked to `probe ADDR`,
/// probes. `Some(code)` means: exit with it now.
pub fn start(program: &str, cluster: &ClusterArgs, command: &Option<ProbeCommand>) -> Option<ExitCode> {
    crate::allocator::keep_freed_memory();
    if let Err(e) = crate::tls::install_files(&cluster.tls) {
        return Some(crate::logging::fail(program, e));
    }
    match command {
        Some(ProbeCommand::Probe(p)) => Some(crate::health::probe_command(program, p)),
        None => None,
    }
}

/// The whole `main` of a serving cluster process (magg-fork, magg-node): [`start`], the
/// log set-up at `cluster.verbose`, then `run`. An error ends the process with its one
/// error line (`PROGRAM: error: ...`, causes included) and the failure exit code.
pub fn main<E: std::fmt::Display>(
    program: &str,
    cluster: &ClusterArgs,
    command: &Option<ProbeCommand>,
    run: impl FnOnce() -> Result<(), E>,
) -> ExitCode {
    if let Some(code) = start(program, cluster, command) {
        return code;
    }
    crate::logging::init(program, cluster.verbose);
    if !cluster.serve_on {
        exit_when_orphaned(program);
    }
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => crate::logging::fail(program, format_args!("{e:#}")),
    }
}

/// Watches this process's parent: when it is gone (the process is re-parented), says so
/// and exits with the failure code, within a second. Does nothing when the parent is
/// init or there is none (a daemon, a container's first process: nothing to outlive).
pub fn exit_when_orphaned(program: &str) {
    #[cfg(unix)]
    {
        let parent = std::os::unix::process::parent_id();
        if parent <= 1 {
            return;
        }
        let program = program.to_string();
        let watch = move || loop {
            std::thread::sleep(std::time::Duration::from_millis(500));
            if std::os::unix::process::parent_id() != parent {
                let why = format!("the process that started it (pid {parent}) is gone; --serve-on keeps serving");
                crate::logging::fail(&program, why);
                std::process::exit(1);
            }
        };
        if let Err(e) = std::thread::Builder::new().name("orphan-watch".into()).spawn(watch) {
            tracing::warn!("cannot watch the parent process: {e}");
        }
    }
    #[cfg(not(unix))]
    let _ = program;
}

/// Which signal asked the process to stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// Ctrl-C (SIGINT).
    Interrupt,
    /// SIGTERM (`docker stop`, `kill`, Kubernetes).
    Terminate,
}

impl Stop {
    /// The shell's exit status for a process ended by this signal: 128 + its number
    /// (130 for SIGINT, 143 for SIGTERM).
    pub fn exit_code(self) -> i32 {
        match self {
            Stop::Interrupt => 130,
            Stop::Terminate => 143,
        }
    }
}

/// Registers for Ctrl-C and (on Unix) SIGTERM at once, and returns a future that
/// completes when either arrives. Call it inside a tokio runtime.
pub fn shutdown_signal() -> impl std::future::Future<Output = ()> {
    let stop = stop_signal();
    async move {
        stop.await;
        tracing::info!("shutting down");
    }
}

/// Like [`shutdown_signal`], and says which of the two signals came.
pub fn stop_signal() -> impl std::future::Future<Output = Stop> {
    #[cfg(unix)]
    let signals = {
        use tokio::signal::unix::{signal, SignalKind};
        (signal(SignalKind::interrupt()), signal(SignalKind::terminate()))
    };
    async move {
        #[cfg(unix)]
        match signals {
            (Ok(mut int), Ok(mut term)) => {
                tokio::select! {
                    _ = int.recv() => Stop::Interrupt,
                    _ = term.recv() => Stop::Terminate,
                }
            }
            (Err(e), _) | (_, Err(e)) => {
                tracing::warn!("cannot wait for Ctrl-C or SIGTERM: {e}");
                std::future::pending::<Stop>().await
            }
        }
        #[cfg(not(unix))]
        match tokio::signal::ctrl_c().await {
            Ok(()) => Stop::Interrupt,
            Err(e) => {
                tracing::warn!("cannot wait for Ctrl-C: {e}");
                std::future::pending::<Stop>().await
            }
        }
    }
}

/// For a process with nothing to finish on the way out (a node, which keeps no state of
/// its own): a thread that exits the process with `code` on Ctrl-C or SIGTERM, saying so
/// on stderr. The signals are registered before this returns.
pub fn exit_on_signal(program: &'static str, code: i32) -> std::io::Result<()> {
    on_signal(program, move |_| {
        eprintln!("{program}: stopped by a signal");
        code
    })
}

/// A thread that, on Ctrl-C or SIGTERM, runs `last_words` (which may save what the
/// process has, and says what it did) and exits the process with the code it returns.
/// The signals are registered before this returns. A host uses it to write the partial
/// image of an interrupted render.
pub fn on_signal(program: &str, last_words: impl FnOnce(Stop) -> i32 + Send + 'static) -> std::io::Result<()> {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let signal = {
        let _context = runtime.enter();
        stop_signal()
    };
    std::thread::Builder::new().name(format!("{program}-signals")).spawn(move || {
        let stop = runtime.block_on(signal);
        std::process::exit(last_words(stop));
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_are_the_shells() {
        assert_eq!(Stop::Interrupt.exit_code(), 130);
        assert_eq!(Stop::Terminate.exit_code(), 143);
    }
}
