//! # magg-proto: the cluster protocol
//!
//! The gRPC services of magg's processes (`Fork`, `Host`) and their messages, generated
//! from `proto/magg/v1/magg.proto` by tonic and prost at build time (with protox, so no
//! system `protoc`), plus the one place where protobuf messages are converted to and from
//! the rendering core's types ([`convert`]). Prost types never enter `magg-core`. How a
//! process serves and reaches these services (limits, TLS, token, transport) is
//! `magg-plumbing`'s job.
//!
//! ```no_run
//! use magg_proto::v1::fork_client::ForkClient;
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! let mut fork = ForkClient::connect("http://127.0.0.1:7100").await?;
//! let reply = fork.get_blocks(magg_proto::v1::GetBlocksRequest { ids: vec![0, 1] }).await?;
//! # Ok(()) }
//! ```

pub mod codec;
pub mod convert;
pub mod deposits;
pub mod packed;

/// Generated code of package `magg.v1`.
#[allow(missing_docs, clippy::all)]
pub mod v1 {
    tonic::include_proto!("magg.v1");
}

/// The host's answer (`UNAVAILABLE`) to a node that registers after the render ended.
pub const RENDER_OVER: &str = "the render is over: this host takes no more nodes";

/// The host's answer (`UNAVAILABLE`) to a node that registers between two scenes of one
/// render (refinement's pilot levels, then the render): the node registers again shortly.
pub const NEXT_SCENE: &str = "the host is preparing the next scene of the render: register again";

/// A fork's answer (`UNAVAILABLE`) to any call but `LoadShard` before it holds a shard: it
/// has just started or restarted. Callers retry; the host, seeing it from a fork it had
/// loaded, knows the fork restarted and loads it again.
pub const NOT_LOADED: &str = "no scene loaded";

/// Version of the wire protocol: a node's registration or a fork's `LoadShard` of another
/// version is refused (`FAILED_PRECONDITION`). Its history is in CHANGELOG.md.
pub const PROTOCOL_VERSION: u32 = 16;
