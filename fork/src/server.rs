//! Serving the `Fork` service (and gRPC health): the tonic server with the cluster's
//! limits ([`magg_plumbing::net`]), on a listener the caller binds (so tests and the
//! embedded cluster can use port 0).

use crate::service::ForkService;
use magg_plumbing::auth::{CheckToken, Token};
use magg_plumbing::{net, with_message_limits};
use magg_proto::v1::fork_server::ForkServer;
use std::future::Future;
use std::sync::Arc;
use tokio::net::TcpListener;
use tonic::service::interceptor::InterceptedService;

/// The tonic service of `service`, with the cluster's message size limits
/// ([`net::MAX_MESSAGE_BYTES`]: `LoadShard` carries a whole shard), refusing calls without
/// the cluster `token` (when one is set). What a socket serves, and what the in-process
/// transport ([`magg_plumbing::transport::register`]) calls.
pub fn fork_server(
    service: impl Into<Arc<ForkService>>,
    token: Token,
) -> InterceptedService<ForkServer<ForkService>, CheckToken> {
    let server = with_message_limits!(ForkServer::from_arc(service.into()));
    InterceptedService::new(server, CheckToken { token, server: "fork" })
}

/// Serves a fresh [`ForkService`] on `listener` until `shutdown` completes, then finishes
/// the requests in flight and returns. Every call must carry the cluster `token` (when
/// one is set), and calls to other forks carry it.
pub async fn serve(
    listener: TcpListener,
    token: Token,
    shutdown: impl Future<Output = ()>,
) -> Result<(), tonic::transport::Error> {
    serve_service(ForkService::with_token(token.clone()), token, listener, shutdown).await
}

/// Serves `service` on `listener` until `shutdown` completes, checking `token` on the
/// fork's calls, with the standard gRPC health service beside it (open to all: SERVING
/// from the start, a fork is ready for its shard).
pub async fn serve_service(
    service: impl Into<Arc<ForkService>>,
    token: Token,
    listener: TcpListener,
    shutdown: impl Future<Output = ()>,
) -> Result<(), tonic::transport::Error> {
    let (health, health_service) = magg_plumbing::health::health_service();
    health.set_serving::<ForkServer<ForkService>>().await;
    net::server()?
        .add_service(health_service)
        .add_service(fork_server(service, token))
        .serve_with_incoming_shutdown(net::nodelay_incoming(listener), shutdown)
        .await
}
