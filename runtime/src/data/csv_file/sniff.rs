//! What the first bytes and the size of a CSV text tell before it is parsed: an encoding
//! or line ends the reader would misread, and the number of rows to expect.

use super::super::DataError;
use super::Text;
use std::io::Read;
use std::path::Path;
/// Refuse, by their first bytes, files that the CSV reader would misread: UTF-16 text, and
/// old Mac OS line ends (a carriage return alone), which make the file one line. Returns
/// the first bytes read.
pub(super) fn sniff(path: &Path, text: &Text) -> Result<Vec<u8>, DataError> {
    const HEAD: usize = 64 << 10;
    let mut head = Vec::with_capacity(HEAD);
    let file = match text {
        Text::Bytes(b) => {
            head.extend_from_slice(&b[..b.len().min(HEAD)]);
            None
        }
        Text::File => Some(path),
        Text::Copy(t) => Some(t.path()),
    };
    if let Some(f) = file {
        // The raw bytes (UTF-16 text is full of NUL bytes, which the line reader refuses).
        let Ok(f) = std::fs::File::open(f) else {
            // The reader reports it.
            return Ok(head);
        };
        if f.take(HEAD as u64).read_to_end(&mut head).is_err() {
            return Ok(Vec::new());
        }
    }
    let p = || path.display().to_string();
    if let Some(kind) = dynid_ir::text::utf16_kind(&head) {
        return Err(DataError::Encoding {
            path: p(),
            kind: kind.into(),
        });
    }
    // A carriage return followed by more text, and no line feed in the first block.
    let cr = head.iter().position(|&b| b == b'\r');
    if !head.contains(&b'\n')
        && cr.is_some_and(|k| head[k + 1..].iter().any(|b| !b.is_ascii_whitespace()))
    {
        return Err(DataError::CarriageReturns { path: p() });
    }
    Ok(head)
}

/// Rows of a text of `size` bytes whose first bytes are `head`: the size after the header
/// line divided by the mean length of the complete rows in `head` (or, where no row ends
/// in it, by what follows the header there: a row is at least that long).
pub(super) fn rows_from_size(size: u64, head: &[u8]) -> f64 {
    let Some(h) = head.iter().position(|&b| b == b'\n') else {
        return 0.0;
    };
    let body = &head[h + 1..];
    let (rows, bytes) = match body.iter().rposition(|&b| b == b'\n') {
        Some(last) => (
            body[..=last].iter().filter(|&&b| b == b'\n').count(),
            last + 1,
        ),
        None => (1, body.len()),
    };
    let per_row = bytes.max(1) as f64 / rows.max(1) as f64;
    size.saturating_sub(h as u64 + 1) as f64 / per_row
}

/// The size in bytes of a source's text, where it is known.
pub(super) fn text_size(path: &Path, text: &Text) -> Option<u64> {
    let meta = |p: &Path| {
        std::fs::metadata(p)
            .ok()
            .filter(|m| m.is_file())
            .map(|m| m.len())
    };
    match text {
        Text::File => meta(path),
        Text::Copy(t) => meta(t.path()),
        Text::Bytes(b) => Some(b.len() as u64),
    }
}
