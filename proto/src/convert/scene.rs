//! The scene header's entities on the wire: camera, lights, materials, emitters, render
//! settings and the effects plan, each checked as it comes in.

use super::{
    finite, in_range, invalid, rgb_from_wire, rgb_to_wire, short_string, vec3_from_wire, vec3_to_wire, wire_loc,
    ConvertError, MAX_PLAN_DEPTH, MAX_REASONS, MAX_SUBSPACES,
};
use crate::v1;
use magg_core::color::Rgb;
use magg_core::header::Emitter;
use magg_core::math::Normalized;
use magg_core::plan::EffectsPlan;
use magg_core::scene::{Accel, Camera, DirectLight, Exposure, GridSpec, Light, Material, RenderSettings, Spot};

impl From<&Camera> for v1::Camera {
    fn from(c: &Camera) -> Self {
        camera_to_wire(c)
    }
}

impl TryFrom<v1::Camera> for Camera {
    type Error = ConvertError;
    fn try_from(c: v1::Camera) -> Result<Self, ConvertError> {
        camera_from_wire(c)
    }
}

pub(super) fn camera_to_wire(c: &Camera) -> v1::Camera {
    v1::Camera {
        eye: Some(vec3_to_wire(c.eye)),
        look_at: Some(vec3_to_wire(c.look_at)),
        up: Some(vec3_to_wire(c.up)),
        fov_y_deg: c.fov_y_deg,
    }
}

pub(super) fn camera_from_wire(c: v1::Camera) -> Result<Camera, ConvertError> {
    let eye = vec3_from_wire(c.eye, "camera.eye")?;
    let look_at = vec3_from_wire(c.look_at, "camera.look_at")?;
    let up = vec3_from_wire(c.up, "camera.up")?;
    let fov = finite(c.fov_y_deg, "camera.fov_y_deg")?;
    if !(fov > 0.0 && fov < 180.0) {
        return Err(invalid("camera.fov_y_deg", fov, "in (0, 180)"));
    }
    let view = look_at - eye;
    if view.length() == 0.0 || !view.normalized().is_finite() {
        return Err(invalid("camera.look_at", format!("{look_at:?}"), "a point other than the eye"));
    }
    let side = view.normalized().cross(up.normalized());
    if !side.is_finite() || side.length() < 1e-12 {
        return Err(invalid("camera.up", format!("{up:?}"), "non-zero and not parallel to the view direction"));
    }
    Ok(Camera { eye, look_at, up, fov_y_deg: fov })
}

pub(super) fn light_to_wire(l: &Light) -> v1::Light {
    v1::Light {
        position: Some(vec3_to_wire(l.position)),
        intensity: Some(rgb_to_wire(l.intensity)),
        spot: l.spot.as_ref().map(|s| v1::Spot {
            direction: Some(vec3_to_wire(s.direction)),
            half_angle_deg: s.half_angle_deg,
            falloff_deg: s.falloff_deg,
        }),
    }
}

pub(super) fn light_from_wire(i: usize, l: v1::Light) -> Result<Light, ConvertError> {
    let f = |name: &str| format!("lights[{i}].{name}");
    let position = vec3_from_wire(l.position, &f("position"))?;
    let intensity = rgb_from_wire(l.intensity, &f("intensity"), f64::MAX)?;
    let spot = match l.spot {
        None => None,
        Some(s) => {
            let direction = vec3_from_wire(s.direction, &f("spot.direction"))?;
            if direction.length() == 0.0 || !direction.normalized().is_finite() {
                return Err(invalid(f("spot.direction"), format!("{direction:?}"), "a non-zero vector"));
            }
            let half = finite(s.half_angle_deg, &f("spot.half_angle_deg"))?;
            if !(half > 0.0 && half <= 180.0) {
                return Err(invalid(f("spot.half_angle_deg"), half, "in (0, 180]"));
            }
            let falloff = finite(s.falloff_deg, &f("spot.falloff_deg"))?;
            if !(0.0..=180.0 - half).contains(&falloff) {
                return Err(invalid(f("spot.falloff_deg"), falloff, format!("in [0, {}]", 180.0 - half)));
            }
            Some(Spot { direction, half_angle_deg: half, falloff_deg: falloff })
        }
    };
    Ok(Light { position, intensity, spot, loc: wire_loc() })
}

pub(super) fn material_to_wire(m: &Material) -> v1::Material {
    v1::Material {
        name: m.name.clone(),
        diffuse: Some(rgb_to_wire(m.diffuse)),
        mirror: Some(rgb_to_wire(m.mirror)),
        transmit: Some(rgb_to_wire(m.transmit)),
        ior: m.ior,
        one_sided: m.one_sided,
        emit: m.is_emitter().then(|| rgb_to_wire(m.emit)),
    }
}

