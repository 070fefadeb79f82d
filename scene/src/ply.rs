//! Stanford PLY import for `[[mesh]]` entries: ASCII, binary little-endian and binary
//! big-endian.
//!
//! Read: the `vertex` element's `x`, `y`, `z` (any scalar type) and, when all three are
//! there, its `nx`, `ny`, `nz`; the `face` element's `vertex_indices` (or
//! `vertex_index`) list, polygons fan-triangulated as (0,1,2), (0,2,3), ... like OBJ
//! faces. Every other element and property is read past and ignored (colours, texture
//! coordinates, `edge`, `material`, ...).
//!
//! PLY has no agreed winding. Where the vertices carry normals, a triangle whose winding
//! disagrees with the sum of its corners' normals has two corners swapped, so that the
//! patch faces the way the file's normals say; without normals the winding is kept.
//! PLY files carry no materials a renderer agrees on: a PLY mesh takes the
//! `material =` of its `[[mesh]]`.
//!
//! Errors name the file and, in the header and in ASCII data, the line; in binary data
//! the element and its byte offset (a truncated file says where it ends). No input
//! panics, and no error shows what a file that is not a PLY holds.

use super::error::SceneError;
use super::mesh::{shown, MeshEntry, ModelTriangle, MAX_MESH_TRIANGLES};
use super::model::{SourceLoc, MAX_COORDINATE};
use glam::DVec3;

/// Largest header read, in bytes: far past any real header, so that a file that is not
/// a PLY is refused before it is scanned whole.
const MAX_HEADER_BYTES: usize = 1 << 20;

/// Reads a PLY mesh and returns its triangles in the model's space, all with the entry's
/// `material =` (a PLY has none of its own).
pub(super) fn load(entry: &MeshEntry<'_>, label: &str, bytes: &[u8]) -> Result<Vec<ModelTriangle>, SceneError> {
    let mesh = parse_ply(label, bytes)?;
    let Some(material) = entry.material else {
        return Err(entry.no_material(&format!("{label} (a PLY file has no materials)")));
    };
    Ok(mesh
        .triangles
        .into_iter()
        .map(|(v, normals)| ModelTriangle { v, material, normals, uv: None, texture: None })
        .collect())
}

/// A PLY file's triangles, in file order, oriented by the vertex normals if any.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct PlyMesh {
    /// The triangles (zero-area ones included: placement skips them), with their corners'
    /// normals where the vertices carry them.
    pub triangles: Vec<PlyTriangle>,
    /// Whether the vertices carried normals.
    pub normals: bool,
}

/// How the data after the header is written.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Ascii,
    Binary { big_endian: bool },
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The range of an integer type.
    fn int_range(self) -> (f64, f64) {
        match self {
            Scalar::I8 => (-128.0, 127.0),
            Scalar::U8 => (0.0, 255.0),
            Scalar::I16 => (-32768.0, 32767.0),
            Scalar::U16 => (0.0, 65535.0),
            Scalar::I32 => (-2147483648.0, 2147483647.0),
            Scalar::U32 => (0.0, 4294967295.0),
            Scalar::F32 | Scalar::F64 => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
}

/// A property of an element: a scalar or a list (its count type, its item type).
#[derive(Clone, Debug, PartialEq)]
enum Property {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

/// An `element` of the header with its properties.
#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<(String, Property)>,
}

/// The header: the encoding, the elements, where the data starts and on which line.
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    data_start: usize,
    data_line: u32,
}

/// Parses a PLY file; `label` names it in errors. Its data is read in chunks on every
/// core ([`parallel`]); a file that way cannot read (every file with an error) is read
/// value after value, which says where and why.
pub(super) fn parse_ply(label: &str, bytes: &[u8]) -> Result<PlyMesh, SceneError> {
    parse_ply_in(label, bytes, Some(crate::chunks::CHUNK_BYTES))
}

/// [`parse_ply`] with the data in chunks of about `chunk_bytes`, or (`None`) read value
/// after value only.
fn parse_ply_in(label: &str, bytes: &[u8], chunk_bytes: Option<usize>) -> Result<PlyMesh, SceneError> {
    let at = |line: u32, msg: String| SceneError::new(SourceLoc { file: label.into(), line }, "ply", msg);
    let header = parse_header(bytes).map_err(|(line, msg)| at(line, msg))?;
    if let Some(mesh) = chunk_bytes.and_then(|c| parallel::read(&header, bytes, c)) {
        return Ok(mesh);
    }
    let mut data = Data {
        bytes,
        pos: header.data_start,
        encoding: header.encoding,
        line: header.data_line - 1,
        tokens: "".split_ascii_whitespace(),
    };
    read_body(&header, &mut data).map_err(|msg| match header.encoding {
        Encoding::Ascii => at(data.line, msg),
        Encoding::Binary { .. } => at(0, msg),
    })
}

