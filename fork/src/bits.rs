//! A set of small integers, one bit each: which pairs a fork has applied deposits of,
//! which of its pairs are complete, and which of them deposited on each other fork.
//! A pair costs one bit per set however the render goes, where a hash set cost about
//! 16 bytes and a hash per deposit.

/// The indices below a fixed bound that are in the set.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Bitset {
    words: Vec<u64>,
    len: u64,
}

impl Bitset {
    /// An empty set of indices below `bound`.
    pub fn new(bound: u64) -> Bitset {
        Bitset { words: vec![0; bound.div_ceil(64) as usize], len: 0 }
    }

    /// Adds `i`; true when it was not in the set. Indices past the bound are ignored
    /// (callers check ranges first).
    pub fn insert(&mut self, i: u64) -> bool {
        let Some(w) = self.words.get_mut((i / 64) as usize) else { return false };
        let bit = 1u64 << (i % 64);
        let fresh = *w & bit == 0;
        *w |= bit;
        self.len += fresh as u64;
        fresh
    }

    /// Removes `i`; true when it was in the set.
    pub fn remove(&mut self, i: u64) -> bool {
        let Some(w) = self.words.get_mut((i / 64) as usize) else { return false };
        let bit = 1u64 << (i % 64);
        let was = *w & bit != 0;
        *w &= !bit;
        self.len -= was as u64;
        was
    }

    /// Whether `i` is in the set.
    pub fn contains(&self, i: u64) -> bool {
        self.words.get((i / 64) as usize).is_some_and(|w| w & (1u64 << (i % 64)) != 0)
    }

    /// How many indices are in the set.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// True when the set is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The indices in the set, ascending.
    pub fn iter(&self) -> impl Iterator<Item = u64> + '_ {
        self.words.iter().enumerate().flat_map(|(k, &w)| {
            let mut rest = w;
            std::iter::from_fn(move || {
                (rest != 0).then(|| {
                    let b = rest.trailing_zeros() as u64;
                    rest &= rest - 1;
                    k as u64 * 64 + b
                })
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn insert_remove_and_iterate_agree_with_a_btreeset() {
        let mut b = Bitset::new(200);
        let mut reference = std::collections::BTreeSet::new();
        for i in [0u64, 63, 64, 65, 127, 128, 199, 5, 64] {
            assert_eq!(b.insert(i), reference.insert(i), "insert {i}");
        }
        assert_eq!(b.len(), reference.len() as u64);
        assert!(b.contains(199) && !b.contains(198));
        assert!(b.remove(64) && !b.remove(64));
        reference.remove(&64);
        assert_eq!(b.iter().collect::<Vec<_>>(), reference.iter().copied().collect::<Vec<_>>());
        assert_eq!(b.len(), reference.len() as u64);
    }

    #[test]
    fn indices_past_the_bound_are_ignored() {
        let mut b = Bitset::new(10);
        assert!(!b.insert(64) && !b.contains(64) && b.is_empty());
        assert!(b.insert(9) && b.contains(9));
    }
}
