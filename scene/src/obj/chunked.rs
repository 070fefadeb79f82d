//! The OBJ reader proper: the file is cut at line ends into chunks
//! ([`crate::chunks`]), a window of chunks is parsed on every core, and the chunks are
//! stitched in file order and handed on before the next window is read.
//!
//! A chunk is parsed without knowing what came before it, so what depends on the lines
//! before (a face's indices, checked against the vertices defined so far and counted back
//! from the last one when negative; the `usemtl` in force) is kept as written and resolved
//! when the chunk is stitched. A chunk stops at its first line it cannot read and keeps
//! what that line had read; stitching resolves that part first, so the error is the one a
//! line-by-line reader gives: the first in file order, same file, line, field and words.

use rayon::prelude::*;

use super::{parse_number, resolve_index, rest_after_keyword, MtlLib, ObjFace, ObjMesh, OBJ_FREEFORM, OBJ_IGNORED};
use crate::chunks::{line_chunks, line_count, window_chunks, CHUNK_BYTES};
use crate::error::SceneError;
use crate::mesh::shown;
use crate::model::{SourceLoc, MAX_COORDINATE};
use glam::{DVec2, DVec3};

/// A face corner as written: its `v`, `vt` and `vn` indices (1-based or negative), the
/// last two where it names them.
type RawCorner = (i64, Option<i64>, Option<i64>);

/// A face statement of a chunk, its corners not yet resolved.
struct RawPolygon {
    /// Its corners: `RawParse::corners[first..first + len]`.
    first: usize,
    len: usize,
    /// Positions, texture coordinates and normals the chunk had defined before it.
    counts: [usize; 3],
    /// Line in the chunk (1-based).
    line: u32,
    /// The chunk's `usemtl` in force (an index into `RawParse::usemtl_names`), or `None`
    /// for the one in force where the chunk starts.
    usemtl: Option<u32>,
}

/// The line a chunk stopped at: what it had read of it (the corners of a face) and why
/// it could not go on.
struct Stop {
    polygon: RawPolygon,
    message: String,
}

/// One chunk, parsed.
#[derive(Default)]
struct RawParse {
    positions: Vec<DVec3>,
    uvs: Vec<DVec2>,
    normals: Vec<DVec3>,
    corners: Vec<RawCorner>,
    polygons: Vec<RawPolygon>,
    /// Distinct `usemtl` names, in order of first use in the chunk.
    usemtl_names: Vec<String>,
    /// `mtllib` files, their lines in the chunk.
    mtllibs: Vec<MtlLib>,
    /// The `usemtl` in force where the chunk ends, if it has one.
    usemtl: Option<u32>,
    /// Lines in the chunk.
    lines: usize,
    stop: Option<Stop>,
}

/// Parses an OBJ text; `label` names it in errors. Each chunk is handed to `visit` once
/// stitched, as the mesh so far (positions, normals, texture coordinates,
/// `mtllib`s and `usemtl` names, but no faces) and its new faces, so a caller need not
/// keep the faces. Gives the mesh without faces, or the first error in file order (after
/// handing on the chunks before it). `chunk_bytes` is [`CHUNK_BYTES`] but for tests.
pub(super) fn stream(
    label: &str,
    text: &str,
    chunk_bytes: usize,
    visit: &mut dyn FnMut(&ObjMesh, &[ObjFace]),
) -> Result<ObjMesh, SceneError> {
    let chunks = line_chunks(text.as_bytes(), chunk_bytes);
    let mut stitch = Stitch { mesh: ObjMesh::default(), current: None, lines: 0 };
    let mut faces = Vec::new();
    for window in chunks.chunks(window_chunks()) {
        let parsed: Vec<RawParse> = window.par_iter().map(|r| parse_chunk(text.get(r.clone()).unwrap_or(""))).collect();
        // Handed on chunk by chunk: a run of a chunk's triangles stays small enough for
        // the allocator to reuse its memory rather than map fresh pages every time.
        for chunk in parsed {
            stitch.absorb(label, chunk, &mut faces)?;
            visit(&stitch.mesh, &faces);
            faces.clear();
        }
    }
    Ok(stitch.mesh)
}

/// [`stream`] keeping every face: the whole mesh.
#[cfg(test)]
pub(super) fn parse(label: &str, text: &str, chunk_bytes: usize) -> Result<ObjMesh, SceneError> {
    let mut faces = Vec::new();
    let mut mesh = stream(label, text, chunk_bytes, &mut |_, new| faces.extend_from_slice(new))?;
    mesh.faces = faces;
    Ok(mesh)
}

/// The default chunk size, for callers outside this module.
pub(super) const DEFAULT_CHUNK_BYTES: usize = CHUNK_BYTES;

