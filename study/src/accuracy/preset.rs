//! Quality presets (`magg-host render --quality draft|good|final`) and the element-size
//! scaling they share with the accuracy study.

use magg_core::scene::Scene;

/// A named point on the accuracy/time front.
///
/// The presets raise the light rays per unit area, not only per pair: an element a
/// quarter the area with as many rays per pair would gather as many bounce rays as
/// before, and its noise would not fall. `final` keeps the scene's elements and casts
/// four times the rays per pair (the noise of bounced light, which dominates what is
/// left at `good`, falls about fourfold in variance), and sharpens where the light
/// changes sharply with one more level of adaptive refinement rather than halving every
/// element: halving them all quadrupled the pairs for a sharpness that only shadow and
/// caustic edges need.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Quality {
    /// Quick look: elements twice the scene's size, a quarter of its light rays per pair
    /// (at least 4), 1 pixel sample, the scene's levels of refinement (on coarse
    /// elements a caustic without them is a smudge, and their pilots cost little).
    Draft,
    /// The scene's own `[render]` settings (and, loaded by `magg-host`, what it chose
    /// for those the scene leaves unset: `magg_host::auto`).
    Good,
    /// Near the converged reference: the scene's elements, four times its light rays
    /// per pair, 16 pixel samples, one level of adaptive refinement more than the
    /// scene's.
    Final,
}

/// What a preset changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// Element edge multiplier (see [`scale_elements`]).
    pub element_scale: f64,
    /// Multiplier of the scene's light rays per (light, element) pair.
    pub ray_factor: f64,
    /// Multiplier of the scene's gather rays per viewing ray (`[render] gather_rays`;
    /// none stay none; 0: gather none).
    pub gather_factor: f64,
    /// Viewing rays per pixel; `None` keeps the scene's.
    pub pixel_samples: Option<u32>,
    /// Levels of adaptive refinement added to the scene's (`[render] refine`, at most
    /// [`magg_core::scene::MAX_REFINE_LEVELS`]).
    pub refine: u32,
}

impl Preset {
    /// Light rays per pair for a scene that asks for `scene_rays`.
    pub fn light_rays(&self, scene_rays: u32) -> u32 {
        let r = (scene_rays.max(1) as f64 * self.ray_factor).round();
        if self.ray_factor < 1.0 {
            (r as u32).max(4).min(scene_rays.max(1))
        } else {
            r.min(1_000_000.0) as u32
        }
    }

    /// Gather rays per viewing ray for a scene that asks for `scene_rays` (0 stays 0).
    pub fn gather_rays(&self, scene_rays: u32) -> u32 {
        let r = (scene_rays as f64 * self.gather_factor).round();
        r.min(magg_core::scene::MAX_GATHER_RAYS as f64) as u32
    }
}

impl Quality {
    /// The settings this preset stands for.
    pub fn preset(self) -> Preset {
        match self {
            // `draft` gathers none: at one viewing ray per pixel, a few gather rays are
            // noisier than the interpolation they replace; `final`'s 16 samples need
            // twice the rays each, not four times (docs/ACCURACY.md).
            Quality::Draft => {
                Preset { element_scale: 2.0, ray_factor: 0.25, gather_factor: 0.0, pixel_samples: Some(1), refine: 0 }
            }
            Quality::Good => {
                Preset { element_scale: 1.0, ray_factor: 1.0, gather_factor: 1.0, pixel_samples: None, refine: 0 }
            }
            Quality::Final => {
                Preset { element_scale: 1.0, ray_factor: 4.0, gather_factor: 2.0, pixel_samples: Some(16), refine: 1 }
            }
        }
    }

    /// Applies the preset to a loaded scene (before any explicit knob flag, which wins).
    pub fn apply(self, scene: &mut Scene) {
        let p = self.preset();
        scale_elements(scene, p.element_scale);
        scene.settings.light_rays = p.light_rays(scene.settings.light_rays);
        scene.settings.gather_rays = p.gather_rays(scene.settings.gather_rays);
        if let Some(v) = p.pixel_samples {
            scene.settings.pixel_samples = v;
        }
        scene.settings.refine = scene.settings.refine.saturating_add(p.refine).min(magg_core::scene::MAX_REFINE_LEVELS);
    }
}

