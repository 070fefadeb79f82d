//! Ray casting through the BVH: a depth-first walk over nodes of eight children, the
//! nearest child first, that skips every node entered beyond the best hit so far.
//!
//! Node bounds are f32 rounded outward and padded at build time. The reference slab test
//! runs in f64 on those bounds with its far distance widened by `1 + 2 gamma(3)` (Ize
//! 2013), so a box holding a hit is never skipped; a node entered exactly at the best
//! distance is still visited, so that a tie can go to the lower patch id. The walk runs a
//! faster f32 test that is conservative against that one (it enters every box the f64
//! test enters, no later; see [`SlabRay`]), so it visits every node the f64 test would.
//! The patch test itself is the f64 watertight one, on the same corners as the patch
//! records: the grid's answer, bit for bit, whatever order the nodes are visited in.
//!
//! The slab test reads a node's bounds in place from its record and, on x86_64, runs
//! the children four at a time in an SSE register (the scalar code elsewhere gives the
//! same bits); a ray in the plane of a face (0 x inf = NaN) is not limited by that slab,
//! so it can only enter more boxes, never fewer.

use super::query::{Hit, NextUp, Query, TraceScratch};
use crate::blocks::bvh::{
    BvhNodeLanes, BvhTriangle, BVH_COUNT_AT, BVH_INDEX_AT, BVH_NODE_RECORD, BVH_NODE_SHIFT, BVH_NO_CHILD, BVH_ROW,
    BVH_TRIANGLE_RECORD, BVH_WIDTH, BVH_WIDTH_SHIFT,
};
use crate::blocks::BlockError;
use crate::view::SceneView;

mod packet;

pub(super) use packet::PACKET;

/// `1 + 2 gamma(3)`, gamma(n) = n eps / (1 - n eps) with eps = 2^-53.
const FAR_SLACK: f64 = 1.0 + 2.0 * (3.0 * f64::EPSILON * 0.5) / (1.0 - 3.0 * f64::EPSILON * 0.5);

/// The f32 test's relative widening, `2^-20`: sixteen f32 rounding units, against the
/// four roundings of its distances (difference, inverse, product, this scaling) and the
/// f64 test's own two, with room to spare.
const WIDEN: f32 = 1.0 / (1 << 20) as f32;

/// The smallest positive f32 (subnormal): subtracted from near and added to far distances
/// after scaling, for products that underflowed (where relative bounds do not hold).
const TINY: f32 = f32::from_bits(1);

/// Rays whose every entry distance below this could hold a hit take the f32 test: with
/// the scene's vertices within [`crate::scene::MAX_COORDINATE`] (< 2^100), an origin
/// within 2^100 and a largest direction component of at least 2^-25, every hit lies
/// nearer than 2^126, so a distance that overflows f32 (>= 2^128) is beyond any hit.
const FAST_ORIGIN: f64 = (1u128 << 100) as f64;
const FAST_MIN_DIRECTION: f64 = 1.0 / (1u64 << 25) as f64;

/// The smallest BVH whose rays walk it in packets ([`packs`]): one block of nodes.
const PACKET_MIN_NODES: u32 = crate::blocks::bvh::BVH_NODES_PER_BLOCK as u32;

/// The ray as the slab tests want it.
///
/// The reference test runs in f64 on the f32 bounds ([`SlabRay::enter_f64`]). The walk's
/// usual test runs in f32, four children to an SSE register ([`Narrow`]), and is
/// conservative against the f64 one: every box that test enters, this one enters too, at
/// a distance no greater. A widened box can only add nodes to the walk, never drop one,
/// and the hit kept (nearest, ties to the lower patch id) does not depend on the order
/// nodes are visited in.
///
/// Every ray takes the f32 test where its bounds hold (rays outside those ranges take the
/// f64 test), in the smallest BVH too: with nodes of eight children the f64 test of a
/// node costs more than the f32 test's per-ray data (measured on scenes/magg-paper.toml,
/// one node: 7 % more primary rays per second).
struct SlabRay {
    origin: [f64; 3],
    inv: [f64; 3],
    /// Per axis, whether the ray runs towards lower coordinates: then a box's near face
    /// on that axis is its `hi` and its far face its `lo`, for every box, so the slab
    /// test needs no comparison to order them.
    negative: [bool; 3],
}

/// The f32 test's per-ray data. Per axis the origin is rounded to f32 in the direction
/// that lowers the near distance (`o_near`) or raises the far one (`o_far`), so the
/// origin's rounding only ever widens the slab; the remaining errors are relative (the
/// f32 difference, the f32 inverse, the product) and [`WIDEN`] covers them, applied once
/// to the nearest far and farthest near over the axes (scaling by a positive constant
/// keeps their order), with [`TINY`] for products that underflowed.
///
/// Each value is kept four times over (`[v; 4]`, 16-byte aligned), the way the SSE2 test
/// uses it, so that a node visit reads it straight from memory rather than spreading it
/// across a register first.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Narrow {
    o_near: [[f32; 4]; 3],
    o_far: [[f32; 4]; 3],
    inv: [[f32; 4]; 3],
    /// The ray's octant: bit `a` set when it runs towards lower coordinates on axis `a`
    /// (see [`SlabRay::negative`] and [`rows`]).
    octant: u8,
}