/// Parses one chunk as if it were a file of its own, keeping what depends on the lines
/// before it unresolved; stops at the first line it cannot read.
fn parse_chunk(text: &str) -> RawParse {
    let mut out = RawParse { lines: line_count(text.as_bytes()), ..RawParse::default() };
    let mut current: Option<u32> = None;
    for (n, raw_line) in text.lines().enumerate() {
        let line = u32::try_from(n + 1).unwrap_or(u32::MAX);
        if let Err((message, polygon)) = parse_line(&mut out, &mut current, raw_line, line) {
            let polygon = polygon.unwrap_or(RawPolygon {
                first: out.corners.len(),
                len: 0,
                counts: [0; 3],
                line,
                usemtl: current,
            });
            out.stop = Some(Stop { polygon, message });
            break;
        }
    }
    out.usemtl = current;
    out
}

/// What a line that cannot be read gives: the message and, for a face, the corners it
/// read before the bad one.
type LineError = (String, Option<RawPolygon>);

/// Parses one line of a chunk into `out`.
fn parse_line(out: &mut RawParse, current: &mut Option<u32>, raw_line: &str, line: u32) -> Result<(), LineError> {
    let plain = |m: String| (m, None);
    let content = raw_line.split('#').next().unwrap_or("").trim();
    let mut tokens = content.split_whitespace();
    let Some(keyword) = tokens.next() else {
        return Ok(());
    };
    match keyword {
        "v" => {
            let (xyz, count) = numbers("v", tokens, |x| {
                if x.abs() > MAX_COORDINATE {
                    return Err(format!("{x:e} is out of range [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}]"));
                }
                Ok(())
            })
            .map_err(plain)?;
            if !(3..=7).contains(&count) {
                return Err(plain(format!("v needs 3 coordinates, found {count} numbers")));
            }
            out.positions.push(DVec3::from_array(xyz));
        }
        "vt" => {
            let ([u, v, _], count) = numbers("vt", tokens, |_| Ok(())).map_err(plain)?;
            // `vt u [v [w]]`: v defaults to 0, w is ignored.
            if !(1..=3).contains(&count) {
                return Err(plain(format!("vt needs 1 to 3 numbers, found {count}")));
            }
            out.uvs.push(DVec2::new(u, v));
        }
        "vn" => {
            let (xyz, count) = numbers("vn", tokens, |_| Ok(())).map_err(plain)?;
            if count != 3 {
                return Err(plain(format!("vn needs 3 numbers, found {count}")));
            }
            out.normals.push(DVec3::from_array(xyz));
        }
        "f" => {
            let first = out.corners.len();
            let counts = [out.positions.len(), out.uvs.len(), out.normals.len()];
            let polygon = |len| RawPolygon { first, len, counts, line, usemtl: *current };
            for tok in tokens {
                match parse_corner(tok) {
                    Ok(c) => out.corners.push(c),
                    Err(m) => return Err((format!("f: {m}"), Some(polygon(out.corners.len() - first)))),
                }
            }
            let len = out.corners.len() - first;
            if len < 3 {
                return Err((format!("f needs at least 3 vertices, found {len}"), Some(polygon(len))));
            }
            out.polygons.push(polygon(len));
        }
        "usemtl" => {
            let name = rest_after_keyword(content, keyword);
            if name.is_empty() {
                return Err(plain("usemtl needs a material name".to_string()));
            }
            let k = match out.usemtl_names.iter().position(|m| m == name) {
                Some(k) => k,
                None => {
                    out.usemtl_names.push(name.to_string());
                    out.usemtl_names.len() - 1
                }
            };
            *current = Some(u32::try_from(k).unwrap_or(u32::MAX));
        }
        "mtllib" => {
            let before = out.mtllibs.len();
            out.mtllibs.extend(tokens.map(|t| MtlLib { file: t.to_string(), line }));
            if out.mtllibs.len() == before {
                return Err(plain("mtllib needs a file name".to_string()));
            }
        }
        k if OBJ_IGNORED.contains(&k) => {}
        k if OBJ_FREEFORM.contains(&k) => {
            return Err(plain(format!("free-form geometry ('{k}') is not supported: export triangles or polygons")));
        }
        k => return Err(plain(format!("unknown statement {}", shown(k)))),
    }
    Ok(())
}

/// The numbers of a `v`, `vt` or `vn` statement: the first three (0 where there are
/// fewer) and how many there are, each finite and passing `check`; or the first that is
/// not, with the keyword.
fn numbers<'t>(
    keyword: &str,
    tokens: impl Iterator<Item = &'t str>,
    check: impl Fn(f64) -> Result<(), String>,
) -> Result<([f64; 3], usize), String> {
    let mut first = [0.0; 3];
    let mut count = 0;
    for tok in tokens {
        let x = parse_number(tok).and_then(|x| check(x).map(|()| x)).map_err(|m| format!("{keyword}: {m}"))?;
        if let Some(slot) = first.get_mut(count) {
            *slot = x;
        }
        count += 1;
    }
    Ok((first, count))
}

