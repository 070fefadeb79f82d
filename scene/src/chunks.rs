//! Cutting a text file into chunks at line ends, so that the model readers parse it on
//! every core and still stitch the result together in file order.
//!
//! The cuts depend only on the bytes and the chunk size, never on the thread count, and
//! the readers stitch chunks in order, so a file reads the same, bit for bit and error for
//! error, however it is cut (the readers' tests cut files into chunks of one line).

use std::ops::Range;

/// Bytes per chunk the readers parse as one task: large enough that a task's overhead
/// vanishes, small enough that a window of them stays a few megabytes.
pub(crate) const CHUNK_BYTES: usize = 1 << 20;

/// Chunks parsed together before they are stitched and handed on: a multiple of the
/// cores so that none waits, and a bound on what a reader holds besides its result.
pub(crate) fn window_chunks() -> usize {
    (4 * rayon::current_num_threads()).max(4)
}

/// Cuts `bytes` into ranges of about `target` bytes (at least one byte), each ending
/// just after a `\n` except the last, which ends with the data. Every line lies in one
/// range; an empty input gives no range.
pub(crate) fn line_chunks(bytes: &[u8], target: usize) -> Vec<Range<usize>> {
    let mut out = Vec::with_capacity(bytes.len() / target.max(1) + 1);
    let mut start = 0;
    while start < bytes.len() {
        let want = start.saturating_add(target.max(1)).min(bytes.len());
        let end = match bytes.get(want - 1..).and_then(|rest| rest.iter().position(|&b| b == b'\n')) {
            Some(k) => want + k,
            None => bytes.len(),
        };
        out.push(start..end);
        start = end;
    }
    out
}

/// Lines in a chunk as `str::lines` counts them: its `\n`s, plus one for a last line
/// without one.
pub(crate) fn line_count(chunk: &[u8]) -> usize {
    let newlines = chunk.iter().filter(|&&b| b == b'\n').count();
    newlines + usize::from(chunk.last().is_some_and(|&b| b != b'\n'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_end_at_line_ends_and_cover_the_input() {
        let text = b"ab\ncde\n\nf\ngh";
        for target in 1..16 {
            let chunks = line_chunks(text, target);
            assert_eq!(chunks.first().map(|r| r.start), Some(0));
            assert_eq!(chunks.last().map(|r| r.end), Some(text.len()));
            for pair in chunks.windows(2) {
                assert_eq!(pair[0].end, pair[1].start);
                assert_eq!(text[pair[0].end - 1], b'\n');
            }
            let lines: usize = chunks.iter().map(|r| line_count(&text[r.clone()])).sum();
            assert_eq!(lines, std::str::from_utf8(text).unwrap().lines().count());
        }
        assert!(line_chunks(b"", 4).is_empty());
    }
}
