//! The single ray's f32 slab test with AVX, where the processor has it: a node's eight
//! children in one 256-bit register instead of two SSE2 ones.
//!
//! The operations are those of [`Narrow::enter`] lane for lane (IEEE single precision
//! subtraction, multiplication, `max`, `min` and comparisons give the same bits in any
//! register width), so the walk visits the same nodes and the image is the same bits;
//! `the_avx_slab_test_gives_the_scalar_bits` checks it. The walk is compiled for AVX as a
//! whole (one function per ray octant), so that the test is inlined into it. A processor
//! without AVX, or `MAGG_NO_AVX` set in the environment (to compare the two), takes the
//! SSE2 walk.

use super::{rows, walk, BoxTest, Entered, Narrow, BVH_NODE_RECORD, BVH_ROW, BVH_WIDTH, BVH_WIDTH_SHIFT, TINY, WIDEN};
use crate::blocks::BlockError;
use crate::trace::{Hit, Query, TraceScratch};
use crate::view::SceneView;
use std::arch::x86_64::*;
use std::sync::OnceLock;

const _: () = assert!(BVH_WIDTH == 8, "the AVX test takes a node's children in one register");

/// Whether single rays walk with the AVX test: the processor has AVX and `MAGG_NO_AVX`
/// is not set (read once).
pub(super) fn available() -> bool {
    static AVX: OnceLock<bool> = OnceLock::new();
    *AVX.get_or_init(|| std::is_x86_feature_detected!("avx") && std::env::var_os("MAGG_NO_AVX").is_none())
}

impl Narrow {
    /// [`Narrow::enter`] with AVX, the eight children at once.
    ///
    /// # Safety
    ///
    /// The processor must have AVX ([`available`]).
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn enter_avx<const OCTANT: u8>(&self, record: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        // SAFETY: r < 6, so the 32 bytes read, from byte BVH_ROW r = 32 r, lie in the
        // record's 256 (an unaligned load).
        let row = |r: usize| unsafe { _mm256_loadu_ps(record.as_ptr().add(BVH_ROW * r).cast::<f32>()) };
        let splat = |v: &[f32; 4]| _mm256_set1_ps(v[0]);
        let mut near = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm256_set1_ps(f32::INFINITY);
        for a in 0..3 {
            let (near_row, far_row) = rows(OCTANT, a);
            let inv = splat(&self.inv[a]);
            let n = _mm256_mul_ps(_mm256_sub_ps(row(near_row), splat(&self.o_near[a])), inv);
            let f = _mm256_mul_ps(_mm256_sub_ps(row(far_row), splat(&self.o_far[a])), inv);
            near = _mm256_max_ps(n, near);
            far = _mm256_min_ps(f, far);
        }
        // As `widened_sse2`: the same operations on the same values.
        let tiny = _mm256_set1_ps(TINY);
        let near = _mm256_sub_ps(_mm256_mul_ps(near, _mm256_set1_ps(1.0 - WIDEN)), tiny);
        let far = _mm256_add_ps(_mm256_mul_ps(far, _mm256_set1_ps(1.0 + WIDEN)), tiny);
        let near = _mm256_max_ps(near, _mm256_set1_ps(t0));
        let far = _mm256_min_ps(far, _mm256_set1_ps(t1));
        let inside = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_LE_OQ>(near, far),
            _mm256_cmp_ps::<_CMP_LT_OQ>(near, _mm256_set1_ps(f32::INFINITY)),
        );
        let mut out = Entered { near: [0.0; BVH_WIDTH], mask: _mm256_movemask_ps(inside) as u32 };
        // SAFETY: `out.near` holds eight f32 (an unaligned store).
        unsafe { _mm256_storeu_ps(out.near.as_mut_ptr(), near) };
        out
    }
}

/// The AVX test, from `t0` rounded down, of a ray in `OCTANT`; only built where
/// [`available`] holds.
struct NarrowedAvx<'a, const OCTANT: u8>(&'a Narrow, f32);