/// Reads the header, or gives the line and what is wrong.
fn parse_header(bytes: &[u8]) -> Result<Header, (u32, String)> {
    let mut pos = 0;
    let mut line = 0u32;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line += 1;
        let Some(len) = bytes.get(pos..).and_then(|rest| rest.iter().position(|&b| b == b'\n')) else {
            let msg = if line == 1 { "not a PLY file (no 'ply' line)" } else { "the header has no end_header line" };
            return Err((line, msg.to_string()));
        };
        if pos + len > MAX_HEADER_BYTES {
            return Err((line, format!("the header is longer than {} KiB: not a PLY file?", MAX_HEADER_BYTES >> 10)));
        }
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        let Ok(text) = std::str::from_utf8(raw) else {
            return Err((line, "not UTF-8 text in the header".to_string()));
        };
        let text = text.strip_suffix('\r').unwrap_or(text);
        let mut tokens = text.split_ascii_whitespace();
        let keyword = tokens.next().unwrap_or("");
        if line == 1 {
            if text.trim() != "ply" {
                return Err((line, "not a PLY file (it does not start with a 'ply' line)".to_string()));
            }
            continue;
        }
        match keyword {
            "format" => {
                let kind = tokens.next().unwrap_or("");
                encoding = Some(match kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Binary { big_endian: false },
                    "binary_big_endian" => Encoding::Binary { big_endian: true },
                    other => return Err((line, format!("unknown format {}", shown(other)))),
                });
                if tokens.next() != Some("1.0") {
                    return Err((line, "only PLY version 1.0 is read".to_string()));
                }
            }
            "comment" | "obj_info" | "" => {}
            "element" => {
                let (Some(name), Some(count), None) = (tokens.next(), tokens.next(), tokens.next()) else {
                    return Err((line, "element needs a name and a count".to_string()));
                };
                let count: u64 =
                    count.parse().map_err(|_| (line, format!("element count {} is not a number", shown(count))))?;
                elements.push(Element { name: name.to_string(), count, properties: Vec::new() });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err((line, "property before any element".to_string()));
                };
                let words: Vec<&str> = tokens.collect();
                let scalar = |w: &str| Scalar::parse(w).ok_or_else(|| (line, format!("unknown type {}", shown(w))));
                let (name, property) = match words.as_slice() {
                    ["list", count, item, name] => {
                        let count = scalar(count)?;
                        if !count.is_integer() {
                            return Err((line, "a list's count must have an integer type".to_string()));
                        }
                        (*name, Property::List(count, scalar(item)?))
                    }
                    [ty, name] => (*name, Property::Scalar(scalar(ty)?)),
                    _ => return Err((line, "property needs a type and a name".to_string())),
                };
                element.properties.push((name.to_string(), property));
            }
            "end_header" => break,
            other => return Err((line, format!("unknown header line {}", shown(other)))),
        }
    }
    let Some(encoding) = encoding else {
        return Err((line, "the header has no format line".to_string()));
    };
    Ok(Header { encoding, elements, data_start: pos, data_line: line + 1 })
}

/// The data after the header, read value by value.
struct Data<'b> {
    bytes: &'b [u8],
    pos: usize,
    encoding: Encoding,
    /// ASCII: the line of the element being read.
    line: u32,
    /// ASCII: the values left on that line.
    tokens: std::str::SplitAsciiWhitespace<'b>,
}

impl<'b> Data<'b> {
    /// Starts an element: in ASCII, its line (blank lines are skipped).
    fn begin(&mut self) -> Result<(), String> {
        if self.encoding != Encoding::Ascii {
            return Ok(());
        }
        loop {
            let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
            if rest.is_empty() {
                self.line += 1;
                return Err("the file ends early (truncated?)".to_string());
            }
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            self.pos += len + 1;
            self.line += 1;
            let text = std::str::from_utf8(&rest[..len]).map_err(|_| "not UTF-8 text".to_string())?;
            self.tokens = text.split_ascii_whitespace();
            if !text.trim().is_empty() {
                return Ok(());
            }
        }
    }

    /// Ends an element: in ASCII, nothing may be left on its line.
    fn end(&mut self) -> Result<(), String> {
        match self.tokens.next() {
            Some(_) => Err("more values on the line than the header's properties".to_string()),
            None => Ok(()),
        }
    }

