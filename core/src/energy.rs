//! Energy interpolation to vertices (paper §3.3), the elements' irradiance, the
//! vertices a viewing ray gathers at, and the vertex-energy blocks. Element energies
//! arrive in fixed point ([`crate::fixed`]).

use crate::blocks::{encode_vertex_energy, Block, BlockLayout, BLOCK_SIZE, VERTICES_PER_BLOCK};
use crate::color::Rgb;
use crate::fixed::{from_fixed, Fixed};
use crate::prepared::ElementInfo;

/// Vertex irradiance: the area-weighted mean of the irradiance (flux / area) of the
/// leaf elements sharing the vertex, i.e. `sum(flux) / sum(area)`; then each T-junction
/// `[a, b, m]` (a refinement midpoint `m` on the edge `a b` of an element that does not
/// use it, in the order they were made) takes the mean of `a` and `b`, so that the
/// irradiance is continuous across the edge. Deterministic: integer flux sums, area
/// sums in element order.
pub fn interpolate(
    elements: &[ElementInfo],
    t_junctions: &[[u32; 3]],
    flux: &[Fixed],
    vertices: usize,
    quantum: f64,
) -> Vec<Rgb> {
    let mut sum = vec![[0i128; 3]; vertices];
    let mut area = vec![0.0f64; vertices];
    for (e, f) in elements.iter().zip(flux).filter(|(e, _)| e.is_leaf()) {
        for &v in &e.vertices {
            if let Some(s) = sum.get_mut(v as usize) {
                for c in 0..3 {
                    s[c] += f[c] as i128;
                }
                area[v as usize] += e.area;
            }
        }
    }
    let mut irradiance: Vec<Rgb> = sum
        .iter()
        .zip(&area)
        .map(|(s, &a)| {
            if a > 0.0 {
                Rgb([s[0] as f64 * quantum / a, s[1] as f64 * quantum / a, s[2] as f64 * quantum / a])
            } else {
                Rgb::BLACK
            }
        })
        .collect();
    for &[a, b, m] in t_junctions {
        if let (Some(&ea), Some(&eb)) = (irradiance.get(a as usize), irradiance.get(b as usize)) {
            if let Some(em) = irradiance.get_mut(m as usize) {
                *em = ea.add(eb).scale(0.5);
            }
        }
    }
    irradiance
}

/// The vertices around the elements that received no light at all: for each vertex,
/// whether it belongs to a leaf element that shares a vertex with an unlit leaf element
/// (one of area > 0 whose flux is zero, e.g. the floor under a box), or to an unlit one.
///
/// Where such elements meet lit ones, interpolation cannot be right: an element partly
/// covered by another surface has its flux spread over its whole area, and a vertex on
/// the boundary averages in the dark ones, so the light fades a whole element before a
/// contact (the floor along a box's base). Shading gathers the light there instead
/// ([`crate::vrt`]); two rings of elements around the unlit ones are marked, so that
/// no pixel left to interpolation reads a vertex that averages a covered element.
/// Deterministic: it depends only on which elements hold zero flux.
pub fn gather_vertices(elements: &[ElementInfo], flux: &[Fixed], vertices: usize) -> Vec<bool> {
    let leaves = || elements.iter().zip(flux).filter(|(e, _)| e.is_leaf() && e.area > 0.0);
    let mut dark = vec![false; vertices];
    for (e, _) in leaves().filter(|(_, f)| **f == [0; 3]) {
        for &v in &e.vertices {
            if let Some(d) = dark.get_mut(v as usize) {
                *d = true;
            }
        }
    }
    let mut gather = vec![false; vertices];
    for (e, _) in leaves() {
        if e.vertices.iter().any(|&v| dark.get(v as usize) == Some(&true)) {
            for &v in &e.vertices {
                if let Some(g) = gather.get_mut(v as usize) {
                    *g = true;
                }
            }
        }
    }
    gather
}

/// Irradiance of every element (flux / area).
pub fn element_irradiance(elements: &[ElementInfo], flux: &[Fixed], quantum: f64) -> Vec<Rgb> {
    elements
        .iter()
        .zip(flux)
        .map(|(e, f)| if e.area > 0.0 { from_fixed(*f, quantum).scale(1.0 / e.area) } else { Rgb::BLACK })
        .collect()
}

/// Packs vertex irradiances into vertex-energy blocks: `(block id, block)` pairs; a
/// vertex marked in `gather` ([`gather_vertices`]; empty: none) carries its mark in the
/// record ([`encode_vertex_energy`]).
pub fn vertex_energy_blocks(irradiance: &[Rgb], gather: &[bool], layout: &BlockLayout) -> Vec<(u32, Box<Block>)> {
    let n = layout.vertex_blocks() as usize;
    (0..n)
        .map(|k| {
            let mut b = Box::new([0u8; BLOCK_SIZE]);
            for (i, e) in irradiance.iter().skip(k * VERTICES_PER_BLOCK).take(VERTICES_PER_BLOCK).enumerate() {
                let marked = gather.get(k * VERTICES_PER_BLOCK + i) == Some(&true);
                encode_vertex_energy(&mut b, i * 12, *e, marked);
            }
            (layout.vertex_base + k as u32, b)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn interpolation_is_area_weighted() {
        let e = |v: [u32; 3], area: f64| ElementInfo {
            patch: 0,
            vertices: v,
            area,
            centroid: DVec3::ZERO,
            face: crate::prepared::Face::Both,
            parent: crate::prepared::NO_PARENT,
            child: 0,
        };
        let elements = [e([0, 1, 2], 1.0), e([1, 2, 3], 3.0)];
        let flux = [[10, 10, 10], [60, 60, 60]]; // irradiance 10 and 20
        let v = interpolate(&elements, &[], &flux, 4, 1.0);
        assert_eq!(v[0].0[0], 10.0);
        assert_eq!(v[3].0[0], 20.0);
        assert_eq!(v[1].0[0], 70.0 / 4.0);
    }

    #[test]
    fn gather_marks_two_rings_around_unlit_elements() {
        let e = |v: [u32; 3]| ElementInfo {
            patch: 0,
            vertices: v,
            area: 1.0,
            centroid: DVec3::ZERO,
            face: crate::prepared::Face::Both,
            parent: crate::prepared::NO_PARENT,
            child: 0,
        };
        // A strip of elements 0-1-2-3 sharing vertices in a row: [0,1,2], [1,2,3], ...
        let elements: Vec<_> = (0..6).map(|i| e([i, i + 1, i + 2])).collect();
        let mut flux = vec![[5, 5, 5]; 6];
        flux[0] = [0; 3];
        let g = gather_vertices(&elements, &flux, 8);
        // Element 0 is unlit (vertices 0-2); elements 1 and 2 share a vertex with it, so
        // their vertices (up to 4) are marked; the rest are not.
        assert_eq!(g, [true, true, true, true, true, false, false, false]);
        // Every element lit: nothing marked.
        assert!(!gather_vertices(&elements, &[[1, 0, 0]; 6], 8).iter().any(|&m| m));
    }
}
