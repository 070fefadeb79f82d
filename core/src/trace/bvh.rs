//! Ray casting through the BVH: a depth-first walk over nodes of four children, the
//! nearest child first, that skips every node entered beyond the best hit so far.
//!
//! Node bounds are f32 rounded outward and padded at build time, and the slab test's far
//! distance is widened by `1 + 2 gamma(3)` (Ize 2013), so a box holding a hit is never
//! skipped; a node entered exactly at the best distance is still visited, so that a tie
//! can go to the lower patch id. The patch test itself is the f64 watertight one, on the
//! same corners as the patch records: the grid's answer, bit for bit.
//!
//! The slab test reads a node's bounds in place from its record and, on x86_64, runs
//! two children at a time in SSE2 registers (the scalar code elsewhere gives the same
//! bits); a ray in the plane of a face (0 x inf = NaN) is not limited by that slab, so it
//! can only enter more boxes, never fewer.

use super::{Hit, Query, TraceScratch};
use crate::blocks::bvh::{BvhNodeLanes, BvhTriangle, BVH_NODE_RECORD, BVH_NODE_SHIFT, BVH_TRIANGLE_RECORD, BVH_WIDTH};
use crate::blocks::BlockError;
use crate::view::SceneView;

/// `1 + 2 gamma(3)`, gamma(n) = n eps / (1 - n eps) with eps = 2^-53.
const FAR_SLACK: f64 = 1.0 + 2.0 * (3.0 * f64::EPSILON * 0.5) / (1.0 - 3.0 * f64::EPSILON * 0.5);

/// The ray as the slab test wants it.
struct SlabRay {
    origin: [f64; 3],
    inv: [f64; 3],
    /// Per axis, whether the ray runs towards lower coordinates: then a box's near face
    /// on that axis is its `hi` and its far face its `lo`, for every box, so the slab
    /// test needs no comparison to order them.
    negative: [bool; 3],
}

impl SlabRay {
    fn new(origin: [f64; 3], direction: [f64; 3]) -> SlabRay {
        let inv = direction.map(|d| 1.0 / d);
        SlabRay { origin, inv, negative: inv.map(f64::is_sign_negative) }
    }

