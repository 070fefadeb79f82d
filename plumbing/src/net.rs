//! One set of network limits for every gRPC server and channel of a cluster, and the two
//! builders that apply them: [`server`] and [`endpoint`]. A fork, a node and a host that
//! build their connections here agree on window sizes, message sizes and Nagle.
//!
//! Message size limits are set per generated client or server type (tonic has no trait
//! for them): wrap each in [`with_message_limits!`](crate::with_message_limits).
//!
//! ```no_run
//! # async fn f(listener: tokio::net::TcpListener) -> Result<(), Box<dyn std::error::Error>> {
//! use magg_plumbing::{net, with_message_limits};
//! let (_reporter, health) = magg_plumbing::health::health_service();
//! let server = net::server()?.add_service(with_message_limits!(health));
//! tokio::spawn(server.serve_with_incoming(net::nodelay_incoming(listener)));
//! let channel = net::endpoint("127.0.0.1:7100")?.connect().await?; // TLS when installed
//! # Ok(()) }
//! ```

use tokio::net::{TcpListener, TcpStream};
use tokio_stream::wrappers::TcpListenerStream;
use tokio_stream::{Stream, StreamExt};
use tonic::transport::{Endpoint, Server};

/// Largest message any magg service accepts or sends, both ways, on every server and
/// client. The largest legitimate message is a `LoadShard` request: the host uploads a
/// fork's whole shard in one call (scene blocks plus vertex-energy blocks; all of them
/// with `--forks 1`). A scene at the default memory bound (`--max-memory-mb 4096`, at
/// 400 bytes per element: about 10 million elements) has about 50 bytes of blocks per
/// element (a 32-byte element record, a 12-byte vertex record, its share of patch and
/// subspace blocks), so about 512 MiB: the limit the host already sent shards with.
/// Every other message is far smaller (a `GetBlocks` reply of at most 4096 blocks is
/// 8 MiB; a subscreen's pixel rows a few MiB). A limit is a bound, not an allocation:
/// the same number for every service costs nothing and leaves no pair of peers that
/// disagree (before, the fork decoded 256 MiB, the host's server 16 MiB, a node's fork
/// clients 64 MiB).
pub const MAX_MESSAGE_BYTES: usize = 512 << 20;

/// HTTP/2 window of one stream: a `GetBlocks` reply (up to 8 MiB) flows without waiting
/// for a `WINDOW_UPDATE` round trip per 64 KiB, HTTP/2's default.
pub const STREAM_WINDOW_BYTES: u32 = 4 << 20;

/// HTTP/2 window of a connection, shared by its streams (a node's workers share one
/// connection to each fork).
pub const CONNECTION_WINDOW_BYTES: u32 = 16 << 20;

/// Sets [`MAX_MESSAGE_BYTES`] as the decoding and encoding limit of a generated tonic
/// client or server (`ForkClient`, `HostServer`, ...), which each have these methods but
/// share no trait.
///
/// ```no_run
/// # async fn f(ch: tonic::transport::Channel) {
/// let fork = magg_plumbing::with_message_limits!(magg_proto::v1::fork_client::ForkClient::new(ch));
/// # }
/// ```
#[macro_export]
macro_rules! with_message_limits {
    ($service:expr) => {
        $service
            .max_decoding_message_size($crate::net::MAX_MESSAGE_BYTES)
            .max_encoding_message_size($crate::net::MAX_MESSAGE_BYTES)
    };
}

/// A server builder with the cluster's windows and Nagle off, serving TLS with the
/// installed identity when there is one ([`crate::tls`]). Serve it on
/// [`nodelay_incoming`] when the caller binds the listener.
pub fn server() -> Result<Server, tonic::transport::Error> {
    Ok(crate::tls::server_builder()?
        .initial_stream_window_size(Some(STREAM_WINDOW_BYTES))
        .initial_connection_window_size(Some(CONNECTION_WINDOW_BYTES))
        .tcp_nodelay(true))
}

/// An endpoint to `addr` (`HOST:PORT` or a URI; https and CA-verified when TLS is
/// installed) with the cluster's windows and Nagle off. Callers add their timeouts.
pub fn endpoint(addr: &str) -> Result<Endpoint, tonic::transport::Error> {
    Ok(crate::tls::endpoint(addr)?
        .tcp_nodelay(true)
        .initial_stream_window_size(Some(STREAM_WINDOW_BYTES))
        .initial_connection_window_size(Some(CONNECTION_WINDOW_BYTES)))
}

/// The connections accepted on `listener`, Nagle's algorithm off on each: the protocol
/// is many small request/reply pairs, and `Server::tcp_nodelay` only reaches listeners
/// that tonic binds itself.
pub fn nodelay_incoming(listener: TcpListener) -> impl Stream<Item = std::io::Result<TcpStream>> {
    TcpListenerStream::new(listener).map(|r| {
        r.inspect(|s| {
            let _ = s.set_nodelay(true);
        })
    })
}
