//! Area lights in LRT: the pair (emitting element, receiving element).
//!
//! An emitting element radiates `emit` (W m^-2 sr^-1) from the front of its patch, the
//! same in every direction. Its pair with a receiving element casts `n = light_rays`
//! rays, stratified over both triangles: `a = floor(sqrt(n))` points spread over the
//! emitter (stratified, each standing for `A_e / a` of its area), and from each point
//! about `n / a` rays stratified over the receiver's solid angle, as a point light's
//! rays are. Seen from one point the emitter is a point light of intensity
//! `emit * A_e / a * cos_e` towards `w`, so a ray carries
//! `emit * A_e / a * cos_e(w) * Omega / n_i`: the flux that reaches the receiver
//! (`emit * cos_e * cos_r / d^2 * A_e * A_r` summed over the pair) without the `1 / d^2`
//! of sampling points on both, which is unbounded where an emitter meets a wall. A
//! pair's deposits thus stay below `2 pi * emit * A_e` (twice the emitter's power).
//!
//! Occluded rays deposit nothing (the occluder's own pair accounts for its light); the
//! rays that reach the receiver deposit there unless the plan computes direct light at
//! VRT ([`crate::direct::area_irradiance`] then samples the emitters from each diffuse
//! hit), and scatter on like point-light rays: what they carry via mirrors, glass and
//! diffuse bounces is LRT's either way, so nothing is counted twice. As for a point
//! light, a pair traced only for the bounce its rays start sends fewer light rays with
//! several bounce rays each ([`super::rays_for`]), and a pair that could deposit nothing
//! (direct light at VRT, no diffuse bounce, a receiver that neither mirrors nor
//! transmits) is not traced. Pairs that cannot exchange light are skipped before any
//! ray: a receiver entirely on or behind the emitter's plane, or a one-sided receiver
//! whose front faces away from the whole emitter.

use super::landing::{land_primaries, Target};
use super::result::{LrtTally, RawDeposit};
use super::waves::PairTrees;
use crate::blocks::{BlockError, NO_BACK};
use crate::geometry::{solid_angle, triangle_normal, Ray, SphericalTriangle};
use crate::header::Emitter;
use crate::rng::{hammersley, Rng};
use crate::scatter::offset_scale;
use crate::subdivision::element_triangle;
use crate::trace::{Bundled, TraceScratch};
use crate::view::SceneView;
use glam::DVec3;
use std::f64::consts::PI;

/// The point of triangle `t` at unit-square coordinates `(u0, u1)`, uniform over its
/// area (the square-root warp), stratified when the inputs are.
fn point_on(t: &[DVec3; 3], u0: f64, u1: f64) -> DVec3 {
    let s = u0.sqrt();
    t[0] * (1.0 - s) + t[1] * (s * (1.0 - u1)) + t[2] * (s * u1)
}

/// Emitter points of a pair of `n` rays, and the rays cast from point `i` of them.
fn split(n: u32) -> (u32, impl Fn(u32) -> u32) {
    let a = ((n as f64).sqrt().floor() as u32).clamp(1, n.max(1));
    (a, move |i| n / a + u32::from(i < n % a))
}

