//! A scene written for Mitsuba 3, so that an independent renderer can make the reference
//! magg is measured against (`magg-host export --mitsuba SCENE --out DIR`, docs/ACCURACY.md).
//!
//! What is written: `scene.xml` (Mitsuba's scene format, version 3.0.0) and one binary
//! PLY per material under `meshes/`, holding the scene's patches after every transform.
//! The mapping:
//!
//! - the pinhole camera: a `perspective` sensor with the vertical field of view, a box
//!   pixel filter (magg averages stratified samples over each pixel with equal weights)
//!   and an `hdrfilm` of the scene's size;
//! - point lights: `point` emitters (both take radiant intensity, W/sr); spot lights:
//!   `spot` emitters (`beam_width` = the full-intensity half angle, `cutoff_angle` = that
//!   plus the falloff; Mitsuba's falloff is linear in angle where magg's is a smoothstep);
//! - materials: a diffuse part as `diffuse`, a mirror part as an ideal `conductor`
//!   (`material = none`, no Fresnel, as magg's mirror), a transmissive part as a
//!   `dielectric` with both reflectance and transmittance scaled, several parts as nested
//!   `blendbsdf`s with weights that keep each part's reflectance exactly; opaque parts are
//!   `twosided`, as magg's patches reflect on both faces, except for `sides = 1`
//!   materials, which are Mitsuba's one-sided BSDFs;
//! - emitting materials (`emit`): an `area` emitter on their shape, whose radiance is
//!   `emit` (both one-sided, on the front);
//! - the background as a `constant` emitter when it is not black.
//!
//! Not written: the ambient term (there is no such light in a physically based renderer:
//! render magg with `--set render.ambient=[0,0,0]` to compare) and magg's choices of
//! transport, which the integrator given at render time decides (`deploy/mitsuba-reference.py`).

use magg_core::color::Rgb;
use magg_core::frame::Frame;
use magg_core::scene::{srgb_to_linear, Material, PatchDef, Scene, Texture};
use std::fmt::Write as _;
use std::path::Path;

/// What [`write`] left out, for the user to read.
#[derive(Debug, Default, PartialEq)]
pub struct Notes {
    /// One line per thing the exported scene does not carry.
    pub lines: Vec<String>,
}

