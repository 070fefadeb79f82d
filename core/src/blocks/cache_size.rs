//! How many 2 KB blocks a node's [`BlockCache`](super::BlockCache) may hold: a positive
//! count, or unlimited (the whole scene stays once read). One type for every flag that
//! sets it (`magg-host render --cache-blocks`, `magg-node --cache-blocks`), parsed and
//! printed the same way: `"unlimited"` or the count.
//!
//! ```
//! use magg_core::blocks::CacheSize;
//! let c: CacheSize = "40".parse().unwrap();
//! assert_eq!(c.blocks(), Some(40));
//! assert_eq!("unlimited".parse::<CacheSize>().unwrap(), CacheSize::Unlimited);
//! assert_eq!(c.to_string(), "40");
//! assert!("0".parse::<CacheSize>().is_err());
//! ```

use std::fmt;
use std::num::NonZeroU64;
use std::str::FromStr;

/// A node's cache size in blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CacheSize {
    /// No bound: every block read stays.
    #[default]
    Unlimited,
    /// At most this many blocks.
    Blocks(NonZeroU64),
}

/// Why a cache size does not parse; the message starts with the text, so that a caller
/// can put the flag's name before it (`--cache-blocks 0: ...`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CacheSizeError {
    /// A count of zero: a node cannot trace without one block in its cache.
    #[error("0: a node needs at least one cache block")]
    Zero,
    /// Neither a count nor "unlimited".
    #[error("{0:?}: expected a block count or \"unlimited\"")]
    NotACount(String),
}

impl CacheSize {
    /// The bound in blocks; `None` when unlimited.
    pub fn blocks(self) -> Option<u64> {
        match self {
            CacheSize::Unlimited => None,
            CacheSize::Blocks(n) => Some(n.get()),
        }
    }

    /// The size of a bound in blocks (`None`: unlimited). A bound of 0 blocks is read as
    /// 1, the least a node can trace with.
    pub fn from_blocks(blocks: Option<u64>) -> CacheSize {
        match blocks {
            None => CacheSize::Unlimited,
            Some(n) => CacheSize::Blocks(NonZeroU64::new(n).unwrap_or(NonZeroU64::MIN)),
        }
    }
}

impl FromStr for CacheSize {
    type Err = CacheSizeError;

    /// `"unlimited"` (any case) or a positive block count.
    fn from_str(s: &str) -> Result<CacheSize, CacheSizeError> {
        if s.trim().eq_ignore_ascii_case("unlimited") {
            return Ok(CacheSize::Unlimited);
        }
        let n: u64 = s.trim().parse().map_err(|_| CacheSizeError::NotACount(s.to_string()))?;
        NonZeroU64::new(n).map(CacheSize::Blocks).ok_or(CacheSizeError::Zero)
    }
}

impl fmt::Display for CacheSize {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CacheSize::Unlimited => f.write_str("unlimited"),
            CacheSize::Blocks(n) => write!(f, "{n}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_unlimited_parse_and_print_back() {
        for text in ["unlimited", "1", "40", "18446744073709551615"] {
            assert_eq!(text.parse::<CacheSize>().unwrap().to_string(), text);
        }
        assert_eq!("UNLIMITED".parse::<CacheSize>().unwrap(), CacheSize::Unlimited);
        assert_eq!(" 7 ".parse::<CacheSize>().unwrap().blocks(), Some(7));
    }

    #[test]
    fn zero_negative_and_words_are_refused_by_name() {
        assert_eq!("0".parse::<CacheSize>(), Err(CacheSizeError::Zero));
        for bad in ["-3", "lots", "", "1.5"] {
            let e = bad.parse::<CacheSize>().unwrap_err();
            assert_eq!(e, CacheSizeError::NotACount(bad.to_string()));
            assert!(e.to_string().starts_with(&format!("{bad:?}: ")), "{e}");
        }
    }

    #[test]
    fn blocks_round_trip() {
        assert_eq!(CacheSize::from_blocks(None), CacheSize::Unlimited);
        assert_eq!(CacheSize::from_blocks(Some(5)).blocks(), Some(5));
        assert_eq!(CacheSize::from_blocks(Some(0)).blocks(), Some(1));
    }
}
