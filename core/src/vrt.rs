//! Viewing ray tracing (paper §3.4): rays from the eye through each pixel.
//!
//! At a diffuse hit the irradiance is interpolated from the hit element's vertices (plus,
//! when the plan computes direct light here, what the lights give through one shadow ray
//! each, [`crate::direct`]) and radiance is `rho_d / pi * E + rho_d * ambient` (the
//! ambient term only when the plan keeps it), plus `emit` on the front of an area light.
//! Mirror and dielectric parts recurse with Fresnel weights to the plan's VRT
//! depth. Each pixel is seeded from (scene seed, pixel), so the image does not depend on
//! which node traced which subscreen.

use crate::blocks::BlockError;
use crate::camera::CameraRig;
use crate::color::Rgb;
use crate::direct;
use crate::geometry::{triangle_normal, Ray};
use crate::rng::{hammersley, Rng};
use crate::scatter::{arrive, offset_scale, Dielectric};
use crate::subdivision::locate;
use crate::trace::{cast, TraceScratch, NO_PATCH};
use crate::view::SceneView;
use std::f64::consts::PI;

/// A rectangle of pixels: the paper's subscreen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Subscreen {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels.
    pub w: u32,
    /// Height in pixels.
    pub h: u32,
}

impl Subscreen {
    /// Number of pixels.
    pub fn pixels(&self) -> u64 {
        self.w as u64 * self.h as u64
    }
}

/// Linear radiance of pixel (x, y): the mean of its viewing rays.
pub fn shade_pixel(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    rig: &CameraRig,
    x: u32,
    y: u32,
) -> Result<Rgb, BlockError> {
    // Only copies out of the header: a clone of the shared `Arc` per pixel or ray would
    // bounce its reference count between the cores of every node thread.
    let (n, seed) = (view.header.plan.pixel_samples.max(1), view.header.settings.seed);
    let (sx, sy) = if n > 1 {
        let mut rng = Rng::from_words(&[seed, 0x565254, x as u64, y as u64]);
        (rng.next_f64(), rng.next_f64())
    } else {
        (0.0, 0.0)
    };
    let mut sum = Rgb::BLACK;
    for i in 0..n {
        let (u, v) = if n > 1 { hammersley(i, n, sx, sy) } else { (0.5, 0.5) };
        let ray = rig.ray(x as f64 + u, y as f64 + v);
        sum = sum.add(radiance(view, scratch, &ray, 0, NO_PATCH)?);
    }
    Ok(sum.scale(1.0 / n as f64))
}

/// Radiance arriving along `ray`.
fn radiance(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    ray: &Ray,
    depth: u32,
    exclude: u32,
) -> Result<Rgb, BlockError> {
    view.counters.view_rays += 1;
    let tmin = if exclude == NO_PATCH { 0.0 } else { offset_scale(ray.origin) };
    let Some(hit) = cast(view, scratch, ray, tmin, f64::INFINITY, exclude, false)? else {
        return Ok(view.header.settings.background);
    };
    let prec = view.patch(hit.patch)?;
    let Some(m) = Surface::of(view, prec.material) else {
        return Ok(Rgb::BLACK);
    };
    let normal = triangle_normal(&prec.v);
    if m.one_sided && ray.direction.dot(normal) > 0.0 {
        // The back of a one-sided patch takes no light and reflects none.
        return Ok(Rgb::BLACK);
    }
    let (at, albedo) = arrive(view, &prec, ray.at(hit.t), ray.direction, normal, Some(hit.bary))?;
    // A texture multiplies the diffuse reflectance.
    let diffuse = albedo.map_or(m.diffuse, |a| m.diffuse.mul(a));
    let mut l = Rgb::BLACK;
    if at.front && !m.emit.is_black() {
        // An area light's front: its radiance, plus what it reflects.
        l = m.emit;
    }
    if !m.diffuse.is_black() {
        view.counters.shades += 1;
        let (local, w) = locate(prec.subdivisions, hit.bary);
        // The element of the face the viewing ray arrived on.
        let id = prec.element_on_face(local, ray.direction);
        let rec = view.element(id)?;
        // Refinement may have split it: the leaf under the hit holds the light.
        let (_, e, w) = view.leaf_element(id, rec, w)?;
        let mut irr = Rgb::BLACK;
        for k in 0..3 {
            irr = irr.add(view.vertex_energy(e.vertices[k])?.scale(w[k]));
        }
        if m.direct_vrt {
            irr = irr.add(direct::irradiance(view, scratch, &at, hit.patch)?);
        }
        l = l.add(diffuse.mul(irr).scale(1.0 / PI));
        if let Some(ambient) = m.ambient {
            l = l.add(diffuse.mul(ambient));
        }
    }
    if depth >= m.vrt_depth || (!m.is_specular()) {
        return Ok(l);
    }
    if m.is_mirror() {
        let r = radiance(view, scratch, &at.spawn(at.reflected()), depth + 1, hit.patch)?;
        l = l.add(m.mirror.mul(r));
    }
    if m.is_transmissive() {
        let split = at.dielectric(m.ior, m.refraction);
        let reflected = radiance(view, scratch, &at.spawn(at.reflected()), depth + 1, hit.patch)?;
        match split {
            Dielectric::Split { fresnel, refracted } => {
                let through = radiance(view, scratch, &at.spawn(refracted), depth + 1, hit.patch)?;
                l = l.add(m.transmit.mul(reflected.scale(fresnel).add(through.scale(1.0 - fresnel))));
            }
            Dielectric::Reflected => l = l.add(m.transmit.mul(reflected)),
        }
    }
    Ok(l)
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
