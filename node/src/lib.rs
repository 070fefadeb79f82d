//! # magg-node: a node processor of the cluster
//!
//! A node registers with the host (checking the protocol version), receives the resident
//! scene header and its home fork (node i -> fork i mod F, like an NP on a GPU card),
//! and then does what the host says: pull (light, element) pairs from its home fork and
//! send the deposits to the forks that own the elements (LRT), then pull subscreens from
//! the host and send pixel rows back (VRT), giving back the rows it has not started when
//! the host redivides. Every scene access goes through an LRU cache of 2 KB blocks filled
//! from the home fork (the DMA path). Connections and retries are
//! [`magg_plumbing::retry`]'s.
//!
//! ```no_run
//! # async fn f() -> anyhow::Result<()> {
//! let cfg = magg_node::NodeConfig { host: "127.0.0.1:7000".into(), ..Default::default() };
//! let summary = tokio::task::spawn_blocking(move || magg_node::run(&cfg)).await??;
//! println!("node {} traced {} pairs", summary.node, summary.pairs);
//! # Ok(()) }
//! ```

mod connect;
mod error;
mod fork_blocks;
mod node;
mod pace;
mod report;
pub mod route;
mod timing;
mod work;

pub use connect::connect_with_backoff;
pub use error::NodeError;
pub use fork_blocks::ForkBlocks;
pub use node::{run, run_with_runtime, NodeConfig, NodeSummary};
pub use pace::{NodePace, Processor};
