//! The node's block cache: C blocks of local memory, least recently used evicted first
//! (paper §4.3), counting hits and misses. Block ids are dense, so both the bounded and
//! the unlimited cache find a block through a table indexed by its id: no hashing, and
//! no division on a hit.

use super::layout::{Block, BLOCK_SIZE};
use super::owner::fork_of_block;
use super::resident::Resident;
use super::store::{BlockError, BlockSource};
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

/// The most blocks one [`BlockCache::prefetch`] fetches (128 KB in one request): runs
/// of that many already make the request's own cost small against its blocks', and
/// finding a run's distinct blocks stays a short scan.
pub const PREFETCH_RUN: usize = 64;

/// Marks "no slot" / "no block" in [`Lru`]'s tables.
const NIL: u32 = u32::MAX;

/// A bounded LRU set of blocks without hashing: block ids are dense (`0..total`), so a
/// table indexed by block id gives each cached block's slot. Recency is a stamp per slot
/// from a clock that every use advances, so a hit is two table reads and one store (a
/// linked list's relinks were about 8% of the bounded viewing pass's instructions). The
/// least recently used slot is the one of smallest stamp: a scan keeps the smallest
/// eighth as candidates, and a candidate used since (its stamp changed) is passed over.
/// Every other slot's stamp was above every candidate's at the scan and has only grown,
/// so the first candidate still unused is exactly the least recently used slot, as a
/// list would give it.
struct Lru {
    capacity: usize,
    /// Slot -> block data.
    blocks: Vec<Box<Block>>,
    /// Slot -> block id (NIL for a free slot).
    ids: Vec<u32>,
    /// Slot -> the clock at its last use.
    stamp: Vec<u64>,
    /// Advanced by every use.
    clock: u64,
    /// Block id -> slot (NIL when not cached); grown to the largest id fetched.
    slot_of: Vec<u32>,
    /// Slots emptied by invalidation.
    free: Vec<u32>,
    /// Candidates for eviction, (stamp at the last scan, slot), the least recently used
    /// last.
    victims: Vec<(u64, u32)>,
}

impl Lru {
    fn new(capacity: usize) -> Self {
        Lru {
            capacity: capacity.max(1),
            blocks: Vec::new(),
            ids: Vec::new(),
            stamp: Vec::new(),
            clock: 0,
            slot_of: Vec::new(),
            free: Vec::new(),
            victims: Vec::new(),
        }
    }

    /// The slot of block `id` when cached.
    #[inline]
    fn slot(&self, id: u32) -> Option<u32> {
        self.slot_of.get(id as usize).copied().filter(|&s| s != NIL)
    }

    /// Marks slot `s` most recently used.
    #[inline]
    fn touch(&mut self, s: u32) {
        self.clock += 1;
        self.stamp[s as usize] = self.clock;
    }

    /// The least recently used occupied slot (there is one: the cache is full).
    fn least_recent(&mut self) -> u32 {
        loop {
            while let Some((stamp, s)) = self.victims.pop() {
                if self.stamp[s as usize] == stamp && self.ids[s as usize] != NIL {
                    return s;
                }
            }
            // The occupied slots of smallest stamp, the least recently used last (in
            // the emptied candidates' buffer).
            let all = &mut self.victims;
            all.extend(
                (0..self.ids.len() as u32)
                    .filter(|&s| self.ids[s as usize] != NIL)
                    .map(|s| (self.stamp[s as usize], s)),
            );
            let keep = (all.len() / 8).max(1).min(all.len());
            if keep < all.len() {
                all.select_nth_unstable(keep - 1);
                all.truncate(keep);
            }
            all.sort_unstable_by(|a, b| b.cmp(a));
        }
    }

    /// A slot for a new block: a free one, a new one while under capacity, or the least
    /// recently used one (forgetting its block). The slot owns no id.
    fn take_slot(&mut self) -> u32 {
        if let Some(s) = self.free.pop() {
            return s;
        }
        if self.blocks.len() < self.capacity {
            self.blocks.push(Box::new([0u8; BLOCK_SIZE]));
            self.ids.push(NIL);
            self.stamp.push(0);
            return self.blocks.len() as u32 - 1;
        }
        let s = self.least_recent();
        self.slot_of[self.ids[s as usize] as usize] = NIL;
        self.ids[s as usize] = NIL;
        s
    }

