//! # magg-proto: the cluster protocol
//!
//! The gRPC services of magg's processes (`Fork`, `Host`) and their messages, generated
//! from `proto/magg/v1/magg.proto` by tonic and prost at build time (with protox, so no
//! system `protoc`), plus the one place where protobuf messages are converted to and from
//! the rendering core's types ([`convert`]). Prost types never enter `magg-core`.
//!
//! ```no_run
//! use magg_proto::v1::fork_client::ForkClient;
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! let mut fork = ForkClient::connect("http://127.0.0.1:7100").await?;
//! let reply = fork.get_blocks(magg_proto::v1::GetBlocksRequest { ids: vec![0, 1] }).await?;
//! # Ok(()) }
//! ```

pub mod allocator;
pub mod auth;
pub mod convert;
pub mod deposits;
pub mod lifecycle;
pub mod tls;
pub mod transport;

/// Generated code of package `magg.v1`.
#[allow(missing_docs, clippy::all)]
pub mod v1 {
    tonic::include_proto!("magg.v1");
}

/// `e` and its sources on one line, `: `-separated (a transport error says little by
/// itself: the reason, e.g. "connection refused", is in its sources).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

/// The host's answer (`UNAVAILABLE`) to a node that registers after the render ended.
pub const RENDER_OVER: &str = "the render is over: this host takes no more nodes";

/// Version of the protocol; processes with another version are refused at registration.
/// 3: a batch's deposits on a fork are packed arrays and may carry the next `TakePairs`
/// ([`deposits`]); 2: packed deposits per pair, `Replay` names the lost fork.
pub const PROTOCOL_VERSION: u32 = 3;
