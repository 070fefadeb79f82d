//! The TOML scene front end: [`parse_scene_str`] turns a scene file into a validated
//! [`Scene`].
//!
//! The file is first deserialized into raw tables whose every value remembers its byte
//! span (`toml::Spanned`), then checked field by field, so that each error names the
//! file, the line and the dotted field (`material[2].diffuse`, 0-based entry index).
//! `[[mesh]]` entries pull in model files (OBJ with MTL, PLY, glTF) through the caller's
//! `read` callback (the core does no I/O). The format is documented field by field in `scenes/README.md`.

use std::collections::HashMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::error::SceneError;
use super::field::field_at;
use super::load::stream_mesh;
use super::mesh::{MaterialTable, MeshEntry, MeshShading, ReadFile, Transform};
use super::model::{
    Accel, Camera, CameraPath, DirectLight, Exposure, GridSpec, Light, Material, PatchDef, RenderSettings, Scene,
    SourceLoc, Spot, MAX_BOUNCE_RAYS, MAX_COORDINATE, MAX_GATHER_RAYS, MAX_RADIOMETRIC, MAX_REFINE_LEVELS,
};
use super::shape::{check_quad, is_degenerate};
use crate::color::Rgb;
use crate::math::Normalized;
use glam::DVec3;

mod patches;
use patches::PatchBuilder;