pub(super) fn material_from_wire(i: usize, m: v1::Material) -> Result<Material, ConvertError> {
    let f = |name: &str| format!("materials[{i}].{name}");
    let name = short_string(m.name, &f("name"))?;
    let diffuse = rgb_from_wire(m.diffuse, &f("diffuse"), 1.0)?;
    let mirror = rgb_from_wire(m.mirror, &f("mirror"), 1.0)?;
    let transmit = rgb_from_wire(m.transmit, &f("transmit"), 1.0)?;
    let ior = finite(m.ior, &f("ior"))?;
    in_range(ior, 1.0, 4.0, &f("ior"))?;
    let sum = diffuse.add(mirror).add(transmit);
    for (k, s) in sum.0.iter().enumerate() {
        if *s > 1.0 + 1e-9 {
            let field = f(&format!("diffuse+mirror+transmit[{k}]"));
            return Err(invalid(field, s, "at most 1 (the rest is absorbed)"));
        }
    }
    if m.one_sided && !transmit.is_black() {
        return Err(invalid(f("one_sided"), true, "false for a transmissive material"));
    }
    let emit = match m.emit {
        Some(e) => rgb_from_wire(Some(e), &f("emit"), f64::MAX)?,
        None => Rgb::BLACK,
    };
    Ok(Material { name, diffuse, mirror, transmit, ior, one_sided: m.one_sided, emit, loc: wire_loc() })
}

pub(super) fn emitter_to_wire(e: &Emitter) -> v1::Emitter {
    v1::Emitter { element: e.element, power: Some(rgb_to_wire(e.power)) }
}

/// The emitting elements of a header: ascending element ids below `elements`, each with
/// a finite, non-negative power.
pub(super) fn emitters_from_wire(list: Vec<v1::Emitter>, elements: u32) -> Result<Vec<Emitter>, ConvertError> {
    let mut out: Vec<Emitter> = Vec::with_capacity(list.len().min(elements as usize));
    for (i, e) in list.into_iter().enumerate() {
        let f = |name: &str| format!("emitters[{i}].{name}");
        if e.element >= elements {
            return Err(invalid(f("element"), e.element, format!("an element id below {elements}")));
        }
        if out.last().is_some_and(|last| last.element >= e.element) {
            return Err(invalid(f("element"), e.element, "ascending, each element once"));
        }
        let power = rgb_from_wire(e.power, &f("power"), f64::MAX)?;
        out.push(Emitter { element: e.element, power });
    }
    Ok(out)
}

pub(super) fn settings_to_wire(s: &RenderSettings) -> v1::RenderSettings {
    v1::RenderSettings {
        width: s.width,
        height: s.height,
        pixel_samples: s.pixel_samples,
        element_size: s.element_size,
        light_rays: s.light_rays,
        bounce_rays: s.bounce_rays,
        gather_rays: s.gather_rays,
        lrt_depth: s.lrt_depth,
        vrt_depth: s.vrt_depth,
        diffuse_bounces: s.diffuse_bounces,
        ambient: Some(rgb_to_wire(s.ambient)),
        seed: s.seed,
        background: Some(rgb_to_wire(s.background)),
        exposure: match s.exposure {
            Exposure::Auto => 0.0,
            Exposure::Fixed(x) => x,
        },
        max_elements: s.max_elements,
        grid: match s.grid {
            GridSpec::Auto => Vec::new(),
            GridSpec::Fixed(d) => d.to_vec(),
        },
        accel: match s.accel {
            Accel::Bvh => v1::Accel::Bvh,
            Accel::Grid => v1::Accel::Grid,
        } as i32,
        direct: match s.direct {
            DirectLight::Auto => v1::DirectLight::Auto,
            DirectLight::Vrt => v1::DirectLight::Vrt,
            DirectLight::Lrt => v1::DirectLight::Lrt,
        } as i32,
        shared_faces: s.shared_faces,
        refine: s.refine,
        refine_contrast: s.refine_contrast,
    }
}

