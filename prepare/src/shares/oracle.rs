//! The whole scene welded in one place, the way preparation did before shares: the
//! oracle the shares' welding is held to (every element and vertex, bit for bit).

use super::SharePatch;
use glam::DVec3;
use magg_core::blocks::NO_BACK;
use magg_core::geometry::triangle_area;
use magg_core::geometry::triangle_normal;
use magg_core::prepared::{ElementInfo, Face, NO_PARENT};
use magg_core::subdivision::element_corners;
use magg_core::subdivision::{lattice_count, lattice_index, lattice_point, on_boundary};
use rayon::prelude::*;

/// Result of welding.
struct Welded {
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

fn weld(patches: &[[DVec3; 3]], subdivisions: &[u32]) -> Welded {
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

/// Elements and vertex positions of `patches` the old way.
pub(super) fn elements(patches: &[SharePatch]) -> (Vec<ElementInfo>, Vec<DVec3>) {
    let corners: Vec<[DVec3; 3]> = patches.iter().map(|p| p.v).collect();
    let subdivisions: Vec<u32> = patches.iter().map(|p| p.n).collect();
    let first_element: Vec<u32> = patches.iter().map(|p| p.first_element).collect();
    let back_element: Vec<u32> = patches.iter().map(|p| p.back_element).collect();
    let welded = weld(&corners, &subdivisions);
    let front: Vec<ElementInfo> = (0..patches.len())
        .into_par_iter()
        .flat_map_iter(|p| {
            let n = subdivisions[p];
            let v = corners[p];
            let base = welded.lattice_offset[p];
            let ids = &welded.ids;
            let face = patches[p].front_face;
            (0..n * n).map(move |local| {
                let c = element_corners(n, local);
                let corner = |k: usize| lattice_point(&v, n, c[k].0, c[k].1);
                let tri = [corner(0), corner(1), corner(2)];
                let vid = |k: usize| ids[(base + lattice_index(n, c[k].0, c[k].1) as u64) as usize];
                ElementInfo {
                    patch: p as u32,
                    vertices: [vid(0), vid(1), vid(2)],
                    area: triangle_area(&tri),
                    centroid: (tri[0] + tri[1] + tri[2]) / 3.0,
                    face,
                    parent: NO_PARENT,
                    child: 0,
                }
            })
        })
        .collect();
    with_back_faces(front, welded.positions, &first_element, &back_element)
}

fn with_back_faces(
    front: Vec<ElementInfo>,
    mut positions: Vec<DVec3>,
    first_element: &[u32],
    back_element: &[u32],
) -> (Vec<ElementInfo>, Vec<DVec3>) {
    let mut elements = front;
    let fronts = elements.len();
    let mut back_of = vec![u32::MAX; positions.len()];
    for (p, &b) in back_element.iter().enumerate() {
        if b == NO_BACK {
            continue;
        }
        let first = first_element[p] as usize;
        let end = first_element.get(p + 1).map_or(fronts, |&e| e as usize);
        for e in first..end {
            let mut info = elements[e];
            for v in &mut info.vertices {
                let i = *v as usize;
                if back_of[i] == u32::MAX {
                    back_of[i] = positions.len() as u32;
                    positions.push(positions[i]);
                }
                *v = back_of[i];
            }
            info.face = Face::Back;
            elements.push(info);
        }
    }
    (elements, positions)
}
