//! The dotted name of the TOML field at a byte offset of a scene file (`render.width`,
//! `material[2].diffuse`), for error messages that name the field when the TOML reader
//! only gives an offset.

use std::collections::HashMap;

/// Guesses the dotted field at a byte offset from the text: the last `[table]` or
/// `[[array]]` header before it (with the entry's 0-based index) and the last `key =`.
pub(super) fn field_at(text: &str, offset: usize) -> String {
    let mut table = String::new();
    let mut key: Option<&str> = None;
    let mut counts: HashMap<&str, usize> = HashMap::new();
    let mut start = 0;
    for line in text.split_inclusive('\n') {
        if start > offset {
            break;
        }
        start += line.len();
        let t = line.split('#').next().unwrap_or("").trim();
        if let Some(name) = t.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")).map(str::trim) {
            if is_table_name(name) {
                let n = counts.entry(name).or_insert(0);
                table = format!("{name}[{n}]");
                *n += 1;
                key = None;
            }
        } else if let Some(name) = t.strip_prefix('[').and_then(|r| r.strip_suffix(']')).map(str::trim) {
            if is_table_name(name) {
                table = name.to_string();
                key = None;
            }
        } else if let Some((k, _)) = t.split_once('=') {
            let k = k.trim();
            if is_table_name(k) {
                key = Some(k);
            }
        }
    }
    match (table.is_empty(), key) {
        (true, None) => "toml".to_string(),
        (true, Some(k)) => k.to_string(),
        (false, None) => table,
        (false, Some(k)) => format!("{table}.{k}"),
    }
}

fn is_table_name(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.')
}
