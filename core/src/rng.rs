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

/// The generator of a ray's samples where it arrived, seeded from (`seed`, `tag`, the
/// point `p`, the incoming direction `d`): the same ray gets the same samples on any
/// node, in any order of tracing (the gather's rays and the shadow rays to area lights at
/// a viewing ray's hit).
pub fn arrival_rng(seed: u64, tag: u64, p: glam::DVec3, d: glam::DVec3) -> Rng {
    let bits = |v: glam::DVec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    let ([px, py, pz], [dx, dy, dz]) = (bits(p), bits(d));
    Rng::from_words(&[seed, tag, px, py, pz, dx, dy, dz])
}

/// The Cranley-Patterson rotation `(sx, sy)` of a ray's stratified samples where it
/// arrived: the first two numbers of [`arrival_rng`].
pub fn arrival_rotation(seed: u64, tag: u64, p: glam::DVec3, d: glam::DVec3) -> (f64, f64) {
    let mut rng = arrival_rng(seed, tag, p, d);
    (rng.next_f64(), rng.next_f64())
}

/// Sample `i` of an `n`-point stratified 2D set (Hammersley), shifted by a
/// Cranley-Patterson rotation `(sx, sy)`: each of the n strata of either axis gets one
/// point, whatever n is.
pub fn hammersley(i: u32, n: u32, sx: f64, sy: f64) -> (f64, f64) {
    let u = (i as f64 + 0.5) / n as f64 + sx;
    let v = radical_inverse2(i) + sy;
    (u - u.floor(), v - v.floor())
}

/// Radical inverse of `i` in base `b` (the digits of `i` mirrored about the point).
pub fn radical_inverse(b: u32, mut i: u32) -> f64 {
    let inv = 1.0 / b as f64;
    let (mut r, mut f) = (0.0, inv);
    while i > 0 {
        r += (i % b) as f64 * f;
        i /= b;
        f *= inv;
    }
    r
}

/// Sample `i` of a second stratified 2D set, independent of [`hammersley`]'s on the same
/// indices: the Halton points of bases 3 and 5, shifted by a Cranley-Patterson rotation.
/// A pair's light rays take their position on the element from the first and the
/// direction of their first diffuse bounce from this one, so that together the n rays
/// cover positions and directions evenly (a 4D Halton-Hammersley set).
pub fn halton35(i: u32, sx: f64, sy: f64) -> (f64, f64) {
    let u = radical_inverse(3, i) + sx;
    let v = radical_inverse(5, i) + sy;
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

    #[test]
    fn radical_inverses_mirror_the_digits() {
        assert_eq!(radical_inverse(3, 0), 0.0);
        assert!((radical_inverse(3, 1) - 1.0 / 3.0).abs() < 1e-15);
        assert!((radical_inverse(3, 5) - (2.0 / 3.0 + 1.0 / 9.0)).abs() < 1e-15, "5 = 12 in base 3");
        assert!((radical_inverse(5, 7) - (2.0 / 5.0 + 1.0 / 25.0)).abs() < 1e-15, "7 = 12 in base 5");
        assert!((radical_inverse(2, 6) - radical_inverse2(6)).abs() < 1e-15);
    }

    #[test]
    fn halton35_stratifies_both_axes() {
        // The first 75 = 3 x 5^2 points put one in each box of a third by a 25th (Halton's
        // elementary intervals), so each of the 15 cells of a third by a fifth holds 5.
        let mut cells = [[0; 5]; 3];
        for i in 0..75 {
            let (u, v) = halton35(i, 0.0, 0.0);
            cells[(u * 3.0) as usize][(v * 5.0) as usize] += 1;
        }
        assert!(cells.iter().flatten().all(|&c| c == 5), "{cells:?}");
        // A rotation shifts every point alike, modulo 1.
        for i in [0, 1, 7, 74] {
            let (u, v) = halton35(i, 0.0, 0.0);
            let (ru, rv) = halton35(i, 0.75, 0.5);
            assert!((0.0..1.0).contains(&ru) && (0.0..1.0).contains(&rv));
            assert!(((u + 0.75).fract() - ru).abs() < 1e-12 && ((v + 0.5).fract() - rv).abs() < 1e-12);
        }
    }
}
