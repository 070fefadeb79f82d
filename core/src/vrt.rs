//! Viewing ray tracing (paper §3.4): rays from the eye through each pixel.
//!
//! At a diffuse hit the irradiance is interpolated from the hit element's vertices (plus,
//! when the plan computes direct light here, what the lights give through one shadow ray
//! each and the area lights through shadow rays to points sampled on them,
//! [`crate::direct`]) and radiance is `rho_d / pi * E + rho_d * ambient` (the
//! ambient term only when the plan keeps it), plus `emit` on the front of an area light.
//! Mirror and dielectric parts recurse with Fresnel weights to the plan's VRT
//! depth. Each pixel is seeded from (scene seed, pixel), so the image does not depend on
//! which node traced which subscreen.

use crate::blocks::{BlockError, ElementRecord};
use crate::camera::CameraRig;
use crate::color::Rgb;
use crate::direct::PixelStrata;
use crate::geometry::{cosine_hemisphere, triangle_normal, Ray};
use crate::rng::{arrival_rotation, hammersley, Rng};
use crate::scatter::{arrive, offset_scale, Arrival, Dielectric};
use crate::subdivision::locate;
use crate::subscreen::Subscreen;
use crate::trace::{cast, Bundled, Hit, TraceScratch, NO_PATCH};
use crate::view::SceneView;
use std::f64::consts::PI;

mod waves;

pub use waves::shade_pixels;

/// Linear radiance of pixel (x, y): the mean of its viewing rays ([`shade_pixels`] of
/// one pixel).
pub fn shade_pixel(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    rig: &CameraRig,
    x: u32,
    y: u32,
) -> Result<Rgb, BlockError> {
    let mut out = Vec::with_capacity(1);
    shade_pixels(view, scratch, rig, Subscreen { x, y, w: 1, h: 1 }, &mut out)?;
    Ok(out[0])
}

/// The viewing rays of pixel (x, y): `n` stratified samples, seeded from (scene seed,
/// pixel), in sample order, each with its place among the pixel's shadow rays to the
/// area lights where the plan sends any ([`PixelStrata`]).
fn pixel_rays<'a>(
    seed: u64,
    n: u32,
    area: bool,
    rig: &'a CameraRig,
    x: u32,
    y: u32,
) -> impl Iterator<Item = (Ray, Option<PixelStrata>)> + 'a {
    let (sx, sy) = if n > 1 {
        let mut rng = Rng::from_words(&[seed, 0x565254, x as u64, y as u64]);
        (rng.next_f64(), rng.next_f64())
    } else {
        (0.0, 0.0)
    };
    let rotation = area.then(|| PixelStrata::rotation(seed, x, y));
    (0..n).map(move |i| {
        let (u, v) = if n > 1 { hammersley(i, n, sx, sy) } else { (0.5, 0.5) };
        let strata = rotation.map(|rotation| PixelStrata { index: i, count: n, rotation });
        (rig.ray(x as f64 + u, y as f64 + v), strata)
    })
}

/// What a viewing ray found where it arrived: the radiance leaving the hit towards it,
/// without what the rays it spawned bring ([`Join`] adds that).
struct Shaded {
    local: Rgb,
    join: Join,
    /// The patch hit (the spawned rays start on it).
    patch: u32,
    /// How many rays it spawned.
    spawned: usize,
}

/// How the radiance of the rays spawned at a hit joins the hit's own: none spawned, or
/// a mirror's reflected ray (`mirror`, first) and a dielectric's reflected and refracted
/// rays (`transmit`, then; when both were spawned, the Fresnel reflectance and the
/// refracted ray's radiance factor `eta^2`, `None` for total internal reflection).
///
/// Radiance is not flux: light refracted into a denser medium is squeezed into a smaller
/// solid angle, so what comes back along a viewing ray that crossed from index `n_i`
/// into `n_t` is the far side's radiance times `(1 - F) (n_i / n_t)^2`. Through a closed
/// body the factors of the way in and out cancel; through an open surface (water over a
/// floor) they do not: without it the floor under water looked `n^2` times too bright
/// (light rays carry flux, which refraction conserves, and need no such factor).
#[derive(Clone, Copy)]
enum Join {
    None,
    Specular { mirror: Option<Rgb>, transmit: Option<(Rgb, Option<(f64, f64)>)> },
}

