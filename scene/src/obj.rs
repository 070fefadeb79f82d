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
use super::model::{Material, SourceLoc, MAX_COORDINATE, MAX_RADIOMETRIC};
use crate::color::Rgb;
use glam::{DVec2, DVec3};

/// Parses a mesh's OBJ file `bytes` (read from `obj_path`, named `label`) and its MTL
/// files (read through `read`), and returns its triangles in the model's space with their
/// material indices.
///
/// A `usemtl` name is looked up first in the OBJ's own MTL files, whose materials are added
/// to `materials` (once, in order of first use) as `objfile:mtlname` (e.g.
/// `meshes/sphere.obj:glass`), then among the `[[material]]` tables by plain name.
pub(super) fn load(
    entry: &MeshEntry<'_>,
    obj_path: &Path,
    obj_label: &str,
    bytes: &[u8],
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
) -> Result<Vec<ModelTriangle>, SceneError> {
    let mesh = parse_obj(obj_label, utf8(obj_label, "obj", bytes)?)?;

    // Material of each `usemtl` name (None: defined nowhere, reported at its first face).
    // ... and its texture (`map_Kd`), if any.
    let mut usemtl_ids = Vec::new();
    let mut usemtl_textures: Vec<Option<u32>> = Vec::new();
    if entry.material.is_none() {
        let mtl = load_mtllibs(&mesh, obj_path, obj_label, read)?;
        for name in &mesh.usemtl_names {
            let (id, texture) = match mtl.iter().find(|mm| mm.material.name == *name) {
                Some(mm) => {
                    let id = materials.add_file_material(entry, &mm.material).map_err(|m| entry.file_err(m))?;
                    let texture = match &mm.map_kd {
                        Some((path, line)) => Some(materials.texture(path, read).map_err(|m| {
                            SceneError::new(SourceLoc { file: mm.label.clone(), line: *line }, "map_Kd", m)
                        })?),
                        None => None,
                    };
                    (Some(id), texture)
                }
                None => (materials.toml.get(name).copied(), None),
            };
            usemtl_ids.push(id);
            usemtl_textures.push(texture);
        }
    }

    let mut out = Vec::with_capacity(mesh.faces.len());
    for face in &mesh.faces {
        let material = match (entry.material, face.usemtl) {
            (Some(id), _) => id,
            (None, Some(u)) => match usemtl_ids.get(u).copied().flatten() {
                Some(id) => id,
                None => {
                    let name = mesh.usemtl_names.get(u).map_or("", String::as_str);
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
            *o = mesh.positions.get(k).copied().ok_or_else(|| entry.file_err("face index out of range".into()))?;
        }
        let normals = face.normals.and_then(|n| {
            let [a, b, c] = n.map(|k| mesh.normals.get(k).copied());
            Some([a?, b?, c?])
        });
        let uv = face.uvs.and_then(|t| {
            let [a, b, c] = t.map(|k| mesh.uvs.get(k).copied());
            Some([a?, b?, c?])
        });
        let texture = face.usemtl.and_then(|u| usemtl_textures.get(u).copied().flatten()).filter(|_| uv.is_some());
        out.push(ModelTriangle { v, material, normals, uv, texture });
    }
    Ok(out)
}

/// Reads and parses every `mtllib` of an OBJ, relative to the OBJ's directory; a name
/// defined in two of them is an error.
fn load_mtllibs(
    mesh: &ObjMesh,
    obj_path: &Path,
    obj_label: &str,
    read: ReadFile<'_>,
) -> Result<Vec<MtlMaterial>, SceneError> {
    let dir = obj_path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let mut out: Vec<MtlMaterial> = Vec::new();
    for lib in &mesh.mtllibs {
        let path = dir.join(&lib.file);
        let label = path.display().to_string();
        let bytes = read(&path).map_err(|e| {
            let at = SourceLoc { file: obj_label.to_string(), line: lib.line };
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

/// One triangle of an OBJ face.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ObjFace {
    /// Indices into [`ObjMesh::positions`] (checked in range).
    pub corners: [usize; 3],
    /// Indices into [`ObjMesh::uvs`] (checked in range), when every corner names one.
    pub uvs: Option<[usize; 3]>,
    /// Indices into [`ObjMesh::normals`] (checked in range), when every corner names one.
    pub normals: Option<[usize; 3]>,
    /// Index into [`ObjMesh::usemtl_names`] of the `usemtl` in force, if any.
    pub usemtl: Option<usize>,
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
const OBJ_IGNORED: &[&str] = &[
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
const OBJ_FREEFORM: &[&str] =
    &["cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con"];

/// Parses an OBJ file; `label` names it in errors.
pub(super) fn parse_obj(label: &str, text: &str) -> Result<ObjMesh, SceneError> {
    let mut mesh = ObjMesh::default();
    let mut current: Option<usize> = None;
    for (n, raw_line) in text.lines().enumerate() {
        let line = u32::try_from(n + 1).unwrap_or(u32::MAX);
        let err = |msg: String| SceneError::new(SourceLoc { file: label.to_string(), line }, "obj", msg);
        let content = raw_line.split('#').next().unwrap_or("").trim();
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let mut xyz = [0.0; 3];
                let mut count = 0;
                for tok in tokens {
                    let x = parse_number(tok).map_err(|m| err(format!("v: {m}")))?;
                    if x.abs() > MAX_COORDINATE {
                        return Err(err(format!("v: {x:e} is out of range [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}]")));
                    }
                    if let Some(slot) = xyz.get_mut(count) {
                        *slot = x;
                    }
                    count += 1;
                }
                if !(3..=7).contains(&count) {
                    return Err(err(format!("v needs 3 coordinates, found {count} numbers")));
                }
                mesh.positions.push(DVec3::from_array(xyz));
            }
            "vt" => {
                let uv = tokens
                    .map(|tok| parse_number(tok).map_err(|m| err(format!("vt: {m}"))))
                    .collect::<Result<Vec<_>, _>>()?;
                // `vt u [v [w]]`: v defaults to 0, w is ignored.
                let (Some(&u), 1..=3) = (uv.first(), uv.len()) else {
                    return Err(err(format!("vt needs 1 to 3 numbers, found {}", uv.len())));
                };
                mesh.uvs.push(DVec2::new(u, uv.get(1).copied().unwrap_or(0.0)));
            }
            "vn" => {
                let xyz = tokens
                    .map(|tok| parse_number(tok).map_err(|m| err(format!("vn: {m}"))))
                    .collect::<Result<Vec<_>, _>>()?;
                let [x, y, z] = xyz[..] else {
                    return Err(err(format!("vn needs 3 numbers, found {}", xyz.len())));
                };
                mesh.normals.push(DVec3::new(x, y, z));
            }
            "f" => {
                let corners = tokens
                    .map(|tok| resolve_corner(tok, [mesh.positions.len(), mesh.uvs.len(), mesh.normals.len()]))
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|m| err(format!("f: {m}")))?;
                if corners.len() < 3 {
                    return Err(err(format!("f needs at least 3 vertices, found {}", corners.len())));
                }
                let first = corners[0];
                for pair in corners[1..].windows(2) {
                    if let [b, c] = pair {
                        let all = |k: usize| match (first[k], b[k], c[k]) {
                            (Some(x), Some(y), Some(z)) => Some([x, y, z]),
                            _ => None,
                        };
                        let corners = all(0).unwrap_or_default();
                        let (uvs, normals) = (all(1), all(2));
                        mesh.faces.push(ObjFace { corners, uvs, normals, usemtl: current, line });
                    }
                }
            }
            "usemtl" => {
                let name = rest_after_keyword(content, keyword);
                if name.is_empty() {
                    return Err(err("usemtl needs a material name".to_string()));
                }
                current = Some(match mesh.usemtl_names.iter().position(|m| m == name) {
                    Some(k) => k,
                    None => {
                        mesh.usemtl_names.push(name.to_string());
                        mesh.usemtl_names.len() - 1
                    }
                });
            }
            "mtllib" => {
                let before = mesh.mtllibs.len();
                mesh.mtllibs.extend(tokens.map(|t| MtlLib { file: t.to_string(), line }));
                if mesh.mtllibs.len() == before {
                    return Err(err("mtllib needs a file name".to_string()));
                }
            }
            k if OBJ_IGNORED.contains(&k) => {}
            k if OBJ_FREEFORM.contains(&k) => {
                return Err(err(format!("free-form geometry ('{k}') is not supported: export triangles or polygons")));
            }
            k => return Err(err(format!("unknown statement {}", shown(k)))),
        }
    }
    Ok(mesh)
}

/// One face corner (`v`, `v/vt`, `v//vn`, `v/vt/vn`), resolved against the counts of
/// positions, texture coordinates and normals defined so far: the 0-based position, `vt`
/// and `vn` indices (the last two where the corner names them).
fn resolve_corner(tok: &str, counts: [usize; 3]) -> Result<[Option<usize>; 3], String> {
    let parts: Vec<&str> = tok.split('/').collect();
    let bad = || format!("{} is not a vertex reference (v, v/vt, v//vn or v/vt/vn)", shown(tok));
    if parts.len() > 3 || parts[1..].iter().any(|p| !p.is_empty() && p.parse::<i64>().is_err()) {
        return Err(bad());
    }
    let i: i64 = parts[0].parse().map_err(|_| format!("{} is not a vertex index", shown(tok)))?;
    let mut out = [Some(resolve_index(i, counts[0], "vertex", "vertices")?), None, None];
    for (k, (what, plural)) in
        [(1, ("texture coordinate", "texture coordinates (vt)")), (2, ("normal", "normals (vn)"))]
    {
        if let Some(p) = parts.get(k).filter(|p| !p.is_empty()) {
            let j: i64 = p.parse().map_err(|_| bad())?;
            out[k] = Some(resolve_index(j, counts[k], what, plural)?);
        }
    }
    Ok(out)
}

/// A 1-based (or negative, relative) OBJ index among `count` entries defined so far, as
/// a 0-based index.
fn resolve_index(i: i64, count: usize, what: &str, plural: &str) -> Result<usize, String> {
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
fn parse_number(tok: &str) -> Result<f64, String> {
    match tok.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(x) => Err(format!("{x} is not a finite number")),
        Err(_) => Err(format!("{} is not a number", shown(tok))),
    }
}

/// The rest of a statement after its keyword, trimmed (names may contain spaces).
fn rest_after_keyword<'t>(content: &'t str, keyword: &str) -> &'t str {
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
            loc: SourceLoc { file: label.to_string(), line: self.line },
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
        let err = |msg: String| SceneError::new(SourceLoc { file: label.to_string(), line }, "mtl", msg);
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

#[cfg(test)]
mod tests;
