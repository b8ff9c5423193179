//! CSV level files: streamed, validated (header, equal field counts, finite numbers,
//! uniform time step), with an optional binary copy that later passes replay.
//!
//! This module opens a source (header, first samples, sample interval) and reads whole
//! records; `header` checks the header and its renamings and settles the sample interval,
//! `sniff` tells from the first bytes and the size what the text is, `stream` runs the
//! passes (parsing the text, or replaying the binary copy).

mod header;
mod sniff;
mod stream;

use super::csv_parse::parse_number;
use super::text::{copy_if_stream, read_error, LineCap};
use super::{CsvOptions, DataError, LevelSource, MIN_SAMPLES};
use crate::record::Record;
use dynid_ir::ir::ModelIr;
use header::select_measured;
use sniff::{rows_from_size, sniff, text_size};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// A CSV file bound to a model: validated header, known sample interval; the body is
/// validated while streaming.
///
/// Identification streams every level twice (statistics, then filters). Parsing text
/// dominates the cost of a pass, so the first complete pass also writes the selected columns
/// as raw binary `f64` to an anonymous temporary file (deleted by the system when the source
/// is dropped), and later passes replay that file. Memory use stays independent of the record
/// length; if the temporary file cannot be written, every pass parses the text again.
#[derive(Clone, Debug)]
pub struct CsvSource {
    path: PathBuf,
    ts: f64,
    /// Time of the first sample (0 without a `t` column).
    t0: f64,
    n_fields: usize,
    header: Vec<String>,
    /// `(slot, column)`: slot `s` of every streamed chunk is read from file column `c`.
    wanted: Vec<(usize, usize)>,
    /// Slots per chunk (`SignalId`s of the model; empty slots stay empty).
    n_slots: usize,
    t_col: Option<usize>,
    min_samples: usize,
    /// Whether the first pass writes a binary copy for later passes.
    spill: bool,
    /// The binary copy of a complete, validated pass: samples in order, each the `wanted`
    /// columns as little-endian `f64`.
    pub(super) replay: Arc<Mutex<Option<std::fs::File>>>,
    /// Where the text is read from.
    text: Text,
    /// Samples estimated from the size of the text and the bytes per row of its first
    /// lines (`None` where the size is unknown).
    rows_hint: Option<f64>,
    /// The byte between fields, the comment byte, the lines skipped after the header.
    delimiter: u8,
    comment: Option<u8>,
    skip_after_header: usize,
}

/// Where the text of a [`CsvSource`] is read from.
#[derive(Clone, Debug)]
enum Text {
    /// The file at the source's path.
    File,
    /// A copy of the pipe or device at the source's path (readable only once).
    Copy(Arc<tempfile::NamedTempFile>),
    /// Bytes in memory.
    Bytes(Arc<[u8]>),
}

