//! Direct light at VRT: the irradiance a surface point receives straight from the point
//! and spot lights, with one shadow ray per light ([`irradiance`]), and from the area
//! lights, with shadow rays to points sampled on the emitters ([`area_irradiance`]).
//!
//! The effects plan turns this on (`direct_vrt`) where it pays: shadows then come out as
//! sharp as the pixels instead of one element wide (an area light's penumbra converges
//! with the pixel samples instead of showing the elements' noise), and LRT's elements
//! carry only what light rays alone can find (light via mirrors and glass, diffuse
//! bounces). Only the side the viewing ray arrived on receives light, so nothing leaks
//! through a thin wall. The point lights' part makes no random choice; the area lights'
//! samples are seeded from the point and the direction the ray arrived along, so the
//! result depends only on the ray (not on the node, the fork or the order of tracing).

use crate::blocks::BlockError;
use crate::color::Rgb;
use crate::geometry::{solid_angle, triangle_normal, Ray, SphericalTriangle};
use crate::lights::intensity_towards;
use crate::rng::{arrival_rng, hammersley, radical_inverse, Rng};
use crate::scatter::{offset_scale, Arrival};
use crate::subdivision::element_triangle;
use crate::trace::{occluded, TraceScratch};
use crate::view::SceneView;

/// Irradiance at the point of arrival `at` on patch `patch`, on the side the viewing ray
/// came from, from every light that sees the point unoccluded: `I(w) cos(theta) / r^2`,
/// the cosine taken with the shading normal. A light behind the geometric surface gives
/// nothing, whatever the shading normal says: no light comes through a surface.
pub fn irradiance(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    at: &Arrival,
    patch: u32,
) -> Result<Rgb, BlockError> {
    let (p, facing, shading) = (at.p, at.normal, at.shading);
    let mut e = Rgb::BLACK;
    let tmin = offset_scale(p);
    for i in 0..view.header.lights.len() {
        // Copies out of the header, so that the shadow ray may borrow the view.
        let (w, dist, intensity) = {
            let l = &view.header.lights[i];
            let to_light = l.position - p;
            let r2 = to_light.length_squared();
            if !(r2 > 0.0) || !r2.is_finite() {
                continue;
            }
            let dist = r2.sqrt();
            let w = to_light / dist;
            let cos = shading.dot(w);
            if !(cos > 0.0) || !(facing.dot(w) > 0.0) {
                continue;
            }
            let i = intensity_towards(l, -w);
            if i.is_black() {
                continue;
            }
            (w, dist, i.scale(cos / r2))
        };
        let ray = Ray::new(p, w);
        view.counters.view_rays += 1;
        if !occluded(view, scratch, &ray, tmin, dist * (1.0 - 1e-9), patch)? {
            e = e.add(intensity);
        }
    }
    Ok(e)
}

/// Where a primary viewing ray's shadow rays to the area lights lie among its pixel's:
/// it is sample `index` of the pixel's `count`, whose shadow rays together are one
/// stratified set (interleaved: each sample's rays still cover every emitter), rotated by
/// the pixel's `rotation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelStrata {
    pub index: u32,
    pub count: u32,
    pub rotation: [f64; 3],
}

impl PixelStrata {
    /// The rotation of pixel (x, y)'s shadow rays to the area lights under scene seed
    /// `seed`.
    pub fn rotation(seed: u64, x: u32, y: u32) -> [f64; 3] {
        rotation3(&mut Rng::from_words(&[seed, 0x415245, x as u64, y as u64]))
    }
}

/// Three numbers of `rng`: the rotation of a set of 3-d stratified samples.
fn rotation3(rng: &mut Rng) -> [f64; 3] {
    [rng.next_f64(), rng.next_f64(), rng.next_f64()]
}

/// [`irradiance`] plus [`area_irradiance`] with `area_samples` shadow rays (placed by
/// `strata` for a primary viewing ray): all the direct light the plan computes at VRT.
pub fn all_irradiance(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    at: &Arrival,
    patch: u32,
    area_samples: u32,
    strata: Option<PixelStrata>,
) -> Result<Rgb, BlockError> {
    let e = irradiance(view, scratch, at, patch)?;
    if area_samples == 0 {
        return Ok(e);
    }
    Ok(e.add(area_irradiance(view, scratch, at, patch, area_samples, strata)?))
}

