//! Sampling directions: uniformly over a spherical triangle (for primary light rays, so
//! that every ray of a pair carries the same flux, as in the paper) and cosine-weighted
//! over a hemisphere (diffuse bounces).

use crate::math::Normalized;
use glam::DVec3;
use std::f64::consts::PI;

/// Angle between two unit vectors, accurate near 0 and pi.
fn angle_between(a: DVec3, b: DVec3) -> f64 {
    if a.dot(b) < 0.0 {
        PI - 2.0 * ((a + b).length() / 2.0).min(1.0).asin()
    } else {
        2.0 * ((b - a).length() / 2.0).min(1.0).asin()
    }
}

/// Component of `v` orthogonal to unit `w`, normalised.
fn gram_schmidt(v: DVec3, w: DVec3) -> DVec3 {
    (v - w * v.dot(w)).normalized()
}

/// A unit direction uniformly distributed over the solid angle the triangle `v`
/// subtends from `p` (Arvo 1995, in the numerically careful form of pbrt-v4), for
/// `(u0, u1)` in the unit square; stratified inputs give stratified directions.
/// Returns `None` for degenerate configurations (zero solid angle). A caller drawing many
/// directions towards one triangle from one point builds the [`SphericalTriangle`] once.
pub fn sample_spherical_triangle(p: DVec3, v: &[DVec3; 3], u0: f64, u1: f64) -> Option<DVec3> {
    SphericalTriangle::new(p, v)?.sample(u0, u1)
}

/// The triangle `v` as seen from a point: what [`sample_spherical_triangle`] computes
/// before it looks at `(u0, u1)` (three normalisations, three cross products, three
/// arcsines and a sine and cosine), kept for every sample of a pair, whose light rays all
/// leave one point towards one element. [`SphericalTriangle::sample`] then does the same
/// operations on the same values as the one-shot function: the same bits.
#[derive(Clone, Copy, Debug)]
pub struct SphericalTriangle {
    /// Unit directions to the first two corners.
    a: DVec3,
    b: DVec3,
    /// The spherical triangle's area plus pi (the sum of its angles).
    a_pi: f64,
    sin_alpha: f64,
    cos_alpha: f64,
    /// `a . b`.
    ab: f64,
    /// The direction to the third corner, orthogonal to `a`, normalised.
    c_perp: DVec3,
}

impl SphericalTriangle {
    /// The triangle `v` seen from `p`; `None` when its solid angle is zero (or the
    /// configuration degenerate).
    pub fn new(p: DVec3, v: &[DVec3; 3]) -> Option<SphericalTriangle> {
        let a = (v[0] - p).normalized();
        let b = (v[1] - p).normalized();
        let c = (v[2] - p).normalized();
        let n_ab = a.cross(b);
        let n_bc = b.cross(c);
        let n_ca = c.cross(a);
        if n_ab.length_squared() == 0.0 || n_bc.length_squared() == 0.0 || n_ca.length_squared() == 0.0 {
            return None;
        }
        let (n_ab, n_bc, n_ca) = (n_ab.normalized(), n_bc.normalized(), n_ca.normalized());
        let alpha = angle_between(n_ab, -n_ca);
        let beta = angle_between(n_bc, -n_ab);
        let gamma = angle_between(n_ca, -n_bc);
        let a_pi = alpha + beta + gamma;
        if !(a_pi > PI) {
            return None;
        }
        let (sin_alpha, cos_alpha) = alpha.sin_cos();
        Some(SphericalTriangle { a, b, a_pi, sin_alpha, cos_alpha, ab: a.dot(b), c_perp: gram_schmidt(c, a) })
    }

    /// The direction for `(u0, u1)` in the unit square (see [`sample_spherical_triangle`]).
    pub fn sample(&self, u0: f64, u1: f64) -> Option<DVec3> {
        let SphericalTriangle { a, b, a_pi, sin_alpha, cos_alpha, ab, c_perp } = *self;
        // Sub-triangle area (plus pi) chosen by u0.
        let ap_pi = PI + u0 * (a_pi - PI);
        let sin_phi = ap_pi.sin() * cos_alpha - ap_pi.cos() * sin_alpha;
        let cos_phi = ap_pi.cos() * cos_alpha + ap_pi.sin() * sin_alpha;
        let k1 = cos_phi + cos_alpha;
        let k2 = sin_phi - sin_alpha * ab;
        let den = (k2 * sin_phi + k1 * cos_phi) * sin_alpha;
        let mut cos_bp = if den != 0.0 { (k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / den } else { 1.0 };
        if !cos_bp.is_finite() {
            cos_bp = 1.0;
        }
        let cos_bp = cos_bp.clamp(-1.0, 1.0);
        let sin_bp = (1.0 - cos_bp * cos_bp).max(0.0).sqrt();
        let cp = a * cos_bp + c_perp * sin_bp;
        let cos_theta = 1.0 - u1 * (1.0 - cp.dot(b));
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let w = b * cos_theta + gram_schmidt(cp, b) * sin_theta;
        let w = w.normalized();
        if w.is_finite() && w.length_squared() > 0.5 {
            Some(w)
        } else {
            None
        }
    }
}

/// A cosine-distributed unit direction about the unit normal `n` (Malley's method).
pub fn cosine_hemisphere(n: DVec3, u0: f64, u1: f64) -> DVec3 {
    let r = u0.sqrt();
    let phi = 2.0 * PI * u1;
    let (t, b) = n.any_orthonormal_pair();
    let z = (1.0 - u0).max(0.0).sqrt();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalized()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{intersect_watertight, solid_angle, Ray};

    #[test]
    fn spherical_samples_land_on_the_triangle_and_are_uniform_in_solid_angle() {
        let tri = [DVec3::new(-1.0, -0.5, -2.0), DVec3::new(2.0, -0.3, -1.0), DVec3::new(0.2, 1.5, -3.0)];
        let p = DVec3::new(0.1, 0.2, 0.3);
        // Split the triangle in two halves by a median; the share of samples in each half
        // must match the share of solid angle.
        let m = (tri[1] + tri[2]) * 0.5;
        let half = [tri[0], tri[1], m];
        let expected = solid_angle(p, &half) / solid_angle(p, &tri);
        let n = 64;
        let mut inside = 0;
        for i in 0..n * n {
            let u0 = ((i % n) as f64 + 0.5) / n as f64;
            let u1 = ((i / n) as f64 + 0.5) / n as f64;
            let w = sample_spherical_triangle(p, &tri, u0, u1).unwrap();
            let r = Ray::new(p, w);
            assert!(intersect_watertight(&r, &tri, 0.0, f64::INFINITY).is_some(), "sample missed the triangle");
            if intersect_watertight(&r, &half, 0.0, f64::INFINITY).is_some() {
                inside += 1;
            }
        }
        let got = inside as f64 / (n * n) as f64;
        assert!((got - expected).abs() < 0.01, "got {got}, expected {expected}");
    }

    #[test]
    fn cosine_samples_are_in_the_hemisphere() {
        let n = DVec3::new(0.0, 1.0, 0.0);
        let mut mean_cos = 0.0;
        let k = 32;
        for i in 0..k * k {
            let w = cosine_hemisphere(n, ((i % k) as f64 + 0.5) / k as f64, ((i / k) as f64 + 0.5) / k as f64);
            assert!(w.dot(n) >= 0.0);
            mean_cos += w.dot(n);
        }
        // E[cos] under a cosine distribution is 2/3.
        assert!((mean_cos / (k * k) as f64 - 2.0 / 3.0).abs() < 0.01);
    }
}
