//! The PLY reader's fast path: the data is cut into runs of element instances, which are
//! read on every core by the same [`read_instance`] the value-after-value reader uses,
//! and joined in file order.
//!
//! ASCII data is cut at line ends; a first pass counts each chunk's non-blank lines, which
//! says which instance each chunk starts with. Binary data is cut by byte offset where an
//! element's instances have a fixed size, and where they hold lists (faces) a first pass
//! reads only the lists' lengths to find where each run starts.
//!
//! Anything this path does not read cleanly (an error anywhere, a header with two vertex
//! or face elements, too many triangles) gives `None`, and the caller reads the file
//! value after value, whose answer (the mesh, or the error with its line or byte) is
//! then the answer. So the fast path only ever gives what that reader would.

use rayon::prelude::*;

use super::{
    read_instance, roles, triangles_of, Body, Data, Element, Encoding, Header, PlyMesh, Property, Roles,
    MAX_MESH_TRIANGLES,
};
use crate::chunks::line_chunks;

/// Instances per run of an element with lists (its faces).
const LIST_RUN: u64 = 1 << 14;

/// Polygons per task when they are made into triangles.
const POLYGON_RUN: usize = 1 << 15;

/// A run of instances to read: element, first instance, count, byte where it starts.
type Run = (usize, u64, u64, usize);

/// Reads the data after `header` on every core, or `None` where the file is anything but
/// clean (see the module doc).
pub(super) fn read(header: &Header, bytes: &[u8], chunk_bytes: usize) -> Option<PlyMesh> {
    let roles: Vec<Roles> = header.elements.iter().map(roles).collect::<Result<_, _>>().ok()?;
    let named = |name: &str| header.elements.iter().filter(|e| e.name == name).count();
    if named("vertex") > 1 || named("face") > 1 {
        return None;
    }
    let parts = match header.encoding {
        Encoding::Ascii => ascii(header, &roles, bytes, chunk_bytes)?,
        Encoding::Binary { .. } => binary(header, &roles, bytes, chunk_bytes)?,
    };
    let body = join(parts);
    if body.corners.len() > 3 * MAX_MESH_TRIANGLES {
        return None;
    }
    let has_normals = roles.iter().any(|r| r.vertex.as_ref().is_some_and(|v| v.normal.is_some()));
    let runs: Vec<Vec<_>> =
        body.polygons.par_chunks(POLYGON_RUN).map(|ps| triangles_of(&body, ps).ok()).collect::<Option<_>>()?;
    Some(PlyMesh { triangles: runs.concat(), normals: has_normals })
}

/// The parts read by each run, joined in order (corner indices of the polygons moved to
/// the joined list).
fn join(parts: Vec<Body>) -> Body {
    let mut body = Body::default();
    for part in parts {
        let base = body.corners.len();
        body.positions.extend_from_slice(&part.positions);
        body.normals.extend_from_slice(&part.normals);
        body.corners.extend_from_slice(&part.corners);
        body.polygons.extend(part.polygons.into_iter().map(|(first, n, line, i)| (first + base, n, line, i)));
    }
    body
}

/// Reads `runs` in parallel, each from its own cursor into `bytes`.
fn read_runs(header: &Header, roles: &[Roles], bytes: &[u8], runs: &[Run]) -> Option<Vec<Body>> {
    runs.par_iter()
        .map(|&(e, first, count, pos)| {
            let element = header.elements.get(e)?;
            let mut data = Data { bytes, pos, encoding: header.encoding, line: 0, tokens: "".split_ascii_whitespace() };
            read_part(element, roles.get(e)?, first, count, &mut data)
        })
        .collect()
}

/// Reads `count` instances of `element` from `first` on.
fn read_part(element: &Element, roles: &Roles, first: u64, count: u64, data: &mut Data<'_>) -> Option<Body> {
    let mut body = Body::default();
    let mut scalars = vec![0.0; element.properties.len()];
    for i in first..first + count {
        read_instance(element, roles, i, data, &mut scalars, &mut body).ok()?;
    }
    Some(body)
}

