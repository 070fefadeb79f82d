//! Direct light at VRT: the irradiance a surface point receives straight from the point
//! and spot lights, with one shadow ray per light.
//!
//! The effects plan turns this on (`direct_vrt`) where it pays: shadows then come out as
//! sharp as the pixels instead of one element wide, and LRT's elements carry only what
//! light rays alone can find (light via mirrors and glass, diffuse bounces). Only the side
//! the viewing ray arrived on receives light, so nothing leaks through a thin wall. No
//! random choice is made: the result depends only on the point.

use crate::blocks::BlockError;
use crate::color::Rgb;
use crate::geometry::Ray;
use crate::lights::intensity_towards;
use crate::scatter::{offset_scale, Arrival};
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
