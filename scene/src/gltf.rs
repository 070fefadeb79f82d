//! glTF 2.0 import for `[[mesh]]` entries (`.gltf` with external or embedded buffers,
//! and `.glb`), and the camera and lights a glTF file sets up ([`gltf_stage`]).
//!
//! The `gltf` crate parses and validates the JSON (every index checked); magg reads the
//! GLB container, the buffers and the accessors itself, with every offset checked, so
//! that a broken file is an error and never a panic. What magg can represent is read:
//! - the default scene's node tree (else the first scene's, else every root node), each
//!   node's `matrix` or `translation`/`rotation`/`scale`, composed down the tree;
//! - every mesh a node places: primitives of mode triangles, triangle strip or triangle
//!   fan, indexed or not (points and lines are not surfaces and are skipped); a node
//!   whose transform mirrors space keeps its triangles facing outward;
//! - materials: the base colour factor (its RGB) becomes the diffuse reflectance of a
//!   magg material made per glTF material, named `file:name` (`file:material[3]` when the
//!   name is missing or not unique); the emissive factor, times
//!   `KHR_materials_emissive_strength` where given, becomes its `emit` radiance (an area
//!   light). Metallic, roughness, alpha and textures are ignored. A primitive without a material takes the `[[mesh]]`'s `material =`;
//! - cameras and `KHR_lights_punctual` lights, for [`gltf_stage`] only: inside a TOML
//!   scene a glTF file brings its meshes and materials, not its camera or lights.
//!
//! Errors name the file and the JSON path or the mesh, primitive and accessor at fault
//! (`m.gltf: meshes[0].primitives[0].attributes["POSITION"]: Index out of bounds`).

use std::path::{Path, PathBuf};

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::json;
use ::gltf::mesh::Mode;
use ::gltf::Document;
use glam::{DMat3, DMat4, DQuat, DVec2, DVec3};

use rayon::prelude::*;

use super::error::SceneError;
use super::mesh::{swap_corners, MaterialTable, MeshEntry, ModelTriangle, ReadFile, MAX_MESH_TRIANGLES};
use super::model::{Camera, Light, Material, SourceLoc, Spot, MAX_COORDINATE, MAX_RADIOMETRIC};
use crate::color::Rgb;

mod buffers;
use buffers::{file_err, load_buffers, percent_decode, read_accessor, split_glb, uri_bytes};

/// Deepest node tree walked: far past real files, and an end to a cycle of nodes.
const MAX_DEPTH: usize = 64;
/// Most node visits (a node placed under several parents is visited once per parent).
const MAX_VISITS: usize = 1_000_000;

/// Parses and validates a `.gltf` (JSON) or `.glb` document; returns it with the GLB's
/// binary chunk, if any.
fn parse_document(label: &str, bytes: &[u8]) -> Result<(Document, Option<Vec<u8>>), SceneError> {
    let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
        let (j, b) = split_glb(bytes).map_err(|m| file_err(label, format!("GLB: {m}")))?;
        (j, b.map(<[u8]>::to_vec))
    } else {
        (bytes, None)
    };
    let root: json::Root = json::deserialize::from_slice(json_bytes).map_err(|e| {
        // serde_json's message may quote the file's text: say only where and what kind.
        let what = match e.classify() {
            serde_json::error::Category::Io | serde_json::error::Category::Eof => "the JSON ends early",
            serde_json::error::Category::Syntax => "JSON syntax error",
            serde_json::error::Category::Data => "not a glTF document (a value of the wrong type or a missing field)",
        };
        let line = u32::try_from(e.line()).unwrap_or(u32::MAX);
        let file =
            if bin.is_some() || bytes.starts_with(b"glTF") { format!("{label} (JSON chunk)") } else { label.into() };
        SceneError::new(SourceLoc { file: file.into(), line }, "gltf", format!("{what} at column {}", e.column()))
    })?;
    // The crate's validation indexes the POSITION accessor without checking it first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = prim.attributes.get(&json::validation::Checked::Valid(json::mesh::Semantic::Positions));
            if let Some(i) = position.filter(|i| i.value() >= root.accessors.len()) {
                let msg = format!(
                    "meshes[{m}].primitives[{p}].attributes[\"POSITION\"]: accessor {} does not exist ({} accessors)",
                    i.value(),
                    root.accessors.len()
                );
                return Err(file_err(label, msg));
            }
        }
    }
    let document = Document::from_json(root).map_err(|e| match e {
        ::gltf::Error::Validation(list) => {
            let shown: Vec<String> =
                list.iter().take(3).map(|(path, e)| format!("{}: {e}", json_path(&path.to_string()))).collect();
            file_err(label, shown.join("; "))
        }
        other => file_err(label, other.to_string()),
    })?;
    Ok((document, bin))
}

