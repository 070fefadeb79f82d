//! The node's block cache: C blocks of local memory, least recently used evicted first
//! (paper §4.3), counting hits and misses.

use super::layout::{Block, BLOCK_SIZE};
use super::owner::fork_of_block;
use super::store::{BlockError, BlockSource};
use lru::LruCache;
use std::num::NonZeroUsize;
use std::sync::Arc;

/// Hit and miss counts of a cache.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CacheStats {
    /// Accesses served from the cache.
    pub hits: u64,
    /// Accesses that fetched the block from the source.
    pub misses: u64,
    /// Misses of blocks whose owning fork is not the node's home fork (they cross the
    /// G-bus in the paper's machine).
    pub remote_misses: u64,
    /// Blocks fetched ahead of demand, along with a missed block (not counted as misses;
    /// a later access to one is a hit).
    pub prefetched: u64,
}

impl CacheStats {
    /// hits / (hits + misses), 1 when there was no access.
    pub fn hit_ratio(&self) -> f64 {
        let n = self.hits + self.misses;
        if n == 0 {
            1.0
        } else {
            self.hits as f64 / n as f64
        }
    }
    /// Sum of two counts.
    pub fn add(self, o: CacheStats) -> CacheStats {
        CacheStats {
            hits: self.hits + o.hits,
            misses: self.misses + o.misses,
            remote_misses: self.remote_misses + o.remote_misses,
            prefetched: self.prefetched + o.prefetched,
        }
    }
}

/// Storage of the cached blocks: an LRU list when bounded; a table indexed by block id
/// when unlimited (nothing is ever evicted, so no recency needs tracking).
enum Slots {
    Bounded(LruCache<u32, Box<Block>>),
    Unlimited { table: Vec<Option<Box<Block>>>, held: usize },
}

/// An LRU cache of blocks in front of a [`BlockSource`]. Capacity `None` is unlimited.
pub struct BlockCache {
    source: Arc<dyn BlockSource>,
    slots: Slots,
    stats: CacheStats,
    /// (home fork, number of forks), to count remote misses.
    home: (u32, u32),
    /// Blocks fetched per miss (1 = no prefetch), the id stride between them, and the
    /// first ids of each kind of block (a prefetch stays within one kind); see
    /// [`BlockCache::with_prefetch`].
    prefetch: (u32, u32, Vec<u32>),
}

impl BlockCache {
    /// A cache of `capacity` blocks (at least 1), or unlimited for `None`.
    pub fn new(source: Arc<dyn BlockSource>, capacity: Option<usize>) -> Self {
        let slots = match capacity {
            Some(c) => Slots::Bounded(LruCache::new(NonZeroUsize::new(c.max(1)).unwrap_or(NonZeroUsize::MIN))),
            None => Slots::Unlimited { table: Vec::new(), held: 0 },
        };
        BlockCache { source, slots, stats: CacheStats::default(), home: (0, 1), prefetch: (1, 1, Vec::new()) }
    }

    /// With an unlimited cache, fetch up to `window` blocks per miss in one request: the
    /// missed block b and the uncached blocks b + stride, b + 2 stride, ... without
    /// crossing any of `boundaries` (the first ids of each kind of block). With the stride
    /// equal to the number of forks, they all live on the missed block's fork (no extra
    /// G-bus transfers) and, for the element blocks of a node's home fork, they are the
    /// blocks of the pairs it traces next. A bounded cache ignores this: prefetched blocks
    /// would evict ones still in use.
    pub fn with_prefetch(mut self, window: u32, stride: u32, boundaries: Vec<u32>) -> Self {
        self.prefetch = (window.max(1), stride.max(1), boundaries);
        self
    }

    /// Declares the node's home fork among `forks` (block `b` lives on fork [`fork_of_block`]`(b, forks)`),
    /// so that misses of blocks owned by another fork are counted as remote.
    pub fn with_home(mut self, home_fork: u32, forks: u32) -> Self {
        self.home = (home_fork, forks.max(1));
        self
    }

