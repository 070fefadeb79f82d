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
use crate::lrt::intensity_towards;
use crate::scatter::offset_scale;
use crate::trace::{occluded, TraceScratch};
use crate::view::SceneView;
use glam::DVec3;

/// Irradiance at `p` on the side of unit normal `facing` (turned towards the viewer) of
/// patch `patch`, from every light that sees `p` unoccluded: `I(w) cos(theta) / r^2`.
pub fn irradiance(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    p: DVec3,
    facing: DVec3,
    patch: u32,
) -> Result<Rgb, BlockError> {
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
            let cos = facing.dot(w);
            if !(cos > 0.0) {
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