/// Of a ray in `octant` (see [`Narrow::octant`]), the node record's rows of the near and
/// far faces on axis `a`: the walk is compiled once per octant, so that these are
/// constants rather than loads at every node.
#[inline(always)]
const fn rows(octant: u8, a: usize) -> (usize, usize) {
    if octant >> a & 1 == 1 {
        (3 + a, a)
    } else {
        (a, 3 + a)
    }
}

impl Narrow {
    /// The f32 test's data for a ray, `None` when its bounds do not hold for it: an
    /// inverse direction component that is neither a normal f32 nor infinite (in f64
    /// too), an origin beyond 2^100, or a direction whose largest component is below
    /// 2^-25.
    fn of(ray: &SlabRay, direction: [f64; 3]) -> Option<Narrow> {
        let (origin, inv, negative) = (ray.origin, ray.inv, ray.negative);
        let inv32 = [inv[0] as f32, inv[1] as f32, inv[2] as f32];
        let bounded = |a: usize| inv32[a].is_normal() || (inv32[a].is_infinite() && inv[a].is_infinite());
        let largest = direction[0].abs().max(direction[1].abs()).max(direction[2].abs());
        let within = |o: f64| o.abs() <= FAST_ORIGIN;
        // (`&`, not `&&`: every check is cheap, and branches are not.)
        let fits = bounded(0)
            & bounded(1)
            & bounded(2)
            & within(origin[0])
            & within(origin[1])
            & within(origin[2])
            & (largest >= FAST_MIN_DIRECTION);
        if !fits {
            return None;
        }
        // A larger origin lowers (b - o) * inv when inv > 0 and raises it when inv < 0.
        // (Written out per axis: the array closures were not always inlined. The origin
        // is finite here, within FAST_ORIGIN.)
        let (b, h) = (origin.map(f32_below_finite), origin.map(f32_above_finite));
        let (n0, n1, n2) = (negative[0], negative[1], negative[2]);
        let pick = |neg: bool, a: usize| if neg { [b[a]; 4] } else { [h[a]; 4] };
        Some(Narrow {
            o_near: [pick(n0, 0), pick(n1, 1), pick(n2, 2)],
            o_far: [pick(!n0, 0), pick(!n1, 1), pick(!n2, 2)],
            inv: [[inv32[0]; 4], [inv32[1]; 4], [inv32[2]; 4]],
            octant: n0 as u8 | (n1 as u8) << 1 | (n2 as u8) << 2,
        })
    }

    /// Which of the child boxes of the node `record` the ray enters within `[t0, t1]`
    /// (rounded outward to f32), and at what distance (a lower bound).
    /// `OCTANT` is the ray's [`Narrow::octant`].
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn enter<const OCTANT: u8>(&self, record: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        // SAFETY: SSE2 is part of the x86_64 baseline, so every processor that runs this
        // build has it; the function reads nothing but its arguments.
        unsafe { self.enter_sse2::<OCTANT>(record, t0, t1) }
    }

    /// [`Narrow::enter`] with SSE2, four children at a time: the same operations on the
    /// same values as [`Narrow::enter_scalar`], so the same bits (`max` and `min` keep
    /// their second operand when either is NaN, as the scalar comparisons do).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    fn enter_sse2<const OCTANT: u8>(&self, record: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        use std::arch::x86_64::*;
        // SAFETY: `v` is four f32, 16-byte aligned (`Narrow` is `align(16)` and its fields
        // are arrays of them).
        let lanes = |v: &[f32; 4]| unsafe { _mm_load_ps(v.as_ptr()) };
        let mut out = Entered { near: [0.0; BVH_WIDTH], mask: 0 };
        for quad in 0..BVH_WIDTH / 4 {
            if !quad_used(record, quad) {
                break;
            }
            let mut near = _mm_set1_ps(f32::NEG_INFINITY);
            let mut far = _mm_set1_ps(f32::INFINITY);
            for a in 0..3 {
                let (near_row, far_row) = rows(OCTANT, a);
                let inv = lanes(&self.inv[a]);
                let n = _mm_mul_ps(_mm_sub_ps(row_quad(record, near_row, quad), lanes(&self.o_near[a])), inv);
                let f = _mm_mul_ps(_mm_sub_ps(row_quad(record, far_row, quad), lanes(&self.o_far[a])), inv);
                near = _mm_max_ps(n, near);
                far = _mm_min_ps(f, far);
            }
            widened_sse2(near, far, t0, t1, quad, &mut out);
        }
        out
    }

    /// [`Narrow::enter`] one lane at a time (other processors; the SSE2 version's oracle
    /// in the tests).
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    #[inline]
    fn enter_scalar(&self, record: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        let node = &BvhNodeLanes::read(record);
        let mut near = [f32::NEG_INFINITY; BVH_WIDTH];
        let mut far = [f32::INFINITY; BVH_WIDTH];
        for a in 0..3 {
            let (near_face, far_face) =
                if rows(self.octant, a).0 > a { (&node.hi[a], &node.lo[a]) } else { (&node.lo[a], &node.hi[a]) };
            let (o_near, o_far, inv) = (self.o_near[a][0], self.o_far[a][0], self.inv[a][0]);
            for k in 0..BVH_WIDTH {
                let tn = (near_face[k] - o_near) * inv;
                let tf = (far_face[k] - o_far) * inv;
                near[k] = if tn > near[k] { tn } else { near[k] };
                far[k] = if tf < far[k] { tf } else { far[k] };
            }
        }
        widened_scalar(near, far, t0, t1)
    }

    /// [`Narrow::enter`] on processors without SSE2 code here.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline]
    fn enter<const OCTANT: u8>(&self, record: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        self.enter_scalar(record, t0, t1)
    }
}

