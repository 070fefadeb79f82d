//! How light leaves a surface, written once for both passes.
//!
//! Light ray tracing ([`crate::lrt`]) and viewing ray tracing ([`crate::vrt`]) ask this
//! module the same questions at every specular hit, in the spirit of pbrt's
//! `SpawnRay`/`OffsetRayOrigin` and its bxdfs: which side of the surface the ray came
//! from ([`Arrival`], the face-forward normal), the index ratio on that side, the mirror
//! direction, the Fresnel split of a dielectric into reflection and refraction
//! ([`Dielectric`]), and where a new ray starts so that it does not hit the surface it
//! leaves ([`Arrival::spawn`], [`offset_scale`]).
//!
//! ```
//! use glam::DVec3;
//! use magg_core::scatter::{Arrival, Dielectric};
//! // A ray going straight down onto the top of a glass floor.
//! let at = Arrival::new(DVec3::ZERO, DVec3::new(0.0, -1.0, 0.0), DVec3::new(0.0, 1.0, 0.0));
//! assert_eq!(at.reflected(), DVec3::new(0.0, 1.0, 0.0));
//! let Dielectric::Split { fresnel, refracted } = at.dielectric(1.5, true) else { unreachable!() };
//! assert!((fresnel - 0.04).abs() < 1e-12 && (refracted - DVec3::NEG_Y).length() < 1e-12);
//! assert!(at.spawn(refracted).origin.y < 0.0);
//! ```

use crate::geometry::Ray;
use crate::math::Normalized;
use glam::DVec3;

/// Offset from a surface point for a new ray, scaled to the coordinates' magnitude (the
/// rays of scenes far from the origin need a larger one).
pub fn offset_scale(p: DVec3) -> f64 {
    1e-9 * (1.0 + p.abs().max_element())
}

/// Mirror reflection of direction `d` about unit normal `n` (either side).
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
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
pub fn refract(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalized())
}

/// A ray's arrival at a surface point: the point, the incoming direction and the
/// geometric normal turned to face the side the ray came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arrival {
    /// The surface point.
    pub p: DVec3,
    /// The incoming unit direction.
    pub d: DVec3,
    /// The unit normal on the incident side (`d . normal <= 0`).
    pub normal: DVec3,
    /// True when the ray hit the front (the side the patch's winding points to).
    pub front: bool,
}

/// How a dielectric splits the light that reaches it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Dielectric {
    /// A fraction `fresnel` is reflected, the rest leaves along `refracted`.
    Split {
        /// Fresnel reflectance, in [0, 1).
        fresnel: f64,
        /// The refracted unit direction.
        refracted: DVec3,
    },
    /// Everything is reflected: total internal reflection, or refraction left out by the
    /// effects plan.
    Reflected,
}

impl Arrival {
    /// The arrival of direction `d` at point `p` of a surface with unit geometric normal
    /// `normal` (either side).
    pub fn new(p: DVec3, d: DVec3, normal: DVec3) -> Self {
        let front = d.dot(normal) < 0.0;
        Arrival { p, d, normal: if front { normal } else { -normal }, front }
    }

    /// Index ratio `n_i / n_t` at a dielectric of index `ior` in air, by the side hit.
    pub fn eta(&self, ior: f64) -> f64 {
        if self.front {
            1.0 / ior
        } else {
            ior
        }
    }

    /// The mirror direction.
    pub fn reflected(&self) -> DVec3 {
        reflect(self.d, self.normal)
    }

    /// The split at a dielectric of index `ior`; `refraction` false (the effects plan
    /// leaves refraction out) reflects everything.
    pub fn dielectric(&self, ior: f64, refraction: bool) -> Dielectric {
        let eta = self.eta(ior);
        let fresnel = fresnel_dielectric(-self.d.dot(self.normal), eta);
        let refracted = if refraction { refract(self.d, self.normal, eta) } else { None };
        match refracted {
            Some(refracted) if fresnel < 1.0 => Dielectric::Split { fresnel, refracted },
            _ => Dielectric::Reflected,
        }
    }

    /// A new ray leaving the point along `dir`, its origin pushed off the surface to the
    /// side `dir` goes to, so that it does not hit the surface it leaves.
    pub fn spawn(&self, dir: DVec3) -> Ray {
        let side = if dir.dot(self.normal) >= 0.0 { self.normal } else { -self.normal };
        Ray::new(self.p + side * offset_scale(self.p), dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UP: DVec3 = DVec3::new(0.0, 1.0, 0.0);

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
        let th = critical + 0.01;
        let d = DVec3::new(th.sin(), -th.cos(), 0.0);
        assert!(refract(d, UP, 1.5).is_none());
    }

    #[test]
    fn refraction_obeys_snell() {
        let th: f64 = 0.5;
        let d = DVec3::new(th.sin(), -th.cos(), 0.0);
        let t = refract(d, UP, 1.0 / 1.5).unwrap();
        assert!((t.x - th.sin() / 1.5).abs() < 1e-12);
        assert!(t.y < 0.0);
    }

    #[test]
    fn arrival_faces_the_normal_towards_the_incident_side() {
        let d = DVec3::new(0.6, -0.8, 0.0);
        let top = Arrival::new(DVec3::ZERO, d, UP);
        let bottom = Arrival::new(DVec3::ZERO, d, -UP);
        assert!(top.front && !bottom.front);
        assert_eq!((top.normal, bottom.normal), (UP, UP));
        assert_eq!((top.eta(1.5), bottom.eta(1.5)), (1.0 / 1.5, 1.5));
        assert_eq!(top.reflected(), DVec3::new(0.6, 0.8, 0.0));
    }

    #[test]
    fn dielectric_splits_reflects_past_the_critical_angle_and_without_refraction() {
        let th: f64 = 0.5;
        let d = DVec3::new(th.sin(), -th.cos(), 0.0);
        let into_glass = Arrival::new(DVec3::ZERO, d, UP);
        let Dielectric::Split { fresnel, refracted } = into_glass.dielectric(1.5, true) else {
            panic!("air to glass must refract");
        };
        assert_eq!(fresnel, fresnel_dielectric(th.cos(), 1.0 / 1.5));
        assert_eq!(Some(refracted), refract(d, UP, 1.0 / 1.5));
        assert_eq!(into_glass.dielectric(1.5, false), Dielectric::Reflected);
        // Leaving glass past the critical angle (the ray hits the back of the surface).
        let th = (1.0f64 / 1.5).asin() + 0.01;
        let out_of_glass = Arrival::new(DVec3::ZERO, DVec3::new(th.sin(), -th.cos(), 0.0), -UP);
        assert_eq!(out_of_glass.dielectric(1.5, true), Dielectric::Reflected);
    }

    #[test]
    fn spawned_rays_start_off_the_surface_on_their_own_side() {
        let p = DVec3::new(1e5, 0.0, 0.0);
        let at = Arrival::new(p, DVec3::new(0.0, -1.0, 0.0), UP);
        let eps = offset_scale(p);
        assert_eq!(eps, 1e-9 * (1.0 + 1e5));
        assert_eq!(at.spawn(UP).origin, p + UP * eps);
        assert_eq!(at.spawn(-UP).origin, p - UP * eps);
        // Along the surface counts as leaving on the normal's side.
        assert_eq!(at.spawn(DVec3::X).origin, p + UP * eps);
        assert_eq!(at.spawn(DVec3::X).direction, DVec3::X);
    }
}