/// A JSON path as an error may show it (field names and indices; a key the file made up
/// is shown only by its length).
fn json_path(p: &str) -> String {
    let plain = p.len() <= 120 && p.bytes().all(|b| b.is_ascii_alphanumeric() || b"._[]\"".contains(&b));
    if plain {
        p.to_string()
    } else {
        format!("a JSON path of {} bytes", p.len())
    }
}

/// The texture of glTF material `m`'s `baseColorTexture` (decoded once into
/// `materials`) and the `TEXCOORD_n` set it uses; `None` when it has none.
fn base_colour_texture(
    doc: &Document,
    m: usize,
    buffers: &[Vec<u8>],
    gltf_path: &Path,
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
) -> Result<Option<(u32, u32)>, String> {
    let Some(mat) = doc.materials().nth(m) else { return Ok(None) };
    let Some(info) = mat.pbr_metallic_roughness().base_color_texture() else { return Ok(None) };
    let image = info.texture().source();
    let at = format!("images[{}]", image.index());
    let dir = gltf_path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    // Textures are keyed by where they come from: a file, or an image of this glTF.
    let (key, bytes) = match image.source() {
        ::gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
            let name = percent_decode(uri).ok_or_else(|| format!("{at}: a URI that is not a relative file name"))?;
            let id = materials.texture(&dir.join(name), read).map_err(|m| format!("{at}: {m}"))?;
            return Ok(Some((id, info.tex_coord())));
        }
        ::gltf::image::Source::Uri { uri, .. } => {
            (gltf_path.join(&at), uri_bytes(uri, &dir, read, "image").map_err(|m| format!("{at}: {m}"))?)
        }
        ::gltf::image::Source::View { view, .. } => {
            let buf = buffers.get(view.buffer().index()).ok_or_else(|| format!("{at}: no such buffer"))?;
            let end = view.offset().checked_add(view.length());
            let bytes = end
                .and_then(|e| buf.get(view.offset()..e))
                .ok_or_else(|| format!("{at}: its buffer view lies past the end of its buffer"))?;
            (gltf_path.join(&at), bytes.to_vec())
        }
    };
    let id = materials.add_texture(key, &bytes).map_err(|m| format!("{at}: {m}"))?;
    Ok(Some((id, info.tex_coord())))
}

/// A node's own transform in f64, or why it is not one.
fn local_matrix(node: &::gltf::Node<'_>) -> Result<DMat4, String> {
    let m = match node.transform() {
        ::gltf::scene::Transform::Matrix { matrix } => DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from))),
        ::gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
            let q = DQuat::from_array(rotation.map(f64::from));
            let len = q.length();
            if !(len.is_finite() && len > 0.0) {
                return Err(format!("nodes[{}].rotation is not a rotation", node.index()));
            }
            DMat4::from_scale_rotation_translation(
                DVec3::from_array(scale.map(f64::from)),
                q / len,
                DVec3::from_array(translation.map(f64::from)),
            )
        }
    };
    if !m.is_finite() {
        return Err(format!("nodes[{}]: its transform is not finite", node.index()));
    }
    Ok(m)
}

/// Every node of the document's scene with its world transform, depth first.
fn placed_nodes<'d>(doc: &'d Document) -> Result<Vec<(::gltf::Node<'d>, DMat4)>, String> {
    let roots: Vec<::gltf::Node<'d>> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    if let Some(slot) = child.get_mut(c.index()) {
                        *slot = true;
                    }
                }
            }
            doc.nodes().filter(|n| !child.get(n.index()).copied().unwrap_or(false)).collect()
        }
    };
    let mut out = Vec::new();
    let mut stack: Vec<(::gltf::Node<'d>, DMat4, usize)> =
        roots.into_iter().rev().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return Err(format!("the node tree is deeper than {MAX_DEPTH} (a node among its own children?)"));
        }
        if out.len() >= MAX_VISITS {
            return Err(format!("more than {MAX_VISITS} placed nodes"));
        }
        let world = parent * local_matrix(&node)?;
        let children: Vec<_> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, world, depth + 1)));
        out.push((node, world));
    }
    Ok(out)
}

