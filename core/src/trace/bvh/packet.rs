//! Packets: up to [`PACKET`] rays that leave one origin (a pinhole camera's eye, a point
//! light) walk the BVH together. A node is read, its boxes tested, its children
//! ordered and pushed once for the whole packet, by a slab test on the interval of the
//! rays' inverse directions (interval arithmetic, as in Boulos et al. 2006), in f32 like
//! the single ray's test ([`super::Narrow`]). Where a node's children include leaves,
//! each ray also runs its own slab test on them, so that a leaf's triangles are tested
//! only by the rays that enter its box, each by the f64 watertight test as alone.
//!
//! The interval test is conservative against each of its rays' own f32 test, so against
//! their f64 test too: every box one of the rays enters, the packet enters, no later. For
//! a fixed difference `D` (the same origin, rounded the same way for rays whose
//! directions have the same signs), `fl(D * inv)` is monotone in `inv`, so the products
//! at the interval's ends bound every ray's product as its own test computes it; the
//! widening that follows is monotone too. A ray's own test on a leaf's box is its test
//! as alone. Each ray therefore reaches every leaf it would reach alone within its best
//! hit so far, and keeps the hit it keeps alone: the nearest, ties to the lower patch
//! id, which does not depend on the order or the number of nodes visited. An occlusion
//! ray leaves the packet at its first hit, the packet when none is left.
//!
//! Rays whose directions differ in sign on an axis, or that have an infinite inverse (a
//! direction component of zero, whose products can be NaN at a face through the origin),
//! or that the f32 test does not take, are not packed: the caller traces them alone.

use super::{
    child_count, child_index, f32_above, f32_below, test_leaf, visit, widened_scalar, Entered, FAST_MIN_DIRECTION,
    FAST_ORIGIN,
};
#[cfg(target_arch = "x86_64")]
use super::{quad_used, row_quad, widened_sse2};
use crate::blocks::bvh::{BVH_NODE_RECORD, BVH_WIDTH};
use crate::blocks::BlockError;
use crate::trace::query::{Hit, NextUp, Query, TraceScratch};
use crate::view::SceneView;

/// The most rays one packet walks together (one bit each in a `u32` mask).
pub const PACKET: usize = 16;

/// Per axis, four copies of an f32 (one SSE register's worth), 16-byte aligned.
type Splat3 = [[f32; 4]; 3];

/// A node record's bytes.
type Record = [u8; BVH_NODE_RECORD];

/// A packet's slab data: the shared origin rounded as each ray's f32 test rounds it, per
/// axis the smallest and largest of the rays' f32 inverse directions, and each ray's own.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(super) struct Spread {
    o_near: Splat3,
    o_far: Splat3,
    inv_lo: Splat3,
    inv_hi: Splat3,
    /// Each ray's inverse direction in f32, as its own test has it.
    inv: [Splat3; PACKET],
    /// Per axis, the record rows of the near and far faces (the same for every ray).
    rows: [(usize, usize); 3],
}

impl Spread {
    /// The packet of `queries` (one origin, at most [`PACKET`]), `None` when one of them
    /// cannot be packed: the checks of [`super::Narrow::of`] for each ray, the signs of
    /// the first, no infinite inverse. Each ray's f32 inverse is computed as there
    /// (`1 / d` in f64, rounded to f32), the origin rounded once.
    pub(super) fn of(queries: &[Query]) -> Option<Spread> {
        let first = queries.first()?;
        let origin = first.ray.origin.to_array();
        let negative = first.ray.direction.to_array().map(|d| (1.0 / d).is_sign_negative());
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut inv = [[[0.0f32; 4]; 3]; PACKET];
        // (`&`, not `&&`: every check is cheap, and branches are not.)
        let mut fits =
            (origin[0].abs() <= FAST_ORIGIN) & (origin[1].abs() <= FAST_ORIGIN) & (origin[2].abs() <= FAST_ORIGIN);
        for (q, own) in queries.iter().zip(&mut inv) {
            let d = q.ray.direction.to_array();
            fits &= q.ray.origin == first.ray.origin;
            fits &= d[0].abs().max(d[1].abs()).max(d[2].abs()) >= FAST_MIN_DIRECTION;
            for a in 0..3 {
                let i64 = 1.0 / d[a];
                let i32 = i64 as f32;
                fits &= i32.is_normal() & (i64.is_sign_negative() == negative[a]);
                lo[a] = lo[a].min(i32);
                hi[a] = hi[a].max(i32);
                own[a] = [i32; 4];
            }
        }
        if !fits {
            return None;
        }
        // As `Narrow::of`: a larger origin lowers (b - o) * inv when inv > 0.
        let (below, above) = (origin.map(f32_below), origin.map(f32_above));
        let pick = |a: usize, neg: bool| if negative[a] == neg { [below[a]; 4] } else { [above[a]; 4] };
        Some(Spread {
            o_near: [pick(0, true), pick(1, true), pick(2, true)],
            o_far: [pick(0, false), pick(1, false), pick(2, false)],
            inv_lo: lo.map(|v| [v; 4]),
            inv_hi: hi.map(|v| [v; 4]),
            inv,
            rows: [0, 1, 2].map(|a| if negative[a] { (3 + a, a) } else { (a, 3 + a) }),
        })
    }