impl Join {
    /// The radiance along the ray: `local` plus the spawned rays' radiance `spawned`
    /// (in the order they were spawned), weighted.
    fn radiance(self, local: Rgb, spawned: &[Rgb]) -> Rgb {
        let Join::Specular { mirror, transmit } = self else { return local };
        let mut l = local;
        let mut rest = spawned.iter().copied();
        let mut next = || rest.next().unwrap_or(Rgb::BLACK);
        if let Some(m) = mirror {
            l = l.add(m.mul(next()));
        }
        if let Some((t, split)) = transmit {
            let reflected = next();
            l = match split {
                Some((fresnel, eta2)) => {
                    l.add(t.mul(reflected.scale(fresnel).add(next().scale((1.0 - fresnel) * eta2))))
                }
                None => l.add(t.mul(reflected)),
            };
        }
        l
    }
}

/// A viewing ray arrived at a surface that takes or passes light on: what its shading
/// stages ([`interpolated`], [`crate::direct::all_irradiance`], [`Arrived::finish`]) need.
struct Arrived {
    at: Arrival,
    patch: u32,
    m: Surface,
    /// The element of the patch's lattice hit, on the face arrived on, and the hit's
    /// local coordinates in it.
    element: u32,
    w: [f64; 3],
    /// The diffuse reflectance there (textured or not).
    diffuse: Rgb,
    /// The surface reflects diffusely (its elements' light shows), and takes direct
    /// light through shadow rays.
    shaded: bool,
    direct: bool,
    depth: u32,
    /// A primary ray's place among its pixel's shadow rays to the area lights.
    strata: Option<PixelStrata>,
}

impl Arrived {
    /// Shades where this ray arrived: reflects `irr` (the irradiance there, when the
    /// surface is diffuse), adds what the surface emits and the ambient term, and
    /// puts the specular rays it spawns in `spawned` (mirror reflection, then a
    /// dielectric's reflection and refraction; [`Shaded::spawned`] says how many).
    #[inline]
    fn finish(&self, irr: Rgb, spawned: &mut [Ray; 3]) -> Shaded {
        let (m, at) = (&self.m, &self.at);
        let mut l = Rgb::BLACK;
        if at.front && !m.emit.is_black() {
            // An area light's front: its radiance, plus what it reflects.
            l = m.emit;
        }
        if !m.diffuse.is_black() {
            l = l.add(self.diffuse.mul(irr).scale(1.0 / PI));
            if let Some(ambient) = m.ambient {
                l = l.add(self.diffuse.mul(ambient));
            }
        }
        if self.depth >= m.vrt_depth || (!m.is_specular()) {
            return Shaded { local: l, join: Join::None, patch: self.patch, spawned: 0 };
        }
        let mut n = 0;
        let mut spawn = |ray: Ray| {
            spawned[n] = ray;
            n += 1;
        };
        let mut mirror = None;
        if m.is_mirror() {
            spawn(at.spawn(at.reflected()));
            mirror = Some(m.mirror);
        }
        let mut transmit = None;
        if m.is_transmissive() {
            spawn(at.spawn(at.reflected()));
            transmit = Some(match at.dielectric(m.ior, m.refraction) {
                Dielectric::Split { fresnel, refracted } => {
                    spawn(at.spawn(refracted));
                    let eta = at.eta(m.ior);
                    (m.transmit, Some((fresnel, eta * eta)))
                }
                Dielectric::Reflected => (m.transmit, None),
            });
        }
        Shaded { local: l, join: Join::Specular { mirror, transmit }, patch: self.patch, spawned: n }
    }
}

