//! The spatial split of a scene into shares: contiguous ranges of a Morton order over the
//! scene's bounds, balanced by weight (the elements each patch will make).
//!
//! A share is prepared by one fork, so that each fork's part of the BVH is compact and the
//! forks prepare side by side. Only the balance of the work and the shape of the
//! acceleration structure depend on the split, never an id or a bit of the image: ids are
//! numbered in input order whatever prepares them.
//!
//! The split is a function of positions: [`SpaceSplit::share_of`] also names the *home*
//! of a point, the share that resolves the welding of every lattice point at that
//! position, so that all the patches meeting at a point agree where to send it.

use glam::DVec3;
use magg_core::geometry::Aabb;

/// Bits per axis of the Morton grid the split is made on (a 2^15-cell grid).
const BITS: u32 = 5;
/// Cells per axis.
const CELLS: u32 = 1 << BITS;

/// Where each share's part of space begins along the Morton curve.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SpaceSplit {
    /// Lower corner of the grid.
    min: DVec3,
    /// Cells per unit length, per axis (0 along a flat axis).
    scale: DVec3,
    /// First Morton cell of shares 1, 2, ... (ascending; share 0 begins at 0).
    starts: Vec<u32>,
}

/// Spreads the low 5 bits of `x` three apart.
fn spread(x: u32) -> u32 {
    let mut v = x & 0x1f;
    v = (v | (v << 8)) & 0x0300_f00f;
    v = (v | (v << 4)) & 0x030c_30c3;
    (v | (v << 2)) & 0x0924_9249
}

impl SpaceSplit {
    /// One share: everything in it.
    pub fn single() -> SpaceSplit {
        SpaceSplit { min: DVec3::ZERO, scale: DVec3::ZERO, starts: Vec::new() }
    }

    /// Splits `bounds` into `shares` Morton ranges holding about equal weight of the
    /// `points` (position, weight).
    pub fn balanced(bounds: Aabb, shares: usize, points: impl Iterator<Item = (DVec3, f64)>) -> SpaceSplit {
        let ext = bounds.extent();
        let scale = DVec3::new(per(ext.x), per(ext.y), per(ext.z));
        let mut split = SpaceSplit { min: bounds.min, scale, starts: Vec::new() };
        if shares <= 1 {
            return split;
        }
        let mut weight = vec![0.0f64; (CELLS * CELLS * CELLS) as usize];
        let mut total = 0.0;
        for (p, w) in points {
            let w = if w.is_finite() && w > 0.0 { w } else { 1.0 };
            weight[split.cell(p) as usize] += w;
            total += w;
        }
        // Share k begins at the first cell where the weight before it reaches k / shares
        // of the total.
        let mut acc = 0.0;
        let mut next = 1;
        for (cell, w) in weight.iter().enumerate() {
            while next < shares && acc >= total * next as f64 / shares as f64 {
                split.starts.push(cell as u32);
                next += 1;
            }
            acc += w;
        }
        while split.starts.len() < shares - 1 {
            split.starts.push(CELLS * CELLS * CELLS);
        }
        split
    }

    /// The share whose part of space holds `p` (points outside the bounds go to the
    /// nearest cell).
    pub fn share_of(&self, p: DVec3) -> u32 {
        if self.starts.is_empty() {
            return 0;
        }
        let c = self.cell(p);
        self.starts.partition_point(|&s| s <= c) as u32
    }

    /// Number of shares.
    pub fn shares(&self) -> usize {
        self.starts.len() + 1
    }

    /// Morton cell of `p`.
    fn cell(&self, p: DVec3) -> u32 {
        let q = (p - self.min) * self.scale;
        let axis = |x: f64| if x.is_finite() { x.clamp(0.0, (CELLS - 1) as f64) as u32 } else { 0 };
        spread(axis(q.x)) | (spread(axis(q.y)) << 1) | (spread(axis(q.z)) << 2)
    }
}

/// Cells per unit length along an axis of extent `e`.
fn per(e: f64) -> f64 {
    if e > 0.0 && e.is_finite() {
        CELLS as f64 / e
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Aabb {
        Aabb { min: DVec3::ZERO, max: DVec3::ONE }
    }

    #[test]
    fn morton_cells_interleave_the_axes() {
        assert_eq!(spread(0b11111), 0b1001001001001);
        let s = SpaceSplit::balanced(cube(), 1, std::iter::empty());
        assert_eq!(s.cell(DVec3::new(1.0 / 32.0, 0.0, 0.0)), 1);
        assert_eq!(s.cell(DVec3::new(0.0, 1.0 / 32.0, 0.0)), 2);
        assert_eq!(s.cell(DVec3::new(0.0, 0.0, 1.0 / 32.0)), 4);
        assert_eq!(s.cell(DVec3::splat(2.0)), CELLS * CELLS * CELLS - 1);
    }

    #[test]
    fn shares_hold_about_equal_weight_and_are_ordered_along_the_curve() {
        let pts: Vec<DVec3> = (0..4000)
            .map(|i| DVec3::new((i % 16) as f64 / 16.0, (i / 16 % 16) as f64 / 16.0, (i / 256) as f64 / 16.0))
            .collect();
        for shares in [2usize, 3, 5, 7] {
            let s = SpaceSplit::balanced(cube(), shares, pts.iter().map(|&p| (p, 1.0)));
            assert_eq!(s.shares(), shares);
            let mut count = vec![0usize; shares];
            for &p in &pts {
                count[s.share_of(p) as usize] += 1;
            }
            let even = pts.len() / shares;
            for c in &count {
                assert!(c.abs_diff(even) <= 256, "{shares} shares: {count:?}");
            }
        }
    }

    #[test]
    fn a_flat_or_empty_scene_splits_without_dividing_by_zero() {
        let flat = Aabb { min: DVec3::ZERO, max: DVec3::new(1.0, 0.0, 1.0) };
        let s = SpaceSplit::balanced(flat, 4, (0..100).map(|i| (DVec3::new(i as f64 / 100.0, 0.0, 0.5), 1.0)));
        assert!(s.share_of(DVec3::new(0.99, 0.0, 0.5)) < 4);
        let none = SpaceSplit::balanced(flat, 3, std::iter::empty());
        assert_eq!(none.share_of(DVec3::splat(f64::NAN)), none.share_of(DVec3::ZERO));
    }
}
