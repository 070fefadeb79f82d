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

use crate::blocks::{BlockError, PatchRecord, NO_TEXTURE};
use crate::color::Rgb;
use crate::geometry::Ray;
use crate::math::Normalized;
use crate::view::SceneView;
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

/// The shading normal at barycentric weights `bary` of a patch whose corners have unit
/// normals `n`: their weighted sum, normalised. `None` where it has no direction (three
/// normals that cancel), which shades flat.
pub fn interpolate_normal(n: &[DVec3; 3], bary: [f64; 3]) -> Option<DVec3> {
    let s = n[0] * bary[0] + n[1] * bary[1] + n[2] * bary[2];
    let len = s.length();
    (len > 0.0 && len.is_finite()).then(|| s / len)
}

/// The arrival of direction `d` at point `p` of patch `patch` (unit geometric normal
/// `normal`, barycentric weights `bary`, worked out from `p` when not given), shaded with
/// the patch's normals when it has them, and the linear albedo of the patch's texture at
/// the point (white, [`Rgb::WHITE`], where the patch has no texture: multiplying by it
/// changes no bit); both read through the view's cache. A flat, untextured patch reads
/// nothing more.
///
/// The albedo is a colour, never an `Option`: callers multiplied the diffuse reflectance
/// by `Some` albedo, and the optimiser computed that product for `None` too (it is
/// cheap, and its result was thrown away), on the `None`'s uninitialised payload. Stack
/// garbage there, pointers most often, reads as subnormal doubles, and each such
/// multiply took a microcode assist: 10 to 15% of a node's viewing pass on magg-paper,
/// the same instructions as the embedded core's, which happened to find other garbage.
pub fn arrive(
    view: &mut SceneView,
    patch: &PatchRecord,
    p: DVec3,
    d: DVec3,
    normal: DVec3,
    bary: Option<[f64; 3]>,
) -> Result<(Arrival, Rgb), BlockError> {
    let at = Arrival::new(p, d, normal);
    let Some(rec) = view.shading(patch)? else { return Ok((at, Rgb::WHITE)) };
    let bary = bary.unwrap_or_else(|| barycentric(&patch.v, p));
    let at = at.with_shading(interpolate_normal(&rec.normals, bary));
    if rec.texture == NO_TEXTURE {
        return Ok((at, Rgb::WHITE));
    }
    let uv = rec.uv[0] * bary[0] + rec.uv[1] * bary[1] + rec.uv[2] * bary[2];
    Ok((at, view.texture_albedo(rec.texture, uv)?))
}