    /// Which child boxes of node `record` some ray of the packet may enter within
    /// `[t0, t1]`, and a distance no greater than any of them enters it at.
    #[inline]
    pub(super) fn enter(&self, record: &[u8; BVH_NODE_RECORD], t0: f32, t1: f32) -> Entered<f32> {
        enter(self, [&self.inv_lo, &self.inv_hi], record, (t0, t1), u32::MAX)
    }

    /// Which of the child boxes `children` (a bit mask) of node `record` ray `i` enters
    /// within `[t0, t1]`: its own f32 test, the same bits (the product's minimum and
    /// maximum over one inverse are the product). Only the quads of children that hold
    /// one of `children` are tested; others may be answered or not.
    #[inline]
    pub(super) fn enter_one(
        &self,
        i: usize,
        record: &[u8; BVH_NODE_RECORD],
        t0: f32,
        t1: f32,
        children: u32,
    ) -> Entered<f32> {
        enter(self, [&self.inv[i], &self.inv[i]], record, (t0, t1), children)
    }
}

/// The slab test of [`Spread`] over the inverse directions `[lo, hi]`, on the quads of
/// children that hold one of `children` (a bit mask): in SSE2 on x86_64, one lane at a
/// time elsewhere (every quad).
#[inline]
fn enter(s: &Spread, [lo, hi]: [&Splat3; 2], record: &Record, t: (f32, f32), children: u32) -> Entered<f32> {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86_64 baseline; the function reads nothing but its
    // arguments.
    return unsafe { enter_sse2(s, [lo, hi], record, t, children) };
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = children;
        enter_scalar(s, [lo, hi], record, t)
    }
}

/// [`enter`] with SSE2, four children at a time: the same operations on the same values as
/// [`enter_scalar`] (no NaN arises: every inverse is a normal f32, every origin finite).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn enter_sse2(s: &Spread, [lo, hi]: [&Splat3; 2], record: &Record, t: (f32, f32), children: u32) -> Entered<f32> {
    let (t0, t1) = t;
    use std::arch::x86_64::*;
    // SAFETY: `v` is four f32, 16-byte aligned (`Spread` is `align(16)`).
    let lanes = |v: &[f32; 4]| unsafe { _mm_load_ps(v.as_ptr()) };
    let mut out = Entered { near: [0.0; BVH_WIDTH], mask: 0 };
    for quad in 0..BVH_WIDTH / 4 {
        if !quad_used(record, quad) {
            break;
        }
        if children >> (4 * quad) & 0xf == 0 {
            continue;
        }
        let mut near = _mm_set1_ps(f32::NEG_INFINITY);
        let mut far = _mm_set1_ps(f32::INFINITY);
        for a in 0..3 {
            let (near_row, far_row) = s.rows[a];
            let (l, h) = (lanes(&lo[a]), lanes(&hi[a]));
            let dn = _mm_sub_ps(row_quad(record, near_row, quad), lanes(&s.o_near[a]));
            let df = _mm_sub_ps(row_quad(record, far_row, quad), lanes(&s.o_far[a]));
            let n = _mm_min_ps(_mm_mul_ps(dn, l), _mm_mul_ps(dn, h));
            let f = _mm_max_ps(_mm_mul_ps(df, l), _mm_mul_ps(df, h));
            near = _mm_max_ps(n, near);
            far = _mm_min_ps(f, far);
        }
        widened_sse2(near, far, t0, t1, quad, &mut out);
    }
    out
}