/// Reads a glTF mesh file and returns its triangles in the file's world space (node
/// transforms applied), with their materials, added to `materials` on first use.
pub(super) fn load(
    entry: &MeshEntry<'_>,
    path: &Path,
    label: &str,
    bytes: &[u8],
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
) -> Result<Vec<ModelTriangle>, SceneError> {
    let (doc, bin) = parse_document(label, bytes)?;
    let buffers = load_buffers(&doc, bin, path, label, read)?;
    let err = |m: String| file_err(label, m);
    let names = material_names(&doc);
    let mut material_ids: Vec<Option<u32>> = vec![None; names.len()];
    let mut textures: Vec<Option<Option<(u32, u32)>>> = vec![None; names.len()];
    let mut out: Vec<ModelTriangle> = Vec::new();
    for (node, world) in placed_nodes(&doc).map_err(err)? {
        let Some(mesh) = node.mesh() else { continue };
        let flip = world.determinant() < 0.0;
        for prim in mesh.primitives() {
            let at = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
            let material = match (entry.material, prim.material().index()) {
                (Some(id), _) => id,
                (None, Some(m)) => match material_ids.get(m).copied().flatten() {
                    Some(id) => id,
                    None => {
                        let made = gltf_material(&doc, m, &names, label)
                            .ok_or_else(|| err(format!("{at}: no material {m}")))?;
                        let id = materials.add_file_material(entry, &made).map_err(|m| entry.file_err(m))?;
                        if let Some(slot) = material_ids.get_mut(m) {
                            *slot = Some(id);
                        }
                        id
                    }
                },
                (None, None) => return Err(entry.no_material(&format!("{label}: {at}"))),
            };
            // The base colour texture, when the face takes the file's material.
            let texture = match (entry.material, prim.material().index()) {
                (None, Some(m)) => match textures.get(m).copied().flatten() {
                    Some(t) => t,
                    None => {
                        let t = base_colour_texture(&doc, m, &buffers, path, read, materials)
                            .map_err(|e| err(format!("materials[{m}].pbrMetallicRoughness.baseColorTexture: {e}")))?;
                        if let Some(slot) = textures.get_mut(m) {
                            *slot = Some(t);
                        }
                        t
                    }
                },
                _ => None,
            };
            // Normals go through the inverse transpose of the node's matrix.
            let normal_matrix = DMat3::from_mat4(world).inverse().transpose();
            let tris =
                primitive_triangles(&prim, &buffers, texture.map(|t| t.1)).map_err(|m| err(format!("{at}: {m}")))?;
            // Placed on every core: each triangle on its own, the same message for any
            // vertex sent too far, so the result and the error do not depend on the split.
            let texture_id = texture.map(|t| t.0);
            let placed: Vec<ModelTriangle> = tris
                .into_par_iter()
                .map(|(corners, normals, uv)| {
                    let mut v = corners.map(|p| world.transform_point3(p));
                    let mut normals = normals.map(|n| n.map(|n| normal_matrix * n));
                    if !v.iter().all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE) {
                        return Err(());
                    }
                    let mut uv = uv;
                    if flip {
                        swap_corners(&mut v, &mut normals, &mut uv);
                    }
                    let texture = texture_id.filter(|_| uv.is_some());
                    Ok(ModelTriangle { v, material, normals, uv, texture })
                })
                .collect::<Result<_, ()>>()
                .map_err(|()| err(format!("{at}: node {} places a vertex past {MAX_COORDINATE:e}", node.index())))?;
            out.extend(placed);
            if out.len() > MAX_MESH_TRIANGLES {
                return Err(err(format!("more than {MAX_MESH_TRIANGLES} triangles once placed by its nodes")));
            }
        }
    }
    if out.is_empty() {
        return Err(
            entry.file_err(format!("glTF file '{label}' places no triangles (no node of its scene has a mesh)"))
        );
    }
    Ok(out)
}

/// A primitive's triangle in its mesh's space, with its corners' `NORMAL`s and texture
/// coordinates (v up, as magg takes them) if it has them.
type PrimitiveTriangle = ([DVec3; 3], Option<[DVec3; 3]>, Option<[DVec2; 3]>);

