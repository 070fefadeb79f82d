//! What the model readers share: the `[[mesh]]` entry they read for (with its
//! transform and shading), the triangles they hand back in the model's own space, the
//! scene's material table that their files extend, the formats by extension, and the
//! helpers of their error messages. [`super::load`] reads an entry's file by its format
//! and places its triangles in the scene. Nothing here does I/O: files are read through
//! the caller's `read` callback, as bytes.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::error::SceneError;
use super::model::{Material, SourceLoc};
use super::texture::Texture;
use glam::{DMat3, DVec2, DVec3};

/// How the scene loader reads a file it names (a mesh, an MTL, a glTF buffer): the
/// caller's I/O, which may refuse (size caps, folders the user did not allow).
pub type ReadFile<'r> = &'r dyn Fn(&Path) -> std::io::Result<Vec<u8>>;

/// Most triangles one mesh file may bring (after a glTF's instancing): about what a
/// 2 GiB OBJ holds, and past the renderer's default memory bound.
pub(super) const MAX_MESH_TRIANGLES: usize = 20_000_000;

/// A triangle in the model's own space with the index of its material and, where the
/// file gives them, its corners' shading normals.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ModelTriangle {
    /// Corner positions.
    pub v: [DVec3; 3],
    /// Index into the scene's materials.
    pub material: u32,
    /// The file's vertex normals at the corners (any length, not yet checked; unit
    /// shading normals once placed, `None` for a flat face).
    pub normals: Option<[DVec3; 3]>,
    /// Texture coordinates at the corners.
    pub uv: Option<[DVec2; 3]>,
    /// Index into [`MaterialTable::textures`] of the face's diffuse texture.
    pub texture: Option<u32>,
}

impl ModelTriangle {
    /// A face with material `material` and nothing else.
    #[cfg(test)]
    pub(super) fn plain(v: [DVec3; 3], material: u32) -> Self {
        ModelTriangle { v, material, normals: None, uv: None, texture: None }
    }
}
/// Swaps a triangle's second and third corners, with the normals and texture
/// coordinates they carry: the same triangle, facing the other way.
pub(super) fn swap_corners(v: &mut [DVec3; 3], normals: &mut Option<[DVec3; 3]>, uv: &mut Option<[DVec2; 3]>) {
    v.swap(1, 2);
    if let Some(n) = normals.as_mut() {
        n.swap(1, 2);
    }
    if let Some(c) = uv.as_mut() {
        c.swap(1, 2);
    }
}

/// The scene's materials, which meshes extend with the materials their files define.
pub(super) struct MaterialTable {
    /// Every material, referenced by index (`[[material]]` tables first).
    pub list: Vec<Material>,
    /// Index of each `[[material]]` by name.
    pub toml: HashMap<String, u32>,
    /// Index of each file material already added, by its scene name `file:name`.
    pub from_file: HashMap<String, u32>,
    /// The textures mesh files brought (MTL `map_Kd`), each once.
    pub textures: Vec<Texture>,
    /// Index of each texture in `textures` by the path it was read from.
    pub texture_ids: HashMap<PathBuf, u32>,
}

impl MaterialTable {
    /// An empty table.
    pub(super) fn new() -> Self {
        MaterialTable {
            list: Vec::new(),
            toml: HashMap::new(),
            from_file: HashMap::new(),
            textures: Vec::new(),
            texture_ids: HashMap::new(),
        }
    }

    /// The index of the texture at `path` (read through `read` and decoded the first
    /// time), or why it cannot be had.
    pub(super) fn texture(&mut self, path: &Path, read: ReadFile<'_>) -> Result<u32, String> {
        if let Some(&id) = self.texture_ids.get(path) {
            return Ok(id);
        }
        let bytes = read(path).map_err(|e| format!("cannot read texture '{}': {e}", path.display()))?;
        self.add_texture(path.to_path_buf(), &bytes)
    }

    /// Decodes the image `bytes` as the texture known by `key` (its file, or the glTF
    /// image it is) and returns its index; the same key gives the same texture.
    pub(super) fn add_texture(&mut self, key: PathBuf, bytes: &[u8]) -> Result<u32, String> {
        if let Some(&id) = self.texture_ids.get(&key) {
            return Ok(id);
        }
        let t = Texture::decode(&key.display().to_string(), bytes)?;
        let id = u32::try_from(self.textures.len()).map_err(|_| "too many textures".to_string())?;
        self.textures.push(t);
        self.texture_ids.insert(key, id);
        Ok(id)
    }

    /// Adds a material that the mesh file of `entry` defines (once) and returns its
    /// index, or why it clashes. Its scene name is `file:name` (`meshes/sphere.obj:glass`).
    pub(super) fn add_file_material(&mut self, entry: &MeshEntry<'_>, m: &Material) -> Result<u32, String> {
        let name = format!("{}:{}", entry.file, m.name);
        if let Some(&id) = self.from_file.get(&name) {
            return Ok(id);
        }
        if self.toml.contains_key(&name) {
            return Err(format!("material '{name}' of the mesh file clashes with a [[material]] of the same name"));
        }
        let id = u32::try_from(self.list.len()).map_err(|_| "too many materials".to_string())?;
        self.list.push(Material { name: name.clone(), ..m.clone() });
        self.from_file.insert(name, id);
        Ok(id)
    }
}

