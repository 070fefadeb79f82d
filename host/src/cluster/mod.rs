//! The cluster driver: the host of the paper's machine, over gRPC.
//!
//! Loads each fork with its shard of blocks (block b on fork b mod F), serves the `Host`
//! service to nodes, runs the phases with barriers (LRT until every fork reports all of
//! its pairs done; energy interpolation here; VRT until every pixel row is in), and
//! assembles the same [`RenderOutput`] as the embedded renderer: bit for bit the same
//! image and energies.
//!
//! Forks and nodes run either inside this process (the single-process harness: real gRPC
//! over 127.0.0.1 ports) or as separate processes (`--forks-at`, `--external-nodes`).

mod drive;
pub mod emulation;
pub mod events;
pub mod forks;
mod inprocess;
pub mod schedule;
pub mod service;

pub use drive::{drive, DriveOptions};
pub use inprocess::{ClusterShape, InProcessOptions, StartedCluster};