/// Writes `scene` as `dir/scene.xml` and `dir/meshes/*.ply`.
pub fn write(scene: &Scene, dir: &Path) -> anyhow::Result<Notes> {
    use anyhow::Context;
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).with_context(|| format!("cannot create {}", meshes.display()))?;
    let mut notes = Notes::default();
    let mut xml = String::new();
    let s = &scene.settings;
    let c = &scene.camera;
    let _ = writeln!(xml, "<?xml version=\"1.0\" encoding=\"utf-8\"?>");
    let _ = writeln!(xml, "<!-- Written by magg-host export --mitsuba from scene {:?}. -->", scene.name);
    let _ = writeln!(xml, "<scene version=\"3.0.0\">");
    let _ = writeln!(xml, "  <default name=\"spp\" value=\"{}\"/>", s.pixel_samples.max(1));
    let _ = writeln!(xml, "  <default name=\"max_depth\" value=\"{}\"/>", s.vrt_depth + 2 + s.diffuse_bounces);
    let _ =
        writeln!(xml, "  <integrator type=\"path\"><integer name=\"max_depth\" value=\"$max_depth\"/></integrator>");
    let _ = writeln!(xml, "  <sensor type=\"perspective\">");
    let _ = writeln!(xml, "    <string name=\"fov_axis\" value=\"y\"/>");
    let _ = writeln!(xml, "    <float name=\"fov\" value=\"{}\"/>", c.fov_y_deg);
    let _ = writeln!(xml, "    <transform name=\"to_world\">");
    let _ = writeln!(
        xml,
        "      <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>",
        vec3(c.eye.to_array()),
        vec3(c.look_at.to_array()),
        vec3(c.up.to_array())
    );
    let _ = writeln!(xml, "    </transform>");
    let _ =
        writeln!(xml, "    <sampler type=\"independent\"><integer name=\"sample_count\" value=\"$spp\"/></sampler>");
    let _ = writeln!(xml, "    <film type=\"hdrfilm\">");
    let _ = writeln!(xml, "      <integer name=\"width\" value=\"{}\"/>", s.width);
    let _ = writeln!(xml, "      <integer name=\"height\" value=\"{}\"/>", s.height);
    let _ = writeln!(xml, "      <string name=\"pixel_format\" value=\"rgb\"/>");
    let _ = writeln!(xml, "      <rfilter type=\"box\"/>");
    let _ = writeln!(xml, "    </film>");
    let _ = writeln!(xml, "  </sensor>");
    for l in &scene.lights {
        match &l.spot {
            None => {
                let _ = writeln!(xml, "  <emitter type=\"point\">");
                let _ = writeln!(xml, "    <point name=\"position\" value=\"{}\"/>", vec3(l.position.to_array()));
            }
            Some(spot) => {
                let target = l.position + spot.direction;
                let _ = writeln!(xml, "  <emitter type=\"spot\">");
                let _ = writeln!(
                    xml,
                    "    <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform>",
                    vec3(l.position.to_array()),
                    vec3(target.to_array()),
                    vec3(any_perpendicular(spot.direction.to_array()))
                );
                let _ = writeln!(xml, "    <float name=\"beam_width\" value=\"{}\"/>", spot.half_angle_deg);
                let _ = writeln!(
                    xml,
                    "    <float name=\"cutoff_angle\" value=\"{}\"/>",
                    spot.half_angle_deg + spot.falloff_deg
                );
                if spot.falloff_deg > 0.0 {
                    notes.lines.push(format!(
                        "{}: the spot's falloff is linear in angle in Mitsuba, a smoothstep in magg",
                        l.loc
                    ));
                }
            }
        }
        let _ = writeln!(xml, "    <rgb name=\"intensity\" value=\"{}\"/>", rgb(l.intensity));
        let _ = writeln!(xml, "  </emitter>");
    }
    if !s.background.is_black() {
        let _ = writeln!(
            xml,
            "  <emitter type=\"constant\"><rgb name=\"radiance\" value=\"{}\"/></emitter>",
            rgb(s.background)
        );
    }
    if !s.ambient.is_black() && s.diffuse_bounces == 0 {
        notes.lines.push(format!(
            "the ambient term ({}) is not exported: render magg with --set render.ambient=[0,0,0] to compare",
            rgb(s.ambient)
        ));
    }
    for (id, m) in scene.materials.iter().enumerate() {
        // One PLY per material, shading (flat or smooth) and texture, in that order.
        let mut groups: std::collections::BTreeMap<(bool, Option<u32>), Vec<&PatchDef>> = Default::default();
        for p in scene.patches.iter().filter(|p| p.material as usize == id) {
            groups.entry((p.normals.is_some(), p.texture.filter(|_| p.uv.is_some()))).or_default().push(p);
        }
        for ((smooth, texture), patches) in groups {
            let tag = match (smooth, texture) {
                (false, None) => String::new(),
                (true, None) => "-smooth".into(),
                (false, Some(t)) => format!("-texture-{t}"),
                (true, Some(t)) => format!("-smooth-texture-{t}"),
            };
            let file = format!("material-{id}{tag}.ply");
            let path = meshes.join(&file);
            std::fs::write(&path, ply(&patches)).with_context(|| format!("cannot write {}", path.display()))?;
            let shading = if smooth { "smooth" } else { "flat" };
            let _ = writeln!(xml, "  <!-- material {:?}: {} triangles, {shading} -->", m.name, patches.len());
            let _ = writeln!(xml, "  <shape type=\"ply\">");
            let _ = writeln!(xml, "    <string name=\"filename\" value=\"meshes/{file}\"/>");
            let _ = writeln!(xml, "    <boolean name=\"face_normals\" value=\"{}\"/>", !smooth);
            let texture = match texture.and_then(|t| scene.textures.get(t as usize).map(|x| (t, x))) {
                Some((t, tex)) => {
                    Some(Bitmap { texture: tex, file: format!("meshes/material-{id}-texture-{t}.exr"), dir })
                }
                None => None,
            };
            bsdf(&mut xml, m, texture.as_ref(), "    ")?;
            if m.is_emitter() {
                // Mitsuba's area emitter radiates from the front, by the winding, as magg's.
                let _ = writeln!(
                    xml,
                    "    <emitter type=\"area\"><rgb name=\"radiance\" value=\"{}\"/></emitter>",
                    rgb(m.emit)
                );
            }
            let _ = writeln!(xml, "  </shape>");
        }
    }
    let _ = writeln!(xml, "</scene>");
    let path = dir.join("scene.xml");
    std::fs::write(&path, xml).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(notes)
}

