//! What every magg process does around its gRPC services, the same in all three binaries:
//! it serves the standard gRPC health service (`grpc.health.v1.Health`, so that Docker,
//! Kubernetes and any gRPC tool can tell a live process from a wedged one), it can probe
//! another process's health service (the `probe ADDR` subcommand: a HEALTHCHECK for
//! images built `FROM scratch`, which have no shell and no curl), and it stops on Ctrl-C
//! or SIGTERM (in a container the binary is PID 1, which the kernel gives no default
//! signal action: without a handler, `docker stop` would wait and then kill).
//!
//! ```no_run
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! // Serve health (and the process's own services) on one server:
//! let (reporter, health) = magg_proto::lifecycle::health_service();
//! // tonic::transport::Server::builder().add_service(health).add_service(...)
//! // Ask a running fork:
//! let status = magg_proto::lifecycle::probe("127.0.0.1:7100", std::time::Duration::from_secs(3)).await?;
//! assert_eq!(status, magg_proto::lifecycle::ServingStatus::Serving);
//! # Ok(()) }
//! ```

use std::process::ExitCode;
use std::time::Duration;
use tonic_health::pb::health_check_response::ServingStatus as WireStatus;
use tonic_health::pb::health_client::HealthClient;
use tonic_health::pb::HealthCheckRequest;

pub use tonic_health::server::HealthReporter;
pub use tonic_health::ServingStatus;

/// The health service of one server and the reporter that sets its statuses. The whole
/// server (service name "") starts SERVING; a process marks its own services with
/// [`HealthReporter::set_serving`].
pub fn health_service(
) -> (HealthReporter, tonic_health::pb::health_server::HealthServer<impl tonic_health::pb::health_server::Health>) {
    tonic_health::server::health_reporter()
}

/// Serves only the health service on `listener` (SERVING) until `shutdown` completes: for
/// a process that serves nothing else (a node), so that it can be health-checked too.
pub async fn serve_health(
    listener: tokio::net::TcpListener,
    shutdown: impl std::future::Future<Output = ()>,
) -> Result<(), tonic::transport::Error> {
    let (_reporter, health) = health_service();
    crate::tls::server_builder()?
        .add_service(health)
        .serve_with_incoming_shutdown(tokio_stream::wrappers::TcpListenerStream::new(listener), shutdown)
        .await
}

/// Why a probe got no status.
#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    /// The address is not a valid URI.
    #[error("{addr}: not an address ({reason})")]
    Address {
        /// The address probed.
        addr: String,
        /// The parser's complaint.
        reason: String,
    },
    /// Nothing answered at the address.
    #[error("{addr}: cannot connect ({reason})")]
    Connect {
        /// The address probed.
        addr: String,
        /// The transport's error.
        reason: String,
    },
    /// The process answered, but not with a health status.
    #[error("{addr}: health check failed ({status})")]
    Rpc {
        /// The address probed.
        addr: String,
        /// The gRPC status it returned.
        status: tonic::Status,
    },
    /// The process answered with another status than SERVING.
    #[error("{addr}: {status:?}")]
    NotServing {
        /// The address probed.
        addr: String,
        /// What it reported.
        status: ServingStatus,
    },
}

/// Asks the health service at `addr` (`HOST:PORT` or a URI) for the whole server's status
/// (service ""), giving up after `timeout`.
pub async fn probe(addr: &str, timeout: Duration) -> Result<ServingStatus, ProbeError> {
    let endpoint = crate::tls::endpoint(addr)
        .map_err(|e| ProbeError::Address { addr: addr.to_string(), reason: e.to_string() })?
        .connect_timeout(timeout)
        .timeout(timeout);
    let channel = endpoint
        .connect()
        .await
        .map_err(|e| ProbeError::Connect { addr: addr.to_string(), reason: crate::error_chain(&e) })?;
    let reply = HealthClient::new(channel)
        .check(HealthCheckRequest { service: String::new() })
        .await
        .map_err(|status| ProbeError::Rpc { addr: addr.to_string(), status })?
        .into_inner();
    Ok(match WireStatus::try_from(reply.status) {
        Ok(WireStatus::Serving) => ServingStatus::Serving,
        Ok(WireStatus::NotServing) => ServingStatus::NotServing,
        _ => ServingStatus::Unknown,
    })
}

/// Arguments of the `probe` subcommand of every binary.
#[derive(Debug, clap::Args)]
pub struct ProbeArgs {
    /// Address to probe (HOST:PORT): a magg-fork, a magg-node with --health-listen, or a
    /// magg-host while it renders.
    pub addr: String,
    /// PEM CA to verify a TLS server against (the cluster's --tls-ca): the probe then
    /// speaks TLS.
    #[arg(long = "tls-ca", env = "MAGG_TLS_CA", value_name = "FILE")]
    pub tls_ca: Option<std::path::PathBuf>,
}

