//! The body of a CSV level file at parse speed: the text is read in large blocks, each block
//! is cut at line ends into pieces that are parsed in parallel (numbers by `fast-float2`),
//! and the pieces are handed on in file order.
//!
//! Every row is validated as the `csv` crate path did it before: equal field counts, finite
//! numbers, a uniform time step; an error names the file's line (counted before the pieces
//! are parsed, so a parallel parse reports the same first error as a serial one). Fields
//! are trimmed and may be quoted (`"1.5"`; a comma inside quotes does not split the field,
//! and is then not a number); a quoted field cannot hold a line break. Blank lines are skipped. The header line (validated when the
//! file was opened) is skipped.

use super::DataError;
use rayon::prelude::*;
use std::io::Read;
use std::path::Path;

/// Bytes of text read per block (each block is split across the threads).
const BLOCK: usize = 4 << 20;
/// Smallest piece of a block worth a thread of its own.
const MIN_PIECE: usize = 64 << 10;

/// What a column of the file is for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Role {
    Skip,
    /// The `k`-th wanted column.
    Wanted(usize),
    Time,
}

/// How to read the body of one file.
pub(super) struct Layout<'a> {
    pub path: &'a Path,
    pub header: &'a [String],
    /// Role of each of the `header.len()` fields of a row.
    pub roles: Vec<Role>,
    pub n_wanted: usize,
    pub ts: f64,
    /// Relative tolerance on the time step.
    pub time_tol: f64,
    /// The byte between fields.
    pub delimiter: u8,
    /// Lines whose first non-blank byte is this are skipped.
    pub comment: Option<u8>,
    /// Lines after the header skipped (units rows).
    pub skip_after_header: usize,
}

/// The rows of one piece: the wanted columns, and the first and last time stamp.
struct Piece {
    cols: Vec<Vec<f64>>,
    rows: usize,
    /// `(line, t)` of the first row and the time of the last (with a `t` column).
    first: Option<(u64, f64)>,
    last_t: f64,
    /// The first error in the piece; the rows before it are in `cols`.
    error: Option<DataError>,
}

/// The byte ranges of the fields of `row`, split at `delim` outside double quotes.
fn fields(row: &[u8], delim: u8, spans: &mut Vec<(usize, usize)>) {
    spans.clear();
    let mut from = 0;
    if !row.contains(&b'"') {
        for (k, _) in row.iter().enumerate().filter(|(_, &b)| b == delim) {
            spans.push((from, k));
            from = k + 1;
        }
    } else {
        let mut quoted = false;
        for (k, &b) in row.iter().enumerate() {
            match b {
                b'"' => quoted = !quoted,
                b if b == delim && !quoted => {
                    spans.push((from, k));
                    from = k + 1;
                }
                _ => {}
            }
        }
    }
    spans.push((from, row.len()));
}

/// Parse one field (surrounding blanks and double quotes removed).
pub(super) fn parse_number(
    path: &Path,
    line: u64,
    column: &str,
    raw: &[u8],
) -> Result<f64, DataError> {
    let mut s = raw.trim_ascii();
    if s.len() >= 2 && s[0] == b'"' && s[s.len() - 1] == b'"' {
        s = s[1..s.len() - 1].trim_ascii();
    }
    let v: f64 = fast_float2::parse(s).map_err(|_| DataError::NotANumber {
        path: path.display().to_string(),
        line,
        column: dynid_ir::text::escape(column),
        value: dynid_ir::text::escape(&shown_field(s)),
        note: dynid_ir::text::describe_invisibles(&shown_field(s)),
    })?;
    if !v.is_finite() {
        return Err(DataError::NonFinite {
            path: path.display().to_string(),
            line,
            column: dynid_ir::text::escape(column),
            value: v,
        });
    }
    Ok(v)
}