/// The triangles of a primitive in its mesh's space (empty for points and lines), with
/// the texture coordinates of set `TEXCOORD_{uv_set}` when asked for.
fn primitive_triangles(
    prim: &::gltf::Primitive<'_>,
    buffers: &[Vec<u8>],
    uv_set: Option<u32>,
) -> Result<Vec<PrimitiveTriangle>, String> {
    let mode = prim.mode();
    if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
        return Ok(Vec::new());
    }
    let pos = prim.get(&::gltf::Semantic::Positions).ok_or("it has no POSITION")?;
    if pos.dimensions() != Dimensions::Vec3 || pos.data_type() != DataType::F32 {
        return Err(format!("attributes[\"POSITION\"] (accessors[{}]) is not VEC3 of floats", pos.index()));
    }
    let flat = read_accessor(&pos, buffers)?;
    let positions: Vec<DVec3> = flat.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect();
    let normals: Option<Vec<DVec3>> = match prim.get(&::gltf::Semantic::Normals) {
        Some(acc) => {
            if acc.dimensions() != Dimensions::Vec3 || acc.data_type() != DataType::F32 {
                return Err(format!("attributes[\"NORMAL\"] (accessors[{}]) is not VEC3 of floats", acc.index()));
            }
            let flat = read_accessor(&acc, buffers)?;
            if flat.len() != 3 * positions.len() {
                return Err(format!(
                    "attributes[\"NORMAL\"] has {} normals for {} positions",
                    flat.len() / 3,
                    positions.len()
                ));
            }
            Some(flat.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect())
        }
        None => None,
    };
    let uvs: Option<Vec<DVec2>> = match uv_set.and_then(|k| prim.get(&::gltf::Semantic::TexCoords(k)).map(|a| (k, a))) {
        Some((k, acc)) => {
            let scale = match (acc.data_type(), acc.normalized()) {
                (DataType::F32, _) => 1.0,
                (DataType::U8, true) => 1.0 / 255.0,
                (DataType::U16, true) => 1.0 / 65535.0,
                _ => return Err(format!("attributes[\"TEXCOORD_{k}\"] is not float or normalized unsigned")),
            };
            let flat = read_accessor(&acc, buffers)?;
            if acc.dimensions() != Dimensions::Vec2 || flat.len() != 2 * positions.len() {
                return Err(format!("attributes[\"TEXCOORD_{k}\"] is not one VEC2 per position"));
            }
            // glTF's t runs down the image; magg's v runs up.
            Some(flat.chunks_exact(2).map(|c| DVec2::new(c[0] * scale, 1.0 - c[1] * scale)).collect())
        }
        None => None,
    };
    let indices: Vec<usize> = match prim.indices() {
        Some(acc) => {
            if acc.dimensions() != Dimensions::Scalar
                || !matches!(acc.data_type(), DataType::U8 | DataType::U16 | DataType::U32)
            {
                return Err(format!("indices (accessors[{}]) are not unsigned integer scalars", acc.index()));
            }
            read_accessor(&acc, buffers)?.into_iter().map(|x| x as usize).collect()
        }
        None => (0..positions.len()).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&k| k >= positions.len()) {
        return Err(format!("index {bad} is out of range: {} vertices", positions.len()));
    }
    let n = indices.len();
    let triangle = |a: usize, b: usize, c: usize| -> PrimitiveTriangle {
        let [a, b, c] = [indices[a], indices[b], indices[c]];
        let normals = normals.as_ref().map(|n| [n[a], n[b], n[c]]);
        let uv = uvs.as_ref().map(|t| [t[a], t[b], t[c]]);
        ([positions[a], positions[b], positions[c]], normals, uv)
    };
    // Made on every core, in order.
    let tris: Vec<PrimitiveTriangle> = match mode {
        Mode::Triangles => {
            if n % 3 != 0 {
                return Err(format!("{n} indices is not a whole number of triangles"));
            }
            (0..n / 3).into_par_iter().map(|t| triangle(3 * t, 3 * t + 1, 3 * t + 2)).collect()
        }
        // The spec's orders: strip i = (i, i + 1 + i % 2, i + 2 - i % 2); fan i = (i + 1, i + 2, 0).
        Mode::TriangleStrip => {
            (0..n.saturating_sub(2)).into_par_iter().map(|i| triangle(i, i + 1 + i % 2, i + 2 - i % 2)).collect()
        }
        _ => (0..n.saturating_sub(2)).into_par_iter().map(|i| triangle(i + 1, i + 2, 0)).collect(),
    };
    Ok(tris)
}

/// The scene name of each glTF material: its name where that is unique and plain, else
/// `material[i]`.
fn material_names(doc: &Document) -> Vec<String> {
    let all: Vec<Option<&str>> = doc.materials().map(|m| m.name()).collect();
    all.iter()
        .enumerate()
        .map(|(i, name)| match name {
            Some(n)
                if !n.trim().is_empty()
                    && !n.contains(':')
                    && n.len() <= 200
                    && all.iter().filter(|o| o.as_deref() == Some(*n)).count() == 1 =>
            {
                n.trim().to_string()
            }
            _ => format!("material[{i}]"),
        })
        .collect()
}