/// A texture of the diffuse part, written as a linear EXR at `dir/file` (with the
/// material's `Kd`, and the weight a blend gives the part, multiplied in).
struct Bitmap<'a> {
    texture: &'a Texture,
    file: String,
    dir: &'a Path,
}

impl Bitmap<'_> {
    /// Writes the texture times `scale` and returns the XML of Mitsuba's bitmap texture.
    fn write(&self, scale: Rgb) -> anyhow::Result<String> {
        use anyhow::Context;
        let t = self.texture;
        let mut frame = Frame::new(t.width, t.height);
        for (i, texel) in t.texels.iter().enumerate() {
            let lin = Rgb(texel.map(srgb_to_linear));
            frame.set(i as u32 % t.width, i as u32 / t.width, lin.mul(scale));
        }
        let path = self.dir.join(&self.file);
        std::fs::write(&path, crate::images::encode_exr(&frame)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(format!(
            "<texture type=\"bitmap\" name=\"reflectance\"><string name=\"filename\" value=\"{}\"/>\
             <string name=\"filter_type\" value=\"bilinear\"/><string name=\"wrap_mode\" value=\"repeat\"/></texture>",
            self.file
        ))
    }
}

/// The BSDF of `m`: its parts, blended so that each keeps its own reflectance; the
/// diffuse part textured by `texture` when given.
fn bsdf(xml: &mut String, m: &Material, texture: Option<&Bitmap<'_>>, indent: &str) -> anyhow::Result<()> {
    let mut parts: Vec<(f64, Part)> = Vec::new();
    for (part, c) in [(Part::Diffuse, m.diffuse), (Part::Mirror, m.mirror), (Part::Dielectric, m.transmit)] {
        if !c.is_black() {
            parts.push((c.0.iter().sum::<f64>() / 3.0, part));
        }
    }
    if parts.is_empty() {
        let _ = writeln!(xml, "{indent}<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0, 0, 0\"/></bsdf>");
        return Ok(());
    }
    blend(xml, m, texture, &parts, 1.0, indent)
}

/// Writes `parts` as one BSDF whose total weight is `scale` (each part's colour divided
/// by the weight its blend gives it, so the sum stays the material's).
fn blend(
    xml: &mut String,
    m: &Material,
    texture: Option<&Bitmap<'_>>,
    parts: &[(f64, Part)],
    scale: f64,
    indent: &str,
) -> anyhow::Result<()> {
    if let [(_, part)] = parts {
        return part.write(xml, m, texture, scale, indent);
    }
    let (first, rest) = (&parts[0], &parts[1..]);
    let total: f64 = parts.iter().map(|p| p.0).sum();
    // blendbsdf: (1 - weight) * first + weight * rest.
    let weight = (total - first.0) / total;
    let _ = writeln!(xml, "{indent}<bsdf type=\"blendbsdf\">");
    let _ = writeln!(xml, "{indent}  <float name=\"weight\" value=\"{weight}\"/>");
    first.1.write(xml, m, texture, scale * (1.0 - weight), &format!("{indent}  "))?;
    blend(xml, m, texture, rest, scale * weight, &format!("{indent}  "))?;
    let _ = writeln!(xml, "{indent}</bsdf>");
    Ok(())
}

