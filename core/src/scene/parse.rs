//! The TOML scene front end: [`parse_scene_str`] turns a scene file into a validated
//! [`Scene`].
//!
//! The file is first deserialized into raw tables whose every value remembers its byte
//! span (`toml::Spanned`), then checked field by field, so that each error names the
//! file, the line and the dotted field (`material[2].diffuse`, 0-based entry index).
//! `[[mesh]]` entries pull in OBJ/MTL files through the caller's `read` callback (the
//! core does no I/O). The format is documented field by field in `scenes/README.md`.

use std::collections::HashMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::error::SceneError;
use super::model::{
    Accel, Camera, CameraPath, Exposure, GridSpec, Light, Material, PatchDef, RenderSettings, Scene, SourceLoc, Spot,
};
use super::obj::{self, MaterialTable, MeshEntry, Transform};
use crate::color::Rgb;
use crate::math::Normalized;
use glam::DVec3;

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
    mesh: Vec<RawMesh>,
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
    lrt_depth: Option<Spanned<i64>>,
    vrt_depth: Option<Spanned<i64>>,
    diffuse_bounces: Option<Spanned<i64>>,
    ambient: Option<SVec>,
    accel: Option<Spanned<String>>,
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
    obj: Spanned<String>,
    material: Option<Spanned<String>>,
    translate: Option<SVec>,
    rotate: Option<SVec>,
    scale: Option<Spanned<toml::Value>>,
    subdivisions: Option<Spanned<i64>>,
}

/// Subdivision counts allowed in `subdivisions =`.
const MAX_SUBDIVISIONS: i64 = 4096;
/// Largest subspace count of an explicit grid.
const MAX_GRID_CELLS: i64 = 16_777_216;
/// Relative tolerance of the zero-area test: `|cross| <= EPS_AREA * longest_edge^2`.
const EPS_AREA: f64 = 1e-12;
/// Relative tolerance of the quad planarity test (distance / longest edge).
const EPS_PLANAR: f64 = 1e-6;

/// Parses and validates a TOML scene.
///
/// `file_label` names the file in errors and becomes [`Scene::name`]; OBJ paths are
/// `base_dir.join(obj)`, and `read` loads them (and their MTL files). Every problem is a
/// [`SceneError`] naming the file, line and field; no input makes this panic.
///
/// A `[camera_path]` is checked but dropped: [`parse_scene_with_path`] returns it.
pub fn parse_scene_str(
    file_label: &str,
    text: &str,
    base_dir: &Path,
    read: &dyn Fn(&Path) -> std::io::Result<String>,
) -> Result<Scene, SceneError> {
    parse_scene_with_path(file_label, text, base_dir, read).map(|(scene, _)| scene)
}

/// Parses and validates a TOML scene and its optional `[camera_path]` (as
/// [`parse_scene_str`]). With a path and no `[camera]`, the scene's camera is the
/// path's first frame.
pub fn parse_scene_with_path(
    file_label: &str,
    text: &str,
    base_dir: &Path,
    read: &dyn Fn(&Path) -> std::io::Result<String>,
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
    if lights.is_empty() {
        return Err(cx.whole_file("light", "the scene has no [[light]]: nothing would be lit"));
    }

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
        materials: MaterialTable { list: materials, toml: by_name, from_mtl: HashMap::new() },
        patches: Vec::new(),
    };
    // Patches in file order, whatever their kind.
    let mut entries: Vec<(usize, Entry<'_>)> = Vec::new();
    entries.extend(raw.triangle.iter().enumerate().map(|(i, t)| (t.vertices.span().start, Entry::Triangle(i, t))));
    entries.extend(raw.quad.iter().enumerate().map(|(i, q)| (q.vertices.span().start, Entry::Quad(i, q))));
    entries.extend(raw.mesh.iter().enumerate().map(|(i, m)| (m.obj.span().start, Entry::Mesh(i, m))));
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
    Ok((Scene { name: file_label.to_string(), camera, settings, lights, materials: materials.list, patches }, path))
}

