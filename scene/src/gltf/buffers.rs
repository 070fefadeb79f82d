//! The bytes behind a glTF document: the GLB container's chunks, the buffers (the GLB's
//! binary chunk, `data:` URIs, files beside the document) and the accessors' values,
//! every offset and length checked.

use std::path::{Path, PathBuf};

use ::gltf::accessor::DataType;
use ::gltf::buffer::Source;
use ::gltf::Document;
use base64::Engine;

use crate::error::SceneError;
use crate::mesh::{ReadFile, MAX_MESH_TRIANGLES};
use crate::model::SourceLoc;

/// An error about the glTF file `label` as a whole (no line).
pub(super) fn file_err(label: &str, msg: String) -> SceneError {
    SceneError::new(SourceLoc { file: label.into(), line: 0 }, "gltf", msg)
}

/// Splits a GLB file into its JSON chunk and its optional binary chunk.
pub(super) fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    let u32_at = |at: usize| -> Option<u32> {
        bytes.get(at..at.checked_add(4)?).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let version = u32_at(4).ok_or("the file ends inside the header")?;
    if version != 2 {
        return Err(format!("version {version} (only glTF 2 is read)"));
    }
    let length = u32_at(8).ok_or("the file ends inside the header")? as usize;
    if length > bytes.len() {
        return Err(format!("the header says {length} bytes, the file has {} (truncated?)", bytes.len()));
    }
    let bytes = &bytes[..length];
    /// A chunk's type, its data and where the next chunk starts.
    type Chunk<'b> = (u32, &'b [u8], usize);
    let chunk = |at: usize| -> Result<Option<Chunk<'_>>, String> {
        if at >= bytes.len() {
            return Ok(None);
        }
        let (Some(len), Some(ty)) = (u32_at(at), u32_at(at + 4)) else {
            return Err(format!("the chunk at byte {at} is cut short"));
        };
        let start = at + 8;
        let end = start.checked_add(len as usize).filter(|&e| e <= bytes.len());
        let end = end.ok_or_else(|| format!("the chunk at byte {at} runs past the end of the file (truncated?)"))?;
        Ok(Some((ty, &bytes[start..end], end.next_multiple_of(4))))
    };
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    let Some((JSON, json, next)) = chunk(12)? else {
        return Err("the first chunk is not JSON".to_string());
    };
    match chunk(next)? {
        Some((BIN, bin, _)) => Ok((json, Some(bin))),
        _ => Ok((json, None)),
    }
}

/// Loads every buffer of the document: the GLB's binary chunk, a `data:` URI, or a file
/// beside the glTF read through `read`. Each must hold at least its `byteLength`.
pub(super) fn load_buffers(
    doc: &Document,
    bin: Option<Vec<u8>>,
    gltf_path: &Path,
    label: &str,
    read: ReadFile<'_>,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let dir = gltf_path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let mut bin = bin;
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let i = buffer.index();
        let err = |m: String| file_err(label, format!("buffers[{i}]: {m}"));
        let data = match buffer.source() {
            Source::Bin => {
                bin.take().ok_or_else(|| err("refers to a GLB binary chunk the file does not have".into()))?
            }
            Source::Uri(uri) => uri_bytes(uri, &dir, read, "buffer").map_err(err)?,
        };
        if data.len() < buffer.length() {
            return Err(err(format!("{} bytes where byteLength says {} (truncated?)", data.len(), buffer.length())));
        }
        out.push(data);
    }
    Ok(out)
}

/// The bytes a URI of the file (in folder `dir`) names: a base64 `data:` URI, or a file
/// beside it read through `read`; `what` ("buffer", "image") labels errors.
pub(super) fn uri_bytes(uri: &str, dir: &Path, read: ReadFile<'_>, what: &str) -> Result<Vec<u8>, String> {
    if uri.starts_with("data:") {
        let (_, payload) = uri.split_once(";base64,").ok_or("a data: URI that is not base64")?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|_| "a data: URI whose base64 does not decode".to_string());
    }
    let name = percent_decode(uri).ok_or("a URI that is not a relative file name")?;
    let path = dir.join(&name);
    read(&path).map_err(|e| format!("cannot read {what} file '{}': {e}", path.display()))
}

