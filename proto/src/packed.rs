//! The bytes of packed repeated fields, written and read here rather than by prost.
//!
//! A packed `repeated uint64` (or `uint32`) is one length-delimited field holding the
//! values' varints back to back; a packed `repeated sfixed64` holds each value as 8
//! little-endian bytes. The messages that carry many of them (a batch's deposits, a
//! fork's energies) declare those fields as `bytes`, which is the same wire format, and
//! fill them with these functions. Prost would decode such an array one value at a time
//! through its generic buffer (each varint byte an `advance` of the receive buffer, each
//! value a `Vec::push` behind a bounds check); here a whole array is one slice walked in
//! a tight loop, and the message keeps the received bytes without copying them.
//!
//! ```
//! use magg_proto::packed::{put_varint, varints_u32};
//! let mut b = Vec::new();
//! for v in [3u64, 300, 70_000] {
//!     put_varint(&mut b, v);
//! }
//! assert_eq!(b, [3, 0xac, 0x02, 0xf0, 0xa2, 0x04]); // protobuf's varints
//! assert_eq!(varints_u32(&b).unwrap(), [3, 300, 70_000]);
//! ```

/// Why a packed array cannot be read.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum PackedError {
    /// The bytes end inside a varint.
    #[error("the last varint is cut short")]
    Truncated,
    /// A varint longer than ten bytes, or above the value's type.
    #[error("a varint at byte {at} is too large for a {bits}-bit value")]
    Overflow {
        /// Its first byte.
        at: usize,
        /// Bits of the value's type.
        bits: u32,
    },
    /// A fixed-width array whose length is not a multiple of its values' size.
    #[error("{len} bytes are not a whole number of {size}-byte values")]
    Ragged {
        /// Bytes of the array.
        len: usize,
        /// Bytes per value.
        size: usize,
    },
}

/// Appends `v` as a varint (7 bits a byte, low bits first, the high bit set on every byte
/// but the last).
#[inline]
pub fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push(v as u8 | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// The bytes of a packed `repeated uint64` (or `uint32`) holding `values`.
pub fn varint_bytes(values: impl IntoIterator<Item = u64>) -> bytes::Bytes {
    let mut out = Vec::new();
    values.into_iter().for_each(|v| put_varint(&mut out, v));
    out.into()
}

/// The varints of `b`, each at most `bits` bits (32 or 64).
fn varints<T>(b: &[u8], bits: u32, cast: impl Fn(u64) -> T) -> Result<Vec<T>, PackedError> {
    // Every varint ends on its one byte below 0x80: their count, for one allocation.
    let mut out = Vec::with_capacity(b.iter().filter(|&&x| x < 0x80).count());
    let mut i = 0;
    while i < b.len() {
        let at = i;
        let (mut v, mut shift) = (0u64, 0u32);
        loop {
            let Some(&x) = b.get(i) else {
                return Err(PackedError::Truncated);
            };
            i += 1;
            let part = (x & 0x7f) as u64;
            // Ten bytes at most, the tenth bringing bit 63 only.
            if shift > 63 || (shift == 63 && part > 1) {
                return Err(PackedError::Overflow { at, bits });
            }
            v |= part << shift;
            if x < 0x80 {
                break;
            }
            shift += 7;
        }
        if bits < 64 && v >> bits != 0 {
            return Err(PackedError::Overflow { at, bits });
        }
        out.push(cast(v));
    }
    Ok(out)
}

/// The values of a packed `repeated uint64`.
pub fn varints_u64(b: &[u8]) -> Result<Vec<u64>, PackedError> {
    varints(b, 64, |v| v)
}

/// The values of a packed `repeated uint32`; a value above `u32::MAX` is refused
/// (prost would keep its low 32 bits).
pub fn varints_u32(b: &[u8]) -> Result<Vec<u32>, PackedError> {
    varints(b, 32, |v| v as u32)
}

/// Appends `v` as 8 little-endian bytes (one value of a packed `repeated sfixed64`).
#[inline]
pub fn put_i64(out: &mut Vec<u8>, v: i64) {
    out.extend_from_slice(&v.to_le_bytes());
}

/// The bytes of a packed `repeated sfixed64` holding `values`.
pub fn i64_bytes(values: impl IntoIterator<Item = i64>) -> bytes::Bytes {
    let mut out = Vec::new();
    values.into_iter().for_each(|v| put_i64(&mut out, v));
    out.into()
}

/// The values of a packed `repeated sfixed64`.
pub fn fixed_i64(b: &[u8]) -> Result<Vec<i64>, PackedError> {
    if b.len() % 8 != 0 {
        return Err(PackedError::Ragged { len: b.len(), size: 8 });
    }
    Ok(b.chunks_exact(8).map(|c| i64::from_le_bytes(c.try_into().unwrap_or_default())).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The values prost writes for `repeated uint64` / `uint32` / `sfixed64` fields, and
    /// the bytes this module writes for them, are the same.
    #[test]
    fn the_bytes_are_protobufs_packed_arrays() {
        let big = [0u64, 1, 127, 128, 16_383, 16_384, u32::MAX as u64, 1 << 35, u64::MAX];
        let mut ours = Vec::new();
        for &v in &big {
            put_varint(&mut ours, v);
        }
        let mut theirs = Vec::new();
        prost::encoding::uint64::encode_packed(1, &big, &mut theirs);
        assert!(theirs.ends_with(&ours), "a packed field is its tag, its length and these bytes");
        assert_eq!(theirs.len(), 2 + ours.len());
        assert_eq!(varints_u64(&ours).unwrap(), big);

        let fixed = [0i64, -1, i64::MIN, i64::MAX, 12_345];
        let mut ours = Vec::new();
        fixed.iter().for_each(|&v| put_i64(&mut ours, v));
        let mut theirs = Vec::new();
        prost::encoding::sfixed64::encode_packed(1, &fixed, &mut theirs);
        assert!(theirs.ends_with(&ours));
        assert_eq!(fixed_i64(&ours).unwrap(), fixed);
    }

    #[test]
    fn small_arrays_read_back() {
        assert_eq!(varints_u32(&[]).unwrap(), Vec::<u32>::new());
        let mut b = Vec::new();
        put_varint(&mut b, u32::MAX as u64);
        put_varint(&mut b, 0);
        assert_eq!(varints_u32(&b).unwrap(), [u32::MAX, 0]);
    }

    #[test]
    fn malformed_arrays_are_refused() {
        assert_eq!(varints_u64(&[0x80]), Err(PackedError::Truncated));
        assert_eq!(varints_u64(&[5, 0xff, 0xff]), Err(PackedError::Truncated));
        // Eleven bytes, or a tenth byte beyond bit 63.
        let long = [0xffu8, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01];
        assert_eq!(varints_u64(&long), Err(PackedError::Overflow { at: 0, bits: 64 }));
        let wide = [0xffu8, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02];
        assert_eq!(varints_u64(&wide), Err(PackedError::Overflow { at: 0, bits: 64 }));
        // 2^32 for a 32-bit value.
        let mut b = vec![1];
        put_varint(&mut b, 1 << 32);
        assert_eq!(varints_u32(&b), Err(PackedError::Overflow { at: 1, bits: 32 }));
        assert_eq!(fixed_i64(&[0; 12]), Err(PackedError::Ragged { len: 12, size: 8 }));
    }
}