    /// Records that slot `s` (taken by [`Lru::take_slot`]) now holds block `id`, as the
    /// most recently used.
    fn bind(&mut self, s: u32, id: u32) {
        let i = id as usize;
        if self.slot_of.len() <= i {
            self.slot_of.resize(i + 1, NIL);
        }
        self.slot_of[i] = s;
        self.ids[s as usize] = id;
        self.touch(s);
    }

    fn forget(&mut self, id: u32) {
        if let Some(s) = self.slot(id) {
            self.slot_of[id as usize] = NIL;
            self.ids[s as usize] = NIL;
            self.free.push(s);
        }
    }

    fn len(&self) -> usize {
        self.blocks.len() - self.free.len()
    }
}

/// Storage of the cached blocks: an LRU list when bounded; the blocks side by side,
/// indexed by block id, when unlimited (nothing is ever evicted, so no recency needs
/// tracking).
enum Slots {
    Bounded(Lru),
    Unlimited(Resident),
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
    /// Buffers of [`BlockCache::prefetch`], kept from call to call: the distinct ids
    /// wanted, those missing, and block buffers to fetch into (a prefetched block's
    /// buffer takes its slot's place; the one it replaces is kept for the next call).
    scratch: (Vec<u32>, Vec<u32>, Vec<Box<Block>>),
}

impl BlockCache {
    /// A cache of `capacity` blocks (at least 1), or unlimited for `None`.
    pub fn new(source: Arc<dyn BlockSource>, capacity: Option<usize>) -> Self {
        let slots = match capacity {
            Some(c) => Slots::Bounded(Lru::new(c)),
            None => Slots::Unlimited(Resident::default()),
        };
        BlockCache {
            source,
            slots,
            stats: CacheStats::default(),
            home: (0, 1),
            prefetch: (1, 1, Vec::new()),
            scratch: Default::default(),
        }
    }

    /// With an unlimited cache, fetch up to `window` blocks per miss in one request: the
    /// missed block b and the uncached blocks b + stride, b + 2 stride, ..., then b -
    /// stride, b - 2 stride, ..., without crossing any of `boundaries` (the first ids of
    /// each kind of block). With the stride equal to the number of forks, they all live
    /// on the missed block's fork (no extra G-bus transfers) and, for the element blocks
    /// of a node's home fork, the first of them are the blocks of the pairs it traces
    /// next; those before b would otherwise be missed one at a time when a ray goes back
    /// to them. A bounded cache fetches nothing more on a miss (blocks fetched on a guess
    /// would evict ones still in use), but with a window over one block its kernels fetch
    /// ahead what they know they will read next, in runs of at most half the cache
    /// ([`BlockCache::prefetch`], [`BlockCache::prefetch_room`]). The paper's scheme, a
    /// block per request, leaves the window at one.
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
    /// recently used block when full). A hit hashes nothing and divides nothing, looks
    /// the block up once, and is inlined into the caller: the miss path is a call of its
    /// own.
    #[inline(always)]
    pub fn get(&mut self, id: u32) -> Result<&Block, BlockError> {
        let cached: Option<*const Block> = match &mut self.slots {
            Slots::Bounded(lru) => lru.slot(id).map(|s| {
                lru.touch(s);
                &*lru.blocks[s as usize] as *const Block
            }),
            Slots::Unlimited(resident) => resident.get(id).map(|b| b as *const Block),
        };
        if let Some(block) = cached {
            self.stats.hits += 1;
            // SAFETY: `block` points into a boxed block that `self.slots` owns; nothing
            // between the lookup and here touches the slots, and the reference returned
            // borrows `self` mutably for as long as it lives, so the box can be neither
            // dropped nor moved (nor its block written) while it is in use. (The pointer
            // only works around the borrow checker's refusal of a reference returned on
            // one path of a match followed by a mutable use of `self` on the other.)
            return Ok(unsafe { &*block });
        }
        self.get_missed(id)
    }

