//! The line-by-line OBJ reader the chunked one replaced, kept as the oracle its tests
//! compare with: the same file must give the same mesh, or the same error.

use super::{parse_number, resolve_index, rest_after_keyword, MtlLib, ObjFace, ObjMesh, OBJ_FREEFORM, OBJ_IGNORED};
use crate::error::SceneError;
use crate::mesh::shown;
use crate::model::{SourceLoc, MAX_COORDINATE};
use glam::{DVec2, DVec3};

/// Parses an OBJ file; `label` names it in errors.
pub(super) fn parse_obj_by_lines(label: &str, text: &str) -> Result<ObjMesh, SceneError> {
    let mut mesh = ObjMesh::default();
    let mut current: Option<usize> = None;
    for (n, raw_line) in text.lines().enumerate() {
        let line = u32::try_from(n + 1).unwrap_or(u32::MAX);
        let err = |msg: String| SceneError::new(SourceLoc { file: label.into(), line }, "obj", msg);
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
                        let narrow = |a: [usize; 3]| a.map(|k| k as u32);
                        let corners = narrow(all(0).unwrap_or_default());
                        let (uvs, normals) = (all(1).map(narrow), all(2).map(narrow));
                        let usemtl = current.map(|k| k as u32);
                        mesh.faces.push(ObjFace { corners, uvs, normals, usemtl, line });
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