/// Row `r` of node `record`'s bounds (`lo` x, y, z, then `hi` x, y, z), children
/// `4 quad` to `4 quad + 3`, in an SSE register (f32, little endian like the processor).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn row_quad(record: &[u8; BVH_NODE_RECORD], r: usize, quad: usize) -> std::arch::x86_64::__m128 {
    let at = (BVH_ROW * r + 16 * quad).min(BVH_NODE_RECORD - 16);
    // SAFETY: `at + 16` is within the record's bytes (clamped above; for r < 6 and
    // quad < BVH_WIDTH / 4 the clamp changes nothing); an unaligned load.
    unsafe { std::arch::x86_64::_mm_loadu_ps(record.as_ptr().add(at).cast::<f32>()) }
}

/// The f32 slab test's end, in SSE2, for children `4 quad` to `4 quad + 3`: their
/// farthest near and nearest far distances widened by [`WIDEN`] and [`TINY`], clamped to
/// `[t0, t1]`, written to `out` with the boxes entered (within the interval, not only at
/// infinity).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
#[inline]
fn widened_sse2(
    near: std::arch::x86_64::__m128,
    far: std::arch::x86_64::__m128,
    t0: f32,
    t1: f32,
    quad: usize,
    out: &mut Entered<f32>,
) {
    use std::arch::x86_64::*;
    let tiny = _mm_set1_ps(TINY);
    let near = _mm_sub_ps(_mm_mul_ps(near, _mm_set1_ps(1.0 - WIDEN)), tiny);
    let far = _mm_add_ps(_mm_mul_ps(far, _mm_set1_ps(1.0 + WIDEN)), tiny);
    let near = _mm_max_ps(near, _mm_set1_ps(t0));
    let far = _mm_min_ps(far, _mm_set1_ps(t1));
    let inside = _mm_and_ps(_mm_cmple_ps(near, far), _mm_cmplt_ps(near, _mm_set1_ps(f32::INFINITY)));
    let mut four = [0.0f32; 4];
    // SAFETY: `four` holds four f32 (an unaligned store).
    unsafe { _mm_storeu_ps(four.as_mut_ptr(), near) };
    if let Some(slots) = out.near.get_mut(4 * quad..4 * quad + 4) {
        slots.copy_from_slice(&four);
    }
    out.mask |= (_mm_movemask_ps(inside) as u32) << (4 * quad);
}

/// [`widened_sse2`] one lane at a time: the same bits.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline]
fn widened_scalar(mut near: [f32; BVH_WIDTH], far: [f32; BVH_WIDTH], t0: f32, t1: f32) -> Entered<f32> {
    let mut mask = 0;
    for k in 0..BVH_WIDTH {
        let n = near[k] * (1.0 - WIDEN) - TINY;
        let f = far[k] * (1.0 + WIDEN) + TINY;
        near[k] = if n > t0 { n } else { t0 };
        let f = if f < t1 { f } else { t1 };
        mask |= ((near[k] <= f && near[k] < f32::INFINITY) as u32) << k;
    }
    Entered { near, mask }
}

impl SlabRay {
    /// The ray's slab data. (The f32 test's, [`Narrow::of`] it, is kept apart, so that it
    /// is built where the walk uses it, not moved.)
    #[inline(always)]
    fn new(origin: [f64; 3], direction: [f64; 3]) -> SlabRay {
        let inv = [1.0 / direction[0], 1.0 / direction[1], 1.0 / direction[2]];
        let negative = [inv[0].is_sign_negative(), inv[1].is_sign_negative(), inv[2].is_sign_negative()];
        SlabRay { origin, inv, negative }
    }

