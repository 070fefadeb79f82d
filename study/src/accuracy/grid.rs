//! The settings grid of the accuracy study: a base point (the scene's own settings), each
//! knob varied alone from it, a few combined points, and (full grid) the whole
//! element size x light rays x pixel samples product.

use super::preset::{scale_elements, Quality};
use magg_core::scene::Scene;

/// One setting of every accuracy knob. The element size is a multiplier of the scene's
/// (see [`scale_elements`]); the rest are absolute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Element edge multiplier.
    pub element_scale: f64,
    /// Light rays per (light, element) pair.
    pub light_rays: u32,
    /// Viewing rays per pixel.
    pub pixel_samples: u32,
    /// Specular bounces of light rays.
    pub lrt_depth: u32,
    /// Specular bounces of viewing rays.
    pub vrt_depth: u32,
    /// Diffuse-to-diffuse bounces of light rays.
    pub diffuse_bounces: u32,
}

impl Point {
    /// The scene's own settings.
    pub fn of_scene(scene: &Scene) -> Point {
        let s = &scene.settings;
        Point {
            element_scale: 1.0,
            light_rays: s.light_rays,
            pixel_samples: s.pixel_samples,
            lrt_depth: s.lrt_depth,
            vrt_depth: s.vrt_depth,
            diffuse_bounces: s.diffuse_bounces,
        }
    }

    /// The converged reference: elements half the scene's size, eight times its light
    /// rays per pair (at least 256, twice the `final` preset's), 16 pixel samples, the
    /// scene's depths and diffuse bounces.
    pub fn reference(scene: &Scene) -> Point {
        let light_rays = (scene.settings.light_rays.saturating_mul(8)).max(256);
        Point { element_scale: 0.5, light_rays, pixel_samples: 16, ..Point::of_scene(scene) }
    }

    /// Where a quality preset puts the scene.
    pub fn of_quality(scene: &Scene, q: Quality) -> Point {
        let p = q.preset();
        let base = Point::of_scene(scene);
        Point {
            element_scale: p.element_scale,
            light_rays: p.light_rays(base.light_rays),
            pixel_samples: p.pixel_samples.unwrap_or(base.pixel_samples),
            ..base
        }
    }

    /// `scene` with this point's settings.
    pub fn apply(&self, scene: &Scene) -> Scene {
        let mut s = scene.clone();
        scale_elements(&mut s, self.element_scale);
        let r = &mut s.settings;
        r.light_rays = self.light_rays;
        r.pixel_samples = self.pixel_samples;
        r.lrt_depth = self.lrt_depth;
        r.vrt_depth = self.vrt_depth;
        r.diffuse_bounces = self.diffuse_bounces;
        s
    }
}

/// A point of the grid with the knob it varies (`base`, `combined`, `grid`, or a knob
/// name) and that knob's value, as text.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// What this row varies.
    pub knob: String,
    /// The varied value.
    pub value: String,
    /// The settings.
    pub point: Point,
}

/// How much of the grid to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GridSize {
    /// One knob at a time from the scene's settings, plus the presets and two combined
    /// points.
    Small,
    /// The small grid plus every element size x light rays x pixel samples combination.
    Full,
}

/// Element edge multipliers of the study.
pub const ELEMENT_SCALES: [f64; 3] = [2.0, 1.0, 0.5];
/// Light rays per pair of the study.
pub const LIGHT_RAYS: [u32; 3] = [4, 16, 64];
/// Pixel samples of the full grid (the one-knob sweep also runs 16).
pub const PIXEL_SAMPLES: [u32; 2] = [1, 4];

/// The settings to measure for `scene`, without duplicates (the first label wins).
pub fn settings(scene: &Scene, size: GridSize) -> Vec<Setting> {
    let base = Point::of_scene(scene);
    let mut out: Vec<Setting> = Vec::new();
    let mut push = |knob: &str, value: String, point: Point| {
        if !out.iter().any(|s| s.point == point) {
            out.push(Setting { knob: knob.into(), value, point });
        }
    };
    push("base", "scene".into(), base);
    for f in ELEMENT_SCALES {
        push("element_size", format!("x{f}"), Point { element_scale: f, ..base });
    }
    for n in LIGHT_RAYS {
        push("light_rays", n.to_string(), Point { light_rays: n, ..base });
    }
    for n in PIXEL_SAMPLES.into_iter().chain([16]) {
        push("pixel_samples", n.to_string(), Point { pixel_samples: n, ..base });
    }
    let depths = |scene_depth: u32| {
        let mut d = vec![0, 1, scene_depth];
        d.dedup();
        d
    };
    for d in depths(base.lrt_depth) {
        push("lrt_depth", d.to_string(), Point { lrt_depth: d, ..base });
    }
    for d in depths(base.vrt_depth) {
        push("vrt_depth", d.to_string(), Point { vrt_depth: d, ..base });
    }
    if base.diffuse_bounces > 0 {
        for d in [0, 1] {
            push("diffuse_bounces", d.to_string(), Point { diffuse_bounces: d, ..base });
        }
    }
    for (name, q) in [("draft", Quality::Draft), ("final", Quality::Final)] {
        push("quality", name.into(), Point::of_quality(scene, q));
    }
    push("combined", "x0.5, 16 rays".into(), Point { element_scale: 0.5, light_rays: 16, ..base });
    push(
        "combined",
        "x0.5, 64 rays, 4 spp".into(),
        Point { element_scale: 0.5, light_rays: 64, pixel_samples: 4, ..base },
    );
    if size == GridSize::Full {
        for f in ELEMENT_SCALES {
            for n in LIGHT_RAYS {
                for p in PIXEL_SAMPLES {
                    push(
                        "grid",
                        format!("x{f}, {n} rays, {p} spp"),
                        Point { element_scale: f, light_rays: n, pixel_samples: p, ..base },
                    );
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_grid_varies_one_knob_at_a_time_without_duplicates() {
        let scene = crate::test_scene("magg-paper.toml");
        let small = settings(&scene, GridSize::Small);
        assert_eq!(small[0].knob, "base");
        for (i, a) in small.iter().enumerate() {
            assert!(small[i + 1..].iter().all(|b| b.point != a.point), "duplicate {a:?}");
        }
        let base = small[0].point;
        for s in small.iter().filter(|s| s.knob == "light_rays") {
            assert_eq!(Point { light_rays: base.light_rays, ..s.point }, base);
        }
        assert!(!small.iter().any(|s| s.knob == "diffuse_bounces"), "scene has no diffuse bounces");
        let full = settings(&scene, GridSize::Full);
        assert!(full.len() > small.len());
        assert_eq!(&full[..small.len()], &small[..]);
    }
}
