//! The effects plan: simulate only the effects a scene calls for (docs/ARCHITECTURE.md, the effects plan).
//!
//! Before rendering, the scene is analysed and each optional pass or ray kind is switched
//! on or off with a reason. A pass left out costs nothing, and because every kernel only
//! spawns rays whose weight is non-zero, forcing it on gives a bitwise-identical image.
//!
//! Area lights (patches of a material with `emit`) follow `direct` like the point lights:
//! where direct light is computed at VRT, a diffuse hit samples points on the emitters
//! with shadow rays ([`crate::direct::area_irradiance`]) and their pairs (emitting element,
//! element) deposit only what arrives via a mirror, glass or a diffuse bounce
//! ([`EffectsPlan::deposits_direct`]); with `direct = "lrt"` their light rays deposit it
//! all on the elements (the paper's way).

use crate::scene::{DirectLight, Scene};

/// With `direct = "auto"`, direct light is computed at VRT for at most this many lights:
/// each costs one shadow ray at every diffuse hit of every viewing ray, in every frame,
/// where LRT's pairs are traced once for all frames.
pub const MAX_VRT_LIGHTS: usize = 16;

/// Which passes and ray kinds run, and why.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct EffectsPlan {
    /// Light ray tracing runs (false only with no light that can reach any element).
    pub lrt: bool,
    /// Maximum specular bounces of light rays (0 = secondary light rays off).
    pub lrt_depth: u32,
    /// Refracted rays are traced (a dielectric exists).
    pub refraction: bool,
    /// Diffuse-to-diffuse bounces of light rays.
    pub diffuse_bounces: u32,
    /// Maximum specular bounces of viewing rays (0 = primary viewing rays only).
    pub vrt_depth: u32,
    /// The constant ambient term is added (paper's model, when no diffuse bounce runs).
    pub ambient: bool,
    /// Viewing rays per pixel.
    pub pixel_samples: u32,
    /// Direct light is computed at VRT: from point and spot lights with one shadow ray
    /// per light at each diffuse hit, from area lights with shadow rays to points sampled
    /// on the emitters ([`crate::direct`]); light rays of both kinds then deposit only
    /// what arrives via a specular surface or a diffuse bounce.
    pub direct_vrt: bool,
    /// Some patch emits (a material with `emit`): LRT traces (emitting element, element)
    /// pairs after the point lights' pairs (their direct light on the elements only
    /// where `direct_vrt` is off).
    pub area_lights: bool,
    /// One line per decision, for people.
    pub reasons: Vec<String>,
}

/// How a pair traced for its bounce alone sends `bounces` bounce rays: as (light rays,
/// bounce rays per light ray), at most `bounce_rays` per light ray and never more than
/// there are bounces, the light rays rounded up.
pub fn bounce_split(bounces: u32, bounce_rays: u32) -> (u32, u32) {
    let bounces = bounces.max(1);
    let fan = bounce_rays.clamp(1, bounces);
    (bounces.div_ceil(fan), fan)
}

