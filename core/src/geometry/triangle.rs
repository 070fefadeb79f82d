//! Triangles: watertight ray intersection, area and exact solid angle.

use super::Ray;
use crate::math::Normalized;
use glam::DVec3;

/// A ray/triangle hit: distance and barycentric weights of the three corners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Barycentric weights of vertices 0, 1, 2 (sum to 1, each in [0, 1]).
    pub bary: [f64; 3],
}

/// Watertight ray/triangle intersection (Woop, Benthin and Wald, JCGT 2013).
///
/// The ray is sheared so that it points along +z; the three 2D edge functions of the
/// triangle are then evaluated at the origin. A shared edge of two triangles yields edge
/// functions that are exact negatives of each other, so a ray through that edge hits at
/// least one of them: no ray passes between neighbouring triangles. Values of exactly
/// zero (on an edge or vertex) count as a hit. Returns a hit with `tmin < t < tmax`.
/// Degenerate triangles (zero determinant) and non-finite rays never hit.
pub fn intersect_watertight(ray: &Ray, v: &[DVec3; 3], tmin: f64, tmax: f64) -> Option<TriHit> {
    WatertightRay::new(ray)?.intersect(v, tmin, tmax)
}

/// The per-ray part of [`intersect_watertight`] (axis permutation and shear), computed
/// once for a ray tested against many triangles. `WatertightRay::new(ray)?.intersect(..)`
/// is `intersect_watertight`, the same operations in the same order: the same bits.
///
/// The test reads only the permuted components of each corner (`x` along `kx`, ...), so
/// it can read them straight from a record's bytes ([`WatertightRay::intersect_record`])
/// without decoding the corners first.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    /// The origin's components along `kx`, `ky`, `kz`.
    origin: [f64; 3],
    /// The axes that become x, y and z (each 0, 1 or 2).
    k: [usize; 3],
    sx: f64,
    sy: f64,
    sz: f64,
}

impl WatertightRay {
    /// The sheared ray; `None` for a zero or non-finite direction (which hits nothing).
    #[inline]
    pub fn new(ray: &Ray) -> Option<WatertightRay> {
        let d = ray.direction.to_array();
        let ad = [d[0].abs(), d[1].abs(), d[2].abs()];
        // Axis of the largest direction component becomes z; the next two (cyclically)
        // x and y, swapped when it points down z (a table, not `% 3`).
        let (kz, mut kx, mut ky) = if ad[0] >= ad[1] && ad[0] >= ad[2] {
            (0, 1, 2)
        } else if ad[1] >= ad[2] {
            (1, 2, 0)
        } else {
            (2, 0, 1)
        };
        let dz = d[kz];
        if dz < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        if dz == 0.0 || !dz.is_finite() {
            return None; // zero or non-finite direction
        }
        let o = ray.origin.to_array();
        Some(WatertightRay {
            origin: [o[kx], o[ky], o[kz]],
            k: [kx, ky, kz],
            sx: d[kx] / dz,
            sy: d[ky] / dz,
            sz: 1.0 / dz,
        })
    }

    /// The hit of triangle `v` with `tmin < t < tmax`, as [`intersect_watertight`].
    #[inline]
    pub fn intersect(&self, v: &[DVec3; 3], tmin: f64, tmax: f64) -> Option<TriHit> {
        let [kx, ky, kz] = self.k;
        let p = v.map(|c| {
            let c = c.to_array();
            [c[kx], c[ky], c[kz]]
        });
        self.intersect_permuted(&p, tmin, tmax)
    }

    /// [`WatertightRay::intersect`] on corners stored as nine little-endian f64 (corner 0's
    /// x, y, z, then corner 1's, corner 2's) at the start of `record`, as patch and leaf
    /// triangle records hold them: the same bits, without decoding the corners.
    #[inline(always)]
    pub fn intersect_record(&self, record: &[u8; 72], tmin: f64, tmax: f64) -> Option<TriHit> {
        // `k & 3` and `min(64)` keep every read within the 72 bytes whatever `k` (the
        // compiler sees it and checks nothing); `k` is 0, 1 or 2, so neither changes one.
        let at = |corner: usize, k: usize| {
            let o = 24 * corner + 8 * (k & 3);
            let bytes: [u8; 8] = record[o.min(64)..o.min(64) + 8].try_into().unwrap_or([0; 8]);
            f64::from_le_bytes(bytes)
        };
        let [kx, ky, kz] = self.k;
        // (Written out, not `[0, 1, 2].map`: the map is not always inlined.)
        let p =
            [[at(0, kx), at(0, ky), at(0, kz)], [at(1, kx), at(1, ky), at(1, kz)], [at(2, kx), at(2, ky), at(2, kz)]];
        self.intersect_permuted(&p, tmin, tmax)
    }

