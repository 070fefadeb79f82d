//! Byte layout of the BVH blocks: node blocks, then leaf-triangle blocks.
//!
//! A node record holds the bounds of its two children (f32, rounded outward) and a
//! reference to each: an inner node (by node index), a leaf (a run of triangle records
//! in one block) or nothing. Node `n` is record `n & 31` of node block `n >> 5`; leaf
//! triangle address `a` is record `a & 31` of triangle block `a >> 5` (a block holds
//! [`BVH_TRIANGLES_PER_BLOCK`] of them, so some addresses are unused): shifts and masks,
//! no division on the traversal path. A triangle record carries the patch's corners in
//! f64, exactly as the patch block does, so the watertight test gives the same bits.

use super::layout::{get_corners, get_f32, get_u32, put_corners, put_u32, Block};
use glam::DVec3;

/// Bytes of one node record: 2 x (6 x f32 bounds) + 2 x (index, count).
pub const BVH_NODE_RECORD: usize = 64;
/// Node records per block.
pub const BVH_NODES_PER_BLOCK: usize = 32;
/// `log2(BVH_NODES_PER_BLOCK)`: node `n` lives in node block `n >> BVH_NODE_SHIFT`.
pub const BVH_NODE_SHIFT: u32 = 5;
/// Bytes of one leaf-triangle record: 3 corners (9 x f64), patch id, padding.
pub const BVH_TRIANGLE_RECORD: usize = 80;
/// Leaf-triangle records per block.
pub const BVH_TRIANGLES_PER_BLOCK: usize = 25;
/// Triangle address `a` lives in triangle block `a >> BVH_TRIANGLE_SHIFT`, record
/// `a & (1 << BVH_TRIANGLE_SHIFT) - 1`.
pub const BVH_TRIANGLE_SHIFT: u32 = 5;
/// Most triangles of one leaf (a leaf never straddles two blocks).
pub const BVH_MAX_LEAF: u32 = 8;
/// Index of an absent child.
pub const BVH_NO_CHILD: u32 = u32::MAX;

/// One child of a node record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhChild {
    /// Lower corner of the child's bounds (rounded down).
    pub lo: [f32; 3],
    /// Upper corner (rounded up).
    pub hi: [f32; 3],
    /// Inner node index (`count == 0`), first triangle address (`count > 0`), or
    /// [`BVH_NO_CHILD`].
    pub index: u32,
    /// Triangles of a leaf; 0 for an inner node or no child.
    pub count: u32,
}

impl BvhChild {
    /// No child.
    pub const NONE: BvhChild =
        BvhChild { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3], index: BVH_NO_CHILD, count: 0 };

    /// Writes the child as child `k` (0 or 1) of the record at byte offset `at`.
    fn encode(&self, b: &mut Block, at: usize, k: usize) {
        let bounds = at + 24 * k;
        for a in 0..3 {
            b[bounds + 4 * a..bounds + 4 * a + 4].copy_from_slice(&self.lo[a].to_le_bytes());
            b[bounds + 12 + 4 * a..bounds + 16 + 4 * a].copy_from_slice(&self.hi[a].to_le_bytes());
        }
        put_u32(b, at + 48 + 8 * k, self.index);
        put_u32(b, at + 52 + 8 * k, self.count);
    }

    #[inline]
    fn decode(b: &Block, at: usize, k: usize) -> BvhChild {
        let bounds = at + 24 * k;
        let f = |i: usize| get_f32(b, bounds + 4 * i);
        BvhChild {
            lo: [f(0), f(1), f(2)],
            hi: [f(3), f(4), f(5)],
            index: get_u32(b, at + 48 + 8 * k),
            count: get_u32(b, at + 52 + 8 * k),
        }
    }
}

/// A node record: two children.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNode {
    /// The children, in build order (the lower side of the split first).
    pub children: [BvhChild; 2],
}