/// One part of a magg material.
#[derive(Clone, Copy)]
enum Part {
    Diffuse,
    Mirror,
    Dielectric,
}

impl Part {
    /// Writes the part, its colour divided by `weight` (the share a blend gives it).
    fn write(
        self,
        xml: &mut String,
        m: &Material,
        texture: Option<&Bitmap<'_>>,
        weight: f64,
        indent: &str,
    ) -> anyhow::Result<()> {
        let scaled = |c: Rgb| rgb(c.scale(1.0 / weight));
        // A one-sided material is Mitsuba's plain (one-sided) BSDF.
        let (open, close) = if m.one_sided { ("", "") } else { ("<bsdf type=\"twosided\">", "</bsdf>") };
        match self {
            Part::Diffuse => {
                let reflectance = match texture {
                    Some(b) => b.write(m.diffuse.scale(1.0 / weight))?,
                    None => format!("<rgb name=\"reflectance\" value=\"{}\"/>", scaled(m.diffuse)),
                };
                let _ = writeln!(xml, "{indent}{open}<bsdf type=\"diffuse\">{reflectance}</bsdf>{close}");
            }
            Part::Mirror => {
                let _ = writeln!(
                    xml,
                    "{indent}{open}<bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/>\
                     <rgb name=\"specular_reflectance\" value=\"{}\"/></bsdf>{close}",
                    scaled(m.mirror)
                );
            }
            Part::Dielectric => {
                let _ = writeln!(
                    xml,
                    "{indent}<bsdf type=\"dielectric\"><float name=\"int_ior\" value=\"{}\"/><float name=\"ext_ior\" \
                     value=\"1\"/><rgb name=\"specular_reflectance\" value=\"{t}\"/><rgb name=\"specular_transmittance\" \
                     value=\"{t}\"/></bsdf>",
                    m.ior,
                    t = scaled(m.transmit)
                );
            }
        }
        Ok(())
    }
}

/// A binary little-endian PLY of the patches as unshared triangles (float32 positions,
/// float32 normals when the patches are smooth and texture coordinates when they are
/// textured: all of them or none).
fn ply(patches: &[&PatchDef]) -> Vec<u8> {
    let normals = patches.first().is_some_and(|p| p.normals.is_some());
    let uv = patches.first().is_some_and(|p| p.texture.is_some() && p.uv.is_some());
    let normal_props = if normals { "property float nx\nproperty float ny\nproperty float nz\n" } else { "" };
    let uv_props = if uv { "property float u\nproperty float v\n" } else { "" };
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by magg-host export\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n{normal_props}{uv_props}element face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        patches.len() * 3,
        patches.len()
    );
    let mut out = header.into_bytes();
    for p in patches {
        for (k, v) in p.vertices.iter().enumerate() {
            let mut put = |c: f64| out.extend_from_slice(&(c as f32).to_le_bytes());
            v.to_array().into_iter().for_each(&mut put);
            if let (true, Some(n)) = (normals, p.normals) {
                n[k].to_array().into_iter().for_each(&mut put);
            }
            // Mitsuba's bitmaps put v = 0 at the image's top row; magg's v runs up.
            if let (true, Some(t)) = (uv, p.uv) {
                put(t[k].x);
                put(1.0 - t[k].y);
            }
        }
    }
    for i in 0..patches.len() {
        out.push(3);
        for k in 0..3 {
            out.extend_from_slice(&((3 * i + k) as i32).to_le_bytes());
        }
    }
    out
}

fn vec3(v: [f64; 3]) -> String {
    format!("{}, {}, {}", v[0], v[1], v[2])
}

fn rgb(c: Rgb) -> String {
    format!("{}, {}, {}", c.0[0], c.0[1], c.0[2])
}

/// A unit vector not parallel to `d` (the up vector of a spot light's frame).
fn any_perpendicular(d: [f64; 3]) -> [f64; 3] {
    if d[1].abs() < 0.9 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests;