    /// The next value, of type `s`.
    fn value(&mut self, s: Scalar) -> Result<f64, String> {
        match self.encoding {
            Encoding::Ascii => {
                let tok = self.tokens.next().ok_or("fewer values on the line than the header's properties")?;
                let x: f64 = tok.parse().map_err(|_| format!("{} is not a number", shown(tok)))?;
                let (lo, hi) = s.int_range();
                if s.is_integer() && (x.fract() != 0.0 || x < lo || x > hi) {
                    return Err(format!("{} is not a value of the property's integer type", shown(tok)));
                }
                Ok(x)
            }
            Encoding::Binary { big_endian } => {
                let n = s.size();
                let Some(b) = self.pos.checked_add(n).and_then(|end| self.bytes.get(self.pos..end)) else {
                    return Err(format!("the file ends at byte {} (truncated?)", self.bytes.len()));
                };
                self.pos += n;
                let mut a = [0u8; 8];
                a[..n].copy_from_slice(b);
                if big_endian {
                    a[..n].reverse();
                }
                let [b0, b1, b2, b3, ..] = a;
                Ok(match s {
                    Scalar::I8 => f64::from(b0 as i8),
                    Scalar::U8 => f64::from(b0),
                    Scalar::I16 => f64::from(i16::from_le_bytes([b0, b1])),
                    Scalar::U16 => f64::from(u16::from_le_bytes([b0, b1])),
                    Scalar::I32 => f64::from(i32::from_le_bytes([b0, b1, b2, b3])),
                    Scalar::U32 => f64::from(u32::from_le_bytes([b0, b1, b2, b3])),
                    Scalar::F32 => f64::from(f32::from_le_bytes([b0, b1, b2, b3])),
                    Scalar::F64 => f64::from_le_bytes(a),
                })
            }
        }
    }
}

/// Where the vertex element keeps its coordinates and normals.
struct VertexLayout {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
}

/// An element's role in the mesh: where the vertex element keeps its coordinates, and
/// which property of the face element is its corner list.
struct Roles {
    vertex: Option<VertexLayout>,
    face_list: Option<usize>,
}

/// What an element's roles are, or why the element cannot be read.
fn roles(element: &Element) -> Result<Roles, String> {
    let find = |e: &Element, name: &str| e.properties.iter().position(|(n, _)| n == name);
    let vertex = (element.name == "vertex")
        .then(|| {
            let xyz = [find(element, "x"), find(element, "y"), find(element, "z")];
            let nxyz = [find(element, "nx"), find(element, "ny"), find(element, "nz")];
            match xyz {
                [Some(x), Some(y), Some(z)] => Ok(VertexLayout {
                    xyz: [x, y, z],
                    normal: match nxyz {
                        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                        _ => None,
                    },
                }),
                _ => Err("the vertex element has no x, y and z properties".to_string()),
            }
        })
        .transpose()?;
    let face_list =
        if element.name == "face" { find(element, "vertex_indices").or(find(element, "vertex_index")) } else { None };
    if element.name == "face" && face_list.is_none() {
        return Err("the face element has no vertex_indices list".to_string());
    }
    if let Some(k) = face_list {
        if !matches!(element.properties.get(k), Some((_, Property::List(_, item))) if item.is_integer()) {
            return Err("the face element's vertex_indices is not a list of integers".to_string());
        }
    }
    Ok(Roles { vertex, face_list })
}

/// What the elements read so far hold: vertex positions and normals, and the polygons'
/// corners.
#[derive(Default)]
struct Body {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    corners: Vec<u32>,
    /// Polygons as (first index into `corners`, corner count, line, index in element).
    polygons: Vec<(usize, usize, u32, u64)>,
}

/// Reads instance `i` of `element` from `data` into `body`; `scalars` is scratch, one
/// slot per property. Errors say which instance (the caller adds the line or, in
/// binary, says it has none).
fn read_instance(
    element: &Element,
    roles: &Roles,
    i: u64,
    data: &mut Data<'_>,
    scalars: &mut [f64],
    body: &mut Body,
) -> Result<(), String> {
    let (start, encoding) = (data.pos, data.encoding);
    let where_ = |msg: String| match encoding {
        Encoding::Ascii => format!("{} {i}: {msg}", element.name),
        Encoding::Binary { .. } => format!("{} {i} (byte {start}): {msg}", element.name),
    };
    data.begin().map_err(where_)?;
    for (k, (_, property)) in element.properties.iter().enumerate() {
        match property {
            Property::Scalar(s) => scalars[k] = data.value(*s).map_err(where_)?,
            Property::List(count_type, item) => {
                let n = data.value(*count_type).map_err(where_)?;
                if n < 0.0 {
                    return Err(where_(format!("a list of {n} items")));
                }
                let n = n as u64;
                let is_face = roles.face_list == Some(k);
                if is_face {
                    if n < 3 {
                        return Err(where_(format!("a face needs at least 3 vertices, found {n}")));
                    }
                    body.polygons.push((body.corners.len(), 0, data.line, i));
                }
                for _ in 0..n {
                    let x = data.value(*item).map_err(where_)?;
                    if is_face {
                        if x < 0.0 || x > f64::from(u32::MAX) {
                            return Err(where_(format!("vertex index {x} is out of range")));
                        }
                        body.corners.push(x as u32);
                    }
                }
                if let (true, Some(p)) = (is_face, body.polygons.last_mut()) {
                    p.1 = n as usize;
                }
            }
        }
    }
    data.end().map_err(where_)?;
    if let Some(v) = &roles.vertex {
        let p = DVec3::new(scalars[v.xyz[0]], scalars[v.xyz[1]], scalars[v.xyz[2]]);
        if !p.is_finite() || p.abs().max_element() > MAX_COORDINATE {
            let msg = format!("vertex {p:?} is not finite or out of range [-{MAX_COORDINATE:e}, {MAX_COORDINATE:e}]");
            return Err(where_(msg));
        }
        body.positions.push(p);
        if let Some(n) = v.normal {
            body.normals.push(DVec3::new(scalars[n[0]], scalars[n[1]], scalars[n[2]]));
        }
    }
    Ok(())
}

