//! Defaults that converge: the accuracy knobs a scene file leaves unset are chosen from
//! the scene's size, materials and lights, not taken from fixed numbers tuned on one
//! scene (`magg-host info` prints what was chosen and why).
//!
//! - `element_size`: 1/33 of the scene's largest extent (a 2 m room gets 6 cm elements).
//! - `light_rays`: 64 per pair.
//! - `diffuse_bounces`: enough that what is left after the last bounce, `a^(D+1)` for the
//!   scene's mean reflectance `a` (diffuse, mirror and glass parts, by area), is under
//!   2% of the light, at most [`MAX_AUTO_BOUNCES`]: a room lit by its walls is not left
//!   dark.
//! - `refine`: [`AUTO_REFINE`] levels where the elements hold light that changes sharply
//!   (caustics and mirror light, whenever a mirror or glass is lit; direct light
//!   deposited by light rays, `direct = "lrt"`), none where they hold only bounced light
//!   (smooth; direct light from point and area lights is computed at VRT, pixel-sharp). The quality presets build on it (`final` adds a level).
//!
//! A scene that gives an `ambient` term uses the paper's model of light: its transport is
//! its own, so neither bounces nor refinement are chosen for it (every shipped scene
//! that sets one keeps the meaning it had). A knob set in the file (or by `--set`) is
//! kept; the command line's knob flags apply after.

use magg_core::scene::{DirectLight, Scene};
use std::collections::BTreeSet;

/// Most diffuse bounces chosen automatically.
pub const MAX_AUTO_BOUNCES: u32 = 12;

/// Levels of refinement chosen where refinement pays.
pub const AUTO_REFINE: u32 = 2;

/// Elements per largest extent of the scene chosen automatically.
pub const ELEMENTS_PER_EXTENT: f64 = 33.0;

/// Light left after the last automatic bounce, at most.
const BOUNCE_TAIL: f64 = 0.02;

/// The `[render]` keys a scene's TOML sets.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Given(BTreeSet<String>);

impl Given {
    /// The keys of `text`'s `[render]` table (none when the text does not parse: the
    /// parser reports that).
    pub fn of(text: &str) -> Given {
        let Ok(doc) = text.parse::<toml_edit::DocumentMut>() else { return Given::default() };
        let keys = doc.get("render").and_then(|r| r.as_table_like()).map(|t| t.iter().map(|(k, _)| k.to_string()));
        Given(keys.into_iter().flatten().collect())
    }

    /// Every knob given (a scene built in code).
    pub fn all() -> Given {
        Given(["element_size", "light_rays", "diffuse_bounces", "refine"].iter().map(|k| k.to_string()).collect())
    }

    fn has(&self, key: &str) -> bool {
        self.0.contains(key)
    }
}

/// What was chosen, one line per knob, for people.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Chosen {
    pub lines: Vec<String>,
}

/// Fills the knobs of `scene` that `given` lacks; returns what was chosen and why.
pub fn choose(scene: &mut Scene, given: &Given) -> Chosen {
    let mut lines = Vec::new();
    let s = &mut scene.settings;
    if !given.has("element_size") {
        let extent = extent(scene);
        if extent > 0.0 && extent.is_finite() {
            let size = round2(extent / ELEMENTS_PER_EXTENT);
            scene.settings.element_size = size;
            lines.push(format!(
                "element_size = {size}: 1/{ELEMENTS_PER_EXTENT} of the scene's largest extent ({extent:.3})"
            ));
        }
    } else {
        lines.push(format!("element_size = {}: the scene's", s.element_size));
    }
    let s = &mut scene.settings;
    if !given.has("light_rays") {
        lines.push(format!("light_rays = {}: per (light, element) pair", s.light_rays));
    }
    let paper = given.has("ambient") && !s.ambient.is_black();
    if !given.has("diffuse_bounces") {
        if paper {
            lines.push("diffuse_bounces = 0: the scene gives an ambient term (the paper's model)".into());
        } else {
            let a = mean_reflectance(scene);
            let d = bounces_for(a);
            scene.settings.diffuse_bounces = d;
            lines.push(format!(
                "diffuse_bounces = {d}: the mean reflectance {a:.2} leaves {:.1}% of the light after the last",
                100.0 * a.powi(d as i32 + 1)
            ));
        }
    }
    if !given.has("refine") {
        let why = sharp_light(scene);
        let level = match (&why, paper) {
            (_, true) => {
                lines.push("refine = 0: the scene gives an ambient term (the paper's model)".into());
                0
            }
            (Some(why), false) => {
                lines.push(format!("refine = {AUTO_REFINE}: {why}"));
                AUTO_REFINE
            }
            (None, false) => {
                lines.push(
                    "refine = 0: the elements hold only bounced light, which changes smoothly (direct light is \
                     computed at VRT)"
                        .into(),
                );
                0
            }
        };
        scene.settings.refine = level;
    }
    Chosen { lines }
}

