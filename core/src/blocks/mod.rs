//! Scene data in 2 KB blocks, as in the paper's shared memories (§4.3).
//!
//! Four kinds of block: subspace blocks (the patch ids a grid cell overlaps; a long list
//! chains over several blocks), patch blocks, element blocks and vertex-energy blocks.
//! Block ids are global; block `b` lives on fork `b mod F`. A node reads them through an
//! LRU [`BlockCache`] of C blocks in front of a [`BlockSource`] (an in-memory store for
//! the embedded renderer, a fork over gRPC in the cluster).

mod cache;
mod layout;
mod store;

pub use cache::{BlockCache, CacheStats};
pub use layout::*;
pub use store::{BlockError, BlockSource, MemStore};