/// The magg material of glTF material `m`: its base colour factor as the diffuse part,
/// its emissive factor (times `KHR_materials_emissive_strength`) as the radiance it emits.
fn gltf_material(doc: &Document, m: usize, names: &[String], label: &str) -> Option<Material> {
    let mat = doc.materials().nth(m)?;
    let [r, g, b, _] = mat.pbr_metallic_roughness().base_color_factor().map(|c| f64::from(c).clamp(0.0, 1.0));
    let strength = mat.emissive_strength().map_or(1.0, f64::from);
    let emit = mat.emissive_factor().map(|c| {
        let x = f64::from(c) * strength;
        if x.is_finite() {
            x.clamp(0.0, MAX_RADIOMETRIC)
        } else {
            0.0
        }
    });
    Some(Material {
        name: names.get(m)?.clone(),
        diffuse: Rgb::new(r, g, b),
        mirror: Rgb::BLACK,
        transmit: Rgb::BLACK,
        ior: 1.5,
        one_sided: false,
        emit: Rgb(emit),
        loc: SourceLoc { file: label.into(), line: 0 },
    })
}

/// The camera and lights a glTF file sets up, for rendering the file on its own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GltfStage {
    /// The first perspective camera of `cameras` that a node of the scene places.
    pub camera: Option<Camera>,
    /// That camera's aspect ratio (width / height), if the file gives one.
    pub aspect_ratio: Option<f64>,
    /// Every `KHR_lights_punctual` point and spot light a node places, with a non-zero
    /// intensity (directional lights have no place in magg and are left out).
    pub lights: Vec<Light>,
}

/// Reads the camera and lights of a glTF file (`bytes`, named `label`); the buffers are
/// not needed.
///
/// A light's intensity (candela, lm/sr) is taken as W/sr times its colour: magg's point
/// lights are radiometric, and tone mapping absorbs the constant a photometric
/// conversion would bring. A spot light's inner cone is magg's cone (at least 0.01
/// degrees), the band out to the outer cone its falloff. The `range` is ignored (magg's
/// lights fall off with the inverse square alone).
pub fn gltf_stage(label: &str, bytes: &[u8]) -> Result<GltfStage, SceneError> {
    let (doc, _) = parse_document(label, bytes)?;
    let nodes = placed_nodes(&doc).map_err(|m| file_err(label, m))?;
    let mut stage = GltfStage::default();
    let mut best: Option<usize> = None;
    for (node, world) in &nodes {
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(DVec3::NEG_Z);
        let loc = SourceLoc { file: label.into(), line: 0 };
        if let Some(cam) = node.camera() {
            if let ::gltf::camera::Projection::Perspective(p) = cam.projection() {
                let up = world.transform_vector3(DVec3::Y);
                let fov = f64::from(p.yfov()).to_degrees();
                let usable = fov > 0.0 && fov < 180.0 && forward.length() > 0.0 && forward.cross(up).length() > 0.0;
                if usable && eye.is_finite() && best.is_none_or(|b| cam.index() < b) {
                    best = Some(cam.index());
                    let look_at = eye + forward.normalize();
                    stage.camera = Some(Camera { eye, look_at, up: up.normalize(), fov_y_deg: fov });
                    stage.aspect_ratio = p.aspect_ratio().map(f64::from).filter(|a| a.is_finite() && *a > 0.0);
                }
            }
        }
        if let Some(light) = node.light() {
            let c = light.color().map(|x| f64::from(x).max(0.0) * f64::from(light.intensity()).max(0.0));
            let intensity = Rgb(c.map(|x| x.min(MAX_RADIOMETRIC)));
            if intensity.is_black() || !eye.is_finite() || eye.abs().max_element() > MAX_COORDINATE {
                continue;
            }
            let spot = match light.kind() {
                ::gltf::khr_lights_punctual::Kind::Directional => continue,
                ::gltf::khr_lights_punctual::Kind::Point => None,
                ::gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                    if forward.length().is_nan() || forward.length() <= 0.0 {
                        continue;
                    }
                    let outer = f64::from(outer_cone_angle).to_degrees().clamp(0.01, 90.0);
                    let inner = f64::from(inner_cone_angle).to_degrees().clamp(0.01, outer);
                    Some(Spot { direction: forward.normalize(), half_angle_deg: inner, falloff_deg: outer - inner })
                }
            };
            stage.lights.push(Light { position: eye, intensity, spot, loc });
        }
    }
    Ok(stage)
}

#[cfg(test)]
mod tests;