/// A field for a message: at most 60 characters of it.
fn shown_field(raw: &[u8]) -> String {
    let text = String::from_utf8_lossy(raw);
    let mut shown: String = text.chars().take(60).collect();
    if shown.len() < text.len() {
        shown.push('…');
    }
    shown
}

impl Layout<'_> {
    /// Whether `row` is a comment line.
    fn is_comment(&self, row: &[u8]) -> bool {
        self.comment
            .is_some_and(|c| row.trim_ascii_start().first() == Some(&c))
    }

    fn step_error(&self, line: u64, t: f64, previous: f64) -> Option<DataError> {
        let step = t - previous;
        if step <= 0.0 || step.is_nan() {
            return Some(DataError::TimeNotIncreasing {
                path: self.path.display().to_string(),
                line,
                t,
                previous,
            });
        }
        if (step - self.ts).abs() > self.time_tol * self.ts + 1e-12 * t.abs() {
            // A whole number of intervals: samples dropped, not a jittery clock.
            let k = (step / self.ts).round();
            if (2.0..1e15).contains(&k)
                && (step - k * self.ts).abs() <= self.time_tol * self.ts + 1e-12 * t.abs()
            {
                return Some(DataError::MissingSamples {
                    path: self.path.display().to_string(),
                    line,
                    before: previous,
                    after: t,
                    missing: k as u64 - 1,
                    ts: self.ts,
                });
            }
            return Some(DataError::NonUniformTime {
                path: self.path.display().to_string(),
                line,
                step,
                ts: self.ts,
            });
        }
        None
    }

    /// Parse the complete lines of `text` (ending in `\n`, or the file's last line), the
    /// first of which is line `line0` of the file.
    fn piece(&self, text: &[u8], line0: u64) -> Piece {
        let mut p = Piece {
            cols: vec![Vec::with_capacity(text.len() / 16); self.n_wanted],
            rows: 0,
            first: None,
            last_t: f64::NAN,
            error: None,
        };
        let n_fields = self.roles.len();
        let mut spans = Vec::with_capacity(n_fields);
        for (this, raw) in (line0..).zip(text.split(|&b| b == b'\n')) {
            let row = raw.strip_suffix(b"\r").unwrap_or(raw);
            if row.trim_ascii().is_empty() || self.is_comment(row) {
                continue;
            }
            fields(row, self.delimiter, &mut spans);
            let found = spans.len();
            if found != n_fields {
                p.error = Some(DataError::Ragged {
                    path: self.path.display().to_string(),
                    line: this,
                    expected: n_fields,
                    found,
                });
                return p;
            }
            let mut t = None;
            for (c, &(from, to)) in spans.iter().enumerate() {
                let field = &row[from..to];
                let role = self.roles[c];
                if role == Role::Skip {
                    continue;
                }
                match parse_number(self.path, this, &self.header[c], field) {
                    Ok(v) => match role {
                        Role::Wanted(k) => p.cols[k].push(v),
                        Role::Time => t = Some(v),
                        Role::Skip => {}
                    },
                    Err(e) => {
                        // Keep the columns of equal length: drop this row's values.
                        p.cols.iter_mut().for_each(|c| c.truncate(p.rows));
                        p.error = Some(e);
                        return p;
                    }
                }
            }
            if let Some(t) = t {
                match p.first {
                    None => p.first = Some((this, t)),
                    Some(_) => {
                        if let Some(e) = self.step_error(this, t, p.last_t) {
                            p.cols.iter_mut().for_each(|c| c.truncate(p.rows));
                            p.error = Some(e);
                            return p;
                        }
                    }
                }
                p.last_t = t;
            } else if p.first.is_none() {
                p.first = Some((this, f64::NAN));
            }
            p.rows += 1;
        }
        p
    }
}