/// Bounces that leave at most [`BOUNCE_TAIL`] of the light at mean reflectance `a`.
pub fn bounces_for(a: f64) -> u32 {
    if !(a > 0.0) {
        return 0;
    }
    if a >= 1.0 {
        return MAX_AUTO_BOUNCES;
    }
    let d = (BOUNCE_TAIL.ln() / a.ln()).ceil() - 1.0;
    (d.max(1.0) as u32).min(MAX_AUTO_BOUNCES)
}

/// Why the elements hold light that changes sharply, or `None`.
fn sharp_light(scene: &Scene) -> Option<String> {
    let used = |f: &dyn Fn(&magg_core::scene::Material) -> bool| {
        scene.patches.iter().any(|p| scene.materials.get(p.material as usize).is_some_and(f))
    };
    if used(&|m| m.is_specular()) && scene.settings.lrt_depth > 0 {
        return Some("light via mirrors or glass lands on the elements (caustics' edges)".into());
    }
    if scene.settings.direct == DirectLight::Lrt {
        return Some("direct light is deposited on the elements (`direct = \"lrt\"`: shadows' edges)".into());
    }
    None
}

/// The largest extent of the scene's bounding box.
fn extent(scene: &Scene) -> f64 {
    let mut corners = scene.patches.iter().flat_map(|p| p.vertices);
    let Some(first) = corners.next() else { return 0.0 };
    let (lo, hi) = corners.fold((first, first), |(lo, hi), v| (lo.min(v), hi.max(v)));
    (hi - lo).max_element()
}

/// Area-weighted mean of what the patches' materials pass on (diffuse, mirror and
/// glass parts, mean over channels): the fraction of light that survives a bounce.
fn mean_reflectance(scene: &Scene) -> f64 {
    let (mut sum, mut area) = (0.0, 0.0);
    for p in &scene.patches {
        let Some(m) = scene.materials.get(p.material as usize) else { continue };
        let [a, b, c] = p.vertices;
        let da = 0.5 * (b - a).cross(c - a).length();
        let kept = m.diffuse.add(m.mirror).add(m.transmit);
        sum += da * (kept.0[0] + kept.0[1] + kept.0[2]) / 3.0;
        area += da;
    }
    if area > 0.0 {
        sum / area
    } else {
        0.0
    }
}

/// `x` to two significant digits.
fn round2(x: f64) -> f64 {
    let p = 10f64.powi(1 - x.log10().floor() as i32);
    (x * p).round() / p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounces_leave_two_percent_at_most_and_stop_at_twelve() {
        assert_eq!(bounces_for(0.0), 0);
        assert_eq!(bounces_for(0.1), 1);
        assert_eq!(bounces_for(0.5), 5, "0.5^6 = 1.6%");
        assert!(0.5f64.powi(6) < BOUNCE_TAIL && 0.5f64.powi(5) > BOUNCE_TAIL);
        assert_eq!(bounces_for(0.9), MAX_AUTO_BOUNCES);
        assert_eq!(bounces_for(1.0), MAX_AUTO_BOUNCES);
    }

    #[test]
    fn given_keys_are_read_from_the_render_table() {
        let g = Given::of("[render]\nlight_rays = 3\nrefine = 1\n[camera]\nfov = 3\n");
        assert!(g.has("light_rays") && g.has("refine") && !g.has("fov") && !g.has("element_size"));
        assert_eq!(Given::of("[camera]\nfov = 3\n"), Given::default());
        assert_eq!(Given::of("not toml ["), Given::default());
    }

    #[test]
    fn element_sizes_round_to_two_digits() {
        assert_eq!(round2(2.0 / 33.0), 0.061);
        assert_eq!(round2(14.0 / 33.0), 0.42);
    }
}