    /// The f64 test: the boxes side by side, in f64 from the f32 bounds, the far
    /// distance widened by [`FAR_SLACK`] (Ize 2013), two lanes at a time in SSE2
    /// registers.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn enter_f64(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered<f64> {
        // SAFETY: SSE2 is part of the x86_64 baseline, so every processor that runs this
        // build has it; the function reads nothing but its arguments.
        unsafe { self.enter_f64_sse2(record, t0, t1) }
    }

    /// [`SlabRay::enter_f64`] with SSE2: the same operations on the same values, so the
    /// same bits as [`SlabRay::enter_f64_scalar`] (`max` and `min` keep their second
    /// operand when either is NaN, as the scalar comparisons do).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    fn enter_f64_sse2(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered<f64> {
        use std::arch::x86_64::*;
        // Row r of the record's bounds, children 4 quad and 4 quad + 1, and 4 quad + 2 and
        // 4 quad + 3, widened to f64.
        let row = |r: usize, quad: usize| {
            let v = row_quad(record, r, quad);
            (_mm_cvtps_pd(v), _mm_cvtps_pd(_mm_movehl_ps(v, v)))
        };
        let mut out = Entered { near: [0.0; BVH_WIDTH], mask: 0 };
        for quad in 0..BVH_WIDTH / 4 {
            if !quad_used(record, quad) {
                break;
            }
            let (mut near01, mut near23) = (_mm_set1_pd(t0), _mm_set1_pd(t0));
            let (mut far01, mut far23) = (_mm_set1_pd(f64::INFINITY), _mm_set1_pd(f64::INFINITY));
            for a in 0..3 {
                let (near_row, far_row) = if self.negative[a] { (3 + a, a) } else { (a, 3 + a) };
                let (o, inv) = (_mm_set1_pd(self.origin[a]), _mm_set1_pd(self.inv[a]));
                let (n01, n23) = row(near_row, quad);
                let (f01, f23) = row(far_row, quad);
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
            out.mask |= (mask as u32) << (4 * quad);
            let lanes = |v: __m128d| [_mm_cvtsd_f64(v), _mm_cvtsd_f64(_mm_unpackhi_pd(v, v))];
            let ([n0, n1], [n2, n3]) = (lanes(near01), lanes(near23));
            if let Some(slots) = out.near.get_mut(4 * quad..4 * quad + 4) {
                slots.copy_from_slice(&[n0, n1, n2, n3]);
            }
        }
        out
    }

    /// [`SlabRay::enter_f64`] one lane at a time (other processors; the SSE2 version's
    /// oracle, and the f32 test's reference, in the tests).
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    #[inline]
    fn enter_f64_scalar(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered<f64> {
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

    /// [`SlabRay::enter_f64`] on processors without SSE2 code here.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline]
    fn enter_f64(&self, record: &[u8; BVH_NODE_RECORD], t0: f64, t1: f64) -> Entered<f64> {
        self.enter_f64_scalar(record, t0, t1)
    }
}

/// An f32 not above `x`, within two f32 units of it (not always the nearest: no
/// branch), for finite `x` within 2^100 in magnitude; infinite `x` stays infinite.
/// Rounding to nearest moves `x - |x| 2^-23 - 2^-149` by at most half a unit, which is
/// less than what was taken off.
#[inline]
fn f32_below(x: f64) -> f32 {
    if x.is_finite() {
        (x - x.abs() * F32_UNIT - F32_TINY) as f32
    } else {
        x as f32
    }
}

/// [`f32_below`] for a finite `x` (no branch).
#[inline(always)]
fn f32_below_finite(x: f64) -> f32 {
    (x - x.abs() * F32_UNIT - F32_TINY) as f32
}

/// [`f32_above`] for a finite `x` (no branch).
#[inline(always)]
fn f32_above_finite(x: f64) -> f32 {
    (x + x.abs() * F32_UNIT + F32_TINY) as f32
}

/// An f32 not below `x`, as [`f32_below`] the other way.
#[inline]
fn f32_above(x: f64) -> f32 {
    if x.is_finite() {
        (x + x.abs() * F32_UNIT + F32_TINY) as f32
    } else {
        x as f32
    }
}

/// 2^-23, an f32 unit relative to its value (at most twice the half unit of rounding).
const F32_UNIT: f64 = 1.0 / (1u32 << 23) as f64;
/// 2^-149, the smallest positive f32, in f64.
const F32_TINY: f64 = TINY as f64;

/// What a slab test found for a node's children, its distances in `T` (f32 for the f32
/// test, f64 for the f64 one).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entered<T> {
    /// Distance at which the ray enters each child's box, or one below it (meaningful
    /// for those entered).
    near: [T; BVH_WIDTH],
    /// Bit k set when the ray enters child k's box within the interval, at a finite
    /// distance. An absent child's box is empty (`lo` = +inf, `hi` = -inf), which every
    /// ray enters at +inf, so its bit is never set; a ray parallel to a slab and outside
    /// it enters at +inf too.
    mask: u32,
}

