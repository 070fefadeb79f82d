//! Subdivision of patches into elements, with welded vertices.

use crate::shares::{self, ShareError, SharePatch, ShareSet};
use glam::DVec3;
use magg_core::blocks::{NO_BACK, NO_SHADING};
use magg_core::prepared::{ElementInfo, Face, PrepareError};
use magg_core::scene::Scene;
use magg_core::subdivision::{element_count, lattice_count};
use rayon::prelude::*;

/// Patches subdivided into elements.
pub(super) struct Mesh {
    /// Corners of each patch.
    pub patches: Vec<[DVec3; 3]>,
    /// Subdivision count n of each patch.
    pub subdivisions: Vec<u32>,
    /// First element id of each patch.
    pub first_element: Vec<u32>,
    /// First back element id of each patch, or [`NO_BACK`].
    pub back_element: Vec<u32>,
    /// Elements by id.
    pub elements: Vec<ElementInfo>,
    /// Welded vertex positions.
    pub vertex_positions: Vec<DVec3>,
    /// Vertices refinement made: (edge end, edge end, midpoint), in the order made.
    pub midpoints: Vec<[u32; 3]>,
    /// Patches with a shading record.
    pub shaded: u32,
    /// Seconds numbering and splitting (the host), then welding (the shares).
    pub plan_s: f64,
    /// Seconds of the shares' welding and elements.
    pub weld_s: f64,
    /// How many shares prepared it (they hold their patches until the session ends,
    /// and write those patches' and elements' records).
    pub shares: usize,
}

/// The subdivision count n of a patch: its own, or `ceil(length / element_size)` with
/// length its size hint or longest edge; at least 1. Returned as `f64` so that absurd
/// counts can be refused rather than wrapped or clamped.
pub fn subdivisions_of(v: &[DVec3; 3], fixed: Option<u32>, size_hint: Option<f64>, element_size: f64) -> f64 {
    if let Some(n) = fixed {
        return n.max(1) as f64;
    }
    let longest = (v[1] - v[0]).length().max((v[2] - v[1]).length()).max((v[0] - v[2]).length());
    let n = (size_hint.unwrap_or(longest) / element_size).ceil();
    if n.is_finite() {
        n.max(1.0)
    } else {
        f64::INFINITY
    }
}

/// Subdivides and welds the patches of `scene`, prepared in `shares` by `set` in session
/// `session`. The outer error is the scene's; the inner, the shares'.
pub(super) fn build(
    scene: &Scene,
    shares: shares::Shares,
    set: &mut dyn ShareSet,
    session: u64,
) -> Result<Result<Mesh, ShareError>, PrepareError> {
    let start = std::time::Instant::now();
    let s = &scene.settings;
    let patches: Vec<[DVec3; 3]> = scene.patches.iter().map(|p| p.vertices).collect();
    let counts: Vec<f64> = scene
        .patches
        .par_iter()
        .map(|p| subdivisions_of(&p.vertices, p.subdivisions, p.size_hint, s.element_size))
        .collect();
    let estimate: f64 = counts.iter().map(|n| n * n).sum();
    if !(estimate <= s.max_elements as f64) {
        let (worst, n) = counts.iter().enumerate().fold((0, 0.0), |a, (i, &n)| if n > a.1 { (i, n) } else { a });
        return Err(PrepareError::TooManyElements {
            file: scene.name.clone(),
            estimate: estimate.min(u64::MAX as f64) as u64,
            limit: s.max_elements,
            worst: format!("{} ({n} x {n} subdivisions)", scene.patches[worst].loc),
        });
    }
    let subdivisions: Vec<u32> = counts.iter().map(|&n| n as u32).collect();
    // Patches whose material keeps the light on their backs apart get a second set of
    // elements (and vertices) for the back face.
    let has_back: Vec<bool> = scene
        .patches
        .iter()
        .map(|p| !s.shared_faces && scene.materials.get(p.material as usize).is_some_and(|m| m.has_back_face()))
        .collect();
    let one_sided: Vec<bool> =
        scene.patches.iter().map(|p| scene.materials.get(p.material as usize).is_some_and(|m| m.one_sided)).collect();
    let back_estimate: u64 =
        subdivisions.iter().zip(&has_back).filter(|(_, &b)| b).map(|(&n, _)| element_count(n)).sum();
    let estimate = estimate as u64 + back_estimate;
    let lattice_total: u64 = subdivisions.iter().map(|&n| lattice_count(n)).sum();
    if estimate >= u32::MAX as u64 / 2 || lattice_total >= u32::MAX as u64 / 2 || patches.len() >= u32::MAX as usize / 2
    {
        return Err(PrepareError::TooLarge { file: scene.name.clone(), what: format!("{estimate} elements") });
    }
    // Front elements patch by patch, then the back elements of the patches that have
    // them, in the same order: front ids (and with them each pair's random stream) do
    // not depend on which patches keep a back face.
    let mut first_element = Vec::with_capacity(patches.len());
    let mut acc = 0u32;
    for &n in &subdivisions {
        first_element.push(acc);
        acc += element_count(n) as u32;
    }
    let mut back_element = Vec::with_capacity(patches.len());
    for (&n, &b) in subdivisions.iter().zip(&has_back) {
        back_element.push(if b { acc } else { NO_BACK });
        acc += if b { element_count(n) as u32 } else { 0 };
    }

    // Shading records in patch order, numbered as they come: a patch with normals or a
    // texture has one.
    let mut shaded = 0u32;
    let share_patches: Vec<SharePatch> = (0..patches.len())
        .map(|p| {
            let def = &scene.patches[p];
            let uv = def.uv.zip(def.texture);
            let shading = match def.normals.is_some() || uv.is_some() {
                true => {
                    shaded += 1;
                    shaded - 1
                }
                false => NO_SHADING,
            };
            SharePatch {
                id: p as u32,
                v: patches[p],
                n: subdivisions[p],
                first_element: first_element[p],
                back_element: back_element[p],
                front_face: if one_sided[p] || has_back[p] { Face::Front } else { Face::Both },
                material: def.material,
                shading,
                normals: def.normals,
                uv,
            }
        })
        .collect();
    let split = shares::split_space(&share_patches, shares.count(patches.len()));
    let by_share = shares::by_share(share_patches, &split);
    let plan_s = start.elapsed().as_secs_f64();
    let (elements, vertex_positions) = match shares::weld(set, session, &split, by_share, acc as usize) {
        Ok(welded) => welded,
        Err(e) => return Ok(Err(e)),
    };

    Ok(Ok(Mesh {
        patches,
        subdivisions,
        first_element,
        back_element,
        elements,
        vertex_positions,
        midpoints: Vec::new(),
        shaded,
        plan_s,
        weld_s: start.elapsed().as_secs_f64() - plan_s,
        shares: split.shares(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subdivision_count_follows_element_size() {
        let v = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0)];
        assert_eq!(subdivisions_of(&v, None, None, 0.1), 15.0); // diagonal 1.414
        assert_eq!(subdivisions_of(&v, Some(20), None, 0.1), 20.0);
        assert_eq!(subdivisions_of(&v, None, None, 10.0), 1.0);
        assert_eq!(subdivisions_of(&v, None, Some(3.0), 0.1), 30.0);
        assert_eq!(subdivisions_of(&v, None, None, 1e-320), f64::INFINITY);
    }
}