/// Stream the body of `reader` (positioned at the start of the file) as rows of the wanted
/// columns: `rows(cols, n)` receives `n` rows, `cols[k]` the `k`-th wanted column, in file
/// order. Returns the number of rows; stops at the first invalid row with its error.
pub(super) fn parse_body(
    layout: &Layout,
    reader: &mut dyn Read,
    rows: &mut dyn FnMut(&[Vec<f64>], usize),
) -> Result<usize, DataError> {
    let io = |e: std::io::Error| super::text::read_error(layout.path, &e);
    let mut buf: Vec<u8> = Vec::with_capacity(BLOCK + (64 << 10));
    let mut header_done = false;
    let mut skip_left = layout.skip_after_header;
    let mut line = 1u64;
    let mut last_t: Option<f64> = None;
    let mut n = 0usize;
    let mut eof = false;
    while !eof {
        // Fill the block.
        let start = buf.len();
        // Room for a block, and always some (a line longer than a block keeps growing).
        buf.resize(start.max(BLOCK - (64 << 10)) + (64 << 10), 0);
        let mut filled = start;
        while filled < buf.len() {
            match reader.read(&mut buf[filled..]) {
                Ok(0) => {
                    eof = true;
                    break;
                }
                Ok(k) => filled += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(io(e)),
            }
        }
        buf.truncate(filled);
        let mut text: &[u8] = &buf;
        // The header (after any comment or blank lines), then the lines skipped after it.
        let mut need_more = false;
        while !header_done || skip_left > 0 {
            let Some(k) = text.iter().position(|&b| b == b'\n') else {
                if eof {
                    return Ok(0);
                }
                // A line longer than what is read so far: keep reading.
                need_more = true;
                break;
            };
            let row = &text[..k];
            let blank = row.trim_ascii().is_empty() || layout.is_comment(row);
            if !header_done {
                header_done = !blank;
            } else if !blank {
                skip_left -= 1;
            }
            text = &text[k + 1..];
            line += 1;
        }
        if need_more {
            let used = buf.len() - text.len();
            buf.drain(..used);
            continue;
        } // Complete lines only, unless this is the end of the file.
        let end = if eof {
            text.len()
        } else {
            match text.iter().rposition(|&b| b == b'\n') {
                Some(k) => k + 1,
                None => 0,
            }
        };
        let (complete, rest) = text.split_at(end);
        // Cut into pieces at line ends; count each piece's lines first.
        let n_pieces =
            (complete.len() / MIN_PIECE).clamp(1, 4 * rayon::current_num_threads().max(1));
        let mut pieces: Vec<(&[u8], u64)> = Vec::with_capacity(n_pieces);
        let mut from = 0;
        for k in 1..=n_pieces {
            let target = complete.len() * k / n_pieces;
            let to = if k == n_pieces {
                complete.len()
            } else {
                match complete[target.max(from)..]
                    .iter()
                    .position(|&b| b == b'\n')
                {
                    Some(j) => target.max(from) + j + 1,
                    None => complete.len(),
                }
            };
            if to > from {
                let piece = &complete[from..to];
                pieces.push((piece, line));
                line += piece.iter().filter(|&&b| b == b'\n').count() as u64;
                from = to;
            }
        }
        let parsed: Vec<Piece> = pieces
            .par_iter()
            .map(|&(text, line0)| layout.piece(text, line0))
            .collect();
        for p in parsed {
            if let (Some(prev), Some((l, t))) = (last_t, p.first) {
                if !t.is_nan() {
                    if let Some(e) = layout.step_error(l, t, prev) {
                        return Err(e);
                    }
                }
            }
            if p.rows > 0 {
                rows(&p.cols, p.rows);
                n += p.rows;
                if p.first.is_some_and(|(_, t)| !t.is_nan()) {
                    last_t = Some(p.last_t);
                }
            }
            if let Some(e) = p.error {
                return Err(e);
            }
        }
        let keep = rest.len();
        let at = buf.len() - keep;
        buf.copy_within(at.., 0);
        buf.truncate(keep);
    }
    Ok(n)
}
