//! # magg-cluster: the paper's host, as a library
//!
//! The host side of magg's cluster over gRPC: the `Host` service nodes talk to
//! ([`service`]), the subscreen queue with adaptive redivision ([`schedule`]), the set of
//! forks with their shards ([`forks`]), the fault policy ([`FaultPolicy`]), and the
//! cluster as a [`magg_core::machine::Machine`].
//!
//! [`ClusterMachine`] loads each fork with its shard of blocks (block b on fork b mod F),
//! serves the `Host` service to nodes, and runs each pass with a barrier (LRT until every
//! fork reports all of its pairs done, then the energies collected; VRT until every pixel
//! row is in). The phases are sequenced by [`magg_core::phases::run`], as for the
//! embedded renderer, so the output is bit for bit the same image and energies.
//!
//! Forks and nodes run either inside the calling process (`magg-host`'s single-process
//! harness: real gRPC, in-process transport or 127.0.0.1 ports) or as separate processes
//! (`--forks-at`, `--external-nodes`).
//!
//! ```no_run
//! # fn f(prepared: std::sync::Arc<magg_core::prepared::PreparedScene>, opts: magg_cluster::DriveOptions,
//! #      listener: tokio::net::TcpListener, rt: tokio::runtime::Runtime) -> anyhow::Result<()> {
//! let mut machine = rt.block_on(magg_cluster::ClusterMachine::start(&prepared, &opts, magg_cluster::HostSocket::Listen(listener), rt.handle().clone()))?;
//! let out = magg_core::phases::run(&mut machine, &prepared, &Default::default(),
//!     &magg_core::progress::NoProgress, &mut |_, _, _| Ok(()))?;
//! # Ok(()) }
//! ```

pub mod emulation;
mod error;
pub mod events;
mod failure;
mod faults;
mod figures;
pub mod forks;
mod machine;
mod passes;
pub mod preparing;
pub mod schedule;
pub mod service;

pub use error::HostError;
pub use failure::ClusterError;
pub use faults::FaultPolicy;
pub use machine::{ClusterMachine, DriveOptions, HostEndpoint, HostSocket, SceneEnd};
