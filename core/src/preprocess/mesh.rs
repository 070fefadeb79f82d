//! Subdivision of patches into elements, with welded vertices.

use super::weld::weld;
use super::{ElementInfo, PrepareError};
use crate::geometry::triangle_area;
use crate::math::Vec3;
use crate::scene::Scene;
use crate::subdivision::{element_corners, element_count, lattice_count, lattice_index, lattice_point};
use rayon::prelude::*;

/// Patches subdivided into elements.
pub(super) struct Mesh {
    /// Corners of each patch.
    pub patches: Vec<[Vec3; 3]>,
    /// Material of each patch.
    pub materials: Vec<u32>,
    /// Subdivision count n of each patch.
    pub subdivisions: Vec<u32>,
    /// First element id of each patch.
    pub first_element: Vec<u32>,
    /// Elements by id.
    pub elements: Vec<ElementInfo>,
    /// Welded vertex positions.
    pub vertex_positions: Vec<Vec3>,
}

/// The subdivision count of a patch: its own, or `ceil(longest edge / element_size)`,
/// at least 1 and at most 4096.
pub fn subdivisions_of(v: &[Vec3; 3], fixed: Option<u32>, element_size: f64) -> u32 {
    if let Some(n) = fixed {
        return n.clamp(1, 4096);
    }
    let longest = (v[1] - v[0]).length().max((v[2] - v[1]).length()).max((v[0] - v[2]).length());
    let n = (longest / element_size).ceil();
    if n.is_finite() {
        n.clamp(1.0, 4096.0) as u32
    } else {
        1
    }
}

pub(super) fn build(scene: &Scene) -> Result<Mesh, PrepareError> {
    let s = &scene.settings;
    let patches: Vec<[Vec3; 3]> = scene.patches.iter().map(|p| p.vertices).collect();
    let subdivisions: Vec<u32> =
        scene.patches.par_iter().map(|p| subdivisions_of(&p.vertices, p.subdivisions, s.element_size)).collect();
    let estimate: u64 = subdivisions.iter().map(|&n| element_count(n)).sum();
    if estimate > s.max_elements {
        return Err(PrepareError::TooManyElements { file: scene.name.clone(), estimate, limit: s.max_elements });
    }
    let lattice_total: u64 = subdivisions.iter().map(|&n| lattice_count(n)).sum();
    if estimate >= u32::MAX as u64 / 2 || lattice_total >= u32::MAX as u64 / 2 || patches.len() >= u32::MAX as usize / 2
    {
        return Err(PrepareError::TooLarge { file: scene.name.clone(), what: format!("{estimate} elements") });
    }
    let mut first_element = Vec::with_capacity(patches.len());
    let mut acc = 0u32;
    for &n in &subdivisions {
        first_element.push(acc);
        acc += element_count(n) as u32;
    }

    let welded = weld(&patches, &subdivisions);

    let elements: Vec<ElementInfo> = (0..patches.len())
        .into_par_iter()
        .flat_map_iter(|p| {
            let n = subdivisions[p];
            let v = patches[p];
            let base = welded.lattice_offset[p];
            let ids = &welded.ids;
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
                }
            })
        })
        .collect();

    Ok(Mesh {
        materials: scene.patches.iter().map(|p| p.material).collect(),
        patches,
        subdivisions,
        first_element,
        elements,
        vertex_positions: welded.positions,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subdivision_count_follows_element_size() {
        let v = [Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        assert_eq!(subdivisions_of(&v, None, 0.1), 15); // diagonal 1.414
        assert_eq!(subdivisions_of(&v, Some(20), 0.1), 20);
        assert_eq!(subdivisions_of(&v, None, 10.0), 1);
    }
}