/// A slab test as the walk runs it: which children of a node the ray enters, and at
/// what distance (a lower bound: a node is skipped only when it is entered beyond the
/// best hit).
trait BoxTest {
    /// The far bound as the test takes it, and the type of its distances.
    type Bound: Copy;
    /// The far bound `t` (the best hit's distance, or the query's `tmax`).
    fn bound(&self, t: f64) -> Self::Bound;
    /// The children of node `record` entered within the query's `tmin` and `bound`.
    fn enter(&self, record: &[u8; BVH_NODE_RECORD], bound: Self::Bound) -> Entered<Self::Bound>;
    /// A distance of [`BoxTest::enter`] in f64 (exactly).
    fn wide(t: Self::Bound) -> f64;
    /// A key that orders child `k` entered at `t` among its siblings by distance, ties
    /// by `k`: the distance's bits (a non-negative float's bits order as the float; a
    /// distance below zero, from a `tmin` rounded down, is taken as zero) above the
    /// child's slot. An f64 distance loses its lowest bits to the slot; the order
    /// is only the walk's guess at what to visit first, and changes no answer.
    fn key(t: Self::Bound, k: usize) -> u64;
}

/// The f64 test, from `t0`.
struct Wide<'a>(&'a SlabRay, f64);

impl BoxTest for Wide<'_> {
    type Bound = f64;
    #[inline(always)]
    fn bound(&self, t: f64) -> f64 {
        t
    }
    #[inline(always)]
    fn enter(&self, record: &[u8; BVH_NODE_RECORD], bound: f64) -> Entered<f64> {
        self.0.enter_f64(record, self.1, bound)
    }
    #[inline(always)]
    fn wide(t: f64) -> f64 {
        t
    }
    #[inline(always)]
    fn key(t: f64, k: usize) -> u64 {
        (t.max(0.0).to_bits() & !(BVH_WIDTH as u64 - 1)) | k as u64
    }
}

/// The f32 test, from `t0` rounded down, of a ray in `OCTANT` (its [`Narrow::octant`]).
struct Narrowed<'a, const OCTANT: u8>(&'a Narrow, f32);

impl<const OCTANT: u8> BoxTest for Narrowed<'_, OCTANT> {
    type Bound = f32;
    #[inline(always)]
    fn bound(&self, t: f64) -> f32 {
        f32_above(t)
    }
    #[inline(always)]
    fn enter(&self, record: &[u8; BVH_NODE_RECORD], bound: f32) -> Entered<f32> {
        self.0.enter::<OCTANT>(record, self.1, bound)
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

/// [`super::cast`] through the BVH: the f32 slab test where it applies and pays (see
/// [`SlabRay`]), the f64 test otherwise; the walk is compiled for each.
#[inline(never)]
pub(super) fn cast(view: &mut SceneView, scratch: &mut TraceScratch, q: &Query) -> Result<Option<Hit>, BlockError> {
    let (o, d) = (q.ray.origin.to_array(), q.ray.direction.to_array());
    let t0 = q.tmin.max(0.0);
    let slab = SlabRay::new(o, d);
    let narrow = Narrow::of(&slab, d);
    match &narrow {
        // A tmin beyond f32's range rounds to infinity, which no box is entered within:
        // no hit of a ray the f32 test takes lies that far (see FAST_ORIGIN).
        // (One walk per octant: see `rows`.)
        Some(n) => {
            let t = f32_below(t0);
            match n.octant {
                0 => walk(view, scratch, q, &Narrowed::<0>(n, t)),
                1 => walk(view, scratch, q, &Narrowed::<1>(n, t)),
                2 => walk(view, scratch, q, &Narrowed::<2>(n, t)),
                3 => walk(view, scratch, q, &Narrowed::<3>(n, t)),
                4 => walk(view, scratch, q, &Narrowed::<4>(n, t)),
                5 => walk(view, scratch, q, &Narrowed::<5>(n, t)),
                6 => walk(view, scratch, q, &Narrowed::<6>(n, t)),
                _ => walk(view, scratch, q, &Narrowed::<7>(n, t)),
            }
        }
        None => walk(view, scratch, q, &Wide(&slab, t0)),
    }
}

/// Whether `view`'s rays walk its BVH in packets: a BVH (not the grid) of at least
/// [`PACKET_MIN_NODES`] nodes (in smaller ones a ray visits a node or two, and the
/// packet's set-up would cost more than it saves).
pub(super) fn packs(view: &SceneView) -> bool {
    view.header.settings.accel == crate::scene::Accel::Bvh && view.header.bvh.nodes >= PACKET_MIN_NODES
}

/// [`cast`] of each of `queries` (at most [`PACKET`], one origin) into `out`: walked
/// together as a packet where they can be packed (see [`packet`]), one at a time
/// otherwise; the same answers either way.
pub(super) fn cast_packet(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    queries: &[Query],
    out: &mut [Option<Hit>],
) -> Result<(), BlockError> {
    let packed =
        if queries.len() > 1 && view.header.bvh.nodes >= PACKET_MIN_NODES { packet::Spread::of(queries) } else { None };
    match packed {
        Some(spread) => packet::walk(view, scratch, queries, &spread, out),
        None => {
            for (q, o) in queries.iter().zip(out.iter_mut()) {
                *o = cast(view, scratch, q)?;
            }
            Ok(())
        }
    }
}

/// The depth-first walk from the root, with the slab test `boxes` (a function of its own
/// for each test, so that each keeps its own registers).
///
/// A node whose ray enters one child goes straight on to it; of two or more, the
/// nearest is visited next and the others are stacked farthest first (their order from
/// [`BoxTest::key`]). An entry taken from the stack is skipped when it was entered
/// beyond the best hit found since. An `any` query (occlusion) is walked the same way:
/// taking the children in the node's order instead was measured slower (an occluder
/// is found later).
#[inline(never)]
fn walk<B: BoxTest>(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    q: &Query,
    boxes: &B,
) -> Result<Option<Hit>, BlockError> {
    let mut best: Option<Hit> = None;
    // The farthest distance still of use (the best hit's, or tmax), as the walk and as
    // the slab test take it, and the triangle test's upper limit (next above it, for
    // ties); renewed when a leaf changes the best hit.
    let mut bound = (q.tmax, boxes.bound(q.tmax));
    let mut upper = q.tmax.next_up_or(q.tmax);
    let (mut steps, mut tests) = (0u64, 0u64);
    let mut stack = std::mem::take(&mut scratch.stack);
    stack.clear();
    let (max_steps, bvh_base) = (view.header.bvh.nodes as u64, view.header.layout.bvh_base);
    // The entry visited now: a node index (count 0), or a leaf's first triangle address
    // and triangle count.
    let (mut index, mut count) = (0u32, 0u32);
    let result = 'walk: loop {
        if count > 0 {
            let leaf = match view.bvh_leaf(index, count) {
                Ok(l) => l,
                Err(e) => break Err(e),
            };
            if test_leaf(q, leaf, &mut upper, &mut best, &mut tests) {
                if q.any {
                    break 'walk Ok(best);
                }
                if let Some(b) = best {
                    bound = (b.t, boxes.bound(b.t));
                }
            }
        } else {
            let record = match visit(view, index, &mut steps, (max_steps, bvh_base)) {
                Ok(r) => r,
                Err(e) => break Err(e),
            };
            // Nodes are written depth first, so a ray visits each node at most once; a
            // corrupt block whose child points back up the tree is caught by the step
            // limit of `visit` (more visits than nodes), not by a check per child.
            let Entered { near, mask } = boxes.enter(record, bound.1);
            if mask != 0 {
                let first = mask.trailing_zeros() as usize;
                let k = if mask & (mask - 1) == 0 {
                    first
                } else {
                    let mut keys = [u64::MAX; BVH_WIDTH];
                    let (mut rest, mut n) = (mask, 0);
                    while rest != 0 {
                        let k = rest.trailing_zeros() as usize;
                        rest &= rest - 1;
                        keys[n] = B::key(near[k], k);
                        n += 1;
                    }
                    sort_keys(&mut keys, n);
                    for &key in keys[1..n].iter().rev() {
                        let k = key as usize & (BVH_WIDTH - 1);
                        stack.push((child_index(record, k), child_count(record, k), B::wide(near[k])));
                    }
                    keys[0] as usize & (BVH_WIDTH - 1)
                };
                (index, count) = (child_index(record, k), child_count(record, k));
                continue;
            }
        }
        // The nearest entry stacked that is not beyond the best hit.
        loop {
            match stack.pop() {
                None => break 'walk Ok(best),
                Some((i, c, near)) if !(near > bound.0) => {
                    (index, count) = (i, c);
                    break;
                }
                Some(_) => {}
            }
        }
    };
    scratch.stack = stack;
    view.counters.grid_steps += steps;
    view.counters.patch_tests += tests;
    result
}

