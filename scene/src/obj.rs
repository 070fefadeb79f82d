//! Wavefront OBJ and MTL import for `[[mesh]]` entries.
//!
//! Only what a triangle-patch renderer needs is read:
//! - OBJ: `v` (x y z; an optional w or vertex colour after them is ignored), `f` with
//!   `v`, `v/vt`, `v//vn` or `v/vt/vn` corners and negative (relative) indices, polygons
//!   fan-triangulated as (0,1,2), (0,2,3), ...; `usemtl`, `mtllib`. `o`, `g`, `s`, `vt`,
//!   `vn`, `vp`, `l`, `p` and the other display statements are ignored; free-form
//!   geometry (`cstype`, `curv`, `surf`, ...) and unknown statements are errors.
//! - MTL: `newmtl`, `Kd` (diffuse), `Ks` (ideal mirror), `Tf`, `d`, `Tr` (transmission),
//!   `Ni` (index of refraction), `Ke` (emission: the material's `emit`, an area light);
//!   every other statement is ignored. See [`parse_mtl`] for
//!   how these become a valid material.
//!
//! Errors name the OBJ or MTL file and its line. Nothing here does I/O: the MTL files
//! are read through the caller's `read` callback.

use std::path::{Path, PathBuf};

use super::error::SceneError;
use super::mesh::{shown, utf8, MaterialTable, MeshEntry, ModelTriangle, ReadFile};
use super::model::{Material, SourceLoc, MAX_RADIOMETRIC};
use crate::color::Rgb;
use glam::{DVec2, DVec3};

/// Parses a mesh's OBJ file `bytes` (read from `obj_path`, named `label`) and its MTL
/// files (read through `read`), and hands its triangles in the model's space with their
/// material indices to `visit`, a chunk of the file at a time, in file order.
///
/// A `usemtl` name is looked up first in the OBJ's own MTL files, whose materials are added
/// to `materials` (once, in order of first use) as `objfile:mtlname` (e.g.
/// `meshes/sphere.obj:glass`), then among the `[[material]]` tables by plain name.
///
/// The `mtllib` and `usemtl` statements are found first (a quick pass that parses only
/// their lines), so that faces have their materials as they are read. Errors come in the
/// order of a reader that parses the whole file before it looks at materials: any error of
/// the OBJ's text first, then the MTL files', then a face without a material. The
/// triangles of the chunks before an error have been handed on by then.
pub(super) fn stream(
    entry: &MeshEntry<'_>,
    obj_path: &Path,
    obj_label: &str,
    bytes: &[u8],
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
    visit: &mut dyn FnMut(Vec<ModelTriangle>),
) -> Result<(), SceneError> {
    let text = utf8(obj_label, "obj", bytes)?;
    // An error found before the text is all parsed waits: a parse error would come first.
    let mut pending: Option<SceneError> = None;
    let usemtl = if entry.material.is_none() {
        let (mtllibs, names) = statements::material_statements(text);
        usemtl_materials(entry, &mtllibs, &names, obj_path, obj_label, read, materials).unwrap_or_else(|e| {
            pending = Some(e);
            Vec::new()
        })
    } else {
        Vec::new()
    };
    chunked::stream(obj_label, text, chunked::DEFAULT_CHUNK_BYTES, &mut |mesh, faces| {
        if pending.is_some() {
            return;
        }
        let mut out = Vec::with_capacity(faces.len());
        for face in faces {
            match triangle(entry, obj_label, mesh, face, &usemtl) {
                Ok(t) => out.push(t),
                Err(e) => {
                    pending = Some(e);
                    return;
                }
            }
        }
        visit(out);
    })?;
    pending.map_or(Ok(()), Err)
}

/// The material and texture of each `usemtl` name (the material `None` where neither the
/// MTL files nor a `[[material]]` define it: an error at its first face).
fn usemtl_materials(
    entry: &MeshEntry<'_>,
    mtllibs: &[MtlLib],
    names: &[String],
    obj_path: &Path,
    obj_label: &str,
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
) -> Result<Vec<(Option<u32>, Option<u32>)>, SceneError> {
    let mtl = load_mtllibs(mtllibs, obj_path, obj_label, read)?;
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        out.push(match mtl.iter().find(|mm| mm.material.name == *name) {
            Some(mm) => {
                let id = materials.add_file_material(entry, &mm.material).map_err(|m| entry.file_err(m))?;
                let texture = match &mm.map_kd {
                    Some((path, line)) => Some(materials.texture(path, read).map_err(|m| {
                        SceneError::new(SourceLoc { file: mm.label.as_str().into(), line: *line }, "map_Kd", m)
                    })?),
                    None => None,
                };
                (Some(id), texture)
            }
            None => (materials.toml.get(name).copied(), None),
        });
    }
    Ok(out)
}