/// A `[[mesh]]` entry, already checked by the TOML front end.
pub(super) struct MeshEntry<'a> {
    /// The `file =` (or `obj =`) path as written in the scene, relative to its folder.
    pub file: &'a str,
    /// The key that gave it (`file` or `obj`), for errors.
    pub key: &'static str,
    /// Scene file and line of that key.
    pub at: SourceLoc,
    /// Field prefix for errors (`mesh[2]`).
    pub field: String,
    /// Placement of the mesh.
    pub transform: Transform,
    /// Material overriding every material the file gives (MTL files are then not read).
    pub material: Option<u32>,
    /// How the mesh is shaded: the file's normals, normals made from its faces, or flat.
    pub shading: MeshShading,
}

/// Where a mesh's shading normals come from (`normals` and `crease_angle` of `[[mesh]]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct MeshShading {
    /// Use the normals the file gives (`normals = true`, the default).
    pub file_normals: bool,
    /// For faces the file gives no normals: the cosine of the crease angle, below which
    /// two faces meeting at a vertex do not smooth into each other (`crease_angle =
    /// DEGREES`); `None` shades them flat.
    pub crease_cos: Option<f64>,
}

impl Default for MeshShading {
    fn default() -> Self {
        MeshShading { file_normals: true, crease_cos: None }
    }
}

impl MeshEntry<'_> {
    /// An error at the entry's line, on its field `name` (`mesh[0].file`).
    pub(super) fn err(&self, name: &str, msg: String) -> SceneError {
        SceneError::new(self.at.clone(), format!("{}.{name}", self.field), msg)
    }

    /// An error on the path key itself (`mesh[0].file` or `mesh[0].obj`).
    pub(super) fn file_err(&self, msg: String) -> SceneError {
        self.err(self.key, msg)
    }

    /// The error for a face with no material of its own and no `material =` override;
    /// `where_` says which face (`m.obj:12`, `m.gltf: mesh 0 primitive 1`).
    pub(super) fn no_material(&self, where_: &str) -> SceneError {
        let msg = format!("{where_}: face has no material: add `material = ...` to the [[mesh]]");
        self.err("material", msg)
    }
}

/// The model formats, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (`.obj`), with its MTL files.
    Obj,
    /// Stanford PLY (`.ply`), ASCII or binary.
    Ply,
    /// glTF 2.0, JSON (`.gltf`) or binary (`.glb`).
    Gltf,
}

impl MeshFormat {
    /// The format of the file at `path`, by its extension (any case).
    pub fn of(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "gltf" | "glb" => Some(MeshFormat::Gltf),
            _ => None,
        }
    }

    /// Its name in messages.
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Obj => "OBJ",
            MeshFormat::Ply => "PLY",
            MeshFormat::Gltf => "glTF",
        }
    }
}

/// The text of a text-format file, or an error at the line of its first byte that is not
/// UTF-8 (which the error does not show).
pub(super) fn utf8<'b>(label: &str, field: &str, bytes: &'b [u8]) -> Result<&'b str, SceneError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
        let line = u32::try_from(line).unwrap_or(u32::MAX);
        SceneError::new(SourceLoc { file: label.into(), line }, field, "not UTF-8 text")
    })
}

/// A token as an error message may show it: quoted when it is short and looks like the
/// formats' own words (a keyword, a number, a vertex reference), else only its length, so
/// that an error about a file that is not a model (a secret, a binary) does not print
/// what it holds.
pub(super) fn shown(s: &str) -> String {
    let plain = s.len() <= 24 && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"._+-/".contains(&b));
    if plain {
        format!("'{s}'")
    } else {
        format!("a token of {} bytes", s.len())
    }
}

/// A mesh placement: scale, then rotate (Euler degrees about X, then Y, then Z), then
/// translate.
///
/// Kept as three steps rather than one affine matrix: folding the scale into the
/// rotation (glam's `DAffine3::from_scale_rotation_translation`) would round
/// `(r * s) * p` where the loader has always rounded `r * (s * p)`, and the welded
/// vertices of every shipped mesh depend on those bits.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Transform {
    scale: DVec3,
    /// The rotation `Rz * Ry * Rx`.
    rotation: DMat3,
    translate: DVec3,
}

impl Transform {
    /// Builds a transform from scale factors, Euler angles in degrees and a translation.
    pub(super) fn new(scale: DVec3, rotate_deg: DVec3, translate: DVec3) -> Self {
        let [x, y, z] = rotate_deg.to_array().map(f64::to_radians);
        let rotation = DMat3::from_rotation_z(z) * (DMat3::from_rotation_y(y) * DMat3::from_rotation_x(x));
        Transform { scale, rotation, translate }
    }

    /// Applies the transform to a point.
    pub(super) fn apply(&self, p: DVec3) -> DVec3 {
        self.rotation * (p * self.scale) + self.translate
    }

    /// Applies the transform to a normal (the inverse transpose: rotate `n / scale`);
    /// not normalised.
    pub(super) fn normal(&self, n: DVec3) -> DVec3 {
        self.rotation * (n / self.scale)
    }

    /// True when the transform mirrors space (negative determinant), so that triangles
    /// must have two corners swapped to keep their normals pointing the same way.
    pub(super) fn flips_winding(&self) -> bool {
        self.scale.x * self.scale.y * self.scale.z < 0.0
    }
}

#[cfg(test)]
mod tests;