    /// Which of the child boxes of the node `record` the ray enters within `[t0, t1]`,
    /// and at what distance: the four boxes side by side, in f64 from the f32 bounds,
    /// two lanes at a time in SSE2 registers.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn enter(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered {
        // SAFETY: SSE2 is part of the x86_64 baseline, so every processor that runs this
        // build has it; the function reads nothing but its arguments.
        unsafe { self.enter_sse2(record, t0, t1) }
    }

    /// [`SlabRay::enter`] with SSE2: the same operations on the same values, so the same
    /// bits as [`SlabRay::enter_scalar`] (`max` and `min` keep their second operand when
    /// either is NaN, as the scalar comparisons do).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    fn enter_sse2(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered {
        use std::arch::x86_64::*;
        // Row r of the record's bounds (lo x, y, z, then hi x, y, z: four f32 each, little
        // endian like the processor), children 0 and 1, and 2 and 3, widened to f64.
        let row = |r: usize| {
            // SAFETY: r < 6, so the 16 bytes read, from byte 16 r, lie in the record's 128
            // (an unaligned load).
            let v = unsafe { _mm_loadu_ps(record.as_ptr().add(16 * r).cast::<f32>()) };
            (_mm_cvtps_pd(v), _mm_cvtps_pd(_mm_movehl_ps(v, v)))
        };
        let (mut near01, mut near23) = (_mm_set1_pd(t0), _mm_set1_pd(t0));
        let (mut far01, mut far23) = (_mm_set1_pd(f64::INFINITY), _mm_set1_pd(f64::INFINITY));
        for a in 0..3 {
            let (near_row, far_row) = if self.negative[a] { (3 + a, a) } else { (a, 3 + a) };
            let (o, inv) = (_mm_set1_pd(self.origin[a]), _mm_set1_pd(self.inv[a]));
            let (n01, n23) = row(near_row);
            let (f01, f23) = row(far_row);
            near01 = _mm_max_pd(_mm_mul_pd(_mm_sub_pd(n01, o), inv), near01);
            near23 = _mm_max_pd(_mm_mul_pd(_mm_sub_pd(n23, o), inv), near23);
            far01 = _mm_min_pd(_mm_mul_pd(_mm_sub_pd(f01, o), inv), far01);
            far23 = _mm_min_pd(_mm_mul_pd(_mm_sub_pd(f23, o), inv), far23);
        }
        let (slack, t1) = (_mm_set1_pd(FAR_SLACK), _mm_set1_pd(t1));
        let far01 = _mm_min_pd(_mm_mul_pd(far01, slack), t1);
        let far23 = _mm_min_pd(_mm_mul_pd(far23, slack), t1);
        // Entered within the interval, and not only at infinity.
        let inf = _mm_set1_pd(f64::INFINITY);
        let in01 = _mm_and_pd(_mm_cmple_pd(near01, far01), _mm_cmplt_pd(near01, inf));
        let in23 = _mm_and_pd(_mm_cmple_pd(near23, far23), _mm_cmplt_pd(near23, inf));
        let mask = _mm_movemask_pd(in01) | (_mm_movemask_pd(in23) << 2);
        let lanes = |v: __m128d| [_mm_cvtsd_f64(v), _mm_cvtsd_f64(_mm_unpackhi_pd(v, v))];
        let [n0, n1] = lanes(near01);
        let [n2, n3] = lanes(near23);
        Entered { near: [n0, n1, n2, n3], mask: mask as u32 }
    }

    /// [`SlabRay::enter`] one lane at a time (other processors; the SSE2 version's
    /// oracle in the tests).
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    #[inline]
    fn enter_scalar(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered {
        let node = &BvhNodeLanes::read(record);
        let mut near = [t0; BVH_WIDTH];
        let mut far = [f64::INFINITY; BVH_WIDTH];
        for a in 0..3 {
            let (near_face, far_face) =
                if self.negative[a] { (&node.hi[a], &node.lo[a]) } else { (&node.lo[a], &node.hi[a]) };
            let (o, inv) = (self.origin[a], self.inv[a]);
            for k in 0..BVH_WIDTH {
                let tn = (near_face[k] as f64 - o) * inv;
                let tf = (far_face[k] as f64 - o) * inv;
                // A NaN (0 x inf: a ray in the plane of a face) fails these comparisons
                // and leaves the bound as it was: the slab does not limit the ray, which
                // can only enter more boxes, never fewer.
                near[k] = if tn > near[k] { tn } else { near[k] };
                far[k] = if tf < far[k] { tf } else { far[k] };
            }
        }
        let mask = (0..BVH_WIDTH).fold(0, |m, k| {
            let f = far[k] * FAR_SLACK;
            let f = if f < t1 { f } else { t1 };
            m | ((near[k] <= f && near[k] < f64::INFINITY) as u32) << k
        });
        Entered { near, mask }
    }

    /// [`SlabRay::enter`] on processors without SSE2 code here.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline]
    fn enter(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered {
        self.enter_scalar(record, t0, t1)
    }
}

/// What the slab test found for a node's children.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entered {
    /// Distance at which the ray enters each child's box (meaningful for those entered).
    near: [f64; BVH_WIDTH],
    /// Bit k set when the ray enters child k's box within the interval, at a finite
    /// distance. An absent child's box is empty (`lo` = +inf, `hi` = -inf), which every
    /// ray enters at +inf, so its bit is never set; a ray parallel to a slab and outside
    /// it enters at +inf too.
    mask: u32,
}

/// [`super::cast`] through the BVH.
pub(super) fn cast(view: &mut SceneView, scratch: &mut TraceScratch, q: &Query) -> Result<Option<Hit>, BlockError> {
    let (o, d) = (q.ray.origin, q.ray.direction);
    let t0 = q.tmin.max(0.0);
    let slab = SlabRay::new(o.to_array(), d.to_array());
    let mut best: Option<Hit> = None;
    let (mut steps, mut tests) = (0u64, 0u64);
    let mut stack = std::mem::take(&mut scratch.stack);
    stack.clear();
    // (node index or first triangle address, leaf triangle count (0: a node), entry t):
    // the entry visited next (the nearer child of the last node), then the stack.
    let mut next = Some((0, 0, t0));
    let (max_steps, bvh_base) = (view.header.bvh.nodes as u64, view.header.layout.bvh_base);
    let result = 'walk: loop {
        let Some((index, count, near)) = next.take().or_else(|| stack.pop()) else {
            break Ok(best);
        };
        let bound = best.map_or(q.tmax, |b| b.t);
        if near > bound {
            continue;
        }
        if count > 0 {
            let leaf = match view.bvh_leaf(index, count) {
                Ok(l) => l,
                Err(e) => break Err(e),
            };
            // Each record read in place: the corners by the test, the patch id here.
            for record in leaf.chunks_exact(BVH_TRIANGLE_RECORD) {
                let (corners, patch) = BvhTriangle::parts(record);
                if patch == q.exclude {
                    continue;
                }
                tests += 1;
                if q.test_record(corners, patch, q.tmax, &mut best) && q.any {
                    break 'walk Ok(best);
                }
            }
            continue;
        }
        steps += 1;
        let record = match view.bvh_node_record(index) {
            Ok(r) => r,
            Err(e) => break Err(e),
        };
        if steps > max_steps {
            break Err(corrupt(bvh_base, index));
        }
        // The children entered, nearest first (ties in the node's order): the nearest
        // is visited next, the others stacked farthest first.
        let Entered { near: t, mut mask } = slab.enter(record, t0, bound);
        let mut entered = [(0.0f64, 0u32, 0u32); BVH_WIDTH];
        let mut n = 0;
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            // Nodes are written depth first: an inner child's index is above its
            // parent's, so a ray visits each node at most once. A block that says
            // otherwise is corrupt (and would loop).
            let (child, count) = (child_index(record, k), child_count(record, k));
            if count == 0 && child <= index {
                break 'walk Err(corrupt(bvh_base, index));
            }
            let mut i = n;
            while i > 0 && entered[i - 1].0 > t[k] {
                entered[i] = entered[i - 1];
                i -= 1;
            }
            entered[i] = (t[k], child, count);
            n += 1;
        }
        if n > 0 {
            for &(t, index, count) in entered[1..n].iter().rev() {
                stack.push((index, count, t));
            }
            next = Some((entered[0].1, entered[0].2, entered[0].0));
        }
    };
    scratch.stack = stack;
    view.counters.grid_steps += steps;
    view.counters.patch_tests += tests;
    result
}

