//! The cluster as a machine: the host of the paper's machine, over gRPC.
//!
//! [`ClusterMachine`] loads each fork with its shard of blocks (block b on fork b mod F),
//! serves the `Host` service to nodes, and runs each pass with a barrier (LRT until every
//! fork reports all of its pairs done, then the energies collected; VRT until every pixel
//! row is in). The phases are sequenced by [`magg_core::phases::run`], as for the
//! embedded renderer, so the output is bit for bit the same image and energies.
//!
//! Forks and nodes run either inside this process (the single-process harness: real gRPC
//! over 127.0.0.1 ports) or as separate processes (`--forks-at`, `--external-nodes`).

pub mod emulation;
pub mod events;
mod figures;
pub mod forks;
mod inprocess;
mod machine;
mod passes;
pub mod schedule;
pub mod service;

pub use inprocess::{ClusterShape, InProcessOptions, StartedCluster};
pub use machine::{ClusterMachine, DriveOptions};
