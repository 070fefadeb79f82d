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

/// Version of the protocol; processes with another version are refused at registration.
/// 15: a batch's deposits, a fork's energies and a `TakePairs` reply's pairs are declared
/// as `bytes` holding their packed fields (the same bytes on the wire), and a
/// `TakePairsRequest` may ask for the answering fork's own pairs only (`own_only`, on the
/// completion of stolen pairs, to the fork that lent them);
/// 14: BVH node records hold eight children (256 bytes, 8 records per node block);
/// 13: a registration says whether its session is one of refinement's pilot light passes
/// or a light pass that bins the pilots' kept pairs (`pilot_pairs`), and a DONE may say
/// that another scene of the render follows (`next_scene`: the node registers again);
/// 12: a registration may carry the key of refinement's pilot pairs shared in the
/// host's process (`kept_pairs`); 11: render settings carry `gather_rays` (gather rays per viewing ray beside unlit elements), and a
/// vertex-energy record's first channel its gather mark (sign bit); 10: render settings carry `bounce_rays` (bounce rays per light ray); 9: BVH node records hold four children (16 records per node block), patch records
/// their back element and render settings whether the faces share elements
/// (`shared_faces`); 8: materials carry their emitted radiance (`emit`), the scene header its emitting
/// elements (`emitters`, LRT's light sources after the point lights) and textures, the
/// effects plan whether it has area lights (`area_lights`), the block layout shading
/// blocks (corner normals and texture coordinates) and texture blocks, and `GetEnergies`
/// may ask for a monitoring snapshot (`monitor`: energies that cost the modelled machine
/// nothing, for the live view's preview during LRT); 7: render settings say where direct light is computed and the effects plan whether
/// VRT computes it (`direct`, `direct_vrt`), materials whether they are one-sided; 6: `TakePairs` carries the node's secret, a keyed hash of its id under the render's
/// node key, which `LoadShard` brings the forks; 5: a node's host requests carry the
/// secret its registration gave it; 4: `GetEnergies`
/// replies carry the ledger's digests, checked by the host before it interpolates; 3: a
/// batch's deposits on a fork are packed arrays and may carry the next `TakePairs`
/// ([`deposits`]); 2: packed deposits per pair, `Replay` names the lost fork.
pub const PROTOCOL_VERSION: u32 = 15;
