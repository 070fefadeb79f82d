//! Where blocks come from: the [`BlockSource`] trait and the in-memory [`MemStore`].

use super::layout::{Block, BLOCK_SIZE};
use std::sync::RwLock;

/// Why a block could not be had.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum BlockError {
    /// The id is past the last block of the scene.
    #[error("block {id} does not exist (the scene has {total} blocks)")]
    OutOfRange {
        /// Requested id.
        id: u32,
        /// Number of blocks.
        total: u32,
    },
    /// An entity id (patch, element, vertex, light, subspace) is out of range.
    #[error("{kind} id {id} out of range (the scene has {count})")]
    BadId {
        /// Which kind of id.
        kind: &'static str,
        /// The id.
        id: u64,
        /// How many there are.
        count: u64,
    },
    /// The source (a fork over the network) failed.
    #[error("block {id} could not be fetched: {reason}")]
    Unavailable {
        /// Requested id.
        id: u32,
        /// What went wrong.
        reason: String,
    },
}

/// A source of blocks: the memory the node's cache reads through.
///
/// Implementations: [`MemStore`] (all blocks in this process), and in the cluster a fork
/// client that fetches over gRPC (the paper's DMA and G-bus paths).
pub trait BlockSource: Send + Sync {
    /// Copies block `id` into `out`.
    fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError>;

    /// Copies blocks `ids` into `out` (same length), in one transfer where the source
    /// can (a single request to a fork). The default fetches them one by one.
    fn fetch_batch(&self, ids: &[u32], out: &mut [Box<Block>]) -> Result<(), BlockError> {
        for (id, b) in ids.iter().zip(out.iter_mut()) {
            self.fetch(*id, b)?;
        }
        Ok(())
    }
}

/// Every block of a scene, in memory. Vertex-energy blocks are rewritten after energy
/// interpolation, hence the lock (uncontended in practice: writes happen between phases).
#[derive(Debug)]
pub struct MemStore {
    blocks: RwLock<Vec<Box<Block>>>,
}

impl MemStore {
    /// A store holding `blocks` (block id = index).
    pub fn new(blocks: Vec<Box<Block>>) -> Self {
        MemStore { blocks: RwLock::new(blocks) }
    }
    /// Number of blocks.
    pub fn len(&self) -> u32 {
        self.blocks.read().map(|b| b.len() as u32).unwrap_or(0)
    }
    /// True when the store holds no block.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Replaces block `id` (used to publish vertex energies).
    pub fn replace(&self, id: u32, block: Box<Block>) -> Result<(), BlockError> {
        let mut g = self.blocks.write().unwrap_or_else(|e| e.into_inner());
        let total = g.len() as u32;
        match g.get_mut(id as usize) {
            Some(slot) => {
                *slot = block;
                Ok(())
            }
            None => Err(BlockError::OutOfRange { id, total }),
        }
    }
    /// A copy of block `id`.
    pub fn get(&self, id: u32) -> Result<Box<Block>, BlockError> {
        let mut out = Box::new([0u8; BLOCK_SIZE]);
        self.fetch(id, &mut out)?;
        Ok(out)
    }
}

impl BlockSource for MemStore {
    fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError> {
        let g = self.blocks.read().unwrap_or_else(|e| e.into_inner());
        match g.get(id as usize) {
            Some(b) => {
                out.copy_from_slice(&b[..]);
                Ok(())
            }
            None => Err(BlockError::OutOfRange { id, total: g.len() as u32 }),
        }
    }
}