/// Sorts the first `n` (2 to [`BVH_WIDTH`]) of `keys` ascending: one exchange for two
/// (the usual case), an insertion sort for more.
#[inline(always)]
fn sort_keys(keys: &mut [u64; BVH_WIDTH], n: usize) {
    if n == 2 {
        let (x, y) = (keys[0], keys[1]);
        (keys[0], keys[1]) = (x.min(y), x.max(y));
        return;
    }
    for i in 1..n.min(BVH_WIDTH) {
        let x = keys[i];
        let mut j = i;
        while j > 0 && keys[j - 1] > x {
            keys[j] = keys[j - 1];
            j -= 1;
        }
        keys[j] = x;
    }
}

/// Tests query `q` against the triangle records of `leaf` (each read in place: the
/// corners by the test, the patch id here), keeping the nearest hit in `best` and its
/// upper limit `upper` renewed; counts the tests. Returns whether a hit was kept; an
/// `any` query stops at the first. Both walks run it.
#[inline(always)]
fn test_leaf(q: &Query, leaf: &[u8], upper: &mut f64, best: &mut Option<Hit>, tests: &mut u64) -> bool {
    let mut kept = false;
    for record in leaf.chunks_exact(BVH_TRIANGLE_RECORD) {
        let (corners, patch) = BvhTriangle::parts(record);
        if patch == q.exclude {
            continue;
        }
        *tests += 1;
        if q.test_record(corners, patch, *upper, best) {
            if q.any {
                return true;
            }
            if let Some(b) = best {
                *upper = b.t.next_up_or(b.t);
            }
            kept = true;
        }
    }
    kept
}

