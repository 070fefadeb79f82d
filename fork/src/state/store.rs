//! A fork's block store: the 2 KB blocks it holds (block `b` on fork `b mod F`), kept as
//! received so that they are served to nodes (DMA) and peers (G-bus) without a copy.

use crate::error::ForkError;
use crate::locks::{read, write};
use bytes::Bytes;
use magg_core::blocks::fork_of_block;
use std::sync::RwLock;

/// The owned blocks of fork `index` of `forks`, by local index `id / forks`.
#[derive(Debug)]
pub struct BlockStore {
    index: u32,
    forks: u32,
    /// Blocks in the scene.
    total: u32,
    /// `None` until supplied.
    blocks: RwLock<Vec<Option<Bytes>>>,
}

impl BlockStore {
    /// An empty store for fork `index` of `forks` (at least 1) of a scene of `total`
    /// blocks.
    pub fn new(index: u32, forks: u32, total: u32) -> BlockStore {
        let forks = forks.max(1);
        let local = (total.saturating_sub(index) as usize).div_ceil(forks as usize);
        BlockStore { index, forks, total, blocks: RwLock::new(vec![None; local]) }
    }

    /// The fork holding block `id`.
    pub fn owner(&self, id: u32) -> u32 {
        fork_of_block(id, self.forks)
    }

    /// Refuses ids past the scene's last block.
    pub fn check_id(&self, id: u32) -> Result<(), ForkError> {
        if id < self.total {
            Ok(())
        } else {
            Err(ForkError::BlockOutOfRange { id, total: self.total })
        }
    }

    /// Refuses ids out of range or held by another fork.
    pub fn check_owned(&self, id: u32) -> Result<(), ForkError> {
        self.check_id(id)?;
        match self.owner(id) {
            owner if owner == self.index => Ok(()),
            owner => Err(ForkError::BlockNotOwned { id, owner, fork: self.index }),
        }
    }

    /// Stores (or replaces) owned blocks; all ids are checked before any is stored.
    /// Returns how many were stored.
    pub fn put(&self, blocks: Vec<(u32, Bytes)>) -> Result<u32, ForkError> {
        for (id, _) in &blocks {
            self.check_owned(*id)?;
        }
        let n = blocks.len() as u32;
        let mut store = write(&self.blocks);
        for (id, data) in blocks {
            store[(id / self.forks) as usize] = Some(data);
        }
        Ok(n)
    }

    /// Blocks supplied so far.
    pub fn stored(&self) -> u32 {
        read(&self.blocks).iter().filter(|b| b.is_some()).count() as u32
    }

    /// Owned blocks by id, in request order (payloads shared, not copied).
    pub fn get(&self, ids: &[u32]) -> Result<Vec<(u32, Bytes)>, ForkError> {
        for &id in ids {
            self.check_owned(id)?;
        }
        let store = read(&self.blocks);
        ids.iter()
            .map(|&id| match &store[(id / self.forks) as usize] {
                Some(b) => Ok((id, b.clone())),
                None => Err(ForkError::BlockNotLoaded { id, fork: self.index }),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(v: u8) -> Bytes {
        Bytes::from(vec![v; magg_core::blocks::BLOCK_SIZE])
    }

    #[test]
    fn stored_blocks_come_back_in_request_order_without_a_copy() {
        let s = BlockStore::new(1, 3, 10); // blocks 1, 4, 7
        let b4 = block(4);
        assert_eq!(s.put(vec![(4, b4.clone()), (7, block(7))]).unwrap(), 2);
        assert_eq!(s.stored(), 2);
        let got = s.get(&[7, 4]).unwrap();
        assert_eq!((got[0].0, got[1].0), (7, 4));
        assert_eq!(got[1].1.as_ptr(), b4.as_ptr(), "the block was copied");
        assert!(matches!(s.get(&[1]), Err(ForkError::BlockNotLoaded { id: 1, fork: 1 })));
    }

    #[test]
    fn a_put_with_one_foreign_block_stores_nothing() {
        let s = BlockStore::new(0, 2, 6);
        let e = s.put(vec![(0, block(0)), (3, block(3))]).unwrap_err();
        assert!(matches!(e, ForkError::BlockNotOwned { id: 3, owner: 1, fork: 0 }), "{e}");
        assert!(matches!(s.put(vec![(6, block(6))]), Err(ForkError::BlockOutOfRange { id: 6, total: 6 })));
        assert_eq!(s.stored(), 0);
    }

    #[test]
    fn every_block_has_one_owner() {
        for forks in [1, 2, 5] {
            let stores: Vec<_> = (0..forks).map(|i| BlockStore::new(i, forks, 23)).collect();
            for id in 0..23 {
                let owners = stores.iter().filter(|s| s.check_owned(id).is_ok()).count();
                assert_eq!(owners, 1, "block {id} of {forks} forks");
                assert!(stores[(id % forks) as usize].put(vec![(id, block(0))]).is_ok());
            }
            assert_eq!(stores.iter().map(|s| s.stored()).sum::<u32>(), 23);
        }
    }
}
