//! The unlimited cache's storage: every block it holds side by side in one allocation,
//! indexed by block id.
//!
//! A hit computes the block's address from its id (base + 2 KB x id) while a byte table
//! says whether it is held: the two loads are independent, so the processor reads the
//! record speculatively, and a ray's walk through the BVH waits for one memory access
//! per node rather than two in a chain (a table of boxes needs the box's address before
//! it can read the block). Blocks never move while a reference to one is out: the
//! storage only grows through `&mut self`.

use super::layout::{Block, BLOCK_SIZE};

/// Blocks by id, in one allocation grown to the largest id stored.
#[derive(Default)]
pub(super) struct Resident {
    /// Block `id`'s bytes at `blocks[id]` (zero while not held).
    blocks: Vec<Block>,
    /// Whether `blocks[id]` holds block `id`.
    held: Vec<bool>,
    /// How many are held.
    count: usize,
}

impl Resident {
    /// Block `id` when held.
    #[inline(always)]
    pub(super) fn get(&self, id: u32) -> Option<&Block> {
        let i = id as usize;
        // (`held` and `blocks` are always as long as each other; the address of
        // `blocks[i]` does not depend on `held[i]`.)
        match self.held.get(i) {
            Some(true) => self.blocks.get(i),
            _ => None,
        }
    }

    /// Whether block `id` is held.
    #[inline]
    pub(super) fn contains(&self, id: u32) -> bool {
        self.held.get(id as usize).copied().unwrap_or(false)
    }

    /// Stores `block` as block `id` (replacing what was held).
    pub(super) fn put(&mut self, id: u32, block: &Block) {
        let i = id as usize;
        if self.blocks.len() <= i {
            // Grown by at least half again, so that a render's blocks arriving one id at
            // a time are copied a bounded number of times; a zeroed allocation, whose
            // pages the system maps only once a block is written there.
            let len = (i + 1).max(self.blocks.len() + self.blocks.len() / 2);
            let mut grown = vec![[0u8; BLOCK_SIZE]; len];
            for (new, old) in grown.iter_mut().zip(&self.blocks).zip(&self.held).filter(|(_, h)| **h).map(|(b, _)| b) {
                *new = *old;
            }
            self.blocks = grown;
            self.held.resize(len, false);
        }
        self.blocks[i] = *block;
        if !std::mem::replace(&mut self.held[i], true) {
            self.count += 1;
        }
    }

    /// Forgets block `id`.
    pub(super) fn forget(&mut self, id: u32) {
        if let Some(h) = self.held.get_mut(id as usize) {
            if std::mem::replace(h, false) {
                self.count -= 1;
            }
        }
    }

    /// Blocks held.
    pub(super) fn len(&self) -> usize {
        self.count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_held_by_id_and_forgotten() {
        let mut r = Resident::default();
        assert!(r.get(0).is_none() && !r.contains(7));
        let mut b = [0u8; BLOCK_SIZE];
        b[5] = 9;
        r.put(7, &b);
        r.put(2, &b);
        b[5] = 10;
        r.put(7, &b);
        assert_eq!(r.len(), 2);
        assert_eq!(r.get(7).map(|b| b[5]), Some(10));
        assert_eq!(r.get(2).map(|b| b[5]), Some(9));
        assert!(r.get(3).is_none() && r.get(1000).is_none());
        r.forget(7);
        r.forget(7);
        r.forget(1000);
        assert_eq!(r.len(), 1);
        assert!(r.get(7).is_none() && r.contains(2));
    }
}
