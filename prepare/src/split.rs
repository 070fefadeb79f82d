//! Adaptive refinement of elements (Heckbert 1990, the paper's ref. [11]): an element is
//! split at its edge midpoints into four, its children, which continue its patch's
//! lattice one level finer. Children are appended after every element there is, each
//! split's four together, and their new vertices after every vertex; a midpoint is made
//! once per edge (by the edge's two vertex ids), so that two neighbouring elements split
//! alike share it, across a welded patch edge too.
//!
//! Children, in order, for a parent with corners (a, b, c) and edge midpoints m_ab, m_bc,
//! m_ca: (a, m_ab, m_ca), (m_ab, b, m_bc), (m_ca, m_bc, c) and the middle one
//! (m_bc, m_ca, m_ab), all wound like the parent. [`magg_core::subdivision::child_of`] finds
//! the child a point falls in, and `subdivision::child_triangle` its corners.
//!
//! A midpoint on the edge of a neighbour that was not split is a T-junction: the
//! neighbour interpolates along that edge between the edge's ends only, so the midpoint's
//! irradiance is set to the mean of theirs ([`t_junctions`]), and the image stays
//! continuous across the edge.

use super::mesh::Mesh;
use magg_core::geometry::triangle_area;
use magg_core::idhash::{IdMap, IdSet};
use magg_core::prepared::ElementInfo;
use magg_core::subdivision::child_triangle;

/// The key of the edge between vertices `a` and `b`.
fn edge(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Splits each leaf element of `ids` (ascending) into four.
pub(super) fn split(mesh: &mut Mesh, ids: &[u32]) {
    let mut made: IdMap<(u32, u32), u32> = mesh.midpoints.iter().map(|&[a, b, m]| (edge(a, b), m)).collect();
    for &e in ids {
        let Some(&parent) = mesh.elements.get(e as usize) else { continue };
        if !parent.is_leaf() {
            continue;
        }
        let [a, b, c] = parent.vertices;
        let mut midpoint = |x: u32, y: u32| {
            *made.entry(edge(x, y)).or_insert_with(|| {
                let m = mesh.vertex_positions.len() as u32;
                let (px, py) = (mesh.vertex_positions[x as usize], mesh.vertex_positions[y as usize]);
                mesh.vertex_positions.push((px + py) * 0.5);
                mesh.midpoints.push([x, y, m]);
                m
            })
        };
        let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
        let first = mesh.elements.len() as u32;
        let corners =
            [mesh.vertex_positions[a as usize], mesh.vertex_positions[b as usize], mesh.vertex_positions[c as usize]];
        let ids = [[a, ab, ca], [ab, b, bc], [ca, bc, c], [bc, ca, ab]];
        for (slot, vertices) in ids.into_iter().enumerate() {
            let tri = child_triangle(&corners, slot);
            mesh.elements.push(ElementInfo {
                vertices,
                area: triangle_area(&tri),
                centroid: (tri[0] + tri[1] + tri[2]) / 3.0,
                parent: e,
                child: 0,
                ..parent
            });
        }
        mesh.elements[e as usize].child = first;
    }
}

/// The midpoints that lie on the edge of a leaf element (which does not use them), as
/// (edge end, edge end, midpoint) in the order they were made: a coarser one before any
/// finer one that may depend on it.
pub(super) fn t_junctions(mesh: &Mesh) -> Vec<[u32; 3]> {
    if mesh.midpoints.is_empty() {
        return Vec::new();
    }
    let leaf_edges: IdSet<(u32, u32)> = mesh
        .elements
        .iter()
        .filter(|e| e.is_leaf())
        .flat_map(|e| {
            let [a, b, c] = e.vertices;
            [edge(a, b), edge(b, c), edge(c, a)]
        })
        .collect();
    mesh.midpoints.iter().copied().filter(|&[a, b, _]| leaf_edges.contains(&edge(a, b))).collect()
}
