//! Serving the `Fork` service (and gRPC health): the tonic server with the fork's message
//! size limits, on a listener the caller binds (so tests and the embedded cluster can use port 0).

use crate::service::ForkService;
use magg_proto::v1::fork_server::ForkServer;
use std::future::Future;
use tokio::net::TcpListener;
use tokio_stream::wrappers::TcpListenerStream;
use tokio_stream::StreamExt;

/// Largest message a fork accepts or sends: `LoadShard` carries a whole shard, and a
/// `GetBlocks` reply up to 4096 blocks (8 MiB).
pub const MAX_MESSAGE_BYTES: usize = 256 << 20;

/// The tonic service of `service`, with the size limits applied.
pub fn fork_server(service: ForkService) -> ForkServer<ForkService> {
    ForkServer::new(service).max_decoding_message_size(MAX_MESSAGE_BYTES).max_encoding_message_size(MAX_MESSAGE_BYTES)
}

/// Serves a fresh [`ForkService`] on `listener` until `shutdown` completes, then finishes
/// the requests in flight and returns.
pub async fn serve(listener: TcpListener, shutdown: impl Future<Output = ()>) -> Result<(), tonic::transport::Error> {
    serve_service(ForkService::new(), listener, shutdown).await
}

/// Serves `service` on `listener` until `shutdown` completes, with the standard gRPC
/// health service beside it (SERVING from the start: a fork is ready for its shard).
pub async fn serve_service(
    service: ForkService,
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
    tonic::transport::Server::builder()
        .initial_stream_window_size(Some(4 << 20))
        .initial_connection_window_size(Some(16 << 20))
        .tcp_nodelay(true)
        .add_service(health_service)
        .add_service(fork_server(service))
        .serve_with_incoming_shutdown(incoming, shutdown)
        .await
}
