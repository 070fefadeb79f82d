//! Serving the `Fork` service (and gRPC health): the tonic server with the fork's message
//! size limits, on a listener the caller binds (so tests and the embedded cluster can use port 0).

use crate::service::ForkService;
use magg_proto::auth::{CheckToken, Token};
use magg_proto::v1::fork_server::ForkServer;
use std::future::Future;
use std::sync::Arc;
use tokio::net::TcpListener;
use tokio_stream::wrappers::TcpListenerStream;
use tokio_stream::StreamExt;
use tonic::service::interceptor::InterceptedService;

/// Largest message a fork accepts or sends: `LoadShard` carries a whole shard, and a
/// `GetBlocks` reply up to 4096 blocks (8 MiB).
pub const MAX_MESSAGE_BYTES: usize = 256 << 20;

/// The tonic service of `service`, with the size limits applied, refusing calls without
/// the cluster `token` (when one is set). What a socket serves, and what the in-process
/// transport ([`magg_proto::transport::register`]) calls.
pub fn fork_server(
    service: impl Into<Arc<ForkService>>,
    token: Token,
) -> InterceptedService<ForkServer<ForkService>, CheckToken> {
    let server = ForkServer::from_arc(service.into())
        .max_decoding_message_size(MAX_MESSAGE_BYTES)
        .max_encoding_message_size(MAX_MESSAGE_BYTES);
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
    // Nagle's algorithm off on every accepted connection: the protocol is many small
    // request/reply pairs (`Server::tcp_nodelay` only applies to listeners tonic binds).
    let incoming = TcpListenerStream::new(listener).map(|r| {
        r.inspect(|s| {
            let _ = s.set_nodelay(true);
        })
    });
    let (health, health_service) = magg_proto::lifecycle::health_service();
    health.set_serving::<ForkServer<ForkService>>().await;
    magg_proto::tls::server_builder()?
        .initial_stream_window_size(Some(4 << 20))
        .initial_connection_window_size(Some(16 << 20))
        .tcp_nodelay(true)
        .add_service(health_service)
        .add_service(fork_server(service, token))
        .serve_with_incoming_shutdown(incoming, shutdown)
        .await
}