/// A reader of the text, through [`LineCap`]; `path` names it in errors.
fn open_text(path: &Path, text: &Text) -> Result<Box<dyn Read + Send>, DataError> {
    let file = |p: &Path| std::fs::File::open(p).map_err(|e| io_err(path, e));
    let r: Box<dyn Read + Send> = match text {
        Text::File => Box::new(file(path)?),
        Text::Copy(t) => Box::new(file(t.path())?),
        Text::Bytes(b) => Box::new(std::io::Cursor::new(b.clone())),
    };
    Ok(Box::new(LineCap::new(r)))
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> DataError {
    DataError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

fn csv_err(path: &Path, e: csv::Error) -> DataError {
    let line = e.position().map_or(0, |p| p.line());
    match e.kind() {
        csv::ErrorKind::Io(io) => read_error(path, io),
        _ => DataError::Csv {
            path: path.display().to_string(),
            line,
            message: e.to_string(),
        },
    }
}

impl CsvSource {
    /// Open `path`, match its header to the measured signals of `ir` and fix the sample
    /// interval (from `t`, else from `opts.ts`).
    pub fn open(path: &Path, ir: &ModelIr, opts: &CsvOptions) -> Result<CsvSource, DataError> {
        let select = |names: &[String], header: &[String]| select_measured(path, ir, names, header);
        Self::open_with(path, None, opts, select, MIN_SAMPLES)
    }

    /// As [`Self::open`] for a file's bytes held in memory (`path` names it in messages);
    /// the source parses them on every pass.
    pub fn from_bytes(
        path: &Path,
        bytes: &[u8],
        ir: &ModelIr,
        opts: &CsvOptions,
    ) -> Result<CsvSource, DataError> {
        let select = |names: &[String], header: &[String]| select_measured(path, ir, names, header);
        Ok(Self::open_with(path, Some(bytes.into()), opts, select, MIN_SAMPLES)?.without_replay())
    }

    /// Open with a caller's choice of columns: `select(names, header)` returns the
    /// `(slot, column)` pairs to stream and the number of slots; `names` is the header after
    /// the `--map` renamings.
    fn open_with(
        path: &Path,
        bytes: Option<Arc<[u8]>>,
        opts: &CsvOptions,
        select: impl FnOnce(&[String], &[String]) -> Result<(Vec<(usize, usize)>, usize), DataError>,
        min_samples: usize,
    ) -> Result<CsvSource, DataError> {
        let p = path.display().to_string();
        if let Some(ts) = opts.ts {
            if !(ts.is_finite() && ts > 0.0) {
                return Err(DataError::BadSampleInterval { ts });
            }
        }
        let text = match bytes {
            Some(b) => Text::Bytes(b),
            None => copy_if_stream(path)?.map_or(Text::File, Text::Copy),
        };
        let head = sniff(path, &text)?;
        let rows_hint = text_size(path, &text).map(|size| rows_from_size(size, &head));
        let delimiter = opts.delimiter.unwrap_or(b',');
        let mut rdr = Self::reader(path, &text, delimiter, opts.comment)?;
        let header: Vec<String> = match rdr.headers() {
            // (The reader skips a UTF-8 byte-order mark at the start of the file.)
            Ok(h) => h.iter().map(|s| s.trim().to_string()).collect(),
            Err(e) => return Err(csv_err(path, e)),
        };
        if header.is_empty() || header.iter().all(|h| h.is_empty()) {
            return Err(DataError::Empty { path: p });
        }
        let names = header::renamed(path, &header, opts, delimiter)?;
        let (wanted, n_slots) = select(&names, &header)?;
        let t_col = names.iter().position(|n| n == "t");
        let first_t = first_times(&mut rdr, path, opts.skip_after_header, header.len(), t_col)?;
        let ts = header::sample_interval(path, opts.ts, &first_t, t_col.is_some(), min_samples)?;
        Ok(CsvSource {
            path: path.to_path_buf(),
            ts,
            t0: first_t.first().copied().unwrap_or(0.0),
            n_fields: header.len(),
            header,
            wanted,
            n_slots,
            t_col,
            min_samples,
            spill: true,
            replay: Arc::default(),
            text,
            rows_hint,
            delimiter,
            comment: opts.comment,
            skip_after_header: opts.skip_after_header,
        })
    }

    /// The samples of the record, estimated before reading it from the size of its text and
    /// the bytes per row of its first lines (`None` where the size is unknown).
    pub fn samples_hint(&self) -> Option<f64> {
        self.rows_hint
    }

    /// The memory, in bytes, of the record's streamed columns read whole (estimated, see
    /// [`Self::samples_hint`]; 0 where the size is unknown).
    pub fn whole_bytes(&self) -> f64 {
        self.rows_hint.unwrap_or(0.0) * self.wanted.len() as f64 * 8.0
    }

    /// Refuse to read the record whole when [`Self::whole_bytes`] is above
    /// [`crate::limits::MAX_BYTES`], unless `allow`.
    pub fn check_whole(&self, allow: bool) -> Result<(), DataError> {
        use crate::limits::{bytes_in_words, MAX_BYTES};
        let bytes = self.whole_bytes();
        if allow || bytes <= MAX_BYTES {
            return Ok(());
        }
        Err(DataError::TooLarge {
            path: self.path.display().to_string(),
            estimate: bytes_in_words(bytes),
            rows: format!("{:.1e}", self.rows_hint.unwrap_or(0.0)),
            columns: self.wanted.len(),
            limit: bytes_in_words(MAX_BYTES),
        })
    }

    /// Parse the text on every pass instead of keeping a binary copy (for a source that is
    /// streamed only once).
    pub fn without_replay(mut self) -> Self {
        self.spill = false;
        self.replay = Arc::default();
        self
    }

    /// A CSV reader of the text (`path` names it in errors).
    fn reader(
        path: &Path,
        text: &Text,
        delimiter: u8,
        comment: Option<u8>,
    ) -> Result<csv::Reader<Box<dyn Read + Send>>, DataError> {
        let buf: Box<dyn Read + Send> = Box::new(std::io::BufReader::with_capacity(
            1 << 20,
            open_text(path, text)?,
        ));
        Ok(csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .trim(csv::Trim::All)
            .delimiter(delimiter)
            .comment(comment)
            .from_reader(buf))
    }
}

/// Read a whole CSV file into a [`Record`] (every named column except `t`, renamed by
/// `opts.map`), with the same validation as [`CsvSource`]: a header, equal field counts,
/// finite numbers and a uniform time step (`t` column or `opts.ts`). At least two samples.
/// Refused before reading when the record would take more than
/// [`crate::limits::MAX_BYTES`] of memory (estimated from the file's size, see
/// [`CsvSource::check_whole`]) unless `allow_large`. [`super::read_record`] chooses the
/// reader by the file's format.
pub(super) fn read_csv_record(
    path: &Path,
    opts: &CsvOptions,
    allow_large: bool,
) -> Result<Record, DataError> {
    read_record_from(path, None, opts, allow_large)
}

/// As [`super::read_record`] for a CSV file's bytes held in memory (`path` names it in messages).
pub fn read_record_bytes(
    path: &Path,
    bytes: &[u8],
    opts: &CsvOptions,
) -> Result<Record, DataError> {
    read_record_from(path, Some(bytes.into()), opts, false)
}

fn read_record_from(
    path: &Path,
    bytes: Option<Arc<[u8]>>,
    opts: &CsvOptions,
    allow_large: bool,
) -> Result<Record, DataError> {
    let mut names = Vec::new();
    let src = CsvSource::open_with(
        path,
        bytes,
        opts,
        |renamed, _| {
            let wanted: Vec<(usize, usize)> = renamed
                .iter()
                .enumerate()
                // A column without a name (e.g. from a trailing comma on every line) is not data.
                .filter(|(_, n)| *n != "t" && !n.is_empty())
                .enumerate()
                .map(|(slot, (k, n))| {
                    names.push(n.clone());
                    (slot, k)
                })
                .collect();
            let n = wanted.len();
            Ok((wanted, n))
        },
        2,
    )?
    .without_replay();
    src.check_whole(allow_large)?;
    // Reserved for the estimated length (growth by doubling would hold up to three times
    // the record while a column is moved), unless the estimate is beyond the limit.
    let reserve = match src.samples_hint() {
        Some(n) if src.whole_bytes() <= crate::limits::MAX_BYTES => (n as usize).saturating_add(16),
        _ => 0,
    };
    let mut columns: Vec<Vec<f64>> = (0..names.len())
        .map(|_| Vec::with_capacity(reserve))
        .collect();
    src.stream(1 << 16, &mut |cols, len| {
        for (c, chunk) in columns.iter_mut().zip(cols) {
            c.extend_from_slice(&chunk[..len]);
        }
    })?;
    Ok(Record {
        names,
        columns,
        ts: src.ts,
        t0: src.t0,
    })
}

/// Past the header: skip `skip` lines (units), then read the first two samples, checking
/// their field count, and return their time stamps (empty without a `t` column). An empty
/// body is an error.
fn first_times(
    rdr: &mut csv::Reader<Box<dyn Read + Send>>,
    path: &Path,
    skip: usize,
    n_fields: usize,
    t_col: Option<usize>,
) -> Result<Vec<f64>, DataError> {
    let p = || path.display().to_string();
    // Lines after the header that are not samples (units).
    let mut rec = csv::ByteRecord::new();
    for _ in 0..skip {
        match rdr.read_byte_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => return Err(DataError::HeaderOnly { path: p() }),
            Err(e) => return Err(csv_err(path, e)),
        }
    }
    rec.clear();
    // Read the first two samples for the sample interval (and to tell an empty body).
    let mut first_t = Vec::new();
    for _ in 0..2 {
        match rdr.read_byte_record(&mut rec) {
            Ok(true) => {
                let line = rec.position().map_or(0, |p| p.line());
                if rec.len() != n_fields {
                    return Err(DataError::Ragged {
                        path: p(),
                        line,
                        expected: n_fields,
                        found: rec.len(),
                    });
                }
                if let Some(tc) = t_col {
                    first_t.push(parse_cell(path, line, "t", &rec[tc])?);
                }
            }
            Ok(false) => break,
            Err(e) => return Err(csv_err(path, e)),
        }
    }
    if rec.is_empty() && first_t.is_empty() && rdr.position().record() <= 1 {
        return Err(DataError::HeaderOnly { path: p() });
    }
    Ok(first_t)
}

/// One number of the text, or an error naming its line and column.
fn parse_cell(path: &Path, line: u64, column: &str, raw: &[u8]) -> Result<f64, DataError> {
    parse_number(path, line, column, raw)
}