/// Node `index`'s record, as the walk's next node visit (counted in `steps`): an error
/// past `max_steps` visits, more than the tree has nodes. Nodes are written depth first,
/// so a walk visits each at most once; a corrupt block whose child points back up the
/// tree is caught here, not by a check per child. Both walks run it.
#[inline(always)]
fn visit<'v>(
    view: &'v mut SceneView,
    index: u32,
    steps: &mut u64,
    (max_steps, bvh_base): (u64, u32),
) -> Result<&'v [u8; BVH_NODE_RECORD], BlockError> {
    *steps += 1;
    if *steps > max_steps {
        return Err(corrupt(bvh_base, index));
    }
    view.bvh_node_record(index)
}

/// Whether node `record` has a child among slots `4 quad` to `4 quad + 3`: the children
/// of a node take its first slots, so a quad whose first slot is empty is empty, and so
/// are those after it. The slab tests stop at the first empty quad (a node of four
/// children or fewer costs the test of one).
#[inline(always)]
fn quad_used(record: &[u8; BVH_NODE_RECORD], quad: usize) -> bool {
    quad == 0 || child_index(record, 4 * quad) != BVH_NO_CHILD
}

/// Child `k`'s index in a node record (see [`crate::blocks::bvh::BvhChild::index`]).
#[inline]
fn child_index(record: &[u8; BVH_NODE_RECORD], k: usize) -> u32 {
    let at = BVH_INDEX_AT + 4 * k;
    u32::from_le_bytes(record[at..at + 4].try_into().unwrap_or([0xff; 4]))
}

/// Child `k`'s triangle count in a node record (0 for an inner node or no child).
#[inline]
fn child_count(record: &[u8; BVH_NODE_RECORD], k: usize) -> u32 {
    let at = BVH_COUNT_AT + 4 * k;
    u32::from_le_bytes(record[at..at + 4].try_into().unwrap_or([0; 4]))
}