/// Reads every element after the header, one value after the other; errors say which
/// element (the caller adds the line or, in binary, says it has none). The reference for
/// [`parallel`], and the reader of the files it leaves (every file with an error).
fn read_body(header: &Header, data: &mut Data<'_>) -> Result<PlyMesh, String> {
    let mut body = Body::default();
    let mut has_normals = false;
    // A bound on how many elements the data can still hold (each takes a byte at least),
    // so that a header's count cannot reserve more memory than the file backs.
    let room = data.bytes.len();
    for element in &header.elements {
        let roles = roles(element)?;
        if roles.vertex.is_some() {
            has_normals = roles.vertex.as_ref().is_some_and(|v| v.normal.is_some());
            let cap = usize::try_from(element.count).unwrap_or(usize::MAX).min(room);
            body.positions.reserve(cap);
        }
        let mut scalars = vec![0.0; element.properties.len()];
        for i in 0..element.count {
            let start = data.pos;
            read_instance(element, &roles, i, data, &mut scalars, &mut body)?;
            if body.corners.len() > 3 * MAX_MESH_TRIANGLES {
                return Err(match data.encoding {
                    Encoding::Ascii => format!("{} {i}: more than {MAX_MESH_TRIANGLES} triangles", element.name),
                    Encoding::Binary { .. } => {
                        format!("{} {i} (byte {start}): more than {MAX_MESH_TRIANGLES} triangles", element.name)
                    }
                });
            }
        }
    }
    // Bytes after the last element are ignored (some writers pad).
    triangles(&body, has_normals).map_err(|(line, msg)| {
        data.line = line;
        msg
    })
}

/// A triangle of the mesh and its corners' normals.
type PlyTriangle = ([DVec3; 3], Option<[DVec3; 3]>);

/// A polygon of [`Body::polygons`].
type Polygon = (usize, usize, u32, u64);

/// The mesh of what the elements held: each polygon fan-triangulated, oriented by its
/// corners' normals where the vertices carry them; or the line of the first polygon
/// with a corner out of range, and why.
fn triangles(body: &Body, has_normals: bool) -> Result<PlyMesh, (u32, String)> {
    Ok(PlyMesh { triangles: triangles_of(body, &body.polygons)?, normals: has_normals })
}

/// The triangles of `polygons`, a run of `body`'s, as [`triangles`] makes them.
fn triangles_of(body: &Body, polygons: &[Polygon]) -> Result<Vec<PlyTriangle>, (u32, String)> {
    let (positions, normals, corners) = (&body.positions, &body.normals, &body.corners);
    let corner_count: usize = polygons.iter().map(|p| p.1).sum();
    let mut triangles = Vec::with_capacity(corner_count.saturating_sub(2 * polygons.len()));
    for &(first, n, line, i) in polygons {
        let ids = corners.get(first..first + n).unwrap_or(&[]);
        let vertex = |k: u32| {
            positions.get(k as usize).copied().map(|p| (p, normals.get(k as usize).copied())).ok_or_else(|| {
                (line, format!("face {i}: vertex index {k} is out of range: {} vertices", positions.len()))
            })
        };
        let Some((&first_id, rest)) = ids.split_first() else { continue };
        let a = vertex(first_id)?;
        for pair in rest.windows(2) {
            let (b, c) = (vertex(pair[0])?, vertex(pair[1])?);
            let mut t = [a.0, b.0, c.0];
            let mut normals = None;
            if let (Some(na), Some(nb), Some(nc)) = (a.1, b.1, c.1) {
                let mut n = [na, nb, nc];
                if (t[1] - t[0]).cross(t[2] - t[0]).dot(na + nb + nc) < 0.0 {
                    t.swap(1, 2);
                    n.swap(1, 2);
                }
                normals = Some(n);
            }
            triangles.push((t, normals));
        }
    }
    Ok(triangles)
}

mod parallel;
#[cfg(test)]
pub(super) mod tests;