    /// [`BlockCache::get`] of a block not cached: fetched, stored, then returned.
    #[cold]
    #[inline(never)]
    fn get_missed(&mut self, id: u32) -> Result<&Block, BlockError> {
        self.fetch_missing(id)?;
        let lost = || BlockError::Unavailable { id, reason: "cache lost a block it just stored".into() };
        match &mut self.slots {
            Slots::Bounded(lru) => {
                let s = lru.slot(id).ok_or_else(lost)?;
                Ok(&*lru.blocks[s as usize])
            }
            Slots::Unlimited(resident) => resident.get(id).ok_or_else(lost),
        }
    }

    /// Fetches block `id`, which is not cached, and stores it: with a bounded cache in
    /// the least recently used slot (as the most recently used block), with an unlimited
    /// one together with the prefetch window's uncached blocks.
    #[cold]
    #[inline(never)]
    fn fetch_missing(&mut self, id: u32) -> Result<(), BlockError> {
        match &mut self.slots {
            Slots::Bounded(lru) => {
                self.stats.misses += 1;
                self.stats.remote_misses += (fork_of_block(id, self.home.1) != self.home.0) as u64;
                let s = lru.take_slot();
                if let Err(e) = self.source.fetch(id, &mut lru.blocks[s as usize]) {
                    lru.free.push(s);
                    return Err(e);
                }
                lru.bind(s, id);
                Ok(())
            }
            Slots::Unlimited(resident) => {
                // The missed block and the uncached ones after it, then those before
                // it, up to the window, within the same kind of block.
                let (window, stride) = (self.prefetch.0 as usize, self.prefetch.1);
                let kinds = &self.prefetch.2;
                let limit = kinds.iter().copied().filter(|&b| b > id).min().unwrap_or(u32::MAX);
                let start = kinds.iter().copied().filter(|&b| b <= id).max().unwrap_or(0);
                let uncached = |b: u32| !resident.contains(b);
                let mut ids = vec![id];
                let mut next = id.saturating_add(stride);
                while ids.len() < window && next < limit {
                    if uncached(next) {
                        ids.push(next);
                    }
                    next = next.saturating_add(stride);
                }
                let mut prev = id.checked_sub(stride).filter(|&b| b >= start);
                while let Some(b) = prev.filter(|_| ids.len() < window) {
                    if uncached(b) {
                        ids.push(b);
                    }
                    prev = b.checked_sub(stride).filter(|&b| b >= start);
                }
                let mut bufs: Vec<Box<Block>> = ids.iter().map(|_| Box::new([0u8; BLOCK_SIZE])).collect();
                self.source.fetch_batch(&ids, &mut bufs)?;
                self.stats.misses += 1;
                self.stats.remote_misses += (fork_of_block(id, self.home.1) != self.home.0) as u64;
                self.stats.prefetched += ids.len() as u64 - 1;
                for (&b, buf) in ids.iter().zip(&bufs) {
                    resident.put(b, buf);
                }
                Ok(())
            }
        }
    }

    /// Of a bounded cache that fetches ahead ([`BlockCache::with_prefetch`] with a window
    /// over one block), how many blocks one [`BlockCache::prefetch`] may fetch and keep:
    /// half the capacity, so that what a caller reads between prefetches stays, and at
    /// most [`PREFETCH_RUN`]. `None` for an unlimited cache, or one that fetches a block
    /// per request (the paper's scheme).
    pub fn prefetch_room(&self) -> Option<usize> {
        match &self.slots {
            Slots::Bounded(lru) if self.prefetch.0 > 1 => Some((lru.capacity / 2).clamp(1, PREFETCH_RUN)),
            _ => None,
        }
    }

