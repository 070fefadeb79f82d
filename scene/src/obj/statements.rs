//! The quick pass over an OBJ text that finds its `mtllib` and `usemtl` statements before
//! its faces are read, so that a streamed face has its material at once: only lines with
//! `mtl` in them are parsed, each as the reader parses it, so that on a file the reader
//! reads, the pass finds what the reader records.

use super::{rest_after_keyword, MtlLib};

/// The `mtllib` files (with their lines) and the distinct `usemtl` names (in order of
/// first use) of an OBJ text.
pub(super) fn material_statements(text: &str) -> (Vec<MtlLib>, Vec<String>) {
    let bytes = text.as_bytes();
    let (mut mtllibs, mut names) = (Vec::new(), Vec::<String>::new());
    // Line of byte `counted`, counted as `str::lines` numbers them.
    let (mut line, mut counted) = (1usize, 0usize);
    let mut from = 0;
    while let Some(k) = text.get(from..).and_then(|rest| rest.find("mtl")) {
        let hit = from + k;
        let start = bytes[..hit].iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
        let end = bytes[hit..].iter().position(|&b| b == b'\n').map_or(bytes.len(), |p| hit + p);
        line += bytes[counted..start].iter().filter(|&&b| b == b'\n').count();
        counted = start;
        let content = text.get(start..end).unwrap_or("").split('#').next().unwrap_or("").trim();
        let mut tokens = content.split_whitespace();
        match tokens.next() {
            Some("mtllib") => {
                let line = u32::try_from(line).unwrap_or(u32::MAX);
                mtllibs.extend(tokens.map(|t| MtlLib { file: t.to_string(), line }));
            }
            Some(keyword @ "usemtl") => {
                let name = rest_after_keyword(content, keyword);
                if !name.is_empty() && !names.iter().any(|n| n == name) {
                    names.push(name.to_string());
                }
            }
            _ => {}
        }
        from = end + 1;
    }
    (mtllibs, names)
}
