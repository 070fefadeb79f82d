//! Byte layout of the BVH blocks: node blocks, then leaf-triangle blocks.
//!
//! A node record holds up to [`BVH_WIDTH`] (eight) children, their bounds side by side
//! (f32, rounded outward; all children's `lo.x`, then all `lo.y`, ...) so that a ray
//! tests the boxes of a node together, four to a vector register, and a reference to
//! each: an inner node (by node index), a leaf (a run of triangle records in one block)
//! or nothing. Node `n` is record `n & 7` of node block `n >> 3`; leaf triangle address
//! `a` is record `a & 31` of
//! triangle block `a >> 5` (a block holds [`BVH_TRIANGLES_PER_BLOCK`] of them, so some
//! addresses are unused): shifts and masks, no division on the traversal path. A triangle
//! record carries the patch's corners in f64, exactly as the patch block does, so the
//! watertight test gives the same bits.

use super::layout::{get_corners, get_u32, put_corners, put_u32, Block};
use glam::DVec3;

/// Children of a node record (a multiple of four: the slab tests take four at a time).
pub const BVH_WIDTH: usize = 8;
/// `log2(BVH_WIDTH)`: the bits of a child's slot.
pub const BVH_WIDTH_SHIFT: u32 = BVH_WIDTH.trailing_zeros();
/// Bytes of one row of a node record's bounds: one coordinate of every child, in f32.
pub const BVH_ROW: usize = 4 * BVH_WIDTH;
/// Byte offset of the children's indices in a node record (after the six rows of
/// bounds: `lo` x, y, z, then `hi` x, y, z).
pub const BVH_INDEX_AT: usize = 6 * BVH_ROW;
/// Byte offset of the children's triangle counts in a node record.
pub const BVH_COUNT_AT: usize = BVH_INDEX_AT + 4 * BVH_WIDTH;
/// Bytes of one node record: 6 x [`BVH_WIDTH`] f32 bounds, the indices, the counts.
pub const BVH_NODE_RECORD: usize = BVH_COUNT_AT + 4 * BVH_WIDTH;
/// Node records per block.
pub const BVH_NODES_PER_BLOCK: usize = crate::blocks::BLOCK_SIZE / BVH_NODE_RECORD;
/// `log2(BVH_NODES_PER_BLOCK)`: node `n` lives in node block `n >> BVH_NODE_SHIFT`.
pub const BVH_NODE_SHIFT: u32 = BVH_NODES_PER_BLOCK.trailing_zeros();
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
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// No child: an empty box (lo above hi), so that no ray enters it.
    pub const NONE: BvhChild =
        BvhChild { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3], index: BVH_NO_CHILD, count: 0 };
}

/// A node record: up to [`BVH_WIDTH`] children, absent ones [`BvhChild::NONE`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BvhNode {
    /// The children, in build order.
    pub children: [BvhChild; BVH_WIDTH],
}

/// A node record as the traversal reads it: the children's bounds side by side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNodeLanes {
    /// `lo[axis][child]`.
    pub lo: [[f32; BVH_WIDTH]; 3],
    /// `hi[axis][child]`.
    pub hi: [[f32; BVH_WIDTH]; 3],
    /// Children's index (see [`BvhChild::index`]).
    pub index: [u32; BVH_WIDTH],
    /// Children's triangle count (see [`BvhChild::count`]).
    pub count: [u32; BVH_WIDTH],
}

impl BvhNodeLanes {
    /// Reads the record `r` (one node record's bytes).
    #[inline]
    pub fn read(r: &[u8; BVH_NODE_RECORD]) -> BvhNodeLanes {
        let word = |at: usize| [r[at], r[at + 1], r[at + 2], r[at + 3]];
        let row = |row: usize| std::array::from_fn(|k| f32::from_le_bytes(word(BVH_ROW * row + 4 * k)));
        BvhNodeLanes {
            lo: [row(0), row(1), row(2)],
            hi: [row(3), row(4), row(5)],
            index: std::array::from_fn(|k| u32::from_le_bytes(word(BVH_INDEX_AT + 4 * k))),
            count: std::array::from_fn(|k| u32::from_le_bytes(word(BVH_COUNT_AT + 4 * k))),
        }
    }

    /// Child `k`.
    pub fn child(&self, k: usize) -> BvhChild {
        BvhChild {
            lo: [self.lo[0][k], self.lo[1][k], self.lo[2][k]],
            hi: [self.hi[0][k], self.hi[1][k], self.hi[2][k]],
            index: self.index[k],
            count: self.count[k],
        }
    }
}

impl BvhNode {
    /// Writes the record at byte offset `at`.
    pub fn encode(&self, b: &mut Block, at: usize) {
        let mut put_f32 = |o: usize, v: f32| b[at + o..at + o + 4].copy_from_slice(&v.to_le_bytes());
        for (k, c) in self.children.iter().enumerate() {
            for a in 0..3 {
                put_f32(BVH_ROW * a + 4 * k, c.lo[a]);
                put_f32(BVH_ROW * (3 + a) + 4 * k, c.hi[a]);
            }
        }
        for (k, c) in self.children.iter().enumerate() {
            put_u32(b, at + BVH_INDEX_AT + 4 * k, c.index);
            put_u32(b, at + BVH_COUNT_AT + 4 * k, c.count);
        }
    }

    /// Reads the record at byte offset `at`.
    pub fn decode(b: &Block, at: usize) -> BvhNode {
        let lanes = BvhNodeLanes::read(node_record(b, at));
        BvhNode { children: std::array::from_fn(|k| lanes.child(k)) }
    }
}

/// The bytes of the node record at byte offset `at` of `b`.
#[inline]
pub fn node_record(b: &Block, at: usize) -> &[u8; BVH_NODE_RECORD] {
    let at = at.min(b.len() - BVH_NODE_RECORD);
    b[at..at + BVH_NODE_RECORD].try_into().unwrap_or(&[0; BVH_NODE_RECORD])
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

    /// The corner bytes (nine f64, as [`crate::geometry::WatertightRay::intersect_record`]
    /// reads them) and the patch id of one record, read in place.
    #[inline]
    pub fn parts(record: &[u8]) -> (&[u8; 72], u32) {
        let corners = record.get(..72).and_then(|c| c.try_into().ok()).unwrap_or(&[0; 72]);
        (corners, get_u32(record, 72))
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
        assert_eq!(1 << BVH_WIDTH_SHIFT, BVH_WIDTH);
        assert_eq!(BVH_WIDTH % 4, 0);
        assert!(BVH_TRIANGLES_PER_BLOCK * BVH_TRIANGLE_RECORD <= BLOCK_SIZE);
        assert!(BVH_TRIANGLES_PER_BLOCK <= 1 << BVH_TRIANGLE_SHIFT);
        assert!(BVH_MAX_LEAF as usize <= BVH_TRIANGLES_PER_BLOCK);
    }

    #[test]
    fn records_round_trip() {
        let mut b = [0u8; BLOCK_SIZE];
        let mut n = BvhNode { children: [BvhChild::NONE; BVH_WIDTH] };
        n.children[0] = BvhChild { lo: [-1.0, 0.0, 2.5], hi: [1.0, 3.0, 4.0], index: 7, count: 0 };
        n.children[2] = BvhChild { lo: [-2.0, 0.5, 1.5], hi: [0.0, 3.5, 2.0], index: 96, count: 3 };
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