    /// Makes blocks `ids` (at most [`BlockCache::prefetch_room`] distinct ones, the first
    /// taken) the most recently used: those not cached are fetched in one request
    /// ([`BlockSource::fetch_batch`]: one call to a fork instead of one per block),
    /// counted as prefetched, not missed; a later read of one is a hit. Nothing is
    /// evicted that the prefetch keeps. What a kernel will read next, a level of element
    /// records or a batch of vertex energies, is read without waiting once per block.
    /// An unlimited cache fetches the missing ones the same way.
    pub fn prefetch(&mut self, ids: &[u32]) -> Result<(), BlockError> {
        let room = self.prefetch_room().unwrap_or(usize::MAX);
        let (wanted, missing, bufs) = &mut self.scratch;
        wanted.clear();
        for &id in ids {
            if wanted.len() == room {
                break;
            }
            if !wanted.contains(&id) {
                wanted.push(id);
            }
        }
        missing.clear();
        match &mut self.slots {
            Slots::Bounded(lru) => missing.extend(wanted.iter().copied().filter(|&id| match lru.slot(id) {
                Some(s) => {
                    lru.touch(s);
                    false
                }
                None => true,
            })),
            Slots::Unlimited(resident) => missing.extend(wanted.iter().copied().filter(|&id| !resident.contains(id))),
        }
        if missing.is_empty() {
            return Ok(());
        }
        while bufs.len() < missing.len() {
            bufs.push(Box::new([0u8; BLOCK_SIZE]));
        }
        let bufs = &mut bufs[..missing.len()];
        self.source.fetch_batch(missing, bufs)?;
        self.stats.prefetched += missing.len() as u64;
        for (&id, buf) in missing.iter().zip(bufs) {
            match &mut self.slots {
                Slots::Bounded(lru) => {
                    let s = lru.take_slot();
                    std::mem::swap(&mut lru.blocks[s as usize], buf);
                    lru.bind(s, id);
                }
                Slots::Unlimited(resident) => resident.put(id, buf),
            }
        }
        // (A bounded cache's runs take at most PREFETCH_RUN buffers; a larger batch into
        // an unlimited cache keeps no more than that.)
        self.scratch.2.truncate(PREFETCH_RUN);
        Ok(())
    }

    /// Drops every cached block of the given ids range (used when a phase rewrites
    /// blocks, e.g. vertex energies).
    pub fn invalidate_range(&mut self, ids: std::ops::Range<u32>) {
        match &mut self.slots {
            Slots::Bounded(lru) => {
                for id in ids {
                    lru.forget(id);
                }
            }
            Slots::Unlimited(resident) => {
                for id in ids {
                    resident.forget(id);
                }
            }
        }
    }

    /// True for a cache of a bounded number of blocks (one that may evict).
    pub fn is_bounded(&self) -> bool {
        matches!(self.slots, Slots::Bounded(_))
    }

