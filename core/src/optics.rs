//! Specular optics: mirror reflection, refraction and the dielectric Fresnel factor.

use crate::math::Vec3;

/// Mirror reflection of direction `d` about unit normal `n` (either side).
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - n * (2.0 * d.dot(n))
}

/// Unpolarised Fresnel reflectance of a dielectric interface.
///
/// `cos_i` is the cosine of the incidence angle (>= 0) and `eta = n_i / n_t` the ratio of
/// indices (incident over transmitted side). Returns 1 past the critical angle (total
/// internal reflection).
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    // With n_t = 1, n_i = eta.
    let r_s = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_p = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let f = 0.5 * (r_s * r_s + r_p * r_p);
    if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Refraction of unit `d` through a surface with unit normal `n` facing the incident
/// side (`d . n < 0`), with `eta = n_i / n_t`. `None` on total internal reflection.
pub fn refract(d: Vec3, n: Vec3, eta: f64) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalized())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_normal_incidence_matches_closed_form() {
        // ((n1 - n2) / (n1 + n2))^2 = 0.04 for glass 1.5 in air.
        assert!((fresnel_dielectric(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-12);
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
    }

    #[test]
    fn fresnel_published_values_for_glass() {
        // Air -> glass (n = 1.5): Rs and Rp at 45 degrees are 0.0920 and 0.0085
        // (Hecht, Optics), unpolarised mean 0.0503.
        let c = (45f64).to_radians().cos();
        assert!((fresnel_dielectric(c, 1.0 / 1.5) - 0.0503).abs() < 5e-4);
        // Brewster angle: Rp = 0, so R = Rs / 2 = 0.0739.
        let brewster = 1.5f64.atan();
        assert!((fresnel_dielectric(brewster.cos(), 1.0 / 1.5) - 0.07396).abs() < 5e-4);
        // Grazing incidence reflects everything.
        assert!((fresnel_dielectric(0.0, 1.0 / 1.5) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn total_internal_reflection_at_and_past_critical_angle() {
        let critical = (1.0f64 / 1.5).asin();
        assert_eq!(fresnel_dielectric((critical + 1e-9).cos(), 1.5), 1.0);
        assert!(fresnel_dielectric((critical - 1e-3).cos(), 1.5) < 1.0);
        let n = Vec3::new(0.0, 1.0, 0.0);
        let th = critical + 0.01;
        let d = Vec3::new(th.sin(), -th.cos(), 0.0);
        assert!(refract(d, n, 1.5).is_none());
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = Vec3::new(0.0, 1.0, 0.0);
        let th: f64 = 0.5;
        let d = Vec3::new(th.sin(), -th.cos(), 0.0);
        let t = refract(d, n, 1.0 / 1.5).unwrap();
        assert!((t.x - th.sin() / 1.5).abs() < 1e-12);
        assert!(t.y < 0.0);
    }
}