/// The error for a node record that points back up the tree.
fn corrupt(bvh_base: u32, index: u32) -> BlockError {
    let id = bvh_base + (index >> BVH_NODE_SHIFT);
    BlockError::Unavailable { id, reason: "corrupt BVH node block".into() }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::blocks::bvh::{f32_down, f32_up, BvhNode, BVH_NO_CHILD};
    use crate::rng::Rng;

    /// A random node and ray, including the awkward ones: axis-parallel rays (infinite
    /// inverse), origins on a face (0 x inf = NaN), absent children, empty and
    /// degenerate boxes, boxes touching the origin, far and tiny scales.
    fn case(rng: &mut Rng, case: usize) -> (BvhNodeLanes, SlabRay, Option<Narrow>, f64, f64) {
        let scale = match case % 11 {
            0 => 1e-30,
            1 => 1e25,
            _ => 1.0,
        };
        let coord = |rng: &mut Rng| -> f64 {
            scale
                * match (rng.next_f64() * 8.0) as u32 {
                    0 => 0.0,
                    1 => 1.0,
                    _ => (rng.next_f64() - 0.5) * 4.0,
                }
        };
        let mut node = random_node(rng, coord);
        if case % 7 == 0 {
            // Absent children, as the build leaves them: the last slots, from k on.
            for k in (case / 7) % BVH_WIDTH + 1..BVH_WIDTH {
                node.index[k] = BVH_NO_CHILD;
                for a in 0..3 {
                    node.lo[a][k] = f32::INFINITY;
                    node.hi[a][k] = f32::NEG_INFINITY;
                }
            }
        }
        let mut origin = [coord(rng), coord(rng), coord(rng)];
        if case % 13 == 0 {
            // On a corner of a box, in f64 just off it.
            let k = case % BVH_WIDTH;
            origin = [0, 1, 2].map(|a| node.lo[a][k] as f64 * (1.0 + 1e-12));
        }
        let mut direction = [rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5];
        if case % 5 == 0 {
            direction[case % 3] = if case % 2 == 0 { 0.0 } else { -0.0 };
        }
        if case % 17 == 0 {
            direction[(case + 1) % 3] *= 1e-30;
        }
        let ray = SlabRay::new(origin, direction);
        let narrow = Narrow::of(&ray, direction);
        let (t0, t1) = (
            if case % 4 == 0 { 0.0 } else { rng.next_f64() * 0.1 * scale },
            if case % 3 == 0 { f64::INFINITY } else { rng.next_f64() * 5.0 * scale },
        );
        (node, ray, narrow, t0, t1)
    }

    /// A node of inner children whose boxes have corners drawn by `coord`, rounded
    /// outward to f32.
    pub(super) fn random_node(rng: &mut Rng, coord: impl Fn(&mut Rng) -> f64) -> BvhNodeLanes {
        let mut node = BvhNodeLanes {
            lo: [[0.0; BVH_WIDTH]; 3],
            hi: [[0.0; BVH_WIDTH]; 3],
            index: std::array::from_fn(|k| k as u32 + 1),
            count: [0; BVH_WIDTH],
        };
        for a in 0..3 {
            for k in 0..BVH_WIDTH {
                let (x, y) = (coord(rng), coord(rng));
                node.lo[a][k] = f32_down(x.min(y));
                node.hi[a][k] = f32_up(x.max(y));
            }
        }
        node
    }

    /// The block holding `node` as its first record.
    pub(super) fn record(node: &BvhNodeLanes) -> [u8; crate::blocks::BLOCK_SIZE] {
        let mut block = [0u8; crate::blocks::BLOCK_SIZE];
        BvhNode { children: std::array::from_fn(|k| node.child(k)) }.encode(&mut block, 0);
        assert_eq!(&BvhNodeLanes::read(crate::blocks::bvh::node_record(&block, 0)), node);
        block
    }

    /// `near` where `mask` says a child is entered, zero elsewhere.
    pub(super) fn entered<T: Copy + Default>(near: [T; BVH_WIDTH], mask: u32) -> [T; BVH_WIDTH] {
        std::array::from_fn(|k| if mask >> k & 1 == 1 { near[k] } else { T::default() })
    }

    /// [`Narrow::enter`] as compiled for `n`'s octant (the walk's).
    pub(super) fn enter_in_octant(n: &Narrow, r: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        match n.octant {
            0 => n.enter::<0>(r, t0, t1),
            1 => n.enter::<1>(r, t0, t1),
            2 => n.enter::<2>(r, t0, t1),
            3 => n.enter::<3>(r, t0, t1),
            4 => n.enter::<4>(r, t0, t1),
            5 => n.enter::<5>(r, t0, t1),
            6 => n.enter::<6>(r, t0, t1),
            _ => n.enter::<7>(r, t0, t1),
        }
    }

    /// The SSE2 slab tests answer as the scalar ones, bit for bit.
    #[test]
    fn the_sse2_slab_tests_give_the_scalar_bits() {
        let mut rng = Rng::from_words(&[7, 0x51ab]);
        for c in 0..20_000 {
            let (node, ray, narrow, t0, t1) = case(&mut rng, c);
            let block = record(&node);
            let r = crate::blocks::bvh::node_record(&block, 0);
            // (The distances of the children entered: those of the others mean nothing.)
            let bits = |e: Entered<f64>| (entered(e.near, e.mask).map(f64::to_bits), e.mask);
            assert_eq!(bits(ray.enter_f64(r, t0, t1)), bits(ray.enter_f64_scalar(r, t0, t1)), "case {c}: {node:?}");
            if let Some(n) = narrow {
                let fast = enter_in_octant(&n, r, f32_below(t0), f32_above(t1));
                let slow = n.enter_scalar(r, f32_below(t0), f32_above(t1));
                let bits = |e: Entered<f32>| (entered(e.near, e.mask).map(f32::to_bits), e.mask);
                assert_eq!(bits(fast), bits(slow), "case {c}: {node:?}");
            }
        }
    }

    /// The f32 test enters every box the f64 test enters, at a distance no greater: so
    /// the walk visits every node it visited with the f64 test (and the hit is the same).
    /// Checked as the walk runs it ([`Narrowed`], its far bound from [`BoxTest::bound`]).
    #[test]
    fn the_f32_slab_test_is_conservative_against_the_f64_one() {
        let mut rng = Rng::from_words(&[8, 0x51ab]);
        let mut narrowed = 0;
        for c in 0..200_000 {
            let (node, ray, narrow, t0, t1) = case(&mut rng, c);
            let Some(n) = narrow else { continue };
            narrowed += 1;
            let block = record(&node);
            let r = crate::blocks::bvh::node_record(&block, 0);
            let exact = ray.enter_f64_scalar(r, t0, t1);
            let (boxes, t0) = (Narrowed::<0>(&n, f32_below(t0)), f32_below(t0));
            let wide = enter_in_octant(&n, r, t0, boxes.bound(t1));
            assert_eq!(wide.mask & exact.mask, exact.mask, "case {c}: {node:?}");
            for k in 0..BVH_WIDTH {
                if exact.mask >> k & 1 == 1 {
                    assert!(wide.near[k] as f64 <= exact.near[k], "case {c}, child {k}: {node:?}");
                }
            }
        }
        // Most cases take the f32 test (the others: see the next test).
        assert!(narrowed > 150_000, "{narrowed}");
    }

    /// Rays the f32 test cannot bound take the f64 one.
    #[test]
    fn extreme_rays_take_the_f64_test() {
        let narrow = |o: [f64; 3], d: [f64; 3]| Narrow::of(&SlabRay::new(o, d), d).is_some();
        assert!(narrow([0.0; 3], [1.0, 0.5, 0.0]));
        assert!(narrow([1e29, -1e29, 0.0], [0.0, -0.0, 1.0]));
        assert!(!narrow([1e31, 0.0, 0.0], [1.0, 0.0, 0.0]));
        assert!(!narrow([0.0; 3], [1e-30, 1e-30, 1e-30]));
        assert!(!narrow([0.0; 3], [1.0, 1e-300, 0.0]));
        assert!(!narrow([0.0; 3], [1.0, 1e39, 0.0]));
    }
}