    /// Hits and misses so far.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// Blocks currently held.
    pub fn len(&self) -> usize {
        match &self.slots {
            Slots::Bounded(lru) => lru.len(),
            Slots::Unlimited(resident) => resident.len(),
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

    /// Counts the requests made of a store.
    struct Counted(Arc<MemStore>, std::sync::atomic::AtomicU32);
    impl BlockSource for Counted {
        fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError> {
            self.1.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            self.0.fetch(id, out)
        }
        fn fetch_batch(&self, ids: &[u32], out: &mut [Box<Block>]) -> Result<(), BlockError> {
            self.1.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            ids.iter().zip(out.iter_mut()).try_for_each(|(&id, b)| self.0.fetch(id, b))
        }
    }

    #[test]
    fn prefetch_fetches_a_run_in_one_request_and_keeps_what_it_touched() {
        let source = Arc::new(Counted(store(16), Default::default()));
        let requests = || source.1.load(std::sync::atomic::Ordering::Relaxed);
        let mut c = BlockCache::new(source.clone(), Some(6)).with_prefetch(2, 1, vec![0, 16]);
        assert_eq!(c.prefetch_room(), Some(3));
        for id in 0..5 {
            c.get(id).unwrap();
        }
        assert_eq!(requests(), 5);
        // 1 is cached: touched, not fetched; 9 and 10 come in one request; 11 is past
        // the room (three distinct blocks) and left out. 10 takes the slot of 0, the
        // least recently used.
        c.prefetch(&[9, 1, 10, 9, 11]).unwrap();
        assert_eq!(requests(), 6);
        assert_eq!((c.stats().misses, c.stats().prefetched, c.len()), (5, 2, 6));
        // Reads of what was prefetched or touched are hits, with the right contents.
        for id in [9, 10, 1] {
            assert_eq!(c.get(id).unwrap()[0], id as u8);
        }
        assert_eq!((c.stats().hits, c.stats().misses, requests()), (3, 5, 6));
        // 11 was left out: a miss, which evicts 2; 3 and 4 stay; 0 went.
        c.get(11).unwrap();
        c.get(3).unwrap();
        c.get(4).unwrap();
        assert_eq!((c.stats().misses, requests()), (6, 7));
        c.get(0).unwrap();
        assert_eq!((c.stats().misses, requests()), (7, 8));
    }

    #[test]
    fn a_cache_of_the_papers_scheme_does_not_fetch_ahead() {
        let c = BlockCache::new(store(4), Some(4));
        assert_eq!(c.prefetch_room(), None);
        let c = BlockCache::new(store(4), None).with_prefetch(8, 1, vec![0, 4]);
        assert_eq!(c.prefetch_room(), None);
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
    fn prefetch_goes_back_within_a_kind_after_going_forward() {
        let mut c = BlockCache::new(store(8), None).with_prefetch(3, 1, vec![0, 3, 8]);
        c.get(5).unwrap(); // 5, 6, 7, then 4 would pass the window of 3
        assert_eq!((c.stats().misses, c.stats().prefetched, c.len()), (1, 2, 3));
        c.get(4).unwrap(); // 4, then 3 (2 is another kind)
        assert_eq!((c.stats().misses, c.stats().prefetched, c.len()), (2, 3, 5));
        let mut c = BlockCache::new(store(8), None).with_prefetch(8, 3, vec![0, 8]);
        c.get(7).unwrap(); // 7, then 4 and 1 on the same fork
        assert_eq!((c.stats().prefetched, c.len()), (2, 3));
        assert_eq!(c.get(1).unwrap()[0], 1);
        assert_eq!(c.stats().misses, 1);
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
    fn the_bounded_cache_is_exactly_lru_over_random_accesses_and_invalidations() {
        // Reference: a recency list, most recent first.
        let mut rng = crate::rng::Rng::from_words(&[0x10, 0xca]);
        for cap in [1usize, 2, 5, 17, 33] {
            let mut c = BlockCache::new(store(40), Some(cap));
            let mut model: Vec<u32> = Vec::new();
            let (mut hits, mut misses) = (0, 0);
            for _ in 0..5000 {
                if rng.next_f64() < 0.02 {
                    let lo = (rng.next_f64() * 40.0) as u32;
                    c.invalidate_range(lo..lo + 3);
                    model.retain(|&b| !(lo..lo + 3).contains(&b));
                    assert_eq!(c.len(), model.len());
                    continue;
                }
                // Skewed towards low ids so that there are hits.
                let id = (rng.next_f64() * rng.next_f64() * 40.0) as u32;
                assert_eq!(c.get(id).unwrap()[0], id as u8);
                match model.iter().position(|&b| b == id) {
                    Some(i) => {
                        hits += 1;
                        model.remove(i);
                    }
                    None => {
                        misses += 1;
                        model.truncate(cap - 1);
                    }
                }
                model.insert(0, id);
                assert_eq!((c.stats().hits, c.stats().misses), (hits, misses), "capacity {cap}");
                assert_eq!(c.len(), model.len());
            }
            assert!(hits > 100 && misses > 100, "capacity {cap}: {hits} hits, {misses} misses");
        }
    }

    #[test]
    fn a_failed_fetch_leaves_the_cache_usable() {
        let mut c = BlockCache::new(store(3), Some(2));
        c.get(0).unwrap();
        c.get(1).unwrap();
        assert!(c.get(9).is_err());
        assert_eq!(c.get(2).unwrap()[0], 2);
        assert_eq!(c.get(1).unwrap()[0], 1);
        assert_eq!(c.len(), 2);
        // A run fetched ahead that fails (block 9 does not exist) keeps none of its
        // blocks and evicts nothing.
        let mut c = BlockCache::new(store(4), Some(4)).with_prefetch(2, 1, vec![0, 4]);
        c.get(0).unwrap();
        assert!(c.prefetch(&[2, 9]).is_err());
        assert_eq!((c.len(), c.stats().prefetched), (1, 0));
        c.prefetch(&[2, 3]).unwrap();
        assert_eq!((c.len(), c.stats().prefetched, c.stats().misses), (3, 2, 1));
        assert_eq!(c.get(0).unwrap()[0], 0);
        assert_eq!(c.get(3).unwrap()[0], 3);
        assert_eq!(c.stats().misses, 1);
    }

    #[test]
    fn out_of_range_is_an_error() {
        let mut c = BlockCache::new(store(2), Some(2));
        assert_eq!(c.get(5).unwrap_err(), BlockError::OutOfRange { id: 5, total: 2 });
    }
}
