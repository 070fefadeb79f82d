//! Ray casting through the BVH: a depth-first walk over nodes of four children, the
//! nearest child first, that skips every node entered beyond the best hit so far.
//!
//! Node bounds are f32 rounded outward and padded at build time, and the slab test's far
//! distance is widened by `1 + 2 gamma(3)` (Ize 2013), so a box holding a hit is never
//! skipped; a node entered exactly at the best distance is still visited, so that a tie
//! can go to the lower patch id. The patch test itself is the f64 watertight one, on the
//! same corners as the patch records: the grid's answer, bit for bit.

use super::{Hit, Query, TraceScratch};
use crate::blocks::bvh::{BvhNodeLanes, BvhTriangle, BVH_NO_CHILD, BVH_TRIANGLE_RECORD, BVH_WIDTH};
use crate::blocks::BlockError;
use crate::view::SceneView;

/// `1 + 2 gamma(3)`, gamma(n) = n eps / (1 - n eps) with eps = 2^-53.
const FAR_SLACK: f64 = 1.0 + 2.0 * (3.0 * f64::EPSILON * 0.5) / (1.0 - 3.0 * f64::EPSILON * 0.5);

/// The ray as the slab test wants it.
struct SlabRay {
    origin: [f64; 3],
    inv: [f64; 3],
}

impl SlabRay {
    /// Distance at which the ray enters each of `node`'s child boxes within `[t0, t1]`
    /// (infinity for a box it misses and for an absent child): the four boxes side by
    /// side, in f64 from the f32 bounds.
    #[inline]
    fn enter(&self, node: &BvhNodeLanes, t0: f64, t1: f64) -> [f64; BVH_WIDTH] {
        let mut near = [t0; BVH_WIDTH];
        let mut far = [f64::INFINITY; BVH_WIDTH];
        for a in 0..3 {
            for k in 0..BVH_WIDTH {
                let ta = (node.lo[a][k] as f64 - self.origin[a]) * self.inv[a];
                let tb = (node.hi[a][k] as f64 - self.origin[a]) * self.inv[a];
                // A NaN (0 x inf: a ray in the plane of a padded face, which holds no
                // patch) fails these comparisons.
                let (n, f) = if ta <= tb { (ta, tb) } else { (tb, ta) };
                near[k] = if n > near[k] { n } else { near[k] };
                far[k] = if f < far[k] { f } else { far[k] };
            }
        }
        std::array::from_fn(|k| {
            let f = (far[k] * FAR_SLACK).min(t1);
            if near[k] <= f && node.index[k] != BVH_NO_CHILD {
                near[k]
            } else {
                f64::INFINITY
            }
        })
    }
}

/// [`super::cast`] through the BVH.
pub(super) fn cast(view: &mut SceneView, scratch: &mut TraceScratch, q: &Query) -> Result<Option<Hit>, BlockError> {
    let (o, d) = (q.ray.origin, q.ray.direction);
    let t0 = q.tmin.max(0.0);
    let slab = SlabRay { origin: o.to_array(), inv: [1.0 / d.x, 1.0 / d.y, 1.0 / d.z] };
    let mut best: Option<Hit> = None;
    let (mut steps, mut tests) = (0u64, 0u64);
    let mut stack = std::mem::take(&mut scratch.stack);
    stack.clear();
    // (node index or first triangle address, leaf triangle count (0: a node), entry t):
    // the entry visited next (the nearer child of the last node), then the stack.
    let mut next = Some((0, 0, t0));
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
            for k in 0..count as usize {
                let tri = BvhTriangle::decode(leaf, k * BVH_TRIANGLE_RECORD);
                if tri.patch == q.exclude {
                    continue;
                }
                tests += 1;
                if q.test(&tri.v, tri.patch, q.tmax, &mut best) && q.any {
                    break 'walk Ok(best);
                }
            }
            continue;
        }
        steps += 1;
        let node = match view.bvh_node(index) {
            Ok(n) => n,
            Err(e) => break Err(e),
        };
        // Nodes are written depth first: a child's index is above its parent's, so a
        // ray visits each node at most once. Blocks that say otherwise are corrupt (and
        // would loop).
        let inner_below =
            (0..BVH_WIDTH).all(|k| node.count[k] > 0 || node.index[k] == BVH_NO_CHILD || node.index[k] > index);
        if !inner_below || steps > view.header.bvh.nodes as u64 {
            let id = view.header.layout.bvh_base + (index >> crate::blocks::bvh::BVH_NODE_SHIFT);
            break Err(BlockError::Unavailable { id, reason: "corrupt BVH node block".into() });
        }
        // The children entered, nearest first (ties in the node's order): the nearest
        // is visited next, the others stacked farthest first.
        let t = slab.enter(&node, t0, bound);
        let mut entered = [(0.0f64, 0u32, 0u32); BVH_WIDTH];
        let mut n = 0;
        for k in 0..BVH_WIDTH {
            if t[k] == f64::INFINITY {
                continue;
            }
            let mut i = n;
            while i > 0 && entered[i - 1].0 > t[k] {
                entered[i] = entered[i - 1];
                i -= 1;
            }
            entered[i] = (t[k], node.index[k], node.count[k]);
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
