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

/// Reads a mesh's file through `read` (by its format) and hands its triangles, after the
/// entry's transform, with their material indices, to `visit` in runs, in file order, as
/// they are read, so that the caller need not hold them all: an OBJ is parsed a window
/// of chunks at a time and handed on chunk by chunk (PLY and glTF files are read whole,
/// then handed on in runs). Zero-area
/// triangles are skipped; a file without any other is an error. A mesh smoothed by a
/// crease angle is handed on in one run, once it is all read and smoothed.
///
/// The errors are those of a whole read, in its order: the file's (its text, then its
/// materials, then a face without one), then the placement's, then "no faces". After an
/// error, the runs handed on before it are to be dropped.
pub(super) fn stream_mesh(
    entry: &MeshEntry<'_>,
    base_dir: &Path,
    read: ReadFile<'_>,
    materials: &mut MaterialTable,
    visit: &mut dyn FnMut(Vec<ModelTriangle>),
) -> Result<(), SceneError> {
    let path = base_dir.join(entry.file);
    let label = path.display().to_string();
    let Some(format) = MeshFormat::of(&path) else {
        let msg = format!("'{label}' is not a mesh file magg reads: the name must end in .obj, .ply, .gltf or .glb");
        return Err(entry.file_err(msg));
    };
    let bytes =
        read(&path).map_err(|e| entry.file_err(format!("cannot read {} file '{label}': {e}", format.name())))?;
    let smooth = entry.shading.crease_cos;
    let mut whole = Vec::new();
    let mut placed_any = false;
    // A placement error waits for the file's errors, which come first.
    let mut pending: Option<SceneError> = None;
    let mut take = |triangles: Vec<ModelTriangle>| {
        if pending.is_some() {
            return;
        }
        match place(entry, triangles) {
            Ok(p) if smooth.is_some() => whole.extend(p),
            Ok(p) => {
                placed_any |= !p.is_empty();
                if !p.is_empty() {
                    visit(p);
                }
            }
            Err(e) => pending = Some(e),
        }
    };
    match format {
        MeshFormat::Obj => super::obj::stream(entry, &path, &label, &bytes, read, materials, &mut take)?,
        MeshFormat::Ply => in_runs(super::ply::load(entry, &label, &bytes)?, &mut take),
        MeshFormat::Gltf => in_runs(super::gltf::load(entry, &path, &label, &bytes, read, materials)?, &mut take),
    }
    if let Some(e) = pending {
        return Err(e);
    }
    if let Some(crease_cos) = smooth {
        super::normals::smooth_by_crease(&mut whole, crease_cos);
        placed_any = !whole.is_empty();
        if placed_any {
            visit(whole);
        }
    }
    if !placed_any {
        return Err(entry.file_err(format!("mesh file '{label}' has no faces of non-zero area")));
    }
    Ok(())
}

/// Triangles per run handed on from a file read whole.
const RUN: usize = 1 << 16;

/// Hands `triangles` to `take` in runs of [`RUN`], in order.
fn in_runs(triangles: Vec<ModelTriangle>, take: &mut dyn FnMut(Vec<ModelTriangle>)) {
    let mut all = triangles.into_iter();
    loop {
        let run: Vec<ModelTriangle> = all.by_ref().take(RUN).collect();
        if run.is_empty() {
            return;
        }
        take(run);
    }
}

/// Applies the entry's transform to a run of a file's triangles and their normals,
/// keeping the patches' fronts outward under a mirroring transform, refusing vertices
/// sent past [`MAX_COORDINATE`] and skipping zero-area triangles.
fn place(entry: &MeshEntry<'_>, triangles: Vec<ModelTriangle>) -> Result<Vec<ModelTriangle>, SceneError> {
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
    Ok(out)
}