/// One face corner as written (`v`, `v/vt`, `v//vn`, `v/vt/vn`), or why it is not one.
/// Whether its indices are in range depends on the lines before: [`resolve`] says.
fn parse_corner(tok: &str) -> Result<RawCorner, String> {
    let bad = || format!("{} is not a vertex reference (v, v/vt, v//vn or v/vt/vn)", shown(tok));
    let mut parts = tok.split('/');
    let v = parts.next().unwrap_or("");
    let mut rest = [None, None];
    for slot in &mut rest {
        match parts.next() {
            Some("") | None => {}
            Some(p) => *slot = Some(p.parse::<i64>().map_err(|_| bad())?),
        }
    }
    if parts.next().is_some() {
        return Err(bad());
    }
    let i: i64 = v.parse().map_err(|_| format!("{} is not a vertex index", shown(tok)))?;
    Ok((i, rest[0], rest[1]))
}

/// A corner's 0-based position, texture coordinate and normal indices, checked against
/// the `counts` defined before its face.
fn resolve(c: RawCorner, counts: [usize; 3]) -> Result<[Option<u32>; 3], String> {
    let index = |i: i64, count: usize, what: &str, plural: &str| {
        let k = resolve_index(i, count, what, plural)?;
        u32::try_from(k).map_err(|_| format!("{what} index {i} is out of range"))
    };
    let v = index(c.0, counts[0], "vertex", "vertices")?;
    let vt = c.1.map(|j| index(j, counts[1], "texture coordinate", "texture coordinates (vt)")).transpose()?;
    let vn = c.2.map(|j| index(j, counts[2], "normal", "normals (vn)")).transpose()?;
    Ok([Some(v), vt, vn])
}

/// The mesh as stitched so far.
struct Stitch {
    /// Everything but the faces, which are handed on.
    mesh: ObjMesh,
    /// The `usemtl` in force (an index into `mesh.usemtl_names`).
    current: Option<u32>,
    /// Lines before the next chunk.
    lines: usize,
}

impl Stitch {
    /// Appends a parsed chunk: its definitions to the mesh, its faces (resolved) to
    /// `faces`; or gives the first error in it.
    fn absorb(&mut self, label: &str, chunk: RawParse, faces: &mut Vec<ObjFace>) -> Result<(), SceneError> {
        let line_of = |local: u32| u32::try_from(self.lines.saturating_add(local as usize)).unwrap_or(u32::MAX);
        let err = |local: u32, msg: String| {
            SceneError::new(SourceLoc { file: label.into(), line: line_of(local) }, "obj", msg)
        };
        let base = [self.mesh.positions.len(), self.mesh.uvs.len(), self.mesh.normals.len()];
        let names: Vec<u32> = chunk
            .usemtl_names
            .into_iter()
            .map(|name| {
                let k = match self.mesh.usemtl_names.iter().position(|m| *m == name) {
                    Some(k) => k,
                    None => {
                        self.mesh.usemtl_names.push(name);
                        self.mesh.usemtl_names.len() - 1
                    }
                };
                u32::try_from(k).unwrap_or(u32::MAX)
            })
            .collect();
        self.mesh.positions.extend_from_slice(&chunk.positions);
        self.mesh.uvs.extend_from_slice(&chunk.uvs);
        self.mesh.normals.extend_from_slice(&chunk.normals);
        self.mesh.mtllibs.extend(chunk.mtllibs.into_iter().map(|l| MtlLib { line: line_of(l.line), ..l }));
        let mut corners = Vec::new();
        let mut fan = |p: &RawPolygon, out: Option<&mut Vec<ObjFace>>| -> Result<(), SceneError> {
            let counts = [0, 1, 2].map(|k| base[k] + p.counts[k]);
            corners.clear();
            for &c in chunk.corners.get(p.first..p.first + p.len).unwrap_or(&[]) {
                corners.push(resolve(c, counts).map_err(|m| err(p.line, format!("f: {m}")))?);
            }
            let Some(out) = out else { return Ok(()) };
            let usemtl = p.usemtl.map(|k| names.get(k as usize).copied().unwrap_or(u32::MAX)).or(self.current);
            let line = line_of(p.line);
            let (first, rest) = corners.split_first().map_or((None, &[][..]), |(f, r)| (Some(*f), r));
            let Some(first) = first else { return Ok(()) };
            for pair in rest.windows(2) {
                let (b, c) = (pair[0], pair[1]);
                let all = |k: usize| match (first[k], b[k], c[k]) {
                    (Some(x), Some(y), Some(z)) => Some([x, y, z]),
                    _ => None,
                };
                let corners = all(0).unwrap_or_default();
                out.push(ObjFace { corners, uvs: all(1), normals: all(2), usemtl, line });
            }
            Ok(())
        };
        for p in &chunk.polygons {
            fan(p, Some(faces))?;
        }
        if let Some(stop) = &chunk.stop {
            fan(&stop.polygon, None)?;
            return Err(err(stop.polygon.line, stop.message.clone()));
        }
        if let Some(k) = chunk.usemtl {
            self.current = names.get(k as usize).copied();
        }
        self.lines += chunk.lines;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