/// ASCII data: one instance per non-blank line, cut at line ends.
fn ascii(header: &Header, roles: &[Roles], bytes: &[u8], chunk_bytes: usize) -> Option<Vec<Body>> {
    let data = bytes.get(header.data_start..)?;
    let chunks = line_chunks(data, chunk_bytes);
    // Blank as `Data::begin` sees them: nothing but whitespace between two `\n`s.
    let lines: Vec<u64> = chunks
        .par_iter()
        .map(|r| {
            let text = std::str::from_utf8(data.get(r.clone())?).ok()?;
            Some(text.split_terminator('\n').filter(|l| !l.trim().is_empty()).count() as u64)
        })
        .collect::<Option<_>>()?;
    // Where each element's instances start, counted over all elements.
    let mut starts = Vec::with_capacity(header.elements.len() + 1);
    let mut total = 0u64;
    for e in &header.elements {
        starts.push(total);
        total = total.checked_add(e.count)?;
    }
    starts.push(total);
    if lines.iter().sum::<u64>() < total {
        return None;
    }
    // Each chunk's instances, as runs split where an element ends, read on from the
    // chunk's first byte.
    let mut groups: Vec<(usize, Vec<(usize, u64, u64)>)> = Vec::new();
    let mut g = 0u64;
    for (r, n) in chunks.iter().zip(&lines) {
        let end = (g + n).min(total);
        let mut group = Vec::new();
        while g < end {
            let e = starts.partition_point(|&s| s <= g) - 1;
            let stop = end.min(starts[e + 1]);
            group.push((e, g - starts[e], stop - g));
            g = stop;
        }
        if !group.is_empty() {
            groups.push((header.data_start + r.start, group));
        }
    }
    let parts: Vec<Vec<Body>> = groups
        .par_iter()
        .map(|(pos, group)| {
            let mut data =
                Data { bytes, pos: *pos, encoding: Encoding::Ascii, line: 0, tokens: "".split_ascii_whitespace() };
            group
                .iter()
                .map(|&(e, first, count)| read_part(header.elements.get(e)?, roles.get(e)?, first, count, &mut data))
                .collect::<Option<Vec<Body>>>()
        })
        .collect::<Option<_>>()?;
    Some(parts.into_iter().flatten().collect())
}

/// Binary data: runs of fixed-size instances cut by offset, runs of instances with
/// lists found by reading the lists' lengths.
fn binary(header: &Header, roles: &[Roles], bytes: &[u8], chunk_bytes: usize) -> Option<Vec<Body>> {
    let mut runs: Vec<Run> = Vec::new();
    let mut pos = header.data_start;
    for (e, element) in header.elements.iter().enumerate() {
        let fixed: Option<usize> = element
            .properties
            .iter()
            .map(|(_, p)| match p {
                Property::Scalar(s) => Some(s.size()),
                Property::List(..) => None,
            })
            .sum();
        match fixed {
            Some(size) => {
                if size == 0 && element.count > 0 {
                    return None;
                }
                let end = usize::try_from(element.count).ok()?.checked_mul(size)?.checked_add(pos)?;
                if end > bytes.len() {
                    return None;
                }
                let per = (chunk_bytes / size.max(1)).max(1) as u64;
                let mut first = 0;
                while first < element.count {
                    let n = per.min(element.count - first);
                    runs.push((e, first, n, pos + first as usize * size));
                    first += n;
                }
                pos = end;
            }
            None => {
                let mut data =
                    Data { bytes, pos, encoding: header.encoding, line: 0, tokens: "".split_ascii_whitespace() };
                let mut first = 0;
                let mut start = pos;
                for i in 0..element.count {
                    if i > first && i - first == LIST_RUN {
                        runs.push((e, first, i - first, start));
                        (first, start) = (i, data.pos);
                    }
                    skip_instance(element, &mut data)?;
                }
                if element.count > first {
                    runs.push((e, first, element.count - first, start));
                }
                pos = data.pos;
            }
        }
    }
    read_runs(header, roles, bytes, &runs)
}

/// Moves past one binary instance of `element`, reading only its lists' lengths.
fn skip_instance(element: &Element, data: &mut Data<'_>) -> Option<()> {
    for (_, property) in &element.properties {
        let (n, size) = match property {
            Property::Scalar(s) => (1, s.size()),
            Property::List(count_type, item) => {
                let n = data.value(*count_type).ok()?;
                if n < 0.0 {
                    return None;
                }
                (n as usize, item.size())
            }
        };
        data.pos = n.checked_mul(size)?.checked_add(data.pos)?;
        if data.pos > data.bytes.len() {
            return None;
        }
    }
    Some(())
}