impl BvhNode {
    /// Writes the record at byte offset `at`.
    pub fn encode(&self, b: &mut Block, at: usize) {
        self.children[0].encode(b, at, 0);
        self.children[1].encode(b, at, 1);
    }

    /// Reads the record at byte offset `at`.
    #[inline]
    pub fn decode(b: &Block, at: usize) -> BvhNode {
        BvhNode { children: [BvhChild::decode(b, at, 0), BvhChild::decode(b, at, 1)] }
    }
}

/// A leaf triangle: the patch's corners and id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhTriangle {
    /// Corners, as in the patch record.
    pub v: [DVec3; 3],
    /// Patch id.
    pub patch: u32,
}

impl BvhTriangle {
    /// Writes the record at byte offset `at`.
    pub fn encode(&self, b: &mut Block, at: usize) {
        put_corners(b, at, &self.v);
        put_u32(b, at + 72, self.patch);
    }

    /// Reads the record at byte offset `at` of `b` (a block or a slice of one).
    #[inline]
    pub fn decode(b: &[u8], at: usize) -> BvhTriangle {
        BvhTriangle { v: get_corners(b, at), patch: get_u32(b, at + 72) }
    }
}

/// Largest f32 not above `x` (for lower bounds).
pub fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) > x {
        next_f32_down(f)
    } else {
        f
    }
}

/// Smallest f32 not below `x` (for upper bounds).
pub fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        -next_f32_down(-f)
    } else {
        f
    }
}

fn next_f32_down(f: f32) -> f32 {
    if f.is_nan() || f == f32::NEG_INFINITY {
        f
    } else if f == 0.0 {
        -f32::from_bits(1)
    } else if f > 0.0 {
        f32::from_bits(f.to_bits() - 1)
    } else {
        f32::from_bits(f.to_bits() + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::BLOCK_SIZE;

    #[test]
    fn records_fit_and_addresses_are_shifts() {
        assert_eq!(BVH_NODES_PER_BLOCK * BVH_NODE_RECORD, BLOCK_SIZE);
        assert_eq!(1 << BVH_NODE_SHIFT, BVH_NODES_PER_BLOCK);
        assert!(BVH_TRIANGLES_PER_BLOCK * BVH_TRIANGLE_RECORD <= BLOCK_SIZE);
        assert!(BVH_TRIANGLES_PER_BLOCK <= 1 << BVH_TRIANGLE_SHIFT);
        assert!(BVH_MAX_LEAF as usize <= BVH_TRIANGLES_PER_BLOCK);
    }

    #[test]
    fn records_round_trip() {
        let mut b = [0u8; BLOCK_SIZE];
        let n = BvhNode {
            children: [BvhChild { lo: [-1.0, 0.0, 2.5], hi: [1.0, 3.0, 4.0], index: 7, count: 0 }, BvhChild::NONE],
        };
        n.encode(&mut b, BVH_NODE_RECORD * (BVH_NODES_PER_BLOCK - 1));
        assert_eq!(BvhNode::decode(&b, BVH_NODE_RECORD * (BVH_NODES_PER_BLOCK - 1)), n);
        let t = BvhTriangle { v: [DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.1, 1e300, 0.0), DVec3::ZERO], patch: 99 };
        let last = BVH_TRIANGLE_RECORD * (BVH_TRIANGLES_PER_BLOCK - 1);
        t.encode(&mut b, last);
        assert_eq!(BvhTriangle::decode(&b, last), t);
    }

    #[test]
    fn f32_bounds_round_outward() {
        for x in [0.1f64, -0.1, 1e-40, -1e-40, 0.0, 3.0, 1e39, -1e39, 123456.789] {
            assert!((f32_down(x) as f64) <= x, "{x}");
            assert!((f32_up(x) as f64) >= x, "{x}");
        }
        assert_eq!(f32_down(3.0), 3.0);
        assert_eq!(f32_up(0.1) as f64 - 0.1 < 1e-8, true);
    }
}