/// Traces viewing ray `ray` (of recursion depth `depth`, leaving patch `exclude` or the
/// eye) to the surface it arrives at; `Err` holds the whole radiance along a ray that
/// ends there (the background, or a surface that takes no light).
#[inline]
fn arrive_at(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    ray: &Ray,
    depth: u32,
    exclude: u32,
) -> Result<Result<Arrived, Rgb>, BlockError> {
    let q = query(ray, exclude);
    let hit = cast(view, scratch, ray, q.tmin, q.tmax, exclude, false)?;
    arrival(view, ray, hit, depth, None)
}

/// The query [`arrive_at`] casts for viewing ray `ray` leaving patch `exclude` (or the
/// eye): from just off the patch, or from the eye itself, to any distance.
#[inline]
fn query(ray: &Ray, exclude: u32) -> Bundled {
    let tmin = if exclude == NO_PATCH { 0.0 } else { offset_scale(ray.origin) };
    Bundled { ray: *ray, tmin, tmax: f64::INFINITY, exclude }
}

/// [`arrive_at`] once the ray's hit is known (cast for it alone or with others); a
/// primary ray says its place among its pixel's samples (`strata`).
#[inline]
fn arrival(
    view: &mut SceneView,
    ray: &Ray,
    hit: Option<Hit>,
    depth: u32,
    strata: Option<PixelStrata>,
) -> Result<Result<Arrived, Rgb>, BlockError> {
    view.counters.view_rays += 1;
    let Some(hit) = hit else {
        return Ok(Err(view.header.settings.background));
    };
    let prec = view.patch(hit.patch)?;
    let Some(m) = Surface::of(view, prec.material) else {
        return Ok(Err(Rgb::BLACK));
    };
    let normal = triangle_normal(&prec.v);
    if m.one_sided && ray.direction.dot(normal) > 0.0 {
        // The back of a one-sided patch takes no light and reflects none.
        return Ok(Err(Rgb::BLACK));
    }
    let (at, albedo) = arrive(view, &prec, ray.at(hit.t), ray.direction, normal, Some(hit.bary))?;
    // A texture multiplies the diffuse reflectance.
    let diffuse = m.diffuse.mul(albedo);
    let (shaded, direct) = (!m.diffuse.is_black(), m.direct_vrt && !m.diffuse.is_black());
    // The element hit matters only where the elements' light shows.
    let (element, w) = match shaded {
        true => {
            let (local, w) = locate(prec.subdivisions, hit.bary);
            (prec.element_on_face(local, ray.direction), w)
        }
        false => (0, [0.0; 3]),
    };
    Ok(Ok(Arrived { at, patch: hit.patch, m, element, w, diffuse, shaded, direct, depth, strata }))
}

/// The irradiance the elements hold where `a` arrived on a diffuse surface: the hit
/// element's (its leaf's, when refinement split it) vertex energies, interpolated; or,
/// where a vertex of that element is marked for it and the plan gathers, the bounced
/// light gathered there ([`gathered`]).
#[inline]
fn interpolated(view: &mut SceneView, scratch: &mut TraceScratch, a: &Arrived) -> Result<Rgb, BlockError> {
    let (id, w) = (a.element, a.w);
    let rec = view.element(id)?;
    // Refinement may have split it: the leaf under the hit holds the light.
    let (_, e, w) = view.leaf_element(id, rec, w)?;
    lit(view, scratch, a, &e, w)
}

/// [`interpolated`] once the leaf element under the hit is known: its record `e` and the
/// hit's coordinates `w` in it.
#[inline]
fn lit(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    a: &Arrived,
    e: &ElementRecord,
    w: [f64; 3],
) -> Result<Rgb, BlockError> {
    view.counters.shades += 1;
    let mut irr = Rgb::BLACK;
    let mut gather = false;
    for k in 0..3 {
        let (v, marked) = view.vertex_light(e.vertices[k])?;
        irr = irr.add(v.scale(w[k]));
        gather |= marked;
    }
    let n = view.header.settings.gather_rays;
    if gather && view.header.plan.gathers(n, &view.header.materials) {
        return gathered(view, scratch, &a.at, a.patch, n);
    }
    Ok(irr)
}