/// A relative URI as a file name (`%20` decoded), or None for a URI with a scheme or
/// an absolute path.
pub(super) fn percent_decode(uri: &str) -> Option<String> {
    if uri.starts_with('/') || uri.split('/').next().is_some_and(|first| first.contains(':')) {
        return None;
    }
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut k = 0;
    while k < b.len() {
        if b[k] == b'%' {
            let hex = std::str::from_utf8(b.get(k + 1..k + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            k += 3;
        } else {
            out.push(b[k]);
            k += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// The values of an accessor as `f64`s, `count * components` of them (a missing buffer
/// view reads as zeros; sparse values are applied). Every byte range is checked.
pub(super) fn read_accessor(acc: &::gltf::Accessor<'_>, buffers: &[Vec<u8>]) -> Result<Vec<f64>, String> {
    let i = acc.index();
    let dims = acc.dimensions().multiplicity();
    let ty = acc.data_type();
    let elem = dims * ty.size();
    let count = acc.count();
    if count.saturating_mul(dims) > 9 * MAX_MESH_TRIANGLES {
        return Err(format!("accessors[{i}]: {count} elements is more than magg reads"));
    }
    let view_bytes = |view: &::gltf::buffer::View<'_>| -> Result<&[u8], String> {
        let buf = buffers.get(view.buffer().index()).ok_or_else(|| format!("accessors[{i}]: no such buffer"))?;
        let end = view.offset().checked_add(view.length());
        end.and_then(|e| buf.get(view.offset()..e))
            .ok_or_else(|| format!("bufferViews[{}] lies past the end of its buffer", view.index()))
    };
    let mut out = vec![0.0; count * dims];
    if let Some(view) = acc.view() {
        let bytes = view_bytes(&view)?;
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(format!("accessors[{i}]: byteStride {stride} is less than an element's {elem} bytes"));
        }
        for (k, chunk) in out.chunks_mut(dims).enumerate() {
            let at = k.checked_mul(stride).and_then(|o| o.checked_add(acc.offset()));
            let src = at.and_then(|a| bytes.get(a..a.checked_add(elem)?));
            let src = src.ok_or_else(|| format!("accessors[{i}]: element {k} lies past the end of its buffer view"))?;
            for (c, v) in chunk.iter_mut().enumerate() {
                *v = component(ty, &src[c * ty.size()..]);
            }
        }
    }
    if let Some(sparse) = acc.sparse() {
        let (idx, val) = (sparse.indices(), sparse.values());
        let (ibytes, vbytes) = (view_bytes(&idx.view())?, view_bytes(&val.view())?);
        let ity = match idx.index_type() {
            ::gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            ::gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            ::gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        for j in 0..sparse.count() {
            let bad = || format!("accessors[{i}].sparse: entry {j} lies past the end of its buffer view");
            let at = j.checked_mul(ity.size()).and_then(|o| o.checked_add(idx.offset())).ok_or_else(bad)?;
            let target = component(ity, ibytes.get(at..at + ity.size()).ok_or_else(bad)?) as usize;
            let at = j.checked_mul(elem).and_then(|o| o.checked_add(val.offset())).ok_or_else(bad)?;
            let src = vbytes.get(at..at + elem).ok_or_else(bad)?;
            let dst = out.get_mut(target * dims..(target + 1) * dims);
            let dst =
                dst.ok_or_else(|| format!("accessors[{i}].sparse: index {target} is past its {count} elements"))?;
            for (c, v) in dst.iter_mut().enumerate() {
                *v = component(ty, &src[c * ty.size()..]);
            }
        }
    }
    Ok(out)
}

/// One little-endian component at the start of `b` (which holds at least its size).
pub(super) fn component(ty: DataType, b: &[u8]) -> f64 {
    let at = |n: usize| b.get(n).copied().unwrap_or(0);
    match ty {
        DataType::I8 => f64::from(at(0) as i8),
        DataType::U8 => f64::from(at(0)),
        DataType::I16 => f64::from(i16::from_le_bytes([at(0), at(1)])),
        DataType::U16 => f64::from(u16::from_le_bytes([at(0), at(1)])),
        DataType::U32 => f64::from(u32::from_le_bytes([at(0), at(1), at(2), at(3)])),
        DataType::F32 => f64::from(f32::from_le_bytes([at(0), at(1), at(2), at(3)])),
    }
}