impl EffectsPlan {
    /// Analyses `scene` and decides the passes.
    pub fn for_scene(scene: &Scene) -> EffectsPlan {
        let s = &scene.settings;
        let used = |f: &dyn Fn(&crate::scene::Material) -> bool| {
            scene.patches.iter().any(|p| scene.materials.get(p.material as usize).is_some_and(f))
        };
        let any_specular = used(&|m| m.is_specular());
        let any_dielectric = used(&|m| m.is_transmissive());
        let any_diffuse = used(&|m| !m.diffuse.is_black());
        let any_light = scene.lights.iter().any(|l| !l.intensity.is_black());
        let emitting = scene
            .patches
            .iter()
            .filter(|p| scene.materials.get(p.material as usize).is_some_and(|m| m.is_emitter()))
            .count();
        let mut reasons = Vec::new();

        let lrt = (any_light || emitting > 0) && !scene.patches.is_empty();
        if !lrt {
            reasons.push("no light with non-zero intensity: LRT off".to_string());
        }
        if emitting > 0 {
            reasons.push(format!(
                "{emitting} emitting patch(es): area lights, LRT traces (emitting element, element) pairs"
            ));
        }
        let lrt_depth = if !lrt {
            0
        } else if !any_specular {
            reasons.push("no specular or transmissive material: secondary light rays off".to_string());
            0
        } else if s.lrt_depth == 0 {
            reasons.push("lrt_depth = 0: secondary light rays off".to_string());
            0
        } else {
            reasons.push(format!("specular material present: secondary light rays on, depth {}", s.lrt_depth));
            s.lrt_depth
        };
        let refraction = any_dielectric && (lrt_depth > 0 || s.vrt_depth > 0);
        if !any_dielectric {
            reasons.push("no dielectric: refraction off".to_string());
        } else {
            reasons.push("dielectric present: refraction on".to_string());
        }
        let diffuse_bounces = if !lrt || !any_diffuse {
            if s.diffuse_bounces > 0 {
                reasons.push("no diffuse surface lit: diffuse bounces off".to_string());
            }
            0
        } else {
            if s.diffuse_bounces > 0 {
                reasons.push(format!(
                    "diffuse-to-diffuse transport on, {} bounce(s): replaces the ambient term",
                    s.diffuse_bounces
                ));
            }
            s.diffuse_bounces
        };
        let vrt_depth = if !any_specular {
            reasons.push("no visible mirror or dielectric: VRT depth 0".to_string());
            0
        } else {
            reasons.push(format!("specular material present: VRT recursion on, depth {}", s.vrt_depth));
            s.vrt_depth
        };
        let ambient = diffuse_bounces == 0 && !s.ambient.is_black() && any_diffuse;
        if diffuse_bounces == 0 {
            reasons.push(if ambient {
                "ambient term on (no diffuse-to-diffuse transport)".to_string()
            } else {
                "ambient term off (zero ambient)".to_string()
            });
        }
        let direct_vrt = direct_at_vrt(scene, (any_light || emitting > 0) && lrt && any_diffuse, &mut reasons);
        if direct_vrt && diffuse_bounces > 0 {
            let (light, fan) = bounce_split(s.light_rays, s.bounce_rays);
            reasons.push(format!(
                "direct light at VRT: a diffuse element's light rays only start its bounce, so its pairs cast {light} \
                 light rays, each sending {fan} bounce ray(s) ({} per pair)",
                s.light_rays.max(1)
            ));
        }
        let mut plan = EffectsPlan {
            lrt,
            lrt_depth,
            refraction,
            diffuse_bounces,
            vrt_depth,
            ambient,
            pixel_samples: s.pixel_samples,
            direct_vrt,
            area_lights: emitting > 0,
            reasons,
        };
        if plan.gathers(s.gather_rays, &scene.materials) {
            plan.reasons.push(format!(
                "the elements hold one diffuse bounce alone: beside elements that receive no light (contacts), \
                 a diffuse hit gathers the bounce with {} ray(s) instead of interpolating",
                s.gather_rays
            ));
        }
        plan
    }

    /// True when a diffuse hit beside elements that received no light gathers the bounced
    /// light with `gather_rays` rays instead of interpolating the elements' (see
    /// [`crate::energy::gather_vertices`]): the elements must hold exactly what a gather
    /// finds, one diffuse bounce of the lights' direct light (direct light at VRT, point,
    /// spot and area lights alike; one diffuse bounce; no light carried via mirrors or
    /// glass).
    /// Light via mirrors or glass needs both secondary light rays and a specular material
    /// among `materials`, so forcing secondary light rays on in a scene without one
    /// (`--all-effects`) changes nothing.
    pub fn gathers(&self, gather_rays: u32, materials: &[crate::scene::Material]) -> bool {
        let no_specular_light = self.lrt_depth == 0 || !materials.iter().any(|m| m.is_specular());
        gather_rays > 0 && self.direct_vrt && self.diffuse_bounces == 1 && no_specular_light
    }

    /// True when the primary light rays of a pair (a point, spot or area light's) deposit
    /// what they carry on the element they reach (direct light): unless direct light is
    /// computed at VRT.
    pub fn deposits_direct(&self) -> bool {
        !self.direct_vrt
    }

    /// True when no light ray can deposit anything on an element of a material without
    /// mirror or transmissive parts: direct light is computed at VRT and light rays do
    /// not bounce diffusely, so the pairs of any light (point, spot or emitting element)
    /// and such an element need not be traced.
    pub fn skips_diffuse_pairs(&self) -> bool {
        self.direct_vrt && self.diffuse_bounces == 0
    }

    /// True when the pairs of any light with elements of a material without mirror or
    /// transmissive parts are traced for their diffuse bounce alone (direct light at VRT,
    /// diffuse bounces on): their light rays then split the bounce ([`bounce_split`],
    /// `[render] bounce_rays`).
    pub fn splits_bounces(&self) -> bool {
        self.direct_vrt && self.diffuse_bounces > 0
    }

    /// Shadow rays a diffuse hit sends to the area lights: [`area_samples`] where their
    /// direct light is computed at VRT, else none.
    pub fn area_samples(&self) -> u32 {
        match self.direct_vrt && self.area_lights {
            true => area_samples(self.pixel_samples),
            false => 0,
        }
    }

