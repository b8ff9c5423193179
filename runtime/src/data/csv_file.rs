//! CSV level files: streamed, validated (header, equal field counts, finite numbers,
//! uniform time step), with an optional binary copy that later passes replay.

use super::csv_parse::{parse_body, parse_number, Layout, Role};
use super::text::{copy_if_stream, read_error, LineCap};
use super::*;

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

/// The header's columns for a message (invisible characters escaped), with a note when one
/// of them is `wanted` but for invisible characters.
fn present_columns(header: &[String], wanted: &str) -> String {
    let escaped: Vec<String> = header.iter().map(|h| dynid_ir::text::escape(h)).collect();
    let mut out = columns_in_words(&escaped);
    let clean = |h: &str| -> String {
        h.chars()
            .filter(|&c| dynid_ir::text::invisible_name(c).is_none())
            .collect()
    };
    if let Some(h) = header
        .iter()
        .find(|h| h.as_str() != wanted && clean(h) == wanted)
    {
        let what = dynid_ir::text::describe_invisibles(h).unwrap_or_default();
        out += &format!(
            "; column `{}` is `{wanted}` with an invisible character: {what}; remove it",
            dynid_ir::text::escape(h)
        );
    }
    out
}

/// Refuse, by their first bytes, files that the CSV reader would misread: UTF-16 text, and
/// old Mac OS line ends (a carriage return alone), which make the file one line. Returns
/// the first bytes read.
fn sniff(path: &Path, text: &Text) -> Result<Vec<u8>, DataError> {
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
fn rows_from_size(size: u64, head: &[u8]) -> f64 {
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
fn text_size(path: &Path, text: &Text) -> Option<u64> {
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

fn parse_cell(path: &Path, line: u64, column: &str, raw: &[u8]) -> Result<f64, DataError> {
    parse_number(path, line, column, raw)
}

/// The header's columns for a message: all of them, or the first few and how many there
/// are (a header can be up to [`super::MAX_LINE`] long; a message should not be).
fn columns_in_words(header: &[String]) -> String {
    const SHOWN: usize = 400;
    let all = header.join(", ");
    if all.len() <= SHOWN {
        return all;
    }
    let mut cut = SHOWN;
    while !all.is_char_boundary(cut) {
        cut -= 1;
    }
    format!("{}… ({} columns)", &all[..cut], header.len())
}

/// The `(slot, column)` pairs of the measured signals of `ir` in a header (`names` after
/// the renamings), and the number of slots.
fn select_measured(
    path: &Path,
    ir: &ModelIr,
    names: &[String],
    header: &[String],
) -> Result<(Vec<(usize, usize)>, usize), DataError> {
    let mut wanted = Vec::new();
    for s in ir.measured_signals() {
        let name = &ir.signal(s).name;
        match names.iter().position(|n| n == name) {
            Some(k) => wanted.push((s.index(), k)),
            None => {
                return Err(DataError::MissingColumn {
                    path: path.display().to_string(),
                    signal: name.clone(),
                    present: present_columns(header, name),
                })
            }
        }
    }
    Ok((wanted, ir.signals.len()))
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
        // One column whose name holds another usual separator: `;` or tab-separated data.
        if let [only] = header.as_slice() {
            if let Some(sep) = [",", ";", "\t"]
                .into_iter()
                .filter(|s| s.as_bytes() != [delimiter])
                .find(|s| only.contains(s))
            {
                return Err(DataError::Separator {
                    path: p,
                    header: dynid_ir::text::escape(only),
                    separator: if sep == "\t" {
                        "\\t".into()
                    } else {
                        sep.into()
                    },
                });
            }
        }
        let mut names = header.clone();
        for (c, s) in &opts.map {
            if let Some(k) = header.iter().position(|h| h == c) {
                names[k] = s.clone();
            } else {
                return Err(DataError::MissingColumn {
                    path: p,
                    signal: dynid_ir::text::escape(c),
                    present: present_columns(&header, c),
                });
            }
        }
        // A renaming onto `t` when the file keeps its own `t` column.
        let keeps_t = header.iter().any(|h| h == "t") && !opts.map.iter().any(|(c, _)| c == "t");
        let onto_t = opts.map.iter().find(|(c, s)| s == "t" && c != "t");
        if let (true, Some((c, _))) = (keeps_t, onto_t) {
            return Err(DataError::MapOntoTime {
                path: p,
                spec: format!("{}=t", dynid_ir::text::escape(c)),
                column: dynid_ir::text::escape(c),
            });
        }
        for (k, n) in names.iter().enumerate() {
            if names[..k].contains(n) {
                return Err(DataError::DuplicateColumn {
                    path: p,
                    column: dynid_ir::text::quote(n),
                });
            }
        }
        let (wanted, n_slots) = select(&names, &header)?;
        let t_col = names.iter().position(|n| n == "t");
        // Lines after the header that are not samples (units).
        let mut rec = csv::ByteRecord::new();
        for _ in 0..opts.skip_after_header {
            match rdr.read_byte_record(&mut rec) {
                Ok(true) => {}
                Ok(false) => return Err(DataError::HeaderOnly { path: p }),
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
                    if rec.len() != header.len() {
                        return Err(DataError::Ragged {
                            path: p,
                            line,
                            expected: header.len(),
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
            return Err(DataError::HeaderOnly { path: p });
        }
        let ts = match (opts.ts, first_t.as_slice()) {
            (Some(ts), [a, b]) => {
                // `--sample` with a `t` column: the two must agree.
                let step = b - a;
                if step.is_finite() && step > 0.0 && (step - ts).abs() > TIME_TOL * ts {
                    return Err(DataError::SampleConflict { path: p, ts, step });
                }
                ts
            }
            (Some(ts), _) => ts,
            (None, [a, b]) => {
                let ts = b - a;
                if ts.is_nan() || ts <= 0.0 {
                    return Err(DataError::TimeNotIncreasing {
                        path: p,
                        line: 3,
                        t: *b,
                        previous: *a,
                    });
                }
                ts
            }
            (None, _) if t_col.is_some() => {
                return Err(DataError::TooFewSamples {
                    path: p,
                    n: first_t.len(),
                    need: min_samples,
                })
            }
            (None, _) => return Err(DataError::NoSampleInterval { path: p }),
        };
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

    /// Stream the binary copy written by an earlier complete pass.
    fn stream_copy(
        &self,
        file: &mut std::fs::File,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        let path = self.path.as_path();
        file.rewind().map_err(|e| io_err(path, e))?;
        let width = self.wanted.len();
        let row_bytes = 8 * width;
        let mut reader = BufReader::with_capacity(1 << 20, &*file);
        let mut bufs: Vec<Vec<f64>> = vec![Vec::new(); self.n_slots];
        for &(s, _) in &self.wanted {
            bufs[s].reserve(max_len);
        }
        let mut raw = vec![0u8; row_bytes * max_len];
        loop {
            let mut filled = 0;
            while filled < raw.len() {
                match reader.read(&mut raw[filled..]) {
                    Ok(0) => break,
                    Ok(k) => filled += k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(io_err(path, e)),
                }
            }
            let len = filled / row_bytes.max(1);
            if len == 0 {
                return Ok(());
            }
            for (k, &(s, _)) in self.wanted.iter().enumerate() {
                bufs[s].extend(raw[..len * row_bytes].chunks_exact(row_bytes).map(|row| {
                    let b = &row[8 * k..8 * k + 8];
                    f64::from_le_bytes(b.try_into().expect("invariant: 8 bytes"))
                }));
            }
            let cols: Vec<&[f64]> = bufs.iter().map(Vec::as_slice).collect();
            sink(&cols, len);
            bufs.iter_mut().for_each(Vec::clear);
            if filled < raw.len() {
                return Ok(());
            }
        }
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

impl LevelSource for CsvSource {
    fn origin(&self) -> String {
        self.path.display().to_string()
    }
    fn ts(&self) -> f64 {
        self.ts
    }
    fn locate(&self, k: usize) -> String {
        super::locate_sample(self.t0, self.ts, k)
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        // Passes of one source run one at a time; different sources do not share the lock.
        let mut replay = self.replay.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(file) = replay.as_mut() {
            return self.stream_copy(file, max_len, sink);
        }
        // (Nothing to copy without selected columns: every pass then parses.)
        let mut copy = if self.spill && !self.wanted.is_empty() {
            tempfile::tempfile()
                .ok()
                .map(|f| BufWriter::with_capacity(1 << 20, f))
        } else {
            None
        };
        self.parse(max_len, sink, &mut copy)?;
        // Keep the copy only if it is complete.
        *replay = copy.and_then(|w| w.into_inner().ok());
        Ok(())
    }
}

impl CsvSource {
    /// Stream by parsing the text, validating every row; with `copy`, also write the binary
    /// copy (dropped, and the text parsed next time, at the first write error).
    fn parse(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
        copy: &mut Option<BufWriter<std::fs::File>>,
    ) -> Result<(), DataError> {
        let path = self.path.as_path();
        let p = || path.display().to_string();
        let mut roles = vec![Role::Skip; self.n_fields];
        for (k, &(_, c)) in self.wanted.iter().enumerate() {
            roles[c] = Role::Wanted(k);
        }
        if let Some(tc) = self.t_col {
            roles[tc] = Role::Time;
        }
        let layout = Layout {
            path,
            header: &self.header,
            roles,
            n_wanted: self.wanted.len(),
            ts: self.ts,
            time_tol: TIME_TOL,
            delimiter: self.delimiter,
            comment: self.comment,
            skip_after_header: self.skip_after_header,
        };
        let mut bufs: Vec<Vec<f64>> = vec![Vec::new(); self.n_slots];
        for &(s, _) in &self.wanted {
            bufs[s].reserve(max_len);
        }
        let mut bytes: Vec<u8> = Vec::new();
        let mut in_chunk = 0usize;
        let wanted = &self.wanted;
        let mut flush = |bufs: &mut Vec<Vec<f64>>, len: &mut usize| {
            if *len == 0 {
                return;
            }
            if let Some(w) = copy {
                bytes.clear();
                // Row-major: sample by sample, the wanted columns in order.
                let cols: Vec<&[f64]> = wanted.iter().map(|&(s, _)| &bufs[s][..*len]).collect();
                for i in 0..*len {
                    cols.iter()
                        .for_each(|c| bytes.extend_from_slice(&c[i].to_le_bytes()));
                }
                if w.write_all(&bytes).is_err() {
                    *copy = None;
                }
            }
            let cols: Vec<&[f64]> = bufs.iter().map(Vec::as_slice).collect();
            sink(&cols, *len);
            bufs.iter_mut().for_each(Vec::clear);
            *len = 0;
        };
        // Streaming means an error can surface after earlier chunks were handed on; callers
        // discard their partial results on error.
        let mut file = open_text(path, &self.text)?;
        let n = parse_body(&layout, &mut *file, &mut |cols, rows| {
            let mut done = 0;
            while done < rows {
                let take = (max_len - in_chunk).min(rows - done);
                for (k, &(s, _)) in wanted.iter().enumerate() {
                    bufs[s].extend_from_slice(&cols[k][done..done + take]);
                }
                in_chunk += take;
                done += take;
                if in_chunk == max_len {
                    flush(&mut bufs, &mut in_chunk);
                }
            }
        })?;
        if n == 0 {
            return Err(DataError::HeaderOnly { path: p() });
        }
        if n < self.min_samples {
            return Err(DataError::TooFewSamples {
                path: p(),
                n,
                need: self.min_samples,
            });
        }
        flush(&mut bufs, &mut in_chunk);
        Ok(())
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
