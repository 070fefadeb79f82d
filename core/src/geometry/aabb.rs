//! Axis-aligned boxes and the exact triangle/box overlap test used to fill subspaces.

use glam::DVec3;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb {
    /// The empty box (min = +inf, max = -inf).
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        max: DVec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    };
    /// Smallest box holding `self` and `p`.
    pub fn grow(self, p: DVec3) -> Aabb {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }
    /// Smallest box holding both.
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    /// Box of a triangle.
    pub fn of_triangle(v: &[DVec3; 3]) -> Aabb {
        Aabb::EMPTY.grow(v[0]).grow(v[1]).grow(v[2])
    }
    /// Edge lengths.
    pub fn extent(self) -> DVec3 {
        self.max - self.min
    }
}

/// Exact triangle/box overlap by the separating axis theorem (Akenine-Moller 2001):
/// the 3 box normals, the triangle normal and the 9 edge cross products. Touching
/// counts as overlap, so a patch on a subspace face is listed in both subspaces.
pub fn triangle_overlaps_box(tri: &[DVec3; 3], bmin: DVec3, bmax: DVec3) -> bool {
    let c = (bmin + bmax) * 0.5;
    let h = (bmax - bmin) * 0.5;
    let v0 = tri[0] - c;
    let v1 = tri[1] - c;
    let v2 = tri[2] - c;
    // Box normals.
    for k in 0..3 {
        let lo = v0[k].min(v1[k]).min(v2[k]);
        let hi = v0[k].max(v1[k]).max(v2[k]);
        if lo > h[k] || hi < -h[k] {
            return false;
        }
    }
    let e = [v1 - v0, v2 - v1, v0 - v2];
    // Triangle normal.
    let n = e[0].cross(e[1]);
    let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
    if n.dot(v0).abs() > r {
        return false;
    }
    // Nine edge axes.
    let axes_of =
        |ed: DVec3| [DVec3::new(0.0, -ed.z, ed.y), DVec3::new(ed.z, 0.0, -ed.x), DVec3::new(-ed.y, ed.x, 0.0)];
    for ed in e {
        for a in axes_of(ed) {
            if a == DVec3::ZERO {
                continue;
            }
            let p0 = a.dot(v0);
            let p1 = a.dot(v1);
            let p2 = a.dot(v2);
            let r = h.x * a.x.abs() + h.y * a.y.abs() + h.z * a.z.abs();
            if p0.min(p1).min(p2) > r || p0.max(p1).max(p2) < -r {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_triangle_skips_corner_box_its_bbox_covers() {
        // Triangle near the x+y=2 plane corner; its bbox covers box [0,0.5]^3 but the
        // triangle does not.
        let tri = [DVec3::new(2.0, 0.0, 0.0), DVec3::new(0.0, 2.0, 0.0), DVec3::new(0.0, 0.0, 2.0)];
        assert!(!triangle_overlaps_box(&tri, DVec3::ZERO, DVec3::new(0.5, 0.5, 0.5)));
        assert!(triangle_overlaps_box(&tri, DVec3::new(0.5, 0.5, 0.5), DVec3::new(1.0, 1.0, 1.0)));
    }

    #[test]
    fn touching_face_counts() {
        let tri = [DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 1.0)];
        assert!(triangle_overlaps_box(&tri, DVec3::ZERO, DVec3::new(1.0, 1.0, 1.0)));
        assert!(triangle_overlaps_box(&tri, DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 1.0, 2.0)));
        assert!(!triangle_overlaps_box(&tri, DVec3::new(0.0, 0.0, 1.1), DVec3::new(1.0, 1.0, 2.0)));
    }
}