/// [`enter`] one lane at a time (other processors; the SSE2 version's oracle).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
fn enter_scalar(s: &Spread, [lo, hi]: [&Splat3; 2], record: &Record, (t0, t1): (f32, f32)) -> Entered<f32> {
    let node = &crate::blocks::bvh::BvhNodeLanes::read(record);
    let mut near = [f32::NEG_INFINITY; BVH_WIDTH];
    let mut far = [f32::INFINITY; BVH_WIDTH];
    for a in 0..3 {
        let (near_face, far_face) =
            if s.rows[a].0 > a { (&node.hi[a], &node.lo[a]) } else { (&node.lo[a], &node.hi[a]) };
        let (l, h) = (lo[a][0], hi[a][0]);
        for k in 0..BVH_WIDTH {
            let (dn, df) = (near_face[k] - s.o_near[a][0], far_face[k] - s.o_far[a][0]);
            let n = (dn * l).min(dn * h);
            let f = (df * l).max(df * h);
            near[k] = if n > near[k] { n } else { near[k] };
            far[k] = if f < far[k] { f } else { far[k] };
        }
    }
    widened_scalar(near, far, t0, t1)
}

/// What each ray of a packet holds during the walk.
#[derive(Clone, Copy)]
struct Lane {
    /// Its `tmin` (at least 0) rounded down to f32.
    t0: f32,
    /// The farthest distance still of use to it (its best hit's, or its tmax), and that
    /// rounded up to f32 for the slab test.
    bound: f64,
    bound32: f32,
    /// The triangle test's upper limit (next above `bound`, for ties).
    upper: f64,
    best: Option<Hit>,
}