enum Entry<'a> {
    Triangle(usize, &'a RawPolygon),
    Quad(usize, &'a RawPolygon),
    Mesh(usize, &'a RawMesh),
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
        SourceLoc { file: self.file.to_string(), line: self.line(s.span().start) }
    }

    pub(super) fn err<T>(&self, s: &Spanned<T>, field: impl Into<String>, msg: impl Into<String>) -> SceneError {
        SceneError::new(self.loc(s), field, msg)
    }

    fn whole_file(&self, field: &str, msg: &str) -> SceneError {
        SceneError::new(SourceLoc { file: self.file.to_string(), line: 0 }, field, msg)
    }

    /// Maps a TOML syntax or type error to a [`SceneError`] at its line, guessing the
    /// field from the text around it.
    fn toml_error(&self, e: &toml::de::Error) -> SceneError {
        let offset = e.span().map_or(0, |s| s.start.min(self.text.len()));
        let line = if e.span().is_some() { self.line(offset) } else { 0 };
        let message = e.message().trim().replace('\n', " ");
        SceneError::new(SourceLoc { file: self.file.to_string(), line }, field_at(self.text, offset), message)
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

    fn vec3(&self, v: &SVec, field: &str) -> Result<DVec3, SceneError> {
        self.triple(v, field, XYZ_NAMES).map(DVec3::from_array)
    }

    /// A colour whose channels lie in `[0, hi]`.
    fn rgb(&self, v: &SVec, field: &str, hi: f64) -> Result<Rgb, SceneError> {
        let c = self.triple(v, field, RGB_NAMES)?;
        for (x, name) in c.iter().zip(RGB_NAMES) {
            if *x < 0.0 || *x > hi {
                let range = if hi.is_finite() { format!("[0, {hi}]") } else { ">= 0".to_string() };
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
        u32_in(&r.lrt_depth, "render.lrt_depth", 0, 32, &mut s.lrt_depth)?;
        u32_in(&r.vrt_depth, "render.vrt_depth", 0, 32, &mut s.vrt_depth)?;
        u32_in(&r.diffuse_bounces, "render.diffuse_bounces", 0, 16, &mut s.diffuse_bounces)?;
        if let Some(v) = &r.element_size {
            s.element_size = self.float_in(v, "render.element_size", 0.0, true, f64::MAX)?;
        }
        if let Some(v) = &r.ambient {
            s.ambient = self.rgb(v, "render.ambient", f64::INFINITY)?;
        }
        if let Some(v) = &r.background {
            s.background = self.rgb(v, "render.background", f64::INFINITY)?;
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
        Ok(Exposure::Fixed(x))
    }

    fn light(&self, i: usize, l: &RawLight) -> Result<Light, SceneError> {
        let f = |name: &str| format!("light[{i}].{name}");
        let position = self.vec3(&l.position, &f("position"))?;
        let intensity = self.rgb(&l.intensity, &f("intensity"), f64::INFINITY)?;
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
        Ok(Material { name, diffuse, mirror, transmit, ior, loc: self.loc(&m.name) })
    }
}

/// Builds triangle patches and registers MTL materials as meshes are read.
struct PatchBuilder<'c, 'a> {
    cx: &'c Ctx<'a>,
    materials: MaterialTable,
    patches: Vec<PatchDef>,
}

impl PatchBuilder<'_, '_> {
    fn material_ref(&self, m: &Spanned<String>, field: &str) -> Result<u32, SceneError> {
        self.materials
            .toml
            .get(m.get_ref())
            .copied()
            .ok_or_else(|| self.cx.err(m, field, format!("material '{}' is not defined", m.get_ref())))
    }

    fn subdivisions(&self, v: &Option<Spanned<i64>>, field: &str) -> Result<Option<u32>, SceneError> {
        v.as_ref().map(|v| self.cx.int_in(v, field, 1, MAX_SUBDIVISIONS).map(|n| n as u32)).transpose()
    }

    /// The corners of a `[[triangle]]`/`[[quad]]`, exactly `N` points.
    fn corners<const N: usize>(&self, p: &RawPolygon, field: &str) -> Result<[DVec3; N], SceneError> {
        let pts = p.vertices.get_ref();
        if pts.len() != N {
            return Err(self.cx.err(&p.vertices, field, format!("expected {N} vertices, found {}", pts.len())));
        }
        let mut out = [DVec3::ZERO; N];
        for (k, (o, v)) in out.iter_mut().zip(pts).enumerate() {
            let [x, y, z] = v.as_slice() else {
                return Err(self.cx.err(
                    &p.vertices,
                    field,
                    format!("vertex {k} has {} coordinates, expected 3", v.len()),
                ));
            };
            *o = DVec3::new(*x, *y, *z);
            if !o.is_finite() {
                return Err(self.cx.err(&p.vertices, field, format!("vertex {k} = {:?} is not finite", v)));
            }
        }
        Ok(out)
    }

    fn triangle(&mut self, i: usize, t: &RawPolygon) -> Result<(), SceneError> {
        let field = format!("triangle[{i}].vertices");
        let v: [DVec3; 3] = self.corners(t, &field)?;
        if is_degenerate(&v) {
            return Err(self.cx.err(&t.vertices, field, format!("triangle[{i}] is degenerate (zero area)")));
        }
        let material = self.material_ref(&t.material, &format!("triangle[{i}].material"))?;
        let subdivisions = self.subdivisions(&t.subdivisions, &format!("triangle[{i}].subdivisions"))?;
        self.patches.push(PatchDef {
            vertices: v,
            material,
            subdivisions,
            size_hint: None,
            loc: self.cx.loc(&t.vertices),
        });
        Ok(())
    }

    fn quad(&mut self, i: usize, q: &RawPolygon) -> Result<(), SceneError> {
        let field = format!("quad[{i}].vertices");
        let v: [DVec3; 4] = self.corners(q, &field)?;
        check_quad(&v).map_err(|why| self.cx.err(&q.vertices, &field, format!("quad[{i}] {why}")))?;
        let material = self.material_ref(&q.material, &format!("quad[{i}].material"))?;
        let subdivisions = self.subdivisions(&q.subdivisions, &format!("quad[{i}].subdivisions"))?;
        // Without a fixed n, both halves are subdivided from the longest edge of the quad
        // including the shared diagonal (at preprocessing, with the element size then in
        // force), so that they subdivide identically and weld without seams.
        let longest = [v[1] - v[0], v[2] - v[1], v[3] - v[2], v[0] - v[3], v[2] - v[0]]
            .iter()
            .map(|e| e.length())
            .fold(0.0, f64::max);
        let size_hint = Some(longest);
        let loc = self.cx.loc(&q.vertices);
        for tri in [[v[0], v[1], v[2]], [v[0], v[2], v[3]]] {
            self.patches.push(PatchDef { vertices: tri, material, subdivisions, size_hint, loc: loc.clone() });
        }
        Ok(())
    }

    fn mesh(
        &mut self,
        i: usize,
        m: &RawMesh,
        base_dir: &Path,
        read: &dyn Fn(&Path) -> std::io::Result<String>,
    ) -> Result<(), SceneError> {
        let cx = self.cx;
        let f = |name: &str| format!("mesh[{i}].{name}");
        let translate = m.translate.as_ref().map(|v| cx.vec3(v, &f("translate"))).transpose()?.unwrap_or(DVec3::ZERO);
        let rotate = m.rotate.as_ref().map(|v| cx.vec3(v, &f("rotate"))).transpose()?.unwrap_or(DVec3::ZERO);
        let scale = match &m.scale {
            Some(v) => self.scale(v, &f("scale"))?,
            None => DVec3::new(1.0, 1.0, 1.0),
        };
        let subdivisions = self.subdivisions(&m.subdivisions, &f("subdivisions"))?;
        let material = m.material.as_ref().map(|s| self.material_ref(s, &f("material"))).transpose()?;
        let entry = MeshEntry {
            obj: m.obj.get_ref(),
            at: cx.loc(&m.obj),
            field: format!("mesh[{i}]"),
            transform: Transform::new(scale, rotate, translate),
            material,
        };
        for (vertices, material) in obj::load_mesh(&entry, base_dir, read, &mut self.materials)? {
            self.patches.push(PatchDef { vertices, material, subdivisions, size_hint: None, loc: entry.at.clone() });
        }
        Ok(())
    }

    fn scale(&self, v: &Spanned<toml::Value>, field: &str) -> Result<DVec3, SceneError> {
        let num = |x: &toml::Value| match x {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(f) => Some(*f),
            _ => None,
        };
        let s = match v.get_ref() {
            toml::Value::Array(a) if a.len() == 3 => {
                let c: Vec<f64> = a.iter().filter_map(num).collect();
                match c.as_slice() {
                    [x, y, z] => DVec3::new(*x, *y, *z),
                    _ => return Err(self.cx.err(v, field, "expected a number or [sx, sy, sz]")),
                }
            }
            other => match num(other) {
                Some(x) => DVec3::new(x, x, x),
                None => return Err(self.cx.err(v, field, format!("expected a number or [sx, sy, sz], found {other}"))),
            },
        };
        for (c, name) in s.to_array().iter().zip(XYZ_NAMES) {
            if !c.is_finite() || *c == 0.0 {
                return Err(self.cx.err(v, field, format!("{name} = {c} is not a finite non-zero number")));
            }
        }
        Ok(s)
    }
}

/// True when a triangle has (numerically) zero area: `|cross| <= 1e-12 * longest_edge^2`.
pub(super) fn is_degenerate(v: &[DVec3; 3]) -> bool {
    let (e0, e1, e2) = (v[1] - v[0], v[2] - v[1], v[0] - v[2]);
    let longest2 = e0.length_squared().max(e1.length_squared()).max(e2.length_squared());
    let area2 = e0.cross(v[2] - v[0]).length();
    area2.is_nan() || area2 <= EPS_AREA * longest2
}

/// Checks that a quad is planar (within 1e-6 of its longest edge) and strictly convex with
/// its vertices in order; the error says why not.
fn check_quad(v: &[DVec3; 4]) -> Result<(), String> {
    let longest =
        (0..4).flat_map(|a| (a + 1..4).map(move |b| (a, b))).map(|(a, b)| (v[b] - v[a]).length()).fold(0.0, f64::max);
    let n = (v[2] - v[0]).cross(v[3] - v[1]);
    let area2 = n.length();
    if area2.is_nan() || area2 <= EPS_AREA * longest * longest {
        return Err("is degenerate (zero area)".to_string());
    }
    let n = n.normalized();
    let centre = (v[0] + v[1] + v[2] + v[3]) / 4.0;
    for (k, p) in v.iter().enumerate() {
        let off = (*p - centre).dot(n).abs();
        if off > EPS_PLANAR * longest {
            return Err(format!(
                "is not planar: vertex {k} is {off:e} off the plane (tolerance {:e})",
                EPS_PLANAR * longest
            ));
        }
    }
    for k in 0..4 {
        let (a, b, c) = (v[k], v[(k + 1) % 4], v[(k + 2) % 4]);
        let turn = (b - a).cross(c - b).dot(n);
        if turn.is_nan() || turn <= EPS_AREA * longest * longest {
            return Err(format!("is not convex at vertex {} (or its vertices are out of order)", (k + 1) % 4));
        }
    }
    Ok(())
}

/// Guesses the dotted field at a byte offset from the text: the last `[table]` or
/// `[[array]]` header before it (with the entry's 0-based index) and the last `key =`.
fn field_at(text: &str, offset: usize) -> String {
    let mut table = String::new();
    let mut key: Option<&str> = None;
    let mut counts: HashMap<&str, usize> = HashMap::new();
    let mut start = 0;
    for line in text.split_inclusive('\n') {
        if start > offset {
            break;
        }
        start += line.len();
        let t = line.split('#').next().unwrap_or("").trim();
        if let Some(name) = t.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")).map(str::trim) {
            if is_table_name(name) {
                let n = counts.entry(name).or_insert(0);
                table = format!("{name}[{n}]");
                *n += 1;
                key = None;
            }
        } else if let Some(name) = t.strip_prefix('[').and_then(|r| r.strip_suffix(']')).map(str::trim) {
            if is_table_name(name) {
                table = name.to_string();
                key = None;
            }
        } else if let Some((k, _)) = t.split_once('=') {
            let k = k.trim();
            if is_table_name(k) {
                key = Some(k);
            }
        }
    }
    match (table.is_empty(), key) {
        (true, None) => "toml".to_string(),
        (true, Some(k)) => k.to_string(),
        (false, None) => table,
        (false, Some(k)) => format!("{table}.{k}"),
    }
}

fn is_table_name(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.')
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use std::path::PathBuf;

    /// A small valid scene; line numbers below refer to it.
    const MINI: &str = "\
[camera]
eye = [0, 1, 3]
look_at = [0, 1, 0]
fov = 40

[[light]]
position = [0, 1.9, 0]
intensity = [1, 1, 1]

[[material]]
name = \"white\"
diffuse = [0.7, 0.7, 0.7]

[[triangle]]
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
material = \"white\"
";

    fn parse_with(text: &str, files: &[(&str, &str)]) -> Result<Scene, SceneError> {
        let files: HashMap<PathBuf, String> = files.iter().map(|(p, t)| (PathBuf::from(p), t.to_string())).collect();
        let read = move |p: &Path| {
            files.get(p).cloned().ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "not found"))
        };
        parse_scene_str("t.toml", text, Path::new("base"), &read)
    }

    fn parse(text: &str) -> Result<Scene, SceneError> {
        parse_with(text, &[])
    }

    fn err(text: &str) -> String {
        match parse(text) {
            Ok(_) => panic!("scene unexpectedly parsed:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn minimal_scene_parses_with_defaults() {
        let s = parse(MINI).unwrap();
        assert_eq!(s.name, "t.toml");
        assert_eq!(s.camera.up, DVec3::new(0.0, 1.0, 0.0));
        assert_eq!(s.settings, RenderSettings::default());
        assert_eq!(s.patches.len(), 1);
        assert_eq!(s.patches[0].loc, SourceLoc { file: "t.toml".into(), line: 15 });
        assert_eq!(s.lights[0].loc.line, 7);
        assert_eq!(s.materials[0].loc.line, 11);
        assert_eq!(s.materials[0].ior, 1.5);
    }

    #[test]
    fn render_table_sets_every_field() {
        let text = format!(
            "{MINI}\n[render]\nwidth = 640\nheight = 480\npixel_samples = 2\nelement_size = 0.25\nlight_rays = 16\n\
             lrt_depth = 1\nvrt_depth = 2\ndiffuse_bounces = 3\nambient = [0.1, 0.2, 0.3]\ngrid = [8, 7, 6]\n\
             seed = 42\nexposure = 2\nbackground = [0, 0, 1]\nmax_elements = 1000\n"
        );
        let s = parse(&text).unwrap().settings;
        assert_eq!((s.width, s.height, s.pixel_samples, s.light_rays), (640, 480, 2, 16));
        assert_eq!((s.lrt_depth, s.vrt_depth, s.diffuse_bounces, s.seed, s.max_elements), (1, 2, 3, 42, 1000));
        assert_eq!(s.element_size, 0.25);
        assert_eq!(s.ambient, Rgb::new(0.1, 0.2, 0.3));
        assert_eq!(s.background, Rgb::new(0.0, 0.0, 1.0));
        assert_eq!(s.grid, GridSpec::Fixed([8, 7, 6]));
        assert_eq!(s.exposure, Exposure::Fixed(2.0));
        let auto = parse(&format!("{MINI}[render]\ngrid = \"auto\"\nexposure = \"auto\"\n")).unwrap().settings;
        assert_eq!((auto.grid, auto.exposure), (GridSpec::Auto, Exposure::Auto));
    }

    #[test]
    fn toml_syntax_error_names_file_and_line() {
        let e = err(&format!("{MINI}[render]\nwidth = = 3\n"));
        assert!(e.starts_with("t.toml:18: "), "{e}");
    }

    #[test]
    fn undefined_material_names_the_reference() {
        let e = err(&MINI.replace("material = \"white\"", "material = \"gold\""));
        assert_eq!(e, "t.toml:16: triangle[0].material: material 'gold' is not defined");
    }

    #[test]
    fn nan_and_infinity_are_refused() {
        let e = err(&format!("{MINI}[render]\nelement_size = nan\n"));
        assert!(e.starts_with("t.toml:18: render.element_size: NaN is not a finite number"), "{e}");
        let e = err(&MINI.replace("eye = [0, 1, 3]", "eye = [0, inf, 3]"));
        assert!(e.starts_with("t.toml:2: camera.eye: y = inf"), "{e}");
    }

    #[test]
    fn negative_intensity_is_refused() {
        let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [-1, 1, 1]"));
        assert_eq!(e, "t.toml:8: light[0].intensity: red = -1 is out of range >= 0");
        let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [0, 0, 0]"));
        assert!(e.starts_with("t.toml:8: light[0].intensity"), "{e}");
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let e = err(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "colour = [0.7, 0.7, 0.7]"));
        assert!(e.starts_with("t.toml:12: material[0].colour: unknown field `colour`"), "{e}");
        let e = err(&format!("{MINI}[render]\nwidht = 3\n"));
        assert!(e.starts_with("t.toml:18: render.widht: unknown field `widht`"), "{e}");
    }

    #[test]
    fn accel_is_bvh_unless_the_scene_asks_for_the_grid() {
        assert_eq!(parse(MINI).unwrap().settings.accel, Accel::Bvh);
        let grid = parse(&format!("{MINI}[render]\naccel = \"grid\"\n")).unwrap().settings;
        assert_eq!(grid.accel, Accel::Grid);
        let e = err(&format!("{MINI}[render]\naccel = \"kd-tree\"\n"));
        assert_eq!(e, "t.toml:18: render.accel: expected \"bvh\" or \"grid\", found \"kd-tree\"");
        let e = err(&format!("{MINI}[render]\naccel = 2\n"));
        assert!(e.starts_with("t.toml:18: render.accel: "), "{e}");
    }

    #[test]
    fn wrong_types_name_the_line() {
        let e = err(&format!("{MINI}[render]\nwidth = \"big\"\n"));
        assert!(e.starts_with("t.toml:18: render.width: "), "{e}");
        let e = err(&format!("{MINI}[render]\ngrid = [8, 7]\n"));
        assert!(e.starts_with("t.toml:18: render.grid: "), "{e}");
        let e = err(&MINI.replace("eye = [0, 1, 3]", "eye = [0, 1]"));
        assert_eq!(e, "t.toml:2: camera.eye: expected 3 numbers, found 2");
    }

    #[test]
    fn out_of_range_values_are_refused() {
        for (line, field) in [
            ("width = 0", "render.width"),
            ("height = 20000", "render.height"),
            ("pixel_samples = 5000", "render.pixel_samples"),
            ("element_size = -0.1", "render.element_size"),
            ("light_rays = 0", "render.light_rays"),
            ("lrt_depth = 33", "render.lrt_depth"),
            ("diffuse_bounces = -1", "render.diffuse_bounces"),
            ("ambient = [0, -0.1, 0]", "render.ambient"),
            ("grid = [512, 512, 512]", "render.grid"),
            ("grid = [0, 1, 1]", "render.grid"),
            ("exposure = -1", "render.exposure"),
            ("exposure = \"bright\"", "render.exposure"),
            ("seed = -1", "render.seed"),
        ] {
            let e = err(&format!("{MINI}[render]\n{line}\n"));
            assert!(e.starts_with(&format!("t.toml:18: {field}: ")), "{line}: {e}");
        }
        let e = err(&MINI.replace("fov = 40", "fov = 180"));
        assert!(e.starts_with("t.toml:4: camera.fov: 180 is out of range"), "{e}");
        let e = err(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\nior = 0.5"));
        assert!(e.starts_with("t.toml:13: material[0].ior"), "{e}");
    }

    #[test]
    fn energy_conservation_names_the_channel() {
        let e = err(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\nmirror = [0.2, 0.5, 0.2]"));
        assert!(e.starts_with("t.toml:11: material[0]: "), "{e}");
        assert!(e.contains("green channel"), "{e}");
        // Within the 1e-9 tolerance.
        parse(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\ntransmit = [0.3, 0.3, 0.3]"))
            .unwrap();
    }

    #[test]
    fn duplicate_material_is_refused() {
        let text = MINI.replace("[[triangle]]", "[[material]]\nname = \"white\"\n\n[[triangle]]");
        let e = err(&text);
        assert_eq!(e, "t.toml:15: material[1].name: material 'white' is already defined at line 11");
    }

    #[test]
    fn degenerate_triangle_is_refused() {
        let e = err(&MINI.replace("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "[[0, 0, 0], [1, 1, 1], [2, 2, 2]]"));
        assert!(e.starts_with("t.toml:15: triangle[0].vertices: triangle[0] is degenerate"), "{e}");
        let e = err(&MINI.replace("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "[[0, 0, 0], [1, 0, 0]]"));
        assert!(e.contains("expected 3 vertices, found 2"), "{e}");
    }

    #[test]
    fn missing_tables_are_refused() {
        assert!(err(&MINI.replace("[camera]\neye = [0, 1, 3]\nlook_at = [0, 1, 0]\nfov = 40\n", "")).contains("camera"));
        let no_light = MINI.replace("[[light]]\nposition = [0, 1.9, 0]\nintensity = [1, 1, 1]\n", "");
        assert!(err(&no_light).contains("no [[light]]"));
        let no_patch =
            MINI.replace("[[triangle]]\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\nmaterial = \"white\"\n", "");
        assert!(err(&no_patch).contains("no [[triangle]]"));
        let e = err(&MINI
            .replace("look_at = [0, 1, 0]", "look_at = [0, 1, 0]\nup = [0, 2, 0]")
            .replace("eye = [0, 1, 3]", "eye = [0, 5, 0]"));
        assert!(e.contains("camera.up"), "{e}");
    }

    #[test]
    fn spot_light_is_normalized_and_checked() {
        let spot = "intensity = [1, 1, 1]\ndirection = [0, -2, 0]\ncone = 30\nfalloff = 5";
        let s = parse(&MINI.replace("intensity = [1, 1, 1]", spot)).unwrap();
        let sp = s.lights[0].spot.clone().unwrap();
        assert_eq!(sp.direction, DVec3::new(0.0, -1.0, 0.0));
        assert_eq!((sp.half_angle_deg, sp.falloff_deg), (30.0, 5.0));
        let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [1, 1, 1]\ncone = 30"));
        assert!(e.starts_with("t.toml:9: light[0].cone"), "{e}");
        let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [1, 1, 1]\ndirection = [0, 0, 0]\ncone = 30"));
        assert!(e.starts_with("t.toml:9: light[0].direction"), "{e}");
        let e = err(&MINI.replace(
            "intensity = [1, 1, 1]",
            "intensity = [1, 1, 1]\ndirection = [0, -1, 0]\ncone = 170\nfalloff = 20",
        ));
        assert!(e.starts_with("t.toml:11: light[0].falloff"), "{e}");
    }

    const QUAD: &str = "[[quad]]\nvertices = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]\nmaterial = \"white\"\n";

    #[test]
    fn quad_becomes_two_triangles_with_equal_subdivisions() {
        let s = parse(&format!("{MINI}{QUAD}[render]\nelement_size = 0.5\n")).unwrap();
        assert_eq!(s.patches.len(), 3);
        let (a, b) = (&s.patches[1], &s.patches[2]);
        let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        assert_eq!(a.vertices, [v(0.0, 0.0), v(2.0, 0.0), v(2.0, 1.0)]);
        assert_eq!(b.vertices, [v(0.0, 0.0), v(2.0, 1.0), v(0.0, 1.0)]);
        // Both halves carry the quad's longest edge incl. the diagonal: sqrt(5).
        assert_eq!((a.subdivisions, b.subdivisions), (None, None));
        assert_eq!(a.size_hint, b.size_hint);
        assert!((a.size_hint.unwrap() - 5f64.sqrt()).abs() < 1e-12);
        assert_eq!(a.loc.line, 18);
        // Winding kept: normal +z.
        for p in [a, b] {
            assert!((p.vertices[1] - p.vertices[0]).cross(p.vertices[2] - p.vertices[0]).z > 0.0);
        }
        let fixed = parse(&format!("{MINI}{QUAD}subdivisions = 7\n")).unwrap();
        assert_eq!(fixed.patches[2].subdivisions, Some(7));
    }

    #[test]
    fn bad_quads_are_refused() {
        let bent = QUAD.replace("[2, 1, 0]", "[2, 1, 0.01]");
        assert!(err(&format!("{MINI}{bent}")).contains("quad[0] is not planar"));
        let concave = QUAD.replace("[2, 1, 0]", "[0.5, 0.2, 0]");
        assert!(err(&format!("{MINI}{concave}")).contains("quad[0] is not convex"));
        let crossed = QUAD.replace("[2, 1, 0], [0, 1, 0]", "[0, 1, 0], [2, 1, 0]");
        assert!(err(&format!("{MINI}{crossed}")).contains("quad[0]"));
        let e = err(&format!("{MINI}{QUAD}subdivisions = 0\n"));
        assert!(e.starts_with("t.toml:20: quad[0].subdivisions: 0 is out of range 1..=4096"), "{e}");
    }

    const CUBE_OBJ: &str =
        "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl red\nf 1 2 3 4\nusemtl white\nf -4 -2 -1\n";
    const CUBE_MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\n";

    fn mesh_scene(extra: &str) -> String {
        format!("{MINI}\n[[mesh]]\nobj = \"m/cube.obj\"\n{extra}")
    }

    #[test]
    fn mesh_materials_come_from_mtl_then_toml() {
        let s = parse_with(&mesh_scene(""), &[("base/m/cube.obj", CUBE_OBJ), ("base/m/cube.mtl", CUBE_MTL)]).unwrap();
        assert_eq!(s.patches.len(), 1 + 3);
        let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["white", "m/cube.obj:red"]);
        assert_eq!(s.materials[1].diffuse, Rgb::new(0.8, 0.1, 0.1));
        assert_eq!(s.materials[1].loc, SourceLoc { file: "base/m/cube.mtl".into(), line: 1 });
        assert_eq!([s.patches[1].material, s.patches[2].material, s.patches[3].material], [1, 1, 0]);
        assert_eq!(s.patches[3].loc, SourceLoc { file: "t.toml".into(), line: 19 });
        // An explicit material overrides the MTL, which is then not even read.
        let s = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", CUBE_OBJ)]).unwrap();
        assert!(s.patches.iter().all(|p| p.material == 0));
        assert_eq!(s.materials.len(), 1);
    }

    #[test]
    fn missing_obj_names_scene_line_and_path() {
        let e = err(&mesh_scene(""));
        assert!(e.starts_with("t.toml:19: mesh[0].obj: cannot read OBJ file 'base/m/cube.obj'"), "{e}");
        let e = parse_with(&mesh_scene(""), &[("base/m/cube.obj", CUBE_OBJ)]).unwrap_err().to_string();
        assert!(e.starts_with("base/m/cube.obj:1: mtllib: cannot read MTL file 'base/m/cube.mtl'"), "{e}");
    }

    #[test]
    fn obj_errors_name_the_obj_file_and_line() {
        let bad = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
        let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", bad)]).unwrap_err();
        assert_eq!(e.loc, SourceLoc { file: "base/m/cube.obj".into(), line: 4 });
        let no_mtl = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let e = parse_with(&mesh_scene(""), &[("base/m/cube.obj", no_mtl)]).unwrap_err().to_string();
        assert!(e.starts_with("t.toml:19: mesh[0].material: base/m/cube.obj:4: face has no material"), "{e}");
        let unknown = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl gold\nf 1 2 3\n";
        let e = parse_with(&mesh_scene(""), &[("base/m/cube.obj", unknown)]).unwrap_err().to_string();
        assert!(e.contains("base/m/cube.obj:5: material 'gold' is not defined"), "{e}");
    }

    #[test]
    fn mesh_transform_is_scale_rotate_translate() {
        let obj = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n";
        let text = mesh_scene("material = \"white\"\nscale = 2\nrotate = [0, 0, 90]\ntranslate = [10, 0, 0]\n");
        let s = parse_with(&text, &[("base/m/cube.obj", obj)]).unwrap();
        let v = s.patches[1].vertices;
        // (1,0,0) -> scale (2,0,0) -> 90 deg about z (0,2,0) -> translate (10,2,0).
        assert!((v[0] - DVec3::new(10.0, 2.0, 0.0)).length() < 1e-12, "{:?}", v[0]);
        assert!((v[2] - DVec3::new(10.0, 0.0, 2.0)).length() < 1e-12, "{:?}", v[2]);
    }

    #[test]
    fn negative_scale_keeps_normals_outward() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let normal = |extra: &str| {
            let s = parse_with(&mesh_scene(&format!("material = \"white\"\n{extra}")), &[("base/m/cube.obj", obj)])
                .unwrap();
            let v = s.patches[1].vertices;
            (v[1] - v[0]).cross(v[2] - v[0]).normalized()
        };
        assert_eq!(normal(""), DVec3::new(0.0, 0.0, 1.0));
        // Mirroring x alone maps the +z normal to +z; without the re-flip it would be -z.
        assert_eq!(normal("scale = [-1, 1, 1]"), DVec3::new(0.0, 0.0, 1.0));
        // Mirroring z mirrors the surface too: its front now faces -z, like a box's top face
        // becoming its bottom face (normal = M^-T n, as for a closed mesh staying outward).
        assert_eq!(normal("scale = [1, 1, -3]"), DVec3::new(0.0, 0.0, -1.0));
        let e = err(&mesh_scene("material = \"white\"\nscale = [1, 0, 1]\n"));
        assert!(e.contains("mesh[0].scale"), "{e}");
    }

    #[test]
    fn degenerate_obj_faces_are_skipped() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n";
        let s =
            parse_with(&mesh_scene("material = \"white\"\nsubdivisions = 3\n"), &[("base/m/cube.obj", obj)]).unwrap();
        assert_eq!(s.patches.len(), 2);
        assert_eq!(s.patches[1].subdivisions, Some(3));
        let flat = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
        let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", flat)]).unwrap_err();
        assert!(e.message.contains("no faces of non-zero area"), "{e}");
    }

    #[test]
    fn patches_keep_file_order_across_kinds() {
        let text = MINI.replace("[[triangle]]", &format!("{QUAD}\n[[triangle]]"));
        let s = parse(&text).unwrap();
        assert_eq!(s.patches.iter().map(|p| p.loc.line).collect::<Vec<_>>(), [15, 15, 19]);
    }

    #[test]
    fn mangled_input_never_panics() {
        // Every single-character deletion and a few insertions: an error or a scene, never a panic.
        let text = format!("{MINI}{QUAD}[render]\ngrid = [2, 2, 2]\nexposure = 1.5\n");
        let chars: Vec<char> = text.chars().collect();
        for k in 0..chars.len() {
            let mut deleted = chars.clone();
            deleted.remove(k);
            let _ = parse(&deleted.iter().collect::<String>());
            for c in ['[', '"', '=', '-', '\n', '9'] {
                let mut inserted = chars.clone();
                inserted.insert(k, c);
                let _ = parse(&inserted.iter().collect::<String>());
            }
        }
    }
}