    /// The plan with every optional effect forced on at the scene's settings: used to
    /// show that leaving passes out changes nothing in the image.
    pub fn forced_on(scene: &Scene) -> EffectsPlan {
        let s = &scene.settings;
        let mut p = EffectsPlan::for_scene(scene);
        p.lrt = true;
        p.lrt_depth = s.lrt_depth;
        p.refraction = true;
        p.diffuse_bounces = s.diffuse_bounces;
        p.vrt_depth = s.vrt_depth;
        p.ambient = s.diffuse_bounces == 0;
        // Where direct light is computed changes the image (sharper shadows), so it stays
        // as the scene's plan chose.
        p.reasons = vec!["every effect forced on (--all-effects)".to_string()];
        p
    }

    /// Short names of the passes that run, for the stats file.
    pub fn passes(&self) -> Vec<&'static str> {
        let mut v = vec!["preprocess"];
        if self.lrt {
            v.push("lrt");
            if self.area_lights {
                v.push("lrt_area");
            }
            if self.lrt_depth > 0 {
                v.push("lrt_specular");
            }
            if self.refraction && self.lrt_depth > 0 {
                v.push("lrt_refraction");
            }
            if self.diffuse_bounces > 0 {
                v.push("lrt_diffuse");
            }
        }
        v.push("interp");
        v.push("vrt");
        if self.direct_vrt {
            v.push("vrt_direct");
        }
        if self.vrt_depth > 0 {
            v.push("vrt_specular");
        }
        if self.ambient {
            v.push("ambient");
        }
        v
    }
}

/// Decides where direct light is computed (`lit`: some light reaches a diffuse surface).
fn direct_at_vrt(scene: &Scene, lit: bool, reasons: &mut Vec<String>) -> bool {
    if !lit {
        return false;
    }
    let lights = scene.lights.iter().filter(|l| !l.intensity.is_black()).count();
    let area = scene.patches.iter().any(|p| scene.materials.get(p.material as usize).is_some_and(|m| m.is_emitter()));
    let area_note = match area {
        true => {
            let n = area_samples(scene.settings.pixel_samples);
            format!(", {n} shadow ray(s) to points sampled on the emitters (area lights)")
        }
        false => String::new(),
    };
    let (on, why) = match scene.settings.direct {
        DirectLight::Lrt => {
            (false, "direct = \"lrt\": light rays deposit direct light on elements (the paper's way)".to_string())
        }
        DirectLight::Vrt => (
            true,
            format!("direct = \"vrt\": direct light at VRT, one shadow ray per light at each diffuse hit{area_note}"),
        ),
        DirectLight::Auto if lights <= MAX_VRT_LIGHTS => (
            true,
            format!(
                "{lights} light(s): direct light at VRT, one shadow ray per light at each diffuse hit{area_note} \
                 (pixel-sharp shadows); light rays carry light via mirrors, glass and diffuse bounces"
            ),
        ),
        DirectLight::Auto => (
            false,
            format!(
                "{lights} lights (over {MAX_VRT_LIGHTS}): a shadow ray per light at every hit would cost more than the \
                 light pass; direct light via light rays onto elements"
            ),
        ),
    };
    reasons.push(why);
    on
}

/// Shadow rays a diffuse hit of a viewing ray sends to points sampled on the area lights
/// (all emitters together, [`crate::direct::area_irradiance`]), with `pixel_samples`
/// viewing rays per pixel: [`AREA_SAMPLES_PER_PIXEL`] per pixel shared among its samples,
/// between 1 and [`MAX_AREA_SAMPLES`] per hit.
pub fn area_samples(pixel_samples: u32) -> u32 {
    AREA_SAMPLES_PER_PIXEL.div_ceil(pixel_samples.max(1)).clamp(1, MAX_AREA_SAMPLES)
}

/// Shadow rays to the area lights per pixel ([`area_samples`]).
pub const AREA_SAMPLES_PER_PIXEL: u32 = 32;

/// Most shadow rays to the area lights per diffuse hit ([`area_samples`]).
pub const MAX_AREA_SAMPLES: u32 = 16;

impl std::fmt::Display for EffectsPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "effects plan: {}", self.passes().join(", "))?;
        for r in &self.reasons {
            writeln!(f, "  - {r}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::bounce_split;

    #[test]
    fn the_bounce_is_split_into_whole_light_rays_and_never_more_per_ray_than_bounces() {
        assert_eq!(bounce_split(512, 8), (64, 8));
        assert_eq!(bounce_split(16, 3), (6, 3)); // 18 bounce rays: the light rays round up
        assert_eq!(bounce_split(2, 8), (1, 2)); // a refined element's two bounces
        assert_eq!(bounce_split(16, 0), (16, 1));
        assert_eq!(bounce_split(0, 8), (1, 1));
    }
}