/// The triangle of `face` with its material, or why it has none.
fn triangle(
    entry: &MeshEntry<'_>,
    obj_label: &str,
    mesh: &ObjMesh,
    face: &ObjFace,
    usemtl: &[(Option<u32>, Option<u32>)],
) -> Result<ModelTriangle, SceneError> {
    let of = |u: u32| usemtl.get(u as usize).copied().unwrap_or((None, None));
    let material = match (entry.material, face.usemtl) {
        (Some(id), _) => id,
        (None, Some(u)) => match of(u).0 {
            Some(id) => id,
            None => {
                let name = mesh.usemtl_names.get(u as usize).map_or("", String::as_str);
                let msg = format!(
                    "{obj_label}:{}: material '{name}' is not defined (neither in the OBJ's MTL files nor a [[material]])",
                    face.line
                );
                return Err(entry.file_err(msg));
            }
        },
        (None, None) => return Err(entry.no_material(&format!("{obj_label}:{}", face.line))),
    };
    let mut v = [DVec3::ZERO; 3];
    for (o, &k) in v.iter_mut().zip(&face.corners) {
        // parse_obj checked every index; stay safe anyway.
        *o = mesh.positions.get(k as usize).copied().ok_or_else(|| entry.file_err("face index out of range".into()))?;
    }
    let normals = face.normals.and_then(|n| {
        let [a, b, c] = n.map(|k| mesh.normals.get(k as usize).copied());
        Some([a?, b?, c?])
    });
    let uv = face.uvs.and_then(|t| {
        let [a, b, c] = t.map(|k| mesh.uvs.get(k as usize).copied());
        Some([a?, b?, c?])
    });
    let texture = face.usemtl.and_then(|u| of(u).1).filter(|_| uv.is_some());
    Ok(ModelTriangle { v, material, normals, uv, texture })
}

/// Reads and parses every `mtllib` of an OBJ, relative to the OBJ's directory; a name
/// defined in two of them is an error.
fn load_mtllibs(
    mtllibs: &[MtlLib],
    obj_path: &Path,
    obj_label: &str,
    read: ReadFile<'_>,
) -> Result<Vec<MtlMaterial>, SceneError> {
    let dir = obj_path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let mut out: Vec<MtlMaterial> = Vec::new();
    for lib in mtllibs {
        let path = dir.join(&lib.file);
        let label = path.display().to_string();
        let bytes = read(&path).map_err(|e| {
            let at = SourceLoc { file: obj_label.into(), line: lib.line };
            SceneError::new(at, "mtllib", format!("cannot read MTL file '{label}': {e}"))
        })?;
        for (mm, map) in parse_mtl_maps(&label, utf8(&label, "mtl", &bytes)?)? {
            if let Some(first) = out.iter().find(|o| o.material.name == mm.name) {
                let msg = format!("material '{}' is already defined at {}", mm.name, first.material.loc);
                return Err(SceneError::new(mm.loc.clone(), "newmtl", msg));
            }
            // A texture is named relative to its MTL file.
            let map_kd =
                map.map(|m| (path.parent().map_or_else(PathBuf::new, Path::to_path_buf).join(&m.file), m.line));
            out.push(MtlMaterial { material: mm, map_kd, label: label.clone() });
        }
    }
    Ok(out)
}

/// A material of an OBJ's MTL files, with the path of its `map_Kd` texture and that
/// statement's line, and the MTL file's label.
struct MtlMaterial {
    material: Material,
    map_kd: Option<(PathBuf, u32)>,
    label: String,
}

/// An OBJ file's geometry: positions and triangles (after fan triangulation).
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct ObjMesh {
    /// `v` positions, in file order.
    pub positions: Vec<DVec3>,
    /// `vn` normals, in file order.
    pub normals: Vec<DVec3>,
    /// `vt` texture coordinates, in file order.
    pub uvs: Vec<DVec2>,
    /// Triangles, in file order.
    pub faces: Vec<ObjFace>,
    /// `mtllib` files, in file order.
    pub mtllibs: Vec<MtlLib>,
    /// Distinct `usemtl` names, in order of first use.
    pub usemtl_names: Vec<String>,
}

/// One triangle of an OBJ face: 44 bytes, no heap (its line, not its text, says where
/// it is; messages are made from it when needed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ObjFace {
    /// Indices into [`ObjMesh::positions`] (checked in range).
    pub corners: [u32; 3],
    /// Indices into [`ObjMesh::uvs`] (checked in range), when every corner names one.
    pub uvs: Option<[u32; 3]>,
    /// Indices into [`ObjMesh::normals`] (checked in range), when every corner names one.
    pub normals: Option<[u32; 3]>,
    /// Index into [`ObjMesh::usemtl_names`] of the `usemtl` in force, if any.
    pub usemtl: Option<u32>,
    /// 1-based line of the `f` statement.
    pub line: u32,
}

