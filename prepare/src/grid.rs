//! The uniform grid of subspaces (paper §3, after Fujimoto's ARTS): each subspace lists
//! the patches that overlap it, by exact triangle/box overlap.

use super::mesh::Mesh;
use glam::{DVec3, UVec3};
use magg_core::geometry::{triangle_overlaps_box, Aabb};
use magg_core::scene::{GridSpec, Scene};
use rayon::prelude::*;

/// Grid geometry and per-cell patch lists.
pub(super) struct Grid {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
    /// Cells per axis.
    pub dims: [u32; 3],
    /// Patch ids of each cell, ascending.
    pub cells: Vec<Vec<u32>>,
    /// Triangle/cell overlap tests made.
    pub box_tests: u64,
}

/// Padded scene bounds: a little margin everywhere, and some thickness on flat axes.
fn bounds(mesh: &Mesh) -> Aabb {
    let b = mesh.patches.iter().fold(Aabb::EMPTY, |acc, v| acc.union(Aabb::of_triangle(v)));
    let scale = b.min.abs().max(b.max.abs()).max_element().max(b.extent().max_element()).max(1e-30);
    let ext = b.extent();
    let pad = |e: f64| {
        if e < 1e-6 * scale {
            1e-4 * scale
        } else {
            1e-7 * scale
        }
    };
    let p = DVec3::new(pad(ext.x), pad(ext.y), pad(ext.z));
    Aabb { min: b.min - p, max: b.max + p }
}

/// Cells per axis: the scene's choice, or about two patches' worth of near-cubic cells.
fn dims_for(spec: GridSpec, patches: usize, ext: DVec3) -> [u32; 3] {
    if let GridSpec::Fixed(d) = spec {
        return d;
    }
    let target = (2 * patches).clamp(64, 1 << 21) as f64;
    let e = [ext.x, ext.y, ext.z];
    let longest = ext.max_element();
    let flat: Vec<bool> = e.iter().map(|&x| x < 1e-3 * longest).collect();
    let k = flat.iter().filter(|f| !**f).count().max(1) as f64;
    let measure: f64 = e.iter().zip(&flat).filter(|(_, f)| !**f).map(|(x, _)| *x).product();
    let side = (measure / target).powf(1.0 / k);
    let mut d = [1u32; 3];
    for a in 0..3 {
        if !flat[a] && side > 0.0 && side.is_finite() {
            d[a] = ((e[a] / side).round() as u32).clamp(1, 256);
        }
    }
    d
}

/// The grid of a scene traced through the BVH: the scene's bounds as one empty subspace
/// (no subspace block is written).
pub(super) fn bounds_only(mesh: &Mesh) -> Grid {
    let b = bounds(mesh);
    Grid { min: b.min, max: b.max, dims: [1, 1, 1], cells: vec![Vec::new()], box_tests: 0 }
}

/// The grid of subspaces of `scene`, each listing the patches that overlap it.
pub(super) fn build(scene: &Scene, mesh: &Mesh) -> Grid {
    let b = bounds(mesh);
    let dims = dims_for(scene.settings.grid, mesh.patches.len(), b.extent());
    let cs = b.extent() / UVec3::from_array(dims).as_dvec3();
    let cell_of = |x: f64, a: usize| -> u32 {
        let c = ((x - b.min[a]) / cs[a]).floor();
        if c.is_finite() {
            c.clamp(0.0, (dims[a] - 1) as f64) as u32
        } else {
            0
        }
    };
    let ncells = dims.iter().map(|&d| d as usize).product::<usize>();
    let box_tests = std::sync::atomic::AtomicU64::new(0);
    let mut pairs: Vec<(u32, u32)> = mesh
        .patches
        .par_iter()
        .enumerate()
        .flat_map_iter(|(p, v)| {
            // A zero-area patch can carry no light and must never be hit; rounding in
            // the watertight test can report a hit through one of its corners, so it
            // is listed in no subspace.
            if (v[1] - v[0]).cross(v[2] - v[0]) == DVec3::ZERO {
                return Vec::new();
            }
            let bb = Aabb::of_triangle(v);
            // Candidate cells from the box grown like the cells below, so that a patch
            // whose box starts exactly on a cell face is also tried in the cell before.
            let eps = cs * 1e-9;
            let (bmin, bmax) = (bb.min - eps, bb.max + eps);
            let lo = [cell_of(bmin.x, 0), cell_of(bmin.y, 1), cell_of(bmin.z, 2)];
            let hi = [cell_of(bmax.x, 0), cell_of(bmax.y, 1), cell_of(bmax.z, 2)];
            let tests = (0..3).map(|a| (hi[a] - lo[a] + 1) as u64).product::<u64>();
            box_tests.fetch_add(tests, std::sync::atomic::Ordering::Relaxed);
            let mut out = Vec::new();
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let cmin = b.min + cs * UVec3::new(x, y, z).as_dvec3();
                        // Grow the cell by a hair so that patches lying exactly on a cell
                        // face are listed on both sides despite rounding.
                        if triangle_overlaps_box(v, cmin - eps, cmin + cs + eps) {
                            let cell = (z as usize * dims[1] as usize + y as usize) * dims[0] as usize + x as usize;
                            out.push((cell as u32, p as u32));
                        }
                    }
                }
            }
            out
        })
        .collect();
    pairs.par_sort_unstable();
    let mut cells = vec![Vec::new(); ncells];
    for (c, p) in pairs {
        cells[c as usize].push(p);
    }
    let box_tests = box_tests.into_inner();
    Grid { min: b.min, max: b.max, dims, cells, box_tests }
}