pub(super) fn settings_from_wire(s: v1::RenderSettings) -> Result<RenderSettings, ConvertError> {
    let width = in_range(s.width, 1, 16384, "settings.width")?;
    let height = in_range(s.height, 1, 16384, "settings.height")?;
    let pixel_samples = in_range(s.pixel_samples, 1, 4096, "settings.pixel_samples")?;
    let light_rays = in_range(s.light_rays, 1, 1_000_000, "settings.light_rays")?;
    let bounce_rays = in_range(s.bounce_rays, 1, magg_core::scene::MAX_BOUNCE_RAYS, "settings.bounce_rays")?;
    let gather_rays = in_range(s.gather_rays, 0, magg_core::scene::MAX_GATHER_RAYS, "settings.gather_rays")?;
    let lrt_depth = in_range(s.lrt_depth, 0, 32, "settings.lrt_depth")?;
    let vrt_depth = in_range(s.vrt_depth, 0, 32, "settings.vrt_depth")?;
    let diffuse_bounces = in_range(s.diffuse_bounces, 0, 16, "settings.diffuse_bounces")?;
    let element_size = finite(s.element_size, "settings.element_size")?;
    if element_size <= 0.0 {
        return Err(invalid("settings.element_size", element_size, "a positive number"));
    }
    let ambient = rgb_from_wire(s.ambient, "settings.ambient", f64::MAX)?;
    let background = rgb_from_wire(s.background, "settings.background", f64::MAX)?;
    let exposure = match finite(s.exposure, "settings.exposure")? {
        0.0 => Exposure::Auto,
        x if x > 0.0 => Exposure::Fixed(x),
        x => return Err(invalid("settings.exposure", x, "0 (auto) or a positive multiplier")),
    };
    if s.max_elements == 0 {
        return Err(invalid("settings.max_elements", 0, "at least 1"));
    }
    let grid = if s.grid.iter().all(|&d| d == 0) {
        GridSpec::Auto
    } else {
        let bad = || invalid("settings.grid", format!("{:?}", s.grid), "empty (auto) or 3 values in 1..=512");
        let d: [u32; 3] = s.grid.as_slice().try_into().map_err(|_| bad())?;
        if d.iter().any(|&n| !(1..=512).contains(&n)) {
            return Err(bad());
        }
        if d.iter().map(|&n| n as u64).product::<u64>() > MAX_SUBSPACES {
            return Err(invalid("settings.grid", format!("{d:?}"), format!("at most {MAX_SUBSPACES} subspaces")));
        }
        GridSpec::Fixed(d)
    };
    let accel = match v1::Accel::try_from(s.accel) {
        Ok(v1::Accel::Bvh) => Accel::Bvh,
        Ok(v1::Accel::Grid) => Accel::Grid,
        Err(_) => return Err(invalid("settings.accel", s.accel, "ACCEL_BVH (0) or ACCEL_GRID (1)")),
    };
    let direct = match v1::DirectLight::try_from(s.direct) {
        Ok(v1::DirectLight::Auto) => DirectLight::Auto,
        Ok(v1::DirectLight::Vrt) => DirectLight::Vrt,
        Ok(v1::DirectLight::Lrt) => DirectLight::Lrt,
        Err(_) => {
            return Err(invalid(
                "settings.direct",
                s.direct,
                "DIRECT_LIGHT_AUTO (0), DIRECT_LIGHT_VRT (1) or DIRECT_LIGHT_LRT (2)",
            ))
        }
    };
    Ok(RenderSettings {
        accel,
        direct,
        width,
        height,
        pixel_samples,
        element_size,
        light_rays,
        bounce_rays,
        gather_rays,
        lrt_depth,
        vrt_depth,
        diffuse_bounces,
        ambient,
        grid,
        seed: s.seed,
        exposure,
        background,
        max_elements: s.max_elements,
        shared_faces: s.shared_faces,
        refine: in_range(s.refine, 0, magg_core::scene::MAX_REFINE_LEVELS, "settings.refine")?,
        refine_contrast: match finite(s.refine_contrast, "settings.refine_contrast")? {
            c if c > 0.0 && c <= 1.0 => c,
            c => return Err(invalid("settings.refine_contrast", c, "in (0, 1]")),
        },
    })
}

pub(super) fn plan_to_wire(p: &EffectsPlan) -> v1::EffectsPlan {
    v1::EffectsPlan {
        lrt: p.lrt,
        lrt_depth: p.lrt_depth,
        refraction: p.refraction,
        diffuse_bounces: p.diffuse_bounces,
        vrt_depth: p.vrt_depth,
        ambient: p.ambient,
        pixel_samples: p.pixel_samples,
        reasons: p.reasons.clone(),
        direct_vrt: p.direct_vrt,
        area_lights: p.area_lights,
    }
}

pub(super) fn plan_from_wire(p: v1::EffectsPlan) -> Result<EffectsPlan, ConvertError> {
    if p.reasons.len() > MAX_REASONS {
        return Err(invalid("plan.reasons", format!("<{} lines>", p.reasons.len()), format!("at most {MAX_REASONS}")));
    }
    let reasons = p
        .reasons
        .into_iter()
        .enumerate()
        .map(|(i, r)| short_string(r, &format!("plan.reasons[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(EffectsPlan {
        lrt: p.lrt,
        lrt_depth: in_range(p.lrt_depth, 0, MAX_PLAN_DEPTH, "plan.lrt_depth")?,
        refraction: p.refraction,
        diffuse_bounces: in_range(p.diffuse_bounces, 0, MAX_PLAN_DEPTH, "plan.diffuse_bounces")?,
        vrt_depth: in_range(p.vrt_depth, 0, MAX_PLAN_DEPTH, "plan.vrt_depth")?,
        ambient: p.ambient,
        pixel_samples: in_range(p.pixel_samples, 1, 4096, "plan.pixel_samples")?,
        direct_vrt: p.direct_vrt,
        area_lights: p.area_lights,
        reasons,
    })
}