/// An `mtllib` file name and the line that named it.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MtlLib {
    /// File name, relative to the OBJ file's directory.
    pub file: String,
    /// 1-based line of the `mtllib` statement.
    pub line: u32,
}

/// OBJ statements that do not describe triangle surfaces and are skipped.
pub(super) const OBJ_IGNORED: &[&str] = &[
    "o",
    "g",
    "s",
    "vp",
    "l",
    "p",
    "mg",
    "usemap",
    "maplib",
    "shadow_obj",
    "trace_obj",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "call",
    "csh",
];
/// OBJ free-form statements, which are refused rather than silently dropped.
pub(super) const OBJ_FREEFORM: &[&str] =
    &["cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con"];

/// Parses an OBJ file; `label` names it in errors. It is read in chunks on every core
/// ([`chunked`]).
#[cfg(test)]
pub(super) fn parse_obj(label: &str, text: &str) -> Result<ObjMesh, SceneError> {
    chunked::parse(label, text, chunked::DEFAULT_CHUNK_BYTES)
}

/// A 1-based (or negative, relative) OBJ index among `count` entries defined so far, as
/// a 0-based index.
pub(super) fn resolve_index(i: i64, count: usize, what: &str, plural: &str) -> Result<usize, String> {
    let count_i = i64::try_from(count).unwrap_or(i64::MAX);
    let index = match i {
        0 => return Err(format!("{what} index 0 is not valid (OBJ indices start at 1)")),
        i if i > 0 => i - 1,
        i => count_i.saturating_add(i),
    };
    if index < 0 || index >= count_i {
        return Err(format!("{what} index {i} is out of range: {count} {plural} defined so far"));
    }
    usize::try_from(index).map_err(|_| format!("{what} index {i} is out of range"))
}

/// A finite number, or why not.
pub(super) fn parse_number(tok: &str) -> Result<f64, String> {
    match tok.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(x) => Err(format!("{x} is not a finite number")),
        Err(_) => Err(format!("{} is not a number", shown(tok))),
    }
}

/// The rest of a statement after its keyword, trimmed (names may contain spaces).
pub(super) fn rest_after_keyword<'t>(content: &'t str, keyword: &str) -> &'t str {
    content.strip_prefix(keyword).unwrap_or("").trim()
}

/// The statements of one `newmtl` block, before they are made valid.
#[derive(Default)]
struct MtlPending {
    name: String,
    line: u32,
    kd: Option<Rgb>,
    ks: Option<Rgb>,
    tf: Option<Rgb>,
    d: Option<f64>,
    tr: Option<f64>,
    ni: Option<f64>,
    map_kd: Option<MapKd>,
    ke: Option<Rgb>,
}

impl MtlPending {
    /// Makes the material valid with a fixed rule (no warnings, same result every time):
    /// 1. `diffuse = Kd`, `mirror = Ks` (0 when absent).
    /// 2. Opacity is `d`, else `1 - Tr`. With an opacity, `transmit = (1 - opacity) * Tf`
    ///    (`Tf` defaulting to white); without one, `transmit = Tf` (0 when absent). So an
    ///    exporter's `Tf 1 1 1` beside `d 1` stays opaque.
    /// 3. Every channel of every part is clamped to `[0, 1]`; where a channel's
    ///    `diffuse + mirror + transmit` is still above 1, the three are divided by that sum
    ///    (keeping their ratio).
    /// 4. `ior = Ni` clamped to `[1, 4]`, 1.5 when absent.
    /// 5. `emit = Ke` (radiance, W m^-2 sr^-1) clamped to `[0, MAX_RADIOMETRIC]`, black
    ///    when absent.
    fn finish(self, label: &str) -> Material {
        let clamp = |c: Rgb| Rgb(c.0.map(|x| x.clamp(0.0, 1.0)));
        let opacity = self.d.or(self.tr.map(|t| 1.0 - t)).map(|o| o.clamp(0.0, 1.0));
        let transmit = match (opacity, self.tf) {
            (Some(o), tf) => clamp(tf.unwrap_or(Rgb::splat(1.0))).scale(1.0 - o),
            (None, Some(tf)) => tf,
            (None, None) => Rgb::BLACK,
        };
        let mut diffuse = clamp(self.kd.unwrap_or(Rgb::BLACK));
        let mut mirror = clamp(self.ks.unwrap_or(Rgb::BLACK));
        let mut transmit = clamp(transmit);
        for k in 0..3 {
            let sum = diffuse.0[k] + mirror.0[k] + transmit.0[k];
            if sum > 1.0 {
                diffuse.0[k] /= sum;
                mirror.0[k] /= sum;
                transmit.0[k] /= sum;
            }
        }
        Material {
            name: self.name,
            diffuse,
            mirror,
            transmit,
            ior: self.ni.map_or(1.5, |n| n.clamp(1.0, 4.0)),
            one_sided: false,
            emit: Rgb(self.ke.unwrap_or(Rgb::BLACK).0.map(|x| x.clamp(0.0, MAX_RADIOMETRIC))),
            loc: SourceLoc { file: label.into(), line: self.line },
        }
    }
}