    /// The test on each corner's components along `kx`, `ky`, `kz`.
    #[inline(always)]
    fn intersect_permuted(&self, p: &[[f64; 3]; 3], tmin: f64, tmax: f64) -> Option<TriHit> {
        let WatertightRay { origin: o, sx, sy, sz, .. } = *self;
        let rel = |c: &[f64; 3]| [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
        let (a, b, c) = (rel(&p[0]), rel(&p[1]), rel(&p[2]));
        let ax = a[0] - sx * a[2];
        let ay = a[1] - sy * a[2];
        let bx = b[0] - sx * b[2];
        let by = b[1] - sy * b[2];
        let cx = c[0] - sx * c[2];
        let cy = c[1] - sy * c[2];

        let u = cx * by - cy * bx;
        let vv = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || vv < 0.0 || w < 0.0) && (u > 0.0 || vv > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + vv + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let az = sz * a[2];
        let bz = sz * b[2];
        let cz = sz * c[2];
        let t_scaled = u * az + vv * bz + w * cz;
        let t = t_scaled / det;
        if !(t > tmin && t < tmax) {
            return None;
        }
        // Divide rather than multiply by 1 / det: for a sliver whose det is subnormal,
        // 1 / det overflows and the weights would be inf or NaN.
        Some(TriHit { t, bary: [u / det, vv / det, w / det] })
    }
}

/// Unit geometric normal of a triangle, by its winding (right hand, `v0 -> v1 -> v2`);
/// zero for a degenerate one. Both passes scatter about it.
pub fn triangle_normal(v: &[DVec3; 3]) -> DVec3 {
    (v[1] - v[0]).cross(v[2] - v[0]).normalized()
}

/// Area of a triangle.
pub fn triangle_area(v: &[DVec3; 3]) -> f64 {
    0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length()
}

/// Exact solid angle of a triangle seen from `p` (Van Oosterom and Strackee, 1983):
/// `tan(Omega / 2) = |a . (b x c)| / (abc + (a.b)c + (a.c)b + (b.c)a)`.
/// Zero when `p` lies in the triangle's plane.
pub fn solid_angle(p: DVec3, v: &[DVec3; 3]) -> f64 {
    let a = v[0] - p;
    let b = v[1] - p;
    let c = v[2] - p;
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    if la == 0.0 || lb == 0.0 || lc == 0.0 {
        return 0.0;
    }
    let num = a.dot(b.cross(c)).abs();
    if num == 0.0 {
        // In the plane (inside the triangle, atan2(0, den < 0) would say 2 pi).
        return 0.0;
    }
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    let omega = 2.0 * num.atan2(den);
    if omega.is_finite() {
        omega.max(0.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reading the corners in place from a record gives the bits of the decoded test,
    /// on random and awkward triangles and rays (shared edges, axis-parallel rays).
    #[test]
    fn the_test_on_record_bytes_gives_the_decoded_bits() {
        let mut rng = crate::rng::Rng::from_words(&[19, 0x7e57]);
        let c = |rng: &mut crate::rng::Rng| match (rng.next_f64() * 6.0) as u32 {
            0 => 0.0,
            1 => 1.0,
            _ => (rng.next_f64() - 0.5) * 8.0,
        };
        let mut hits = 0;
        for case in 0..20_000 {
            let v = [0, 1, 2].map(|_| DVec3::new(c(&mut rng), c(&mut rng), c(&mut rng)));
            let mut d = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
            if case % 4 == 0 {
                d[case % 3] = 0.0;
            }
            let ray = Ray::new(DVec3::new(c(&mut rng), c(&mut rng), c(&mut rng)), d.normalize());
            let mut record = [0u8; 72];
            for (i, x) in v.iter().flat_map(|p| p.to_array()).enumerate() {
                record[8 * i..8 * i + 8].copy_from_slice(&x.to_le_bytes());
            }
            let Some(w) = WatertightRay::new(&ray) else { continue };
            let bits = |h: Option<TriHit>| h.map(|h| (h.t.to_bits(), h.bary.map(f64::to_bits)));
            let (a, b) = (w.intersect(&v, 1e-9, f64::INFINITY), w.intersect_record(&record, 1e-9, f64::INFINITY));
            assert_eq!(bits(a), bits(b), "case {case}: {v:?} {ray:?}");
            hits += a.is_some() as u32;
        }
        assert!(hits > 500, "too few hits to compare: {hits}");
    }

    fn tri() -> [DVec3; 3] {
        [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0)]
    }

    #[test]
    fn hits_inside_misses_outside() {
        let r = Ray::new(DVec3::new(0.25, 0.25, 1.0), DVec3::new(0.0, 0.0, -1.0));
        let h = intersect_watertight(&r, &tri(), 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-15);
        assert!((h.bary[1] - 0.25).abs() < 1e-15 && (h.bary[2] - 0.25).abs() < 1e-15);
        let r = Ray::new(DVec3::new(0.75, 0.75, 1.0), DVec3::new(0.0, 0.0, -1.0));
        assert!(intersect_watertight(&r, &tri(), 0.0, f64::INFINITY).is_none());
    }

    #[test]
    fn shared_edge_is_hit_by_one_of_two_triangles() {
        // Square split along its diagonal; rays aimed exactly at points of the diagonal.
        let t1 = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(1.0, 1.0, 0.0)];
        let t2 = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.0, 1.0, 0.0)];
        let o = DVec3::new(0.3, -0.7, 2.0);
        // Interior points of the diagonal (its ends are corners of the square's outline).
        for i in 1..1000 {
            let s = i as f64 / 1000.0;
            let target = DVec3::new(s, s, 0.0);
            let r = Ray::new(o, (target - o).normalized());
            let h1 = intersect_watertight(&r, &t1, 0.0, f64::INFINITY);
            let h2 = intersect_watertight(&r, &t2, 0.0, f64::INFINITY);
            assert!(h1.is_some() || h2.is_some(), "ray through diagonal point {s} missed both");
        }
    }

    #[test]
    fn degenerate_triangle_never_hits() {
        let t = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(2.0, 0.0, 0.0)];
        let r = Ray::new(DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0));
        assert!(intersect_watertight(&r, &t, 0.0, f64::INFINITY).is_none());
    }

    #[test]
    fn non_finite_rays_never_hit() {
        for d in [DVec3::new(f64::NAN, 0.0, -1.0), DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.0, 0.0, f64::INFINITY)] {
            let r = Ray::new(DVec3::new(0.25, 0.25, 1.0), d);
            assert!(intersect_watertight(&r, &tri(), 0.0, f64::INFINITY).is_none());
        }
    }

    #[test]
    fn solid_angle_of_cube_faces_sums_to_four_pi() {
        // A unit cube around the origin: 12 triangles, total 4 pi.
        let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let faces = [
            [c(-1., -1., -1.), c(1., -1., -1.), c(1., 1., -1.), c(-1., 1., -1.)],
            [c(-1., -1., 1.), c(1., -1., 1.), c(1., 1., 1.), c(-1., 1., 1.)],
            [c(-1., -1., -1.), c(1., -1., -1.), c(1., -1., 1.), c(-1., -1., 1.)],
            [c(-1., 1., -1.), c(1., 1., -1.), c(1., 1., 1.), c(-1., 1., 1.)],
            [c(-1., -1., -1.), c(-1., 1., -1.), c(-1., 1., 1.), c(-1., -1., 1.)],
            [c(1., -1., -1.), c(1., 1., -1.), c(1., 1., 1.), c(1., -1., 1.)],
        ];
        let p = c(0.1, -0.2, 0.3);
        let total: f64 =
            faces.iter().map(|q| solid_angle(p, &[q[0], q[1], q[2]]) + solid_angle(p, &[q[0], q[2], q[3]])).sum();
        assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-12, "{total}");
    }

    #[test]
    fn solid_angle_is_zero_in_plane() {
        assert_eq!(solid_angle(DVec3::new(5.0, 5.0, 0.0), &tri()), 0.0);
    }
}
