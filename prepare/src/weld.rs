//! Welding of element vertices: lattice points of one patch are shared by construction;
//! points on patch edges are merged with bitwise-equal points of *coplanar* patches
//! (same facing), so a wall made of two triangles shows no seam while a corner between
//! two walls keeps separate vertices.

use glam::DVec3;
use magg_core::geometry::triangle_normal;
use magg_core::subdivision::{lattice_count, lattice_index, lattice_point, on_boundary};
use rayon::prelude::*;

/// Result of welding.
pub(super) struct Welded {
    /// Offset of each patch's lattice in `ids`.
    pub lattice_offset: Vec<u64>,
    /// Welded vertex id of every lattice point of every patch.
    pub ids: Vec<u32>,
    /// Position of each welded vertex.
    pub positions: Vec<DVec3>,
}

fn key(p: DVec3) -> [u64; 3] {
    // +0.0 and -0.0 must weld: normalise the sign of zero.
    let b = |x: f64| if x == 0.0 { 0u64 } else { x.to_bits() };
    [b(p.x), b(p.y), b(p.z)]
}

fn find(parent: &mut [u64], mut x: u64) -> u64 {
    while parent[x as usize] != x {
        let p = parent[x as usize];
        parent[x as usize] = parent[p as usize];
        x = p;
    }
    x
}

pub(super) fn weld(patches: &[[DVec3; 3]], subdivisions: &[u32]) -> Welded {
    let mut lattice_offset = Vec::with_capacity(patches.len());
    let mut total = 0u64;
    for &n in subdivisions {
        lattice_offset.push(total);
        total += lattice_count(n);
    }
    let normals: Vec<DVec3> = patches.par_iter().map(triangle_normal).collect();

    // Positions of every lattice point, patch by patch.
    let positions: Vec<DVec3> = (0..patches.len())
        .into_par_iter()
        .flat_map_iter(|p| {
            let n = subdivisions[p];
            let v = patches[p];
            (0..=n).flat_map(move |j| (0..=n - j).map(move |i| lattice_point(&v, n, i, j)))
        })
        .collect();

    // Boundary points, sorted by position so that equal points are adjacent.
    let mut boundary: Vec<([u64; 3], u32, u64)> = (0..patches.len())
        .into_par_iter()
        .flat_map_iter(|p| {
            let n = subdivisions[p];
            let off = lattice_offset[p];
            let positions = &positions;
            (0..=n).flat_map(move |j| {
                (0..=n - j).filter(move |&i| on_boundary(n, i, j)).map(move |i| {
                    let g = off + lattice_index(n, i, j) as u64;
                    (key(positions[g as usize]), p as u32, g)
                })
            })
        })
        .collect();
    boundary.par_sort_unstable();

    let mut parent: Vec<u64> = (0..total).collect();
    let mut start = 0;
    while start < boundary.len() {
        let mut end = start + 1;
        while end < boundary.len() && boundary[end].0 == boundary[start].0 {
            end += 1;
        }
        for b in start + 1..end {
            let (_, pb, gb) = boundary[b];
            let nb = normals[pb as usize];
            if let Some(&(_, _, ga)) =
                boundary[start..b].iter().find(|(_, pa, _)| normals[*pa as usize].dot(nb) > 1.0 - 1e-9)
            {
                let (ra, rb) = (find(&mut parent, ga), find(&mut parent, gb));
                let (lo, hi) = (ra.min(rb), ra.max(rb));
                parent[hi as usize] = lo;
            }
        }
        start = end;
    }

    let mut ids = vec![0u32; total as usize];
    let mut out_positions = Vec::new();
    for g in 0..total {
        let r = find(&mut parent, g);
        if r == g {
            ids[g as usize] = out_positions.len() as u32;
            out_positions.push(positions[g as usize]);
        } else {
            ids[g as usize] = ids[r as usize];
        }
    }
    Welded { lattice_offset, ids, positions: out_positions }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_coplanar_triangles_weld_along_the_diagonal() {
        let a = DVec3::new(0.0, 0.0, 0.0);
        let b = DVec3::new(1.0, 0.0, 0.0);
        let c = DVec3::new(1.0, 1.0, 0.0);
        let d = DVec3::new(0.0, 1.0, 0.0);
        let w = weld(&[[a, b, c], [a, c, d]], &[4, 4]);
        // A 4x4 quad lattice has 25 points.
        assert_eq!(w.positions.len(), 25);
    }

    #[test]
    fn a_corner_between_walls_keeps_separate_vertices() {
        let floor = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 0.0, -1.0)];
        let wall = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0), DVec3::new(1.0, 0.0, 0.0)];
        let w = weld(&[floor, wall], &[2, 2]);
        assert_eq!(w.positions.len(), 12);
    }

    #[test]
    fn opposite_facing_triangles_do_not_weld() {
        let a = DVec3::new(0.0, 0.0, 0.0);
        let b = DVec3::new(1.0, 0.0, 0.0);
        let c = DVec3::new(0.0, 1.0, 0.0);
        let w = weld(&[[a, b, c], [a, c, b]], &[1, 1]);
        assert_eq!(w.positions.len(), 6);
    }
}