/// The subcommands of a binary whose only one is `probe` (magg-fork, magg-node).
#[derive(Debug, clap::Subcommand)]
pub enum ProbeCommand {
    /// Ask the gRPC health service at ADDR and exit 0 when it reports SERVING: the health
    /// check of a container image that has no shell.
    Probe(ProbeArgs),
}

/// [`probe`] from synchronous code, with a 3-second limit: `Ok` only when the process at
/// `addr` reports SERVING.
pub fn probe_blocking(addr: &str) -> Result<(), ProbeError> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| ProbeError::Connect { addr: addr.to_string(), reason: format!("no runtime: {e}") })?;
    match runtime.block_on(probe(addr, Duration::from_secs(3)))? {
        ServingStatus::Serving => Ok(()),
        status => Err(ProbeError::NotServing { addr: addr.to_string(), status }),
    }
}

/// The flags every cluster process (magg-fork, magg-node) shares, flattened into each
/// binary's arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct ClusterArgs {
    /// Hardware profile (DESIGN.md §4): a built-in name (native, magg1993) or a profile
    /// file. The host sends each render's profile; with this flag the process refuses a
    /// render that runs another one. Without it, it runs the host's.
    #[arg(long, env = "MAGG_PROFILE")]
    pub profile: Option<String>,
    /// Cluster token: presented on every call, and required on every call a fork serves
    /// (the same on every process of the cluster). Without one, any client is served:
    /// keep the default 127.0.0.1 addresses then.
    #[arg(long, env = "MAGG_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// TLS: the certificate and key of what this process serves, and the CA its peers'
    /// certificates chain to (every connection is then https).
    #[command(flatten)]
    pub tls: crate::tls::TlsFiles,
}

/// What a cluster process does first: keeps the memory it frees
/// ([`crate::allocator`]), puts its TLS files in force and, when asked to `probe ADDR`,
/// probes. `Some(code)` means: exit with it now.
pub fn start(program: &str, cluster: &ClusterArgs, command: &Option<ProbeCommand>) -> Option<ExitCode> {
    crate::allocator::keep_freed_memory();
    if let Err(e) = crate::tls::install_files(&cluster.tls) {
        eprintln!("{program}: error: {e}");
        return Some(ExitCode::FAILURE);
    }
    match command {
        Some(ProbeCommand::Probe(p)) => Some(probe_command(program, p)),
        None => None,
    }
}

/// The `probe ADDR` subcommand of every binary: prints `ADDR: SERVING` and exits 0 when
/// the process at `addr` reports SERVING within 3 seconds; prints why not and exits 1
/// otherwise.
pub fn probe_command(program: &str, args: &ProbeArgs) -> ExitCode {
    let addr = &args.addr;
    if args.tls_ca.is_some() {
        // A process that installed its TLS files already keeps them (same CA flag).
        let files = crate::tls::TlsFiles { ca: args.tls_ca.clone(), ..Default::default() };
        if let Err(e) = crate::tls::install_files(&files) {
            eprintln!("{program}: error: {e}");
            return ExitCode::FAILURE;
        }
    }
    match probe_blocking(addr) {
        Ok(()) => {
            println!("{addr}: SERVING");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{program}: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Registers for Ctrl-C and (on Unix) SIGTERM at once, and returns a future that
/// completes when either arrives. Call it inside a tokio runtime.
pub fn shutdown_signal() -> impl std::future::Future<Output = ()> {
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
                    _ = int.recv() => {}
                    _ = term.recv() => {}
                }
            }
            (Err(e), _) | (_, Err(e)) => {
                tracing::warn!("cannot wait for Ctrl-C or SIGTERM: {e}");
                std::future::pending::<()>().await;
            }
        }
        #[cfg(not(unix))]
        if let Err(e) = tokio::signal::ctrl_c().await {
            tracing::warn!("cannot wait for Ctrl-C: {e}");
            std::future::pending::<()>().await;
        }
        tracing::info!("shutting down");
    }
}

/// For a process with nothing to finish on the way out (a node, which keeps no state of
/// its own; a host, whose render is lost anyway): a thread that exits the
/// process with `code` on Ctrl-C or SIGTERM, saying so on stderr. The signals are
/// registered before this returns.
pub fn exit_on_signal(program: &'static str, code: i32) -> std::io::Result<()> {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let signal = {
        let _context = runtime.enter();
        shutdown_signal()
    };
    std::thread::Builder::new().name(format!("{program}-signals")).spawn(move || {
        runtime.block_on(signal);
        eprintln!("{program}: stopped by a signal");
        std::process::exit(code);
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn probe_reads_serving_and_names_an_address_that_does_not_answer() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let server = tokio::spawn(serve_health(listener, async {
            stopped.await.ok();
        }));
        assert_eq!(probe(&addr, Duration::from_secs(3)).await.unwrap(), ServingStatus::Serving);
        stop.send(()).unwrap();
        server.await.unwrap().unwrap();
        let err = probe(&addr, Duration::from_secs(1)).await.unwrap_err();
        assert!(matches!(err, ProbeError::Connect { .. }), "{err}");
        assert!(err.to_string().contains(&addr), "{err}");
    }
}
