//! The standard gRPC health service (`grpc.health.v1.Health`), served by every magg
//! process so that Docker, Kubernetes and any gRPC tool can tell a live process from a
//! wedged one, and the probe that asks another process's (the `probe ADDR` subcommand: a
//! HEALTHCHECK for images built `FROM scratch`, which have no shell and no curl).
//!
//! ```no_run
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! // Serve health (and the process's own services) on one server:
//! let (reporter, health) = magg_plumbing::health::health_service();
//! // magg_plumbing::net::server()?.add_service(health).add_service(...)
//! // Ask a running fork:
//! let status = magg_plumbing::health::probe("127.0.0.1:7100", std::time::Duration::from_secs(3)).await?;
//! assert_eq!(status, magg_plumbing::health::ServingStatus::Serving);
//! # Ok(()) }
//! ```

use crate::flags::ProbeArgs;
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
    crate::net::server()?
        .add_service(health)
        .serve_with_incoming_shutdown(crate::net::nodelay_incoming(listener), shutdown)
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
    let endpoint = crate::net::endpoint(addr)
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

/// The `probe ADDR` subcommand of every binary: prints `ADDR: SERVING` and exits 0 when
/// the process at `addr` reports SERVING within 3 seconds; prints why not and exits 1
/// otherwise.
pub fn probe_command(program: &str, args: &ProbeArgs) -> ExitCode {
    let addr = &args.addr;
    if args.tls_ca.is_some() {
        // A process that installed its TLS files already keeps them (same CA flag).
        let files = crate::tls::TlsFiles { ca: args.tls_ca.clone(), ..Default::default() };
        if let Err(e) = crate::tls::install_files(&files) {
            return crate::logging::fail(program, e);
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