impl<const OCTANT: u8> BoxTest for NarrowedAvx<'_, OCTANT> {
    type Bound = f32;
    #[inline(always)]
    fn bound(&self, t: f64) -> f32 {
        super::f32_above(t)
    }
    #[inline(always)]
    fn enter(&self, record: &[u8; BVH_NODE_RECORD], bound: f32) -> Entered<f32> {
        // SAFETY: a `NarrowedAvx` is only made by `walk_octant`, which only runs where
        // the processor has AVX.
        unsafe { self.0.enter_avx::<OCTANT>(record, self.1, bound) }
    }
    #[inline(always)]
    fn wide(t: f32) -> f64 {
        t as f64
    }
    #[inline(always)]
    fn key(t: f32, k: usize) -> u64 {
        ((t.max(0.0).to_bits() as u64) << BVH_WIDTH_SHIFT) | k as u64
    }
}

/// The walk of a ray in `OCTANT` with the AVX test, compiled for AVX as a whole.
///
/// # Safety
///
/// The processor must have AVX ([`available`]).
#[target_feature(enable = "avx")]
#[inline(never)]
unsafe fn walk_octant<const OCTANT: u8>(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    q: &Query,
    n: &Narrow,
    t0: f32,
) -> Result<Option<Hit>, BlockError> {
    walk(view, scratch, q, &NarrowedAvx::<OCTANT>(n, t0))
}

/// The walk of a ray that takes the f32 test `n` from `t0`, with AVX; only called where
/// [`available`] holds.
pub(super) fn walk_avx(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    q: &Query,
    n: &Narrow,
    t0: f32,
) -> Result<Option<Hit>, BlockError> {
    assert!(available(), "the AVX walk on a processor without AVX");
    // SAFETY: the processor has AVX (checked above).
    unsafe {
        match n.octant {
            0 => walk_octant::<0>(view, scratch, q, n, t0),
            1 => walk_octant::<1>(view, scratch, q, n, t0),
            2 => walk_octant::<2>(view, scratch, q, n, t0),
            3 => walk_octant::<3>(view, scratch, q, n, t0),
            4 => walk_octant::<4>(view, scratch, q, n, t0),
            5 => walk_octant::<5>(view, scratch, q, n, t0),
            6 => walk_octant::<6>(view, scratch, q, n, t0),
            _ => walk_octant::<7>(view, scratch, q, n, t0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With AVX, the slab test answers as the scalar one, bit for bit (the same cases
    /// as the SSE2 test's).
    #[test]
    fn the_avx_slab_test_gives_the_scalar_bits() {
        if !std::is_x86_feature_detected!("avx") {
            eprintln!("no AVX on this processor: nothing to compare");
            return;
        }
        let mut rng = crate::rng::Rng::from_words(&[9, 0xa5c]);
        let mut compared = 0;
        for c in 0..20_000 {
            let (node, _, narrow, t0, t1) = super::super::tests::case(&mut rng, c);
            let Some(n) = narrow else { continue };
            let block = super::super::tests::record(&node);
            let r = crate::blocks::bvh::node_record(&block, 0);
            let (t0, t1) = (super::super::f32_below(t0), super::super::f32_above(t1));
            let bits = |e: Entered<f32>| (super::super::tests::entered(e.near, e.mask).map(f32::to_bits), e.mask);
            // SAFETY: the processor has AVX (checked above).
            let avx = unsafe {
                match n.octant {
                    0 => n.enter_avx::<0>(r, t0, t1),
                    1 => n.enter_avx::<1>(r, t0, t1),
                    2 => n.enter_avx::<2>(r, t0, t1),
                    3 => n.enter_avx::<3>(r, t0, t1),
                    4 => n.enter_avx::<4>(r, t0, t1),
                    5 => n.enter_avx::<5>(r, t0, t1),
                    6 => n.enter_avx::<6>(r, t0, t1),
                    _ => n.enter_avx::<7>(r, t0, t1),
                }
            };
            assert_eq!(bits(avx), bits(n.enter_scalar(r, t0, t1)), "case {c}: {node:?}");
            compared += 1;
        }
        assert!(compared > 10_000, "{compared}");
    }
}
