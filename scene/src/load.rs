//! `[[mesh]]` entries: the model file they name, read by its format, and placed in the
//! scene.
//!
//! The format is chosen by the file's extension: `.obj` (Wavefront OBJ with MTL, see
//! [`super::obj`]), `.ply` (Stanford PLY, see [`super::ply`]), `.gltf` and `.glb`
//! (glTF 2.0, see [`super::gltf`]). Every format hands back triangles in the model's
//! own space with their materials; this module then applies the entry's transform, skips
//! zero-area triangles and checks that every vertex stays within [`MAX_COORDINATE`], the
//! same way for all of them, and smooths the faces by the crease angle where asked.

use std::path::Path;

use super::error::SceneError;
use super::mesh::{swap_corners, MaterialTable, MeshEntry, MeshFormat, ModelTriangle, ReadFile};
use super::model::MAX_COORDINATE;
use super::shape::is_degenerate;

/// Reads a mesh's file through `read` (by its format) and returns its triangles after
/// the entry's transform, with their material indices. Zero-area triangles are skipped;
/// a file without any other is an error.
pub(super) fn load_mesh(
    entry: &MeshEntry<'_>,
    base_dir: &Path,
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
) -> Result<Vec<ModelTriangle>, SceneError> {
    let path = base_dir.join(entry.file);
    let label = path.display().to_string();
    let Some(format) = MeshFormat::of(&path) else {
        let msg = format!("'{label}' is not a mesh file magg reads: the name must end in .obj, .ply, .gltf or .glb");
        return Err(entry.file_err(msg));
    };
    let bytes =
        read(&path).map_err(|e| entry.file_err(format!("cannot read {} file '{label}': {e}", format.name())))?;
    let triangles = match format {
        MeshFormat::Obj => super::obj::load(entry, &path, &label, &bytes, read, materials)?,
        MeshFormat::Ply => super::ply::load(entry, &label, &bytes)?,
        MeshFormat::Gltf => super::gltf::load(entry, &path, &label, &bytes, read, materials)?,
    };
    let mut placed = place(entry, &label, triangles)?;
    if let Some(crease_cos) = entry.shading.crease_cos {
        super::normals::smooth_by_crease(&mut placed, crease_cos);
    }
    Ok(placed)
}

/// Applies the entry's transform to a file's triangles and their normals, keeping the
/// patches' fronts outward under a mirroring transform, refusing vertices sent past
/// [`MAX_COORDINATE`] and skipping zero-area triangles.
fn place(entry: &MeshEntry<'_>, label: &str, triangles: Vec<ModelTriangle>) -> Result<Vec<ModelTriangle>, SceneError> {
    let flip = entry.transform.flips_winding();
    let mut out = Vec::with_capacity(triangles.len());
    for t in triangles {
        let mut v = t.v.map(|p| entry.transform.apply(p));
        let mut normals =
            t.normals.filter(|_| entry.shading.file_normals).map(|n| n.map(|n| entry.transform.normal(n)));
        let mut uv = t.uv;
        if flip {
            swap_corners(&mut v, &mut normals, &mut uv);
        }
        if !v.iter().all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE) {
            return Err(entry.err("scale", format!("the transform sends a vertex past {MAX_COORDINATE:e}")));
        }
        if !is_degenerate(&v) {
            let normals = normals.and_then(|n| super::normals::shading_normals(&v, n));
            out.push(ModelTriangle { v, material: t.material, normals, uv, texture: t.texture });
        }
    }
    if out.is_empty() {
        return Err(entry.file_err(format!("mesh file '{label}' has no faces of non-zero area")));
    }
    Ok(out)
}