    /// Block `id`, from the cache or fetched from the source (evicting the least
    /// recently used block when full).
    pub fn get(&mut self, id: u32) -> Result<&Block, BlockError> {
        let remote = fork_of_block(id, self.home.1) != self.home.0;
        match &mut self.slots {
            Slots::Bounded(lru) => {
                if lru.contains(&id) {
                    self.stats.hits += 1;
                } else {
                    self.stats.misses += 1;
                    self.stats.remote_misses += remote as u64;
                    // Reuse the evicted block's memory when the cache is full.
                    let mut buf = if lru.len() == lru.cap().get() {
                        lru.pop_lru().map(|(_, b)| b).unwrap_or_else(|| Box::new([0u8; BLOCK_SIZE]))
                    } else {
                        Box::new([0u8; BLOCK_SIZE])
                    };
                    self.source.fetch(id, &mut buf)?;
                    lru.put(id, buf);
                }
                match lru.get(&id) {
                    Some(b) => Ok(&**b),
                    None => Err(BlockError::Unavailable { id, reason: "cache lost a block it just stored".into() }),
                }
            }
            Slots::Unlimited { table, held } => {
                let i = id as usize;
                if table.get(i).is_some_and(|s| s.is_some()) {
                    self.stats.hits += 1;
                } else {
                    // The missed block and the uncached ones after it, up to the window,
                    // within the same kind of block.
                    let (window, stride) = (self.prefetch.0 as usize, self.prefetch.1);
                    let limit = self.prefetch.2.iter().copied().filter(|&b| b > id).min().unwrap_or(u32::MAX);
                    let mut ids = vec![id];
                    let mut next = id.saturating_add(stride);
                    while ids.len() < window && next < limit {
                        if !table.get(next as usize).is_some_and(|s| s.is_some()) {
                            ids.push(next);
                        }
                        next = next.saturating_add(stride);
                    }
                    let mut bufs: Vec<Box<Block>> = ids.iter().map(|_| Box::new([0u8; BLOCK_SIZE])).collect();
                    self.source.fetch_batch(&ids, &mut bufs)?;
                    self.stats.misses += 1;
                    self.stats.remote_misses += remote as u64;
                    self.stats.prefetched += ids.len() as u64 - 1;
                    for (b, buf) in ids.iter().zip(bufs) {
                        let k = *b as usize;
                        if table.len() <= k {
                            table.resize_with(k + 1, || None);
                        }
                        if table[k].replace(buf).is_none() {
                            *held += 1;
                        }
                    }
                }
                match table.get(i) {
                    Some(Some(b)) => Ok(&**b),
                    _ => Err(BlockError::Unavailable { id, reason: "cache lost a block it just stored".into() }),
                }
            }
        }
    }

    /// Drops every cached block of the given ids range (used when a phase rewrites
    /// blocks, e.g. vertex energies).
    pub fn invalidate_range(&mut self, ids: std::ops::Range<u32>) {
        match &mut self.slots {
            Slots::Bounded(lru) => {
                for id in ids {
                    lru.pop(&id);
                }
            }
            Slots::Unlimited { table, held } => {
                for id in ids {
                    if let Some(slot) = table.get_mut(id as usize) {
                        if slot.take().is_some() {
                            *held -= 1;
                        }
                    }
                }
            }
        }
    }

    /// Hits and misses so far.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// Blocks currently held.
    pub fn len(&self) -> usize {
        match &self.slots {
            Slots::Bounded(lru) => lru.len(),
            Slots::Unlimited { held, .. } => *held,
        }
    }

    /// True when no block is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::MemStore;

    fn store(n: u32) -> Arc<MemStore> {
        Arc::new(MemStore::new(
            (0..n)
                .map(|i| {
                    let mut b = Box::new([0u8; BLOCK_SIZE]);
                    b[0] = i as u8;
                    b
                })
                .collect(),
        ))
    }

    #[test]
    fn evicts_least_recently_used() {
        let mut c = BlockCache::new(store(4), Some(2));
        assert_eq!(c.get(0).unwrap()[0], 0);
        assert_eq!(c.get(1).unwrap()[0], 1);
        c.get(0).unwrap(); // 1 is now least recent
        c.get(2).unwrap(); // evicts 1
        c.get(0).unwrap(); // hit
        c.get(1).unwrap(); // miss again
        assert_eq!((c.stats().hits, c.stats().misses), (2, 4));
        assert_eq!(c.len(), 2);
    }

    #[test]
    fn unlimited_cache_misses_once_per_block() {
        let mut c = BlockCache::new(store(4), None);
        for _ in 0..3 {
            for id in 0..4 {
                c.get(id).unwrap();
            }
        }
        assert_eq!((c.stats().hits, c.stats().misses), (8, 4));
    }

    #[test]
    fn prefetch_fetches_following_blocks_within_a_kind() {
        let mut c = BlockCache::new(store(8), None).with_prefetch(4, 1, vec![0, 3, 8]);
        c.get(0).unwrap(); // fetches 0, 1, 2 (3 starts another kind)
        assert_eq!((c.stats().misses, c.stats().prefetched), (1, 2));
        c.get(2).unwrap();
        assert_eq!(c.stats().hits, 1);
        c.get(4).unwrap(); // fetches 4..8
        assert_eq!((c.stats().misses, c.stats().prefetched), (2, 5));
        assert_eq!(c.get(7).unwrap()[0], 7);
        c.get(3).unwrap(); // 3 alone: 4 is cached
        assert_eq!((c.stats().misses, c.stats().prefetched), (3, 5));
    }

    #[test]
    fn strided_prefetch_stays_on_one_fork() {
        let mut c = BlockCache::new(store(8), None).with_prefetch(8, 3, vec![0, 8]);
        c.get(1).unwrap(); // 1, 4, 7
        assert_eq!(c.stats().prefetched, 2);
        assert_eq!(c.len(), 3);
        assert_eq!(c.get(7).unwrap()[0], 7);
    }

    #[test]
    fn out_of_range_is_an_error() {
        let mut c = BlockCache::new(store(2), Some(2));
        assert_eq!(c.get(5).unwrap_err(), BlockError::OutOfRange { id: 5, total: 2 });
    }
}
