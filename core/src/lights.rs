//! Light sources as both passes see them: the radiant intensity a point or spot light
//! sends in a direction (LRT's light rays carry it, VRT's direct light divides it by the
//! squared distance), and whether a triangle lies wholly outside a spot's cone (its pair
//! then casts no ray). Area lights are emitting elements: their radiance is their
//! material's `emit` ([`crate::lrt`]'s area pairs, [`crate::header::Emitter`]).

use crate::color::Rgb;
use crate::scene::Light;
use glam::DVec3;

/// Radiant intensity of `light` in unit direction `w`.
pub fn intensity_towards(light: &Light, w: DVec3) -> Rgb {
    match &light.spot {
        None => light.intensity,
        Some(s) => {
            let angle = w.dot(s.direction).clamp(-1.0, 1.0).acos().to_degrees();
            let f = if angle <= s.half_angle_deg {
                1.0
            } else if s.falloff_deg > 0.0 && angle < s.half_angle_deg + s.falloff_deg {
                let x = 1.0 - (angle - s.half_angle_deg) / s.falloff_deg;
                x * x * (3.0 - 2.0 * x)
            } else {
                0.0
            };
            light.intensity.scale(f)
        }
    }
}

/// True when no direction from `light` towards triangle `tri` can carry light (outside
/// a spot cone, with a margin for the triangle's angular size).
pub fn outside_cone(light: &Light, tri: &[DVec3; 3]) -> bool {
    let Some(s) = &light.spot else { return false };
    let c = (tri[0] + tri[1] + tri[2]) / 3.0 - light.position;
    let dist = c.length();
    if dist == 0.0 {
        return false;
    }
    let radius = tri.iter().map(|v| (*v - (tri[0] + tri[1] + tri[2]) / 3.0).length()).fold(0.0, f64::max);
    if radius >= dist {
        return false;
    }
    let spread = (radius / dist).asin().to_degrees();
    let angle = (c / dist).dot(s.direction).clamp(-1.0, 1.0).acos().to_degrees();
    angle - spread > s.half_angle_deg + s.falloff_deg
}
