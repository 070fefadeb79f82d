//! Shading normals of mesh triangles: checked from a file's vertex normals, or made from
//! the faces around each vertex behind a crease angle.
//!
//! Shading normals only bend how a surface is shaded (the cosine of direct light, the
//! mirror and refraction directions); the geometric normal, from the winding, keeps
//! deciding which side a ray is on, where new rays start and which side of a one-sided
//! patch takes light. Every normal kept here is a finite unit vector on the front side of
//! its triangle's plane (`n . n_g > 0`), so that the kernels never meet a normal that
//! would send a ray through the surface it leaves from the front.

use super::mesh::ModelTriangle;
use crate::math::Normalized;
use glam::DVec3;
use std::collections::HashMap;

/// Smallest cosine kept between a shading normal and its triangle's geometric normal:
/// a normal tilted further (or pointing behind the surface) is pulled back to this.
const MIN_COS_TO_FACE: f64 = 1e-3;

/// The unit shading normals of a triangle with corners `v` from the file's normals `n`
/// (already transformed, any length). `None` (shaded flat) when a normal is zero or not
/// finite. Normals that point to the back, as a whole, are turned to the front: the
/// file's winding decides the front, not its normals. A corner normal still behind the
/// plane, or nearly in it, is pulled towards the face until it makes an angle of at most
/// `acos(MIN_COS_TO_FACE)` with the geometric normal.
pub(super) fn shading_normals(v: &[DVec3; 3], n: [DVec3; 3]) -> Option<[DVec3; 3]> {
    let ng = unit((v[1] - v[0]).cross(v[2] - v[0]))?;
    let [a, b, c] = n.map(unit);
    let mut n = [a?, b?, c?];
    if (n[0] + n[1] + n[2]).dot(ng) < 0.0 {
        n = n.map(|u| -u);
    }
    Some(n.map(|u| toward_face(u, ng)))
}

/// `v` scaled to unit length, `None` when it is zero or not finite.
pub(crate) fn unit(v: DVec3) -> Option<DVec3> {
    let len = v.length();
    (len > 0.0 && len.is_finite()).then(|| v / len)
}

/// `u` (unit), pulled into the cone of half-angle `acos(MIN_COS_TO_FACE)` about the unit
/// geometric normal `ng` when it lies outside.
fn toward_face(u: DVec3, ng: DVec3) -> DVec3 {
    let c = u.dot(ng);
    if c >= MIN_COS_TO_FACE {
        return u;
    }
    let Some(tangent) = unit(u - ng * c) else { return ng };
    let s = (1.0 - MIN_COS_TO_FACE * MIN_COS_TO_FACE).sqrt();
    (ng * MIN_COS_TO_FACE + tangent * s).normalized()
}