/// Walks the BVH once for `queries` (at most [`PACKET`], one origin, packed by
/// [`Spread::of`] into `spread`), writing each ray's answer to `out`: for nearest-hit
/// queries the hit [`super::cast`] gives, bit for bit; for `any` queries whether there
/// is one (`Some` of some hit).
pub(super) fn walk(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    queries: &[Query],
    spread: &Spread,
    out: &mut [Option<Hit>],
) -> Result<(), BlockError> {
    debug_assert!(queries.len() <= PACKET && out.len() == queries.len());
    let any = queries.first().is_some_and(|q| q.any);
    let idle = Lane { t0: 0.0, bound: f64::NEG_INFINITY, bound32: f32::NEG_INFINITY, upper: 0.0, best: None };
    let mut lanes = [idle; PACKET];
    let mut t0 = f32::INFINITY;
    for (lane, q) in lanes.iter_mut().zip(queries) {
        let t = f32_below(q.tmin.max(0.0));
        *lane = Lane { t0: t, bound: q.tmax, bound32: f32_above(q.tmax), upper: q.tmax.next_up_or(q.tmax), best: None };
        t0 = t0.min(t);
    }
    let mut active: u32 = (1u32 << queries.len()) - 1;
    // The packet's far bound: the largest of its active rays' (f64, and f32 as the test
    // takes it).
    let far_of = |lanes: &[Lane; PACKET], active: u32| {
        let (mut far, mut far32, mut m) = (f64::NEG_INFINITY, f32::NEG_INFINITY, active);
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            far = far.max(lanes[i].bound);
            far32 = far32.max(lanes[i].bound32);
        }
        (far, far32)
    };
    let mut bound = far_of(&lanes, active);
    let (mut steps, mut tests) = (0u64, 0u64);
    let mut stack = std::mem::take(&mut scratch.packet_stack);
    stack.clear();
    // (node index or first triangle address, leaf triangle count (0: a node), entry
    // distance, the rays that go on there as a bit mask).
    let mut next = Some((0, 0, t0, active));
    let (max_steps, bvh_base) = (view.header.bvh.nodes as u64, view.header.layout.bvh_base);
    let result = 'walk: loop {
        let Some((index, count, near, rays)) = next.take().or_else(|| stack.pop()) else {
            break Ok(());
        };
        let near64 = near as f64;
        if near64 > bound.0 {
            continue;
        }
        if count > 0 {
            let leaf = match view.bvh_leaf(index, count) {
                Ok(l) => l,
                Err(e) => break Err(e),
            };
            let (mut m, mut changed) = (rays & active, false);
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                let (q, lane) = (&queries[i], &mut lanes[i]);
                if near64 > lane.bound {
                    continue;
                }
                if test_leaf(q, leaf, &mut lane.upper, &mut lane.best, &mut tests) {
                    if any {
                        active &= !(1 << i);
                        if active == 0 {
                            break 'walk Ok(());
                        }
                    } else if let Some(b) = lane.best {
                        lane.bound = b.t;
                        lane.bound32 = f32_above(b.t);
                    }
                    changed = true;
                }
            }
            if changed {
                bound = far_of(&lanes, active);
            }
            continue;
        }
        let record = match visit(view, index, &mut steps, (max_steps, bvh_base)) {
            Ok(r) => r,
            Err(e) => break Err(e),
        };
        let Entered { near: t, mut mask } = spread.enter(record, t0, bound.1);
        // Leaves entered: each ray's own test says which of them it enters.
        let leaves = (0..BVH_WIDTH).fold(0, |m, k| m | ((child_count(record, k) > 0) as u32) << k) & mask;
        let mut with = [rays; BVH_WIDTH];
        if leaves != 0 {
            with = [0; BVH_WIDTH];
            let mut m = rays & active;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                let e = spread.enter_one(i, record, lanes[i].t0, lanes[i].bound32, leaves);
                let mut em = e.mask & leaves;
                while em != 0 {
                    let k = em.trailing_zeros() as usize;
                    em &= em - 1;
                    with[k] |= 1 << i;
                }
            }
            for (k, w) in with.iter_mut().enumerate() {
                if leaves >> k & 1 == 0 {
                    *w = rays;
                } else if *w == 0 {
                    mask &= !(1 << k);
                }
            }
        }
        // The children entered, nearest first: the nearest next, the others stacked.
        let mut entered = [(0.0f32, 0u32, 0u32, 0u32); BVH_WIDTH];
        let mut n = 0;
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (child, count) = (child_index(record, k), child_count(record, k));
            let mut i = n;
            while i > 0 && entered[i - 1].0 > t[k] {
                entered[i] = entered[i - 1];
                i -= 1;
            }
            entered[i] = (t[k], child, count, with[k]);
            n += 1;
        }
        if n > 0 {
            for &(t, index, count, with) in entered[1..n].iter().rev() {
                stack.push((index, count, t, with));
            }
            let (t, index, count, with) = entered[0];
            next = Some((index, count, t, with));
        }
    };
    scratch.packet_stack = stack;
    view.counters.grid_steps += steps;
    view.counters.patch_tests += tests;
    for (o, lane) in out.iter_mut().zip(&lanes) {
        *o = lane.best;
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::bvh::BvhNodeLanes;
    use crate::geometry::{Ray, WatertightRay};
    use crate::rng::Rng;
    use crate::trace::bvh::tests::{random_node, record};
    use crate::trace::bvh::{Narrow, SlabRay};
    use glam::DVec3;

    /// A random node, and up to eight rays from one origin whose directions lie in a
    /// cone (narrow or wide, at any scale), with their own intervals.
    fn case(rng: &mut Rng, c: usize) -> (BvhNodeLanes, DVec3, Vec<(DVec3, f64, f64)>) {
        let scale = [1e-20, 1.0, 1.0, 1.0, 1e20][c % 5];
        let coord = |rng: &mut Rng| scale * (rng.next_f64() - 0.5) * 4.0;
        let node = random_node(rng, coord);
        let origin = if c % 9 == 0 {
            // On a corner of a box.
            DVec3::new(node.lo[0][1] as f64, node.lo[1][1] as f64, node.hi[2][1] as f64)
        } else {
            DVec3::new(coord(rng), coord(rng), coord(rng))
        };
        let base = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
        let spread = [1e-6, 1e-3, 0.05, 0.3][c % 4];
        let rays = (0..1 + c % PACKET)
            .map(|_| {
                let jitter = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
                let t0 = if c % 3 == 0 { 0.0 } else { rng.next_f64() * 0.1 * scale };
                let t1 = if c % 2 == 0 { f64::INFINITY } else { rng.next_f64() * 5.0 * scale };
                ((base + jitter * spread).normalize(), t0, t1)
            })
            .collect();
        (node, origin, rays)
    }

    fn query(ray: &Ray) -> Query<'_> {
        Query { ray, wray: WatertightRay::new(ray).unwrap(), tmin: 0.0, tmax: 1.0, exclude: u32::MAX, any: false }
    }

    /// The packet's test enters every box any of its rays' f64 tests enters, no later;
    /// a ray's own test in the packet is its f32 test alone, bit for bit; and the SSE2
    /// test gives the scalar bits.
    #[test]
    fn the_packet_test_is_conservative_against_each_ray() {
        let mut rng = Rng::from_words(&[9, 0x9ac4]);
        let mut packed = 0;
        for c in 0..100_000 {
            let (node, origin, rays) = case(&mut rng, c);
            let block = record(&node);
            let r = crate::blocks::bvh::node_record(&block, 0);
            let wrays: Vec<Ray> = rays.iter().map(|(d, _, _)| Ray::new(origin, *d)).collect();
            let queries: Vec<Query> = wrays.iter().map(query).collect();
            let Some(spread) = Spread::of(&queries) else { continue };
            packed += 1;
            let t0 = rays.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
            let t1 = rays.iter().map(|r| r.2).fold(f64::NEG_INFINITY, f64::max);
            let (t0, t1) = (f32_below(t0), f32_above(t1));
            let wide = spread.enter(r, t0, t1);
            let bits = |e: Entered<f32>| (super::super::tests::entered(e.near, e.mask).map(f32::to_bits), e.mask);
            let scalar = enter_scalar(&spread, [&spread.inv_lo, &spread.inv_hi], r, (t0, t1));
            assert_eq!(bits(wide), bits(scalar), "case {c}");
            for (i, (d, t0, t1)) in rays.iter().enumerate() {
                let alone = SlabRay::new(origin.to_array(), d.to_array());
                let exact = alone.enter_f64_scalar(r, *t0, *t1);
                assert_eq!(wide.mask & exact.mask, exact.mask, "case {c}: {node:?}");
                for k in 0..BVH_WIDTH {
                    if exact.mask >> k & 1 == 1 {
                        assert!(wide.near[k] as f64 <= exact.near[k], "case {c}, child {k}");
                    }
                }
                let narrow = Narrow::of(&alone, d.to_array()).expect("packed rays take the f32 test");
                let (a, b) = (f32_below(*t0), f32_above(*t1));
                assert_eq!(
                    bits(spread.enter_one(i, r, a, b, u32::MAX)),
                    bits(super::super::tests::enter_in_octant(&narrow, r, a, b)),
                    "case {c}, ray {i}"
                );
            }
        }
        assert!(packed > 80_000, "{packed}");
    }

    /// Rays that differ in sign on an axis, or run parallel to one, are not packed.
    #[test]
    fn rays_of_mixed_signs_are_not_packed() {
        let o = DVec3::new(0.1, 0.2, 0.3);
        let packs = |ds: &[DVec3]| {
            let rays: Vec<Ray> = ds.iter().map(|d| Ray::new(o, *d)).collect();
            Spread::of(&rays.iter().map(query).collect::<Vec<_>>()).is_some()
        };
        assert!(packs(&[DVec3::new(1.0, 0.5, 0.2), DVec3::new(1.0, 0.6, 0.1)]));
        assert!(!packs(&[DVec3::new(1.0, 0.5, 0.2), DVec3::new(1.0, -0.6, 0.1)]));
        assert!(!packs(&[DVec3::new(1.0, 0.5, 0.2), DVec3::new(1.0, 0.0, 0.1)]));
        assert!(!packs(&[DVec3::new(1.0, 0.5, 0.2), DVec3::new(-1.0, 0.5, 0.2)]));
    }
}
