//! Deterministic random numbers, seeded from what a piece of work *is*.
//!
//! Every ray of a (light, element) pair and every sample of a pixel draws from a stream
//! seeded by `(scene seed, kind, ids...)`, never from a thread or arrival order, so a pair
//! re-run on another node produces the same rays and the render is bitwise reproducible.

/// SplitMix64 finaliser: a strong 64-bit mixing function.
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hashes a list of words into one seed.
pub fn seed_of(words: &[u64]) -> u64 {
    let mut h = 0x243f_6a88_85a3_08d3u64;
    for &w in words {
        h = mix64(h ^ w.wrapping_add(0x9e37_79b9_7f4a_7c15));
    }
    h
}

/// A small, fast generator (SplitMix64 stream).
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator seeded from `words` (see [`seed_of`]).
    pub fn from_words(words: &[u64]) -> Self {
        Rng { state: seed_of(words) }
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Base-2 radical inverse of `i` (van der Corput), in [0, 1).
pub fn radical_inverse2(i: u32) -> f64 {
    i.reverse_bits() as f64 * (1.0 / 4_294_967_296.0)
}

/// Sample `i` of an `n`-point stratified 2D set (Hammersley), shifted by a
/// Cranley-Patterson rotation `(sx, sy)`: each of the n strata of either axis gets one
/// point, whatever n is.
pub fn hammersley(i: u32, n: u32, sx: f64, sy: f64) -> (f64, f64) {
    let u = (i as f64 + 0.5) / n as f64 + sx;
    let v = radical_inverse2(i) + sy;
    (u - u.floor(), v - v.floor())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_words_same_stream() {
        let mut a = Rng::from_words(&[1, 2, 3]);
        let mut b = Rng::from_words(&[1, 2, 3]);
        let mut c = Rng::from_words(&[1, 2, 4]);
        let (x, y, z) = (a.next_u64(), b.next_u64(), c.next_u64());
        assert_eq!(x, y);
        assert_ne!(x, z);
    }

    #[test]
    fn hammersley_points_lie_in_unit_square_and_stratify() {
        let n = 16;
        let mut cols = [0; 16];
        for i in 0..n {
            let (u, v) = hammersley(i, n, 0.3, 0.7);
            assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
            cols[(u * 16.0) as usize] += 1;
        }
        assert!(cols.iter().all(|&c| c == 1));
    }
}