/// Parses an MTL file; `label` names it in errors. Unknown statements (`Ka`, `Ns`,
/// `illum`, texture maps, ...) are ignored; a name defined twice is an error.
#[cfg(test)]
pub(super) fn parse_mtl(label: &str, text: &str) -> Result<Vec<Material>, SceneError> {
    Ok(parse_mtl_maps(label, text)?.into_iter().map(|(m, _)| m).collect())
}

/// A `map_Kd` statement: the texture file (relative to the MTL's folder) and its line.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MapKd {
    /// The file name, the statement's last token (options before it are ignored).
    pub file: String,
    /// 1-based line of the statement.
    pub line: u32,
}

/// [`parse_mtl`], each material with its `map_Kd` if it has one.
pub(super) fn parse_mtl_maps(label: &str, text: &str) -> Result<Vec<(Material, Option<MapKd>)>, SceneError> {
    let mut done: Vec<(Material, Option<MapKd>)> = Vec::new();
    let mut pending: Option<MtlPending> = None;
    for (n, raw_line) in text.lines().enumerate() {
        let line = u32::try_from(n + 1).unwrap_or(u32::MAX);
        let err = |msg: String| SceneError::new(SourceLoc { file: label.into(), line }, "mtl", msg);
        let content = raw_line.split('#').next().unwrap_or("").trim();
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        if keyword == "newmtl" {
            let name = rest_after_keyword(content, keyword);
            if name.is_empty() {
                return Err(err("newmtl needs a material name".to_string()));
            }
            if let Some(p) = pending.take() {
                let map = p.map_kd.clone();
                done.push((p.finish(label), map));
            }
            if let Some((first, _)) = done.iter().find(|(m, _)| m.name == name) {
                return Err(err(format!("material '{name}' is already defined at line {}", first.loc.line)));
            }
            pending = Some(MtlPending { name: name.to_string(), line, ..MtlPending::default() });
            continue;
        }
        let known = matches!(keyword, "Kd" | "Ks" | "Tf" | "Ke" | "d" | "Tr" | "Ni" | "map_Kd");
        let Some(p) = pending.as_mut() else {
            if known {
                return Err(err(format!("{} before any newmtl", shown(keyword))));
            }
            continue;
        };
        let args: Vec<&str> = tokens.collect();
        match keyword {
            "Kd" => p.kd = Some(parse_colour(&args).map_err(|m| err(format!("Kd: {m}")))?),
            "map_Kd" => match args.last() {
                Some(file) => p.map_kd = Some(MapKd { file: file.to_string(), line }),
                None => return Err(err("map_Kd needs a file name".to_string())),
            },
            "Ks" => p.ks = Some(parse_colour(&args).map_err(|m| err(format!("Ks: {m}")))?),
            "Tf" => p.tf = Some(parse_colour(&args).map_err(|m| err(format!("Tf: {m}")))?),
            "Ke" => p.ke = Some(parse_colour(&args).map_err(|m| err(format!("Ke: {m}")))?),
            "d" | "Tr" | "Ni" => {
                let args: Vec<&str> = args.into_iter().filter(|a| *a != "-halo").collect();
                let [a] = args.as_slice() else {
                    return Err(err(format!("{keyword} needs one number, found {}", args.len())));
                };
                let x = parse_number(a).map_err(|m| err(format!("{keyword}: {m}")))?;
                match keyword {
                    "d" => p.d = Some(x),
                    "Tr" => p.tr = Some(x),
                    _ => p.ni = Some(x),
                }
            }
            _ => {}
        }
    }
    if let Some(p) = pending.take() {
        let map = p.map_kd.clone();
        done.push((p.finish(label), map));
    }
    Ok(done)
}

/// An MTL colour: `r g b` or a single value for all three.
fn parse_colour(args: &[&str]) -> Result<Rgb, String> {
    match args {
        [first, ..] if *first == "spectral" || *first == "xyz" => {
            Err(format!("{} colours are not supported", shown(first)))
        }
        [v] => parse_number(v).map(Rgb::splat),
        [r, g, b] => Ok(Rgb::new(parse_number(r)?, parse_number(g)?, parse_number(b)?)),
        _ => Err(format!("expected 1 or 3 numbers, found {}", args.len())),
    }
}

mod chunked;
#[cfg(test)]
mod reference;
mod statements;
#[cfg(test)]
mod tests;