/// Irradiance at the point of arrival `at` on patch `patch`, on the side the viewing ray
/// came from, from the area lights (the header's emitters, each an element radiating its
/// material's `emit` from the front of its patch), estimated with `n` shadow rays.
///
/// Each sample picks an emitter in proportion to its power (with its first coordinate)
/// and a direction uniformly over the solid angle `Omega` the emitter subtends (the
/// spherical triangle, with the other two), and counts
/// `emit * cos(theta) * Omega / P` where the shadow ray reaches it unoccluded (`P` the
/// emitter's probability). Sampling the solid angle rather than the area keeps every
/// sample bounded near an emitter (no `1 / d^2`): the variance that a path tracer's
/// multiple importance sampling with the BSDF would remove at a diffuse hit. The `n`
/// samples are stratified in three dimensions (`(k + 1/2) / N` and the radical inverses
/// of `k` in bases 2 and 3, each rotated): with `strata`, as its part of its pixel's set
/// of `N = n count` (the pixel's samples together stratify the lamps `count` times more
/// finely); else on their own, rotated by a seed of the scene seed, the point and the
/// incoming direction. (The coordinate that picks the emitter is not reused within it:
/// evenly spaced picks over equal emitters would land at the same place in each.)
pub fn area_irradiance(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    at: &Arrival,
    patch: u32,
    n: u32,
    strata: Option<PixelStrata>,
) -> Result<Rgb, BlockError> {
    let (p, facing, shading) = (at.p, at.normal, at.shading);
    let PixelStrata { index, count, rotation: [sx, sy, sz] } = match strata {
        Some(s) if s.index < s.count && s.count.checked_mul(n).is_some() => s,
        _ => {
            let rotation = rotation3(&mut arrival_rng(view.header.settings.seed, 0x415245, p, at.d));
            PixelStrata { index: 0, count: 1, rotation }
        }
    };
    let all = n * count;
    let tmin = offset_scale(p);
    let mut e = Rgb::BLACK;
    // The emitter seen from the point, kept while consecutive samples pick it (the
    // stratified first coordinate picks each emitter in a run).
    let mut seen: Option<(usize, Option<Seen>)> = None;
    for j in 0..n {
        let i = j * count + index;
        let (u0, u1) = hammersley(i, all, sx, sy);
        let u2 = radical_inverse(3, i) + sz;
        let Some((k, prob)) = view.pick_emitter(u0) else { break };
        if seen.as_ref().is_none_or(|(kept, _)| *kept != k) {
            seen = Some((k, Seen::of(view, k, p)?));
        }
        let Some((_, Some(Seen { tri, en, emit, omega, spherical }))) = &seen else { continue };
        let (tri, en, emit, omega) = (*tri, *en, *emit, *omega);
        let Some(w) = spherical.sample(u1, u2 - u2.floor()) else { continue };
        let cos = shading.dot(w);
        if !(cos > 0.0) || !(facing.dot(w) > 0.0) || !(en.dot(w) < 0.0) {
            continue;
        }
        // Distance to the emitter's plane along w.
        let t = en.dot(tri[0] - p) / en.dot(w);
        if !(t > 0.0) || !t.is_finite() {
            continue;
        }
        let ray = Ray::new(p, w);
        view.counters.view_rays += 1;
        if !occluded(view, scratch, &ray, tmin, t * (1.0 - 1e-9), patch)? {
            e = e.add(emit.scale(cos * omega / prob));
        }
    }
    Ok(e.scale(1.0 / n.max(1) as f64))
}

/// An emitter as a point sees it: its element's triangle, front normal, radiance and
/// the solid angle it subtends there ([`area_irradiance`]'s samples of it).
struct Seen {
    tri: [glam::DVec3; 3],
    en: glam::DVec3,
    emit: Rgb,
    omega: f64,
    spherical: SphericalTriangle,
}

impl Seen {
    /// Emitter `k` (of the header's `emitters`) seen from `p`; `None` where it sends
    /// nothing there: `p` on or behind its plane, or no solid angle.
    fn of(view: &mut SceneView, k: usize, p: glam::DVec3) -> Result<Option<Seen>, BlockError> {
        let rec = view.element(view.header.emitters[k].element)?;
        let sp = view.patch(rec.patch)?;
        let Some(emit) = view.header.materials.get(sp.material as usize).map(|m| m.emit) else { return Ok(None) };
        let tri = element_triangle(&sp.v, sp.subdivisions, rec.local);
        let en = triangle_normal(&sp.v);
        if !(en.dot(p - tri[0]) > 0.0) {
            return Ok(None);
        }
        let omega = solid_angle(p, &tri);
        let Some(spherical) = SphericalTriangle::new(p, &tri) else { return Ok(None) };
        Ok((omega > 0.0).then_some(Seen { tri, en, emit, omega, spherical }))
    }
}