/// The bounced light arriving at `at` on patch `patch` (irradiance), gathered with `n`
/// rays: directions over the hemisphere of the side arrived on, cosine-weighted and
/// stratified (Hammersley, rotated by a seed of the point and the incoming direction, so
/// that the result depends on the ray alone, not on the node or the order of tracing).
/// Each ray's hit reflects `rho E`: its diffuse reflectance (textured) times the direct
/// irradiance the lights give it there ([`crate::direct::all_irradiance`], on the side
/// the gather ray arrived on, with one shadow ray to the area lights), which is exactly
/// the light that the elements' one diffuse bounce carries; the mean of `rho E` over
/// cosine-weighted directions is the irradiance. (A gather ray that meets an emitter
/// counts nothing of it: that is direct light, which the hit's own shadow rays count.)
///
/// Used where the elements cannot hold that light: beside elements that received none
/// ([`crate::energy::gather_vertices`]), i.e. along a contact with another surface,
/// where an element partly covered spreads its flux over its whole area and a vertex
/// averages in covered ones.
pub fn gathered(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    at: &Arrival,
    patch: u32,
    n: u32,
) -> Result<Rgb, BlockError> {
    let (sx, sy) = arrival_rotation(view.header.settings.seed, 0x474154, at.p, at.d);
    // One shadow ray to the area lights at each gather ray's hit: the n rays average them.
    let area_samples = view.header.plan.area_samples().min(1);
    let mut sum = Rgb::BLACK;
    for j in 0..n {
        let (u0, u1) = hammersley(j, n, sx, sy);
        let dir = cosine_hemisphere(at.normal, u0, u1);
        let ray = at.spawn(dir);
        view.counters.view_rays += 1;
        let Some(hit) = cast(view, scratch, &ray, offset_scale(ray.origin), f64::INFINITY, patch, false)? else {
            continue;
        };
        let prec = view.patch(hit.patch)?;
        let normal = triangle_normal(&prec.v);
        let Some(m) = view.header.materials.get(prec.material as usize) else { continue };
        if m.refuses(dir, normal) || m.diffuse.is_black() {
            continue;
        }
        let diffuse = m.diffuse;
        let (q, albedo) = arrive(view, &prec, ray.at(hit.t), dir, normal, Some(hit.bary))?;
        let rho = diffuse.mul(albedo);
        sum = sum.add(rho.mul(crate::direct::all_irradiance(view, scratch, &q, hit.patch, area_samples, None)?));
    }
    Ok(sum.scale(1.0 / n.max(1) as f64))
}

/// What shading needs of a hit's material and of the plan, copied out of the header so
/// that the recursion holds no borrow of (or reference count on) it.
struct Surface {
    diffuse: Rgb,
    mirror: Rgb,
    transmit: Rgb,
    ior: f64,
    /// The ambient radiance, when the plan keeps the ambient term.
    ambient: Option<Rgb>,
    vrt_depth: u32,
    refraction: bool,
    /// Direct light is computed here, with shadow rays ([`crate::direct`]).
    direct_vrt: bool,
    /// Only the front takes and reflects light.
    one_sided: bool,
    /// Radiance emitted from the front (area lights).
    emit: Rgb,
}

impl Surface {
    /// Material `id` under the view's plan; `None` for an id the header lacks.
    fn of(view: &SceneView, id: u32) -> Option<Surface> {
        let h = &view.header;
        let m = h.materials.get(id as usize)?;
        Some(Surface {
            diffuse: m.diffuse,
            mirror: m.mirror,
            transmit: m.transmit,
            ior: m.ior,
            ambient: h.plan.ambient.then_some(h.settings.ambient),
            vrt_depth: h.plan.vrt_depth,
            refraction: h.plan.refraction,
            direct_vrt: h.plan.direct_vrt,
            one_sided: m.one_sided,
            emit: m.emit,
        })
    }
    fn is_mirror(&self) -> bool {
        !self.mirror.is_black()
    }
    fn is_transmissive(&self) -> bool {
        !self.transmit.is_black()
    }
    fn is_specular(&self) -> bool {
        self.is_mirror() || self.is_transmissive()
    }
}
