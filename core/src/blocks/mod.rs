//! Scene data in 2 KB blocks, as in the paper's shared memories (§4.3).
//!
//! Six kinds of block: subspace blocks (the patch ids a grid cell overlaps; a long list
//! chains over several blocks) or BVH blocks (nodes and leaf triangles, [`bvh`]),
//! whichever structure the scene is traced through, then patch blocks, shading blocks
//! (the corner normals of smoothly shaded patches, read only at hits), element blocks and
//! vertex-energy blocks.
//! Block ids are global; block `b` lives on fork `b mod F` ([`fork_of_block`]), and node
//! `i`'s home fork is fork `i mod F` ([`home_fork_of_node`]). A node reads blocks through
//! an LRU [`BlockCache`] of C blocks in front of a [`BlockSource`] (an in-memory store
//! for the embedded renderer, a fork over gRPC in the cluster).

pub mod bvh;
mod cache;
mod cache_size;
mod layout;
mod owner;
mod resident;
mod store;

pub use cache::{BlockCache, CacheStats, PREFETCH_RUN};
pub use cache_size::{CacheSize, CacheSizeError};
pub use layout::*;
pub use owner::{fork_of_block, home_fork_of_node};
pub use store::{BlockError, BlockSource, MemStore};