/// Gives every triangle of a placed mesh that has no normals the normals of its corners
/// made from the faces around them: at a corner, the area-weighted mean of the geometric
/// normals of the triangles sharing that vertex position whose normal is within the
/// crease angle of this one's (`n_u . n_t >= crease_cos`). A cube stays faceted at a
/// crease angle under 90 degrees, a tessellated sphere turns smooth. Sums run in triangle
/// order, so the normals do not depend on hashing.
pub(super) fn smooth_by_crease(tris: &mut [ModelTriangle], crease_cos: f64) {
    let key = |p: DVec3| p.to_array().map(f64::to_bits);
    // Area-weighted normals (twice the area, by length) and unit normals of every face.
    let faces: Vec<(DVec3, DVec3)> = tris
        .iter()
        .map(|t| {
            let v = &t.v;
            let c = (v[1] - v[0]).cross(v[2] - v[0]);
            (c, c.normalized())
        })
        .collect();
    let mut around: HashMap<[u64; 3], Vec<usize>> = HashMap::new();
    for (i, t) in tris.iter().enumerate() {
        for p in &t.v {
            let list = around.entry(key(*p)).or_default();
            if list.last() != Some(&i) {
                list.push(i);
            }
        }
    }
    for i in 0..tris.len() {
        if tris[i].normals.is_some() {
            continue;
        }
        let own = faces[i].1;
        let mut n = [DVec3::ZERO; 3];
        for (k, p) in tris[i].v.iter().enumerate() {
            for &u in around.get(&key(*p)).map_or(&[][..], Vec::as_slice) {
                if faces[u].1.dot(own) >= crease_cos {
                    n[k] += faces[u].0;
                }
            }
        }
        let v = tris[i].v;
        tris[i].normals = shading_normals(&v, n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [DVec3; 3] {
        [DVec3::ZERO, DVec3::X, DVec3::Y]
    }

    #[test]
    fn file_normals_are_normalised_and_turned_to_the_front() {
        let n = shading_normals(&tri(), [DVec3::Z * 3.0, DVec3::Z, DVec3::new(0.0, 0.0, 0.5)]).unwrap();
        assert_eq!(n, [DVec3::Z; 3]);
        // All pointing to the back: the winding decides, so they are turned.
        let n = shading_normals(&tri(), [DVec3::NEG_Z; 3]).unwrap();
        assert_eq!(n, [DVec3::Z; 3]);
    }

    #[test]
    fn zero_or_nan_normals_shade_flat() {
        assert_eq!(shading_normals(&tri(), [DVec3::Z, DVec3::ZERO, DVec3::Z]), None);
        assert_eq!(shading_normals(&tri(), [DVec3::Z, DVec3::splat(f64::NAN), DVec3::Z]), None);
        assert_eq!(shading_normals(&[DVec3::ZERO, DVec3::X, DVec3::X * 2.0], [DVec3::Z; 3]), None);
    }

    #[test]
    fn normals_in_or_behind_the_plane_are_pulled_to_the_front() {
        let n = shading_normals(&tri(), [DVec3::Z, DVec3::Z, DVec3::new(1.0, 0.0, -0.2)]).unwrap();
        assert!((n[2].length() - 1.0).abs() < 1e-12);
        assert!((n[2].dot(DVec3::Z) - MIN_COS_TO_FACE).abs() < 1e-12);
        assert!(n[2].x > 0.99);
    }

    /// The eight triangles of an octahedron (unit, centred at the origin), wound outward.
    fn octahedron() -> Vec<ModelTriangle> {
        let mut out = Vec::new();
        for sx in [1.0, -1.0] {
            for sy in [1.0, -1.0] {
                for sz in [1.0, -1.0] {
                    let (a, b, c) = (DVec3::X * sx, DVec3::Y * sy, DVec3::Z * sz);
                    let v = if sx * sy * sz > 0.0 { [a, b, c] } else { [a, c, b] };
                    out.push(ModelTriangle::plain(v, 0));
                }
            }
        }
        out
    }

    #[test]
    fn a_wide_crease_angle_smooths_to_the_vertex_directions() {
        let mut tris = octahedron();
        smooth_by_crease(&mut tris, (120f64).to_radians().cos());
        for t in &tris {
            let (v, n) = (t.v, t.normals.unwrap());
            for k in 0..3 {
                // Four faces of equal area meet at each vertex: their mean is the vertex.
                assert!((n[k] - v[k]).length() < 1e-12, "{:?} at {:?}", n[k], v[k]);
            }
        }
    }

    #[test]
    fn a_narrow_crease_angle_keeps_the_faces_flat_and_file_normals_stay() {
        let mut tris = octahedron();
        tris[0].normals = Some([DVec3::X; 3]);
        smooth_by_crease(&mut tris, (60f64).to_radians().cos());
        assert_eq!(tris[0].normals, Some([DVec3::X; 3]));
        for t in &tris[1..] {
            let (v, n) = (t.v, t.normals);
            let ng = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
            for k in 0..3 {
                assert!((n.unwrap()[k] - ng).length() < 1e-12);
            }
        }
    }
}