/// Barycentric weights of point `p` (in or near the plane of `v`) for the corners of `v`.
pub fn barycentric(v: &[DVec3; 3], p: DVec3) -> [f64; 3] {
    let (e1, e2, q) = (v[1] - v[0], v[2] - v[0], p - v[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (q1, q2) = (q.dot(e1), q.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if !(det > 0.0) {
        return [1.0 / 3.0; 3];
    }
    let b1 = (d22 * q1 - d12 * q2) / det;
    let b2 = (d11 * q2 - d12 * q1) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// A ray's arrival at a surface point: the point, the incoming direction, the geometric
/// normal turned to face the side the ray came from, and the shading normal on that side.
///
/// The shading normal (from a mesh's vertex normals, [`Arrival::with_shading`]) bends
/// the mirror and refraction directions and the cosine of direct light; the geometric
/// one decides the side, the index ratio and where new rays start. A direction made with
/// the shading normal that would leave on the wrong side of the geometric surface (a
/// reflection into it, a refraction back out) is made with the geometric normal instead,
/// so no ray crosses a surface it should not and no energy is made or lost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arrival {
    /// The surface point.
    pub p: DVec3,
    /// The incoming unit direction.
    pub d: DVec3,
    /// The unit normal on the incident side (`d . normal <= 0`).
    pub normal: DVec3,
    /// The unit shading normal on the incident side (`d . shading < 0`); the geometric
    /// `normal` for a flat patch.
    pub shading: DVec3,
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
        let normal = if front { normal } else { -normal };
        Arrival { p, d, normal, shading: normal, front }
    }

    /// The arrival shaded with unit normal `shading` (given on the patch's front side, as
    /// stored), or flat for `None`. A shading normal the ray does not arrive against (it
    /// comes from behind the shading normal's side) is not used: the arrival stays flat.
    pub fn with_shading(self, shading: Option<DVec3>) -> Self {
        let Some(s) = shading else { return self };
        let s = if self.front { s } else { -s };
        if self.d.dot(s) < 0.0 {
            Arrival { shading: s, ..self }
        } else {
            self
        }
    }

    /// True when the arrival is shaded with its geometric normal.
    fn is_flat(&self) -> bool {
        self.shading == self.normal
    }

    /// Index ratio `n_i / n_t` at a dielectric of index `ior` in air, by the side hit.
    pub fn eta(&self, ior: f64) -> f64 {
        if self.front {
            1.0 / ior
        } else {
            ior
        }
    }

    /// The mirror direction (about the shading normal, unless that sends it into the
    /// surface).
    pub fn reflected(&self) -> DVec3 {
        if !self.is_flat() {
            let r = reflect(self.d, self.shading);
            if r.dot(self.normal) > 0.0 {
                return r;
            }
        }
        reflect(self.d, self.normal)
    }

    /// The split at a dielectric of index `ior`; `refraction` false (the effects plan
    /// leaves refraction out) reflects everything.
    pub fn dielectric(&self, ior: f64, refraction: bool) -> Dielectric {
        if !self.is_flat() {
            let split = split_about(self.d, self.shading, self.eta(ior), refraction);
            match split {
                // Refracted through the geometric surface, as it must be; or all reflected
                // (total internal reflection about the shading normal, or no refraction),
                // along [`Arrival::reflected`].
                Dielectric::Split { refracted, .. } if refracted.dot(self.normal) < 0.0 => return split,
                Dielectric::Reflected => return split,
                Dielectric::Split { .. } => {}
            }
        }
        split_about(self.d, self.normal, self.eta(ior), refraction)
    }

    /// A new ray leaving the point along `dir`, its origin pushed off the surface to the
    /// side `dir` goes to, so that it does not hit the surface it leaves.
    pub fn spawn(&self, dir: DVec3) -> Ray {
        let side = if dir.dot(self.normal) >= 0.0 { self.normal } else { -self.normal };
        Ray::new(self.p + side * offset_scale(self.p), dir)
    }
}

/// The Fresnel split of unit `d` at a dielectric with unit normal `n` facing the incident
/// side and index ratio `eta`.
fn split_about(d: DVec3, n: DVec3, eta: f64, refraction: bool) -> Dielectric {
    let fresnel = fresnel_dielectric(-d.dot(n), eta);
    let refracted = if refraction { refract(d, n, eta) } else { None };
    match refracted {
        Some(refracted) if fresnel < 1.0 => Dielectric::Split { fresnel, refracted },
        _ => Dielectric::Reflected,
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

    #[test]
    fn shading_normals_bend_reflection_and_refraction_but_never_through_the_surface() {
        let tilt = DVec3::new(0.3, 1.0, 0.0).normalize();
        let d = DVec3::new(0.0, -1.0, 0.0);
        let at = Arrival::new(DVec3::ZERO, d, UP).with_shading(Some(tilt));
        assert_eq!(at.shading, tilt);
        assert_eq!(at.reflected(), reflect(d, tilt));
        let Dielectric::Split { fresnel, refracted } = at.dielectric(1.5, true) else { panic!("refracts") };
        assert_eq!(fresnel, fresnel_dielectric(-d.dot(tilt), 1.0 / 1.5));
        assert_eq!(Some(refracted), refract(d, tilt, 1.0 / 1.5));
        // From the back, the stored (front) normal is turned to the incident side.
        let below = Arrival::new(DVec3::ZERO, -d, UP).with_shading(Some(tilt));
        assert_eq!((below.normal, below.shading), (-UP, -tilt));
        // A grazing ray whose mirror image about the shading normal would dive into the
        // surface is reflected about the geometric normal instead.
        let graze = DVec3::new(0.264, -0.1, 0.0).normalize();
        let at = Arrival::new(DVec3::ZERO, graze, UP).with_shading(Some(tilt));
        assert!(reflect(graze, tilt).dot(UP) <= 0.0);
        assert_eq!(at.reflected(), reflect(graze, UP));
        // A shading normal the ray does not arrive against is not used.
        let at = Arrival::new(DVec3::ZERO, DVec3::new(0.99, -0.141, 0.0).normalize(), UP).with_shading(Some(tilt));
        assert_eq!(at.shading, at.normal);
    }

    #[test]
    fn interpolated_normals_and_barycentrics() {
        let n = [DVec3::X, DVec3::Y, DVec3::Z];
        let s = interpolate_normal(&n, [0.5, 0.5, 0.0]).unwrap();
        assert!((s - DVec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-15);
        assert_eq!(interpolate_normal(&[DVec3::X, -DVec3::X, DVec3::X], [0.5, 0.5, 0.0]), None);
        let v = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let b = barycentric(&v, DVec3::new(0.25, 0.5, 0.0));
        assert!((b[0] - 0.25).abs() < 1e-15 && (b[1] - 0.25).abs() < 1e-15 && (b[2] - 0.5).abs() < 1e-15);
    }
}
