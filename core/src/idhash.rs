//! A hasher for tables keyed by ids (an edge's two vertex ids in preprocessing, a
//! fork's leased pairs): the multiply-rotate hash of rustc's `FxHasher`, far cheaper than
//! the standard library's SipHash on keys this small. It does not resist chosen keys, and
//! need not: the keys of its tables are made by the program itself (by preprocessing from
//! the scene's own structure; by a fork from its own pair queue, a node's message only
//! looking one up), so a collision would slow only the table's maker. Nothing that must
//! be deterministic depends on the order of a table built with it.

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

/// The multiplier (2^64 / golden ratio, odd).
const K: u64 = 0x9e37_79b9_7f4a_7c15;

/// See the module doc.
#[derive(Clone, Copy, Debug, Default)]
pub struct IdHasher(u64);

impl IdHasher {
    #[inline]
    fn add(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(K);
    }
}

impl Hasher for IdHasher {
    /// The product rotated: a product's low bits depend only on the key's low bits, and
    /// a table picks its bucket from the low bits of the hash (and its tag from the top
    /// 7), so keys that differ only in high bits (a patch id above a lattice index, a
    /// pair's light above its element) would share a bucket. Rotating by 26 brings the
    /// well-mixed middle bits down (rustc-hash 2 does the same).
    #[inline]
    fn finish(&self) -> u64 {
        self.0.rotate_left(26)
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.add(u64::from_le_bytes(word));
        }
    }

    #[inline]
    fn write_u32(&mut self, n: u32) {
        self.add(n as u64);
    }

    #[inline]
    fn write_u64(&mut self, n: u64) {
        self.add(n);
    }
}

/// A map keyed by ids, hashed with [`IdHasher`].
pub type IdMap<K, V> = HashMap<K, V, BuildHasherDefault<IdHasher>>;
/// A set of ids, hashed with [`IdHasher`].
pub type IdSet<K> = HashSet<K, BuildHasherDefault<IdHasher>>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_hash_apart_and_are_found_again() {
        let mut m: IdMap<(u32, u32), u32> = IdMap::default();
        for a in 0..300u32 {
            for b in a..a + 20 {
                m.insert((a, b), a * 1000 + b);
            }
        }
        assert_eq!(m.len(), 6000);
        assert_eq!(m.get(&(17, 30)), Some(&17030));
        assert_eq!(m.get(&(30, 17)), None);
        let h = |k: (u32, u32)| {
            let mut s = IdHasher::default();
            std::hash::Hash::hash(&k, &mut s);
            s.finish()
        };
        assert_ne!(h((1, 2)), h((2, 1)));
        let mut bytes = IdHasher::default();
        bytes.write(&[1, 2, 3]);
        assert_ne!(bytes.finish(), 0);
    }

    #[test]
    fn keys_that_differ_only_in_high_bits_spread_over_the_low_bits() {
        // 256 keys i << 32: without the rotation their hashes' low 32 bits are all equal,
        // one bucket of a table of up to 2^32; with it, most pick a bucket of their own
        // among 4096.
        let low: IdSet<u64> = (0..256u64)
            .map(|i| {
                let mut s = IdHasher::default();
                s.write_u64(i << 32);
                s.finish() & 0xfff
            })
            .collect();
        assert!(low.len() > 200, "{} distinct buckets of 4096 for 256 keys", low.len());
    }
}