/// Child `k`'s index in a node record (see [`crate::blocks::bvh::BvhChild::index`]).
#[inline]
fn child_index(record: &[u8; BVH_NODE_RECORD], k: usize) -> u32 {
    u32::from_le_bytes(record[96 + 4 * k..100 + 4 * k].try_into().unwrap_or([0xff; 4]))
}

/// Child `k`'s triangle count in a node record (0 for an inner node or no child).
#[inline]
fn child_count(record: &[u8; BVH_NODE_RECORD], k: usize) -> u32 {
    u32::from_le_bytes(record[112 + 4 * k..116 + 4 * k].try_into().unwrap_or([0; 4]))
}

/// The error for a node record that points back up the tree.
fn corrupt(bvh_base: u32, index: u32) -> BlockError {
    let id = bvh_base + (index >> BVH_NODE_SHIFT);
    BlockError::Unavailable { id, reason: "corrupt BVH node block".into() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::bvh::{BvhNode, BVH_NO_CHILD};
    use crate::rng::Rng;

    /// The SSE2 slab test answers as the scalar one, bit for bit, on random boxes and
    /// rays and on the awkward ones: axis-parallel rays (infinite inverse), origins on a
    /// face (0 x inf = NaN), absent children, empty and degenerate boxes.
    #[test]
    fn the_sse2_slab_test_gives_the_scalar_bits() {
        let mut rng = Rng::from_words(&[7, 0x51ab]);
        let coord = |rng: &mut Rng| -> f64 {
            match (rng.next_f64() * 8.0) as u32 {
                0 => 0.0,
                1 => 1.0,
                _ => (rng.next_f64() - 0.5) * 4.0,
            }
        };
        for case in 0..20_000 {
            let mut node = BvhNodeLanes {
                lo: [[0.0; BVH_WIDTH]; 3],
                hi: [[0.0; BVH_WIDTH]; 3],
                index: [1, 2, 3, 4],
                count: [0; BVH_WIDTH],
            };
            for a in 0..3 {
                for k in 0..BVH_WIDTH {
                    let (x, y) = (coord(&mut rng) as f32, coord(&mut rng) as f32);
                    node.lo[a][k] = x.min(y);
                    node.hi[a][k] = x.max(y);
                }
            }
            if case % 7 == 0 {
                let k = case % BVH_WIDTH;
                node.index[k] = BVH_NO_CHILD;
                for a in 0..3 {
                    node.lo[a][k] = f32::INFINITY;
                    node.hi[a][k] = f32::NEG_INFINITY;
                }
            }
            let origin = [coord(&mut rng), coord(&mut rng), coord(&mut rng)];
            let mut direction = [rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5];
            if case % 5 == 0 {
                direction[case % 3] = if case % 2 == 0 { 0.0 } else { -0.0 };
            }
            let ray = SlabRay::new(origin, direction);
            let (t0, t1) = (rng.next_f64() * 0.1, if case % 3 == 0 { f64::INFINITY } else { rng.next_f64() * 5.0 });
            let mut block = [0u8; crate::blocks::BLOCK_SIZE];
            BvhNode { children: std::array::from_fn(|k| node.child(k)) }.encode(&mut block, 0);
            let record = crate::blocks::bvh::node_record(&block, 0);
            assert_eq!(BvhNodeLanes::read(record), node);
            let fast = ray.enter(record, t0, t1);
            let slow = ray.enter_scalar(record, t0, t1);
            let bits = |e: Entered| (e.near.map(f64::to_bits), e.mask);
            assert_eq!(bits(fast), bits(slow), "case {case}: {node:?} {origin:?} {direction:?}");
        }
    }
}