/// Traces the pair of `emitter` (light index `light`) and `element` with `trees`
/// (cleared): appends its raw deposits to `out` and returns its tally.
pub(super) fn trace_emitter_pair(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    trees: &mut PairTrees,
    light: u32,
    emitter: Emitter,
    element: u32,
    out: &mut Vec<RawDeposit>,
) -> Result<LrtTally, BlockError> {
    let header = view.header.clone();
    let plan = &header.plan;
    let mut tally = LrtTally::default();
    if !plan.lrt || emitter.element == element || emitter.power.is_black() {
        return Ok(tally);
    }
    let own = view.element(element)?;
    if own.child != 0 {
        // Refinement split it: its four children have pairs of their own.
        return Ok(tally);
    }
    let material = header.materials.get(view.patch(own.patch)?.material as usize);
    if plan.skips_diffuse_pairs() && material.is_none_or(|m| !m.is_specular()) {
        // Its direct light is computed at VRT and nothing bounces on from it.
        return Ok(tally);
    }
    let src = view.element(emitter.element)?;
    let sp = view.patch(src.patch)?;
    let etri = element_triangle(&sp.v, sp.subdivisions, src.local);
    let en = triangle_normal(&sp.v);
    let (erec, prec, tri) = view.element_geometry(element, own)?;
    let normal = triangle_normal(&prec.v);
    if tri.iter().all(|v| en.dot(*v - etri[0]) <= 0.0) {
        // On or behind the emitter's plane: its front sends nothing there.
        return Ok(tally);
    }
    if material.is_some_and(|m| m.one_sided) && etri.iter().all(|v| normal.dot(*v - tri[0]) <= 0.0) {
        // Every ray would arrive on the back of a one-sided receiver.
        return Ok(tally);
    }
    if prec.back_element != NO_BACK {
        // An emitter wholly on one side of the receiver's plane sends every ray to one
        // face: the other face's element has nothing to trace.
        let side = |v: &DVec3| normal.dot(*v - tri[0]);
        let behind = etri.iter().all(|v| side(v) <= 0.0);
        if (behind || etri.iter().all(|v| side(v) >= 0.0)) && behind != erec.is_back(prec.subdivisions) {
            return Ok(tally);
        }
    }
    // emit * A_e, per channel.
    let radiance_area = emitter.power.scale(1.0 / PI);
    let (n, fan) = super::rays_for(view, plan, material, own)?;
    let (points, rays_of) = split(n);
    let mut rng = Rng::from_words(&[header.settings.seed, 0x4c5254, light as u64, element as u64]);
    let (sx, sy) = (rng.next_f64(), rng.next_f64());
    let (bx, by) = (rng.next_f64(), rng.next_f64());
    // Index among the pair's n rays of the first ray from the current point (for the
    // rays' bounce samples).
    let mut first_ray = 0u32;
    // The pair's light rays, each with an occlusion query up to (just short of) the
    // element; the rays from one point on the emitter walk the BVH in packets.
    trees.shots.clear();
    trees.bundle.clear();

    for i in 0..points {
        let (u0, u1) = hammersley(i, points, sx, sy);
        let p = point_on(&etri, u0, u1);
        let omega = solid_angle(p, &tri);
        let (tx, ty) = (rng.next_f64(), rng.next_f64());
        let m = rays_of(i);
        first_ray += m;
        let first_ray = first_ray - m;
        if !(omega > 0.0) {
            continue;
        }
        let per_ray = radiance_area.scale(omega / (points as f64 * m as f64));
        let eps0 = offset_scale(p);
        // This point's rays all go towards the same element.
        let Some(seen) = SphericalTriangle::new(p, &tri) else {
            continue;
        };
        for j in 0..m {
            let (w0, w1) = hammersley(j, m, tx, ty);
            let Some(w) = seen.sample(w0, w1) else {
                continue;
            };
            let cos_e = en.dot(w);
            if !(cos_e > 0.0) {
                continue;
            }
            if !prec.receives_on(&erec, w) {
                // It arrives on the other face of the receiver, whose pair traces it.
                continue;
            }
            let flux = per_ray.scale(cos_e);
            view.counters.light_rays += 1;
            let t_plane = normal.dot(prec.v[0] - p) / normal.dot(w);
            if !(t_plane > 0.0) || !t_plane.is_finite() {
                continue;
            }
            trees.shots.push((first_ray + j, flux, t_plane));
            let ray = Ray::new(p, w);
            trees.bundle.push(Bundled { ray, tmin: eps0, tmax: t_plane * (1.0 - 1e-9), exclude: erec.patch });
        }
    }
    let target = Target { light, element, erec, prec, normal, material, fan, offset: (bx, by) };
    land_primaries(view, scratch, trees, &mut tally, &target, out)?;
    trees.trace(view, scratch, &mut tally, out)?;
    Ok(tally)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_casts_exactly_n_rays_over_sqrt_n_points() {
        for n in [1, 2, 3, 16, 17, 64, 100, 1000] {
            let (a, rays) = split(n);
            assert_eq!(a, (n as f64).sqrt().floor() as u32);
            assert_eq!((0..a).map(&rays).sum::<u32>(), n, "n = {n}");
        }
    }

    #[test]
    fn points_fall_inside_the_triangle_and_cover_it_evenly() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let n = 64;
        let mut mean = DVec3::ZERO;
        for i in 0..n {
            let (u0, u1) = hammersley(i, n, 0.25, 0.5);
            let p = point_on(&t, u0, u1);
            assert!(p.x >= 0.0 && p.y >= 0.0 && p.x + p.y <= 1.0 + 1e-12 && p.z == 0.0);
            mean += p / n as f64;
        }
        // The centroid (1/3, 1/3) within stratification error.
        assert!((mean - DVec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0)).length() < 0.02, "{mean}");
    }
}