/// Multiplies the element edge length by `factor`: the scene's `element_size`, and the
/// fixed subdivision count n of patches that set one (n becomes round(n / factor), at
/// least 1), so that scenes such as magg-paper, whose patches all fix n, refine too.
pub fn scale_elements(scene: &mut Scene, factor: f64) {
    if !(factor.is_finite() && factor > 0.0) || factor == 1.0 {
        return;
    }
    scene.settings.element_size *= factor;
    for p in &mut scene.patches {
        if let Some(n) = p.subdivisions {
            p.subdivisions = Some(((n as f64 / factor).round() as u32).max(1));
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn draft_keeps_a_few_rays_and_never_adds_any() {
        let d = Quality::Draft.preset();
        assert_eq!(d.light_rays(64), 16);
        assert_eq!(d.light_rays(8), 4);
        assert_eq!(d.light_rays(2), 2);
        assert_eq!(Quality::Good.preset().light_rays(7), 7);
        assert_eq!(d.gather_rays(128), 0);
        assert_eq!(Quality::Good.preset().gather_rays(128), 128);
        assert_eq!(d.gather_rays(0), 0);
        assert_eq!(Quality::Final.preset().gather_rays(128), 256);
        assert_eq!(Quality::Final.preset().gather_rays(0), 0);
        assert_eq!(Quality::Final.preset().gather_rays(4096), 4096);
    }

    use super::*;
    use glam::DVec3;
    use magg_core::scene::{Camera, PatchDef, RenderSettings, SourceLoc};

    fn scene() -> Scene {
        let patch = |subdivisions| PatchDef {
            vertices: [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0)],
            material: 0,
            subdivisions,
            size_hint: None,
            normals: None,
            uv: None,
            texture: None,
            loc: SourceLoc::default(),
        };
        Scene {
            name: "t".into(),
            camera: Camera {
                eye: DVec3::ZERO,
                look_at: DVec3::new(0.0, 0.0, -1.0),
                up: DVec3::new(0.0, 1.0, 0.0),
                fov_y_deg: 45.0,
            },
            settings: RenderSettings {
                element_size: 0.2,
                light_rays: 16,
                pixel_samples: 2,
                refine: 2,
                ..Default::default()
            },
            lights: vec![],
            materials: vec![],
            patches: vec![patch(Some(16)), patch(None), patch(Some(1))],
            textures: vec![],
        }
    }

    #[test]
    fn draft_coarsens_and_cuts_rays() {
        let mut s = scene();
        Quality::Draft.apply(&mut s);
        assert_eq!(s.settings.element_size, 0.4);
        assert_eq!(s.settings.light_rays, 4, "a quarter of 16");
        assert_eq!(s.settings.pixel_samples, 1);
        assert_eq!(s.settings.refine, 2, "the scene's levels: a caustic's edges need them most on coarse elements");
        assert_eq!(s.patches[0].subdivisions, Some(8));
        assert_eq!(s.patches[1].subdivisions, None);
        assert_eq!(s.patches[2].subdivisions, Some(1), "never below one subdivision");
    }

    #[test]
    fn good_keeps_the_scene() {
        let mut s = scene();
        Quality::Good.apply(&mut s);
        assert_eq!(s, scene());
    }

    #[test]
    fn final_refines_and_adds_rays() {
        let mut s = scene();
        Quality::Final.apply(&mut s);
        assert_eq!(s.settings.element_size, 0.2, "the scene's elements");
        assert_eq!(s.settings.light_rays, 64, "four times 16: four times the rays per unit area");
        assert_eq!(s.settings.pixel_samples, 16);
        assert_eq!(s.settings.refine, 3, "one level more than the scene's");
        assert_eq!(s.patches[0].subdivisions, Some(16));
        let mut deep = scene();
        deep.settings.refine = magg_core::scene::MAX_REFINE_LEVELS;
        Quality::Final.apply(&mut deep);
        assert_eq!(deep.settings.refine, magg_core::scene::MAX_REFINE_LEVELS, "never beyond the deepest level");
    }
}