/// A spanned list of numbers (a point, a direction or a colour before checking).
type SVec = Spanned<Vec<f64>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    camera: Option<Spanned<RawCamera>>,
    camera_path: Option<Spanned<super::path::RawCameraPath>>,
    render: Option<RawRender>,
    #[serde(default)]
    light: Vec<RawLight>,
    #[serde(default)]
    material: Vec<RawMaterial>,
    #[serde(default)]
    triangle: Vec<RawPolygon>,
    #[serde(default)]
    quad: Vec<RawPolygon>,
    #[serde(default)]
    mesh: Vec<Spanned<RawMesh>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCamera {
    eye: SVec,
    look_at: SVec,
    up: Option<SVec>,
    fov: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRender {
    width: Option<Spanned<i64>>,
    height: Option<Spanned<i64>>,
    pixel_samples: Option<Spanned<i64>>,
    element_size: Option<Spanned<f64>>,
    light_rays: Option<Spanned<i64>>,
    bounce_rays: Option<Spanned<i64>>,
    gather_rays: Option<Spanned<i64>>,
    lrt_depth: Option<Spanned<i64>>,
    vrt_depth: Option<Spanned<i64>>,
    diffuse_bounces: Option<Spanned<i64>>,
    ambient: Option<SVec>,
    accel: Option<Spanned<String>>,
    direct: Option<Spanned<String>>,
    faces: Option<Spanned<String>>,
    refine: Option<Spanned<i64>>,
    refine_contrast: Option<Spanned<f64>>,
    grid: Option<Spanned<toml::Value>>,
    seed: Option<Spanned<i64>>,
    exposure: Option<Spanned<toml::Value>>,
    background: Option<SVec>,
    max_elements: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    position: SVec,
    intensity: SVec,
    direction: Option<SVec>,
    cone: Option<Spanned<f64>>,
    falloff: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    name: Spanned<String>,
    diffuse: Option<SVec>,
    mirror: Option<SVec>,
    transmit: Option<SVec>,
    ior: Option<Spanned<f64>>,
    sides: Option<Spanned<i64>>,
    emit: Option<SVec>,
}

/// A `[[triangle]]` or `[[quad]]` entry.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolygon {
    vertices: Spanned<Vec<Vec<f64>>>,
    material: Spanned<String>,
    subdivisions: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMesh {
    file: Option<Spanned<String>>,
    /// The older name of `file`, kept as an alias.
    obj: Option<Spanned<String>>,
    material: Option<Spanned<String>>,
    translate: Option<SVec>,
    rotate: Option<SVec>,
    scale: Option<Spanned<toml::Value>>,
    subdivisions: Option<Spanned<i64>>,
    /// Shade with the file's vertex normals (default true).
    normals: Option<Spanned<bool>>,
    /// Make normals from the faces, for faces the file gives none: degrees.
    crease_angle: Option<Spanned<f64>>,
}

/// Subdivision counts allowed in `subdivisions =`.
const MAX_SUBDIVISIONS: i64 = 4096;
/// Largest subspace count of an explicit grid.
const MAX_GRID_CELLS: i64 = 16_777_216;

/// Parses and validates a TOML scene.
///
/// `file_label` names the file in errors and becomes [`Scene::name`]; mesh paths are
/// `base_dir.join(file)`, and `read` loads them as bytes (and the files they name: MTL
/// files, glTF buffers). Every problem is a
/// [`SceneError`] naming the file, line and field; no input makes this panic.
///
/// A `[camera_path]` is checked but dropped: [`parse_scene_with_path`] returns it.
pub fn parse_scene_str(file_label: &str, text: &str, base_dir: &Path, read: ReadFile<'_>) -> Result<Scene, SceneError> {
    parse_scene_with_path(file_label, text, base_dir, read).map(|(scene, _)| scene)
}

/// Parses and validates a TOML scene and its optional `[camera_path]` (as
/// [`parse_scene_str`]). With a path and no `[camera]`, the scene's camera is the
/// path's first frame.
pub fn parse_scene_with_path(
    file_label: &str,
    text: &str,
    base_dir: &Path,
    read: ReadFile<'_>,
) -> Result<(Scene, Option<CameraPath>), SceneError> {
    let cx = Ctx::new(file_label, text);
    let raw: RawScene = toml::from_str(text).map_err(|e| cx.toml_error(&e))?;

    let path = raw.camera_path.as_ref().map(|p| cx.camera_path(p)).transpose()?;
    let camera = match (&raw.camera, &path) {
        (Some(c), _) => cx.camera(c, "camera")?,
        (None, Some(p)) => p.camera_at(0),
        (None, None) => return Err(cx.whole_file("camera", "the scene has no [camera] table")),
    };
    let settings = match &raw.render {
        Some(r) => cx.render(r)?,
        None => RenderSettings::default(),
    };
    let lights = raw.light.iter().enumerate().map(|(i, l)| cx.light(i, l)).collect::<Result<Vec<_>, _>>()?;

    let mut materials = Vec::with_capacity(raw.material.len());
    let mut by_name: HashMap<String, u32> = HashMap::new();
    for (i, m) in raw.material.iter().enumerate() {
        let mat = cx.material(i, m)?;
        if let Some(&first) = by_name.get(&mat.name) {
            let first_line = materials.get(first as usize).map_or(0, |f: &Material| f.loc.line);
            return Err(cx.err(
                &m.name,
                format!("material[{i}].name"),
                format!("material '{}' is already defined at line {first_line}", mat.name),
            ));
        }
        by_name.insert(mat.name.clone(), materials.len() as u32);
        materials.push(mat);
    }

    let mut builder = PatchBuilder {
        cx: &cx,
        materials: MaterialTable { list: materials, toml: by_name, ..MaterialTable::new() },
        patches: Vec::new(),
    };
    // Patches in file order, whatever their kind.
    let mut entries: Vec<(usize, Entry<'_>)> = Vec::new();
    entries.extend(raw.triangle.iter().enumerate().map(|(i, t)| (t.vertices.span().start, Entry::Triangle(i, t))));
    entries.extend(raw.quad.iter().enumerate().map(|(i, q)| (q.vertices.span().start, Entry::Quad(i, q))));
    entries.extend(raw.mesh.iter().enumerate().map(|(i, m)| (m.span().start, Entry::Mesh(i, m))));
    entries.sort_by_key(|(start, _)| *start);
    for (_, entry) in entries {
        match entry {
            Entry::Triangle(i, t) => builder.triangle(i, t)?,
            Entry::Quad(i, q) => builder.quad(i, q)?,
            Entry::Mesh(i, m) => builder.mesh(i, m, base_dir, read)?,
        }
    }
    if builder.patches.is_empty() {
        return Err(cx.whole_file("triangle", "the scene has no [[triangle]], [[quad]] or [[mesh]]"));
    }
    let PatchBuilder { materials, patches, .. } = builder;
    let emitting = patches.iter().any(|p| materials.list.get(p.material as usize).is_some_and(Material::is_emitter));
    if lights.is_empty() && !emitting {
        return Err(cx.whole_file(
            "light",
            "the scene has no [[light]] and no patch of a material with `emit`: nothing would be lit",
        ));
    }
    let textures = materials.textures;
    Ok((
        Scene { name: file_label.to_string(), camera, settings, lights, materials: materials.list, patches, textures },
        path,
    ))
}

enum Entry<'a> {
    Triangle(usize, &'a RawPolygon),
    Quad(usize, &'a RawPolygon),
    Mesh(usize, &'a Spanned<RawMesh>),
}

/// The file being parsed: turns byte spans into lines and builds errors.
pub(super) struct Ctx<'a> {
    file: &'a str,
    text: &'a str,
    /// Byte offset of the start of every line.
    line_starts: Vec<usize>,
}

const RGB_NAMES: [&str; 3] = ["red", "green", "blue"];
const XYZ_NAMES: [&str; 3] = ["x", "y", "z"];

impl<'a> Ctx<'a> {
    fn new(file: &'a str, text: &'a str) -> Self {
        let mut line_starts = vec![0];
        line_starts.extend(text.bytes().enumerate().filter(|(_, b)| *b == b'\n').map(|(i, _)| i + 1));
        Ctx { file, text, line_starts }
    }

    /// 1-based line of a byte offset.
    fn line(&self, offset: usize) -> u32 {
        self.line_starts.partition_point(|&s| s <= offset).max(1) as u32
    }

    pub(super) fn loc<T>(&self, s: &Spanned<T>) -> SourceLoc {
        SourceLoc { file: self.file.into(), line: self.line(s.span().start) }
    }

    pub(super) fn err<T>(&self, s: &Spanned<T>, field: impl Into<String>, msg: impl Into<String>) -> SceneError {
        SceneError::new(self.loc(s), field, msg)
    }

    fn whole_file(&self, field: &str, msg: &str) -> SceneError {
        SceneError::new(SourceLoc { file: self.file.into(), line: 0 }, field, msg)
    }

    /// Maps a TOML syntax or type error to a [`SceneError`] at its line, guessing the
    /// field from the text around it.
    fn toml_error(&self, e: &toml::de::Error) -> SceneError {
        let offset = e.span().map_or(0, |s| s.start.min(self.text.len()));
        let line = if e.span().is_some() { self.line(offset) } else { 0 };
        let message = e.message().trim().replace('\n', " ");
        SceneError::new(SourceLoc { file: self.file.into(), line }, field_at(self.text, offset), message)
    }

    fn finite(&self, v: &Spanned<f64>, field: &str) -> Result<f64, SceneError> {
        let x = *v.get_ref();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(v, field, format!("{x} is not a finite number")))
        }
    }

    /// A float in `[lo, hi]` (`lo_open` excludes `lo`).
    fn float_in(&self, v: &Spanned<f64>, field: &str, lo: f64, lo_open: bool, hi: f64) -> Result<f64, SceneError> {
        let x = self.finite(v, field)?;
        if (lo_open && x <= lo) || x < lo || x > hi {
            let open = if lo_open { "(" } else { "[" };
            return Err(self.err(v, field, format!("{x} is out of range {open}{lo}, {hi}]")));
        }
        Ok(x)
    }

    pub(super) fn int_in(&self, v: &Spanned<i64>, field: &str, lo: i64, hi: i64) -> Result<i64, SceneError> {
        let x = *v.get_ref();
        if x < lo || x > hi {
            return Err(self.err(v, field, format!("{x} is out of range {lo}..={hi}")));
        }
        Ok(x)
    }

    /// Three finite numbers; `names` label the components in errors.
    fn triple(&self, v: &SVec, field: &str, names: [&str; 3]) -> Result<[f64; 3], SceneError> {
        let a = v.get_ref();
        let [x, y, z] = a.as_slice() else {
            return Err(self.err(v, field, format!("expected 3 numbers, found {}", a.len())));
        };
        let out = [*x, *y, *z];
        for (c, name) in out.iter().zip(names) {
            if !c.is_finite() {
                return Err(self.err(v, field, format!("{name} = {c} is not a finite number")));
            }
        }
        Ok(out)
    }

    /// A position or direction: three numbers within [`MAX_COORDINATE`].
    fn vec3(&self, v: &SVec, field: &str) -> Result<DVec3, SceneError> {
        let c = self.triple(v, field, XYZ_NAMES)?;
        for (x, name) in c.iter().zip(XYZ_NAMES) {
            if x.abs() > MAX_COORDINATE {
                return Err(self.err(
                    v,
                    field,
                    format!("{name} = {x:e} is out of range [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}]"),
                ));
            }
        }
        Ok(DVec3::from_array(c))
    }

    /// A colour whose channels lie in `[0, hi]`.
    fn rgb(&self, v: &SVec, field: &str, hi: f64) -> Result<Rgb, SceneError> {
        let c = self.triple(v, field, RGB_NAMES)?;
        for (x, name) in c.iter().zip(RGB_NAMES) {
            if *x < 0.0 || *x > hi {
                let range = if hi < 1e6 { format!("[0, {hi}]") } else { format!("[0, {hi:e}]") };
                return Err(self.err(v, field, format!("{name} = {x} is out of range {range}")));
            }
        }
        Ok(Rgb(c))
    }

    /// A camera table; `prefix` names it in errors (`camera`, `camera_path.keys[2]`).
    pub(super) fn camera(&self, c: &Spanned<RawCamera>, prefix: &str) -> Result<Camera, SceneError> {
        let raw = c.get_ref();
        let f = |name: &str| format!("{prefix}.{name}");
        let eye = self.vec3(&raw.eye, &f("eye"))?;
        let look_at = self.vec3(&raw.look_at, &f("look_at"))?;
        let up = match &raw.up {
            Some(u) => self.vec3(u, &f("up"))?,
            None => DVec3::new(0.0, 1.0, 0.0),
        };
        let fov_y_deg = self.float_in(&raw.fov, &f("fov"), 0.0, true, 180.0)?;
        if fov_y_deg >= 180.0 {
            return Err(self.err(&raw.fov, f("fov"), format!("{fov_y_deg} is out of range (0, 180)")));
        }
        let view = look_at - eye;
        if view.length() <= 1e-12 * (1.0 + eye.abs().max_element()) {
            return Err(self.err(&raw.look_at, f("look_at"), "look_at is the eye position: no view direction"));
        }
        if view.normalized().cross(up.normalized()).length() < 1e-9 {
            let at = raw.up.as_ref().map_or_else(|| self.loc(c), |u| self.loc(u));
            return Err(SceneError::new(at, f("up"), "up is zero or parallel to the view direction"));
        }
        Ok(Camera { eye, look_at, up, fov_y_deg })
    }

    fn render(&self, r: &RawRender) -> Result<RenderSettings, SceneError> {
        let mut s = RenderSettings::default();
        let u32_in = |v: &Option<Spanned<i64>>, field: &str, lo: i64, hi: i64, out: &mut u32| {
            if let Some(v) = v {
                *out = self.int_in(v, field, lo, hi)? as u32;
            }
            Ok::<(), SceneError>(())
        };
        u32_in(&r.width, "render.width", 1, 16384, &mut s.width)?;
        u32_in(&r.height, "render.height", 1, 16384, &mut s.height)?;
        u32_in(&r.pixel_samples, "render.pixel_samples", 1, 4096, &mut s.pixel_samples)?;
        u32_in(&r.light_rays, "render.light_rays", 1, 1_000_000, &mut s.light_rays)?;
        u32_in(&r.bounce_rays, "render.bounce_rays", 1, MAX_BOUNCE_RAYS as i64, &mut s.bounce_rays)?;
        u32_in(&r.gather_rays, "render.gather_rays", 0, MAX_GATHER_RAYS as i64, &mut s.gather_rays)?;
        u32_in(&r.lrt_depth, "render.lrt_depth", 0, 32, &mut s.lrt_depth)?;
        u32_in(&r.vrt_depth, "render.vrt_depth", 0, 32, &mut s.vrt_depth)?;
        u32_in(&r.diffuse_bounces, "render.diffuse_bounces", 0, 16, &mut s.diffuse_bounces)?;
        u32_in(&r.refine, "render.refine", 0, MAX_REFINE_LEVELS as i64, &mut s.refine)?;
        if let Some(v) = &r.refine_contrast {
            s.refine_contrast = self.float_in(v, "render.refine_contrast", 0.0, true, 1.0)?;
        }
        if let Some(v) = &r.element_size {
            s.element_size = self.float_in(v, "render.element_size", 0.0, true, f64::MAX)?;
        }
        if let Some(v) = &r.ambient {
            s.ambient = self.rgb(v, "render.ambient", MAX_RADIOMETRIC)?;
        }
        if let Some(v) = &r.background {
            s.background = self.rgb(v, "render.background", MAX_RADIOMETRIC)?;
        }
        if let Some(v) = &r.seed {
            s.seed = self.int_in(v, "render.seed", 0, i64::MAX)? as u64;
        }
        if let Some(v) = &r.max_elements {
            s.max_elements = self.int_in(v, "render.max_elements", 1, i64::MAX)? as u64;
        }
        if let Some(v) = &r.accel {
            s.accel = Accel::parse(v.get_ref()).ok_or_else(|| {
                self.err(v, "render.accel", format!("expected \"bvh\" or \"grid\", found {:?}", v.get_ref()))
            })?;
        }
        if let Some(v) = &r.direct {
            s.direct = DirectLight::parse(v.get_ref()).ok_or_else(|| {
                self.err(v, "render.direct", format!("expected \"auto\", \"vrt\" or \"lrt\", found {:?}", v.get_ref()))
            })?;
        }
        if let Some(v) = &r.faces {
            s.shared_faces = match v.get_ref().as_str() {
                "apart" => false,
                "shared" => true,
                other => {
                    return Err(self.err(
                        v,
                        "render.faces",
                        format!("expected \"apart\" or \"shared\", found {other:?}"),
                    ))
                }
            };
        }
        if let Some(v) = &r.grid {
            s.grid = self.grid(v)?;
        }
        if let Some(v) = &r.exposure {
            s.exposure = self.exposure(v)?;
        }
        Ok(s)
    }

    fn grid(&self, v: &Spanned<toml::Value>) -> Result<GridSpec, SceneError> {
        const FIELD: &str = "render.grid";
        let bad = || self.err(v, FIELD, format!("expected \"auto\" or [nx, ny, nz], found {}", v.get_ref()));
        match v.get_ref() {
            toml::Value::String(s) if s == "auto" => Ok(GridSpec::Auto),
            toml::Value::Array(a) if a.len() == 3 => {
                let mut n = [0u32; 3];
                for (k, item) in a.iter().enumerate() {
                    let x = item.as_integer().ok_or_else(bad)?;
                    if !(1..=512).contains(&x) {
                        let msg = format!("{} = {x} is out of range 1..=512", XYZ_NAMES[k]);
                        return Err(self.err(v, FIELD, msg));
                    }
                    n[k] = x as u32;
                }
                let cells = n.iter().map(|&c| i64::from(c)).product::<i64>();
                if cells > MAX_GRID_CELLS {
                    let msg = format!("{cells} subspaces is more than the limit {MAX_GRID_CELLS}");
                    return Err(self.err(v, FIELD, msg));
                }
                Ok(GridSpec::Fixed(n))
            }
            _ => Err(bad()),
        }
    }

    fn exposure(&self, v: &Spanned<toml::Value>) -> Result<Exposure, SceneError> {
        const FIELD: &str = "render.exposure";
        let x = match v.get_ref() {
            toml::Value::String(s) if s == "auto" => return Ok(Exposure::Auto),
            toml::Value::Integer(i) => *i as f64,
            toml::Value::Float(f) => *f,
            other => return Err(self.err(v, FIELD, format!("expected \"auto\" or a number, found {other}"))),
        };
        if !x.is_finite() || x <= 0.0 {
            return Err(self.err(v, FIELD, format!("{x} is not a positive finite number")));
        }
        if !(1.0 / MAX_RADIOMETRIC..=MAX_RADIOMETRIC).contains(&x) {
            return Err(self.err(
                v,
                FIELD,
                format!("{x} is out of range [{:e}, {MAX_RADIOMETRIC:e}]", 1.0 / MAX_RADIOMETRIC),
            ));
        }
        Ok(Exposure::Fixed(x))
    }

    fn light(&self, i: usize, l: &RawLight) -> Result<Light, SceneError> {
        let f = |name: &str| format!("light[{i}].{name}");
        let position = self.vec3(&l.position, &f("position"))?;
        let intensity = self.rgb(&l.intensity, &f("intensity"), MAX_RADIOMETRIC)?;
        if intensity.is_black() {
            return Err(self.err(&l.intensity, f("intensity"), "intensity is zero in every channel"));
        }
        let spot = match (&l.direction, &l.cone) {
            (None, None) => {
                if let Some(fo) = &l.falloff {
                    return Err(self.err(fo, f("falloff"), "falloff needs a spot cone: add `cone` and `direction`"));
                }
                None
            }
            (Some(d), None) => {
                return Err(self.err(d, f("direction"), "a spot light needs `cone` (half-angle, degrees)"))
            }
            (None, Some(c)) => return Err(self.err(c, f("cone"), "a spot light needs `direction`")),
            (Some(d), Some(c)) => {
                let dir = self.vec3(d, &f("direction"))?;
                if dir.length() == 0.0 || !dir.normalized().is_finite() {
                    return Err(self.err(d, f("direction"), "direction is the zero vector"));
                }
                let half_angle_deg = self.float_in(c, &f("cone"), 0.0, true, 180.0)?;
                let falloff_deg = match &l.falloff {
                    Some(fo) => {
                        let x = self.float_in(fo, &f("falloff"), 0.0, false, 180.0)?;
                        if half_angle_deg + x > 180.0 {
                            let msg = format!("cone {half_angle_deg} + falloff {x} is more than 180 degrees");
                            return Err(self.err(fo, f("falloff"), msg));
                        }
                        x
                    }
                    None => 0.0,
                };
                Some(Spot { direction: dir.normalized(), half_angle_deg, falloff_deg })
            }
        };
        Ok(Light { position, intensity, spot, loc: self.loc(&l.position) })
    }

    fn material(&self, i: usize, m: &RawMaterial) -> Result<Material, SceneError> {
        let f = |name: &str| format!("material[{i}].{name}");
        let name = m.name.get_ref().trim().to_string();
        if name.is_empty() {
            return Err(self.err(&m.name, f("name"), "material name is empty"));
        }
        let part = |v: &Option<SVec>, field: &str| match v {
            Some(v) => self.rgb(v, &f(field), 1.0),
            None => Ok(Rgb::BLACK),
        };
        let diffuse = part(&m.diffuse, "diffuse")?;
        let mirror = part(&m.mirror, "mirror")?;
        let transmit = part(&m.transmit, "transmit")?;
        let ior = match &m.ior {
            Some(v) => self.float_in(v, &f("ior"), 1.0, false, 4.0)?,
            None => 1.5,
        };
        let sum = diffuse.add(mirror).add(transmit);
        for (k, s) in sum.0.iter().enumerate() {
            if *s > 1.0 + 1e-9 {
                let msg = format!(
                    "diffuse + mirror + transmit = {s} in the {} channel of material '{name}' is more than 1",
                    RGB_NAMES[k]
                );
                return Err(self.err(&m.name, format!("material[{i}]"), msg));
            }
        }
        let one_sided = match &m.sides {
            None => false,
            Some(v) => {
                let n = self.int_in(v, &f("sides"), 1, 2)?;
                if n == 1 && !transmit.is_black() {
                    return Err(self.err(
                        v,
                        f("sides"),
                        "a transmissive (glass) material has two sides: sides = 1 needs transmit = 0",
                    ));
                }
                n == 1
            }
        };
        let emit = match &m.emit {
            Some(v) => self.rgb(v, &f("emit"), MAX_RADIOMETRIC)?,
            None => Rgb::BLACK,
        };
        Ok(Material { name, diffuse, mirror, transmit, ior, one_sided, emit, loc: self.loc(&m.name) })
    }
}

#[cfg(test)]
mod tests;
