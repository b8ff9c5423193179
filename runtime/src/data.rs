//! Measured data for identification: one source per excitation level, streamed in chunks so
//! that memory use does not grow with the record length.
//!
//! A CSV file must have a header naming its columns. Columns are matched to the model's
//! signals by name (`m1.x`, `m1.v`, `u`; an optional `t` gives the sample times, which must
//! be uniform) or through `col=signal` renamings. Every signal the model declares measured
//! must be present; unmeasured signals are never required and extra columns are ignored.

use crate::record::Record;
use dynid_ir::ir::ModelIr;
use std::io::{BufReader, BufWriter, Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Fewest samples any record may have (the filters need far more; identification checks
/// the actual need against the filter time constants).
pub const MIN_SAMPLES: usize = 100;

/// One excitation level's record, streamed in order.
pub trait LevelSource: Sync {
    /// Where the data comes from, for messages (a file path or a label).
    fn origin(&self) -> String;
    /// Sample interval in seconds.
    fn ts(&self) -> f64;
    /// Call `sink(cols, len)` for consecutive chunks of at most `max_len` samples, where
    /// `cols[s]` is the column of signal `s` (by `SignalId`; empty for unmeasured signals).
    /// Every call streams the whole record from the start.
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError>;
}

/// Problems with measured data. Every variant names the file (or record) and, where it
/// applies, the line.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum DataError {
    #[error("{path}: cannot read: {message}")]
    #[diagnostic(
        code(dynid::data::io),
        help("check that the file exists and is readable")
    )]
    Io { path: String, message: String },
    #[error("{path}: the file is empty")]
    #[diagnostic(
        code(dynid::data::empty),
        help("a data file needs a header line naming the columns (e.g. `t,m1.x,m1.v,u`) and one line per sample")
    )]
    Empty { path: String },
    #[error("{path}: the file has a header but no samples")]
    #[diagnostic(
        code(dynid::data::header_only),
        help("add one line per sample below the header")
    )]
    HeaderOnly { path: String },
    #[error("{path}: line {line}: malformed CSV: {message}")]
    #[diagnostic(
        code(dynid::data::csv),
        help("the file must be comma-separated text with a header line")
    )]
    Csv {
        path: String,
        line: u64,
        message: String,
    },
    #[error(
        "{path}: the header has no column for the measured signal `{signal}` (columns: {present})"
    )]
    #[diagnostic(
        code(dynid::data::missing_column),
        help("name a column `{signal}`, map one with `--map COLUMN={signal}`, or declare `{signal}` unmeasured in the model")
    )]
    MissingColumn {
        path: String,
        signal: String,
        present: String,
    },
    #[error("{path}: column `{column}` appears twice in the header")]
    #[diagnostic(
        code(dynid::data::duplicate_column),
        help("rename or drop one of them")
    )]
    DuplicateColumn { path: String, column: String },
    #[error("{path}: line {line}: expected {expected} fields as in the header, found {found}")]
    #[diagnostic(
        code(dynid::data::ragged),
        help("every line needs one value per header column")
    )]
    Ragged {
        path: String,
        line: u64,
        expected: usize,
        found: usize,
    },
    #[error("{path}: line {line}, column `{column}`: `{value}` is not a number")]
    #[diagnostic(
        code(dynid::data::not_a_number),
        help("use plain decimal numbers such as `-1.25e-3`")
    )]
    NotANumber {
        path: String,
        line: u64,
        column: String,
        value: String,
    },
    #[error("{path}: line {line}, column `{column}`: {value} is not a finite number")]
    #[diagnostic(
        code(dynid::data::non_finite),
        help("remove or repair samples with NaN or infinite values (cut the record into clean pieces)")
    )]
    NonFinite {
        path: String,
        line: u64,
        column: String,
        value: f64,
    },
    #[error("{path}: only {n} samples; at least {need} are needed")]
    #[diagnostic(
        code(dynid::data::too_few_samples),
        help("record a longer run (the slowest identification filter needs many time constants)")
    )]
    TooFewSamples { path: String, n: usize, need: usize },
    #[error("{path}: line {line}: the time step is {step} s, but the sample interval is {ts} s")]
    #[diagnostic(
        code(dynid::data::non_uniform_time),
        help("identification needs uniformly sampled data; resample the record, or drop the `t` column and give `--sample TS`")
    )]
    NonUniformTime {
        path: String,
        line: u64,
        step: f64,
        ts: f64,
    },
    #[error("{path}: no sample interval: the file has no `t` column")]
    #[diagnostic(
        code(dynid::data::no_sample_interval),
        help("add a `t` column or give the interval with `--sample TS`")
    )]
    NoSampleInterval { path: String },
    #[error("invalid sample interval {ts}")]
    #[diagnostic(
        code(dynid::data::bad_sample_interval),
        help("the sample interval is a positive number of seconds")
    )]
    BadSampleInterval { ts: f64 },
    #[error("`--map {spec}`: {message}")]
    #[diagnostic(
        code(dynid::data::bad_map),
        help("write `--map COLUMN=SIGNAL`, e.g. `--map disp=m1.x`; signals: {signals}")
    )]
    BadMap {
        spec: String,
        message: String,
        signals: String,
    },
    #[error("{path}: column `{column}` has {found} samples, expected {expected}")]
    #[diagnostic(
        code(dynid::data::ragged_record),
        help("all columns of a record must have the same length")
    )]
    RaggedRecord {
        path: String,
        column: String,
        expected: usize,
        found: usize,
    },
}

/// How to read CSV files.
#[derive(Clone, Debug, Default)]
pub struct CsvOptions {
    /// `(column, signal)` renamings.
    pub map: Vec<(String, String)>,
    /// Sample interval; required when there is no `t` column. With a `t` column it is
    /// checked against the time steps.
    pub ts: Option<f64>,
}

impl CsvOptions {
    /// Parse a `COLUMN=SIGNAL` renaming, checking the signal exists in `ir`.
    pub fn parse_map(spec: &str, ir: &ModelIr) -> Result<(String, String), DataError> {
        let signals = ir
            .signals
            .iter()
            .map(|s| s.name.as_str())
            .collect::<Vec<_>>()
            .join(", ");
        let Some((c, s)) = spec.split_once('=') else {
            return Err(DataError::BadMap {
                spec: spec.into(),
                message: "expected COLUMN=SIGNAL".into(),
                signals,
            });
        };
        let (c, s) = (c.trim(), s.trim());
        if c.is_empty() || (ir.signal_id(s).is_none() && s != "t") {
            return Err(DataError::BadMap {
                spec: spec.into(),
                message: format!("`{s}` is not a signal of the model"),
                signals,
            });
        }
        Ok((c.to_string(), s.to_string()))
    }
}

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
    replay: Arc<Mutex<Option<std::fs::File>>>,
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
        csv::ErrorKind::Io(_) => io_err(path, e),
        _ => DataError::Csv {
            path: path.display().to_string(),
            line,
            message: e.to_string(),
        },
    }
}

fn parse_cell(path: &Path, line: u64, column: &str, raw: &[u8]) -> Result<f64, DataError> {
    let s = std::str::from_utf8(raw).unwrap_or("").trim();
    let v: f64 = s.parse().map_err(|_| DataError::NotANumber {
        path: path.display().to_string(),
        line,
        column: column.to_string(),
        value: String::from_utf8_lossy(raw).into_owned(),
    })?;
    if !v.is_finite() {
        return Err(DataError::NonFinite {
            path: path.display().to_string(),
            line,
            column: column.to_string(),
            value: v,
        });
    }
    Ok(v)
}

/// Relative tolerance on the time step (times printed with few digits jitter slightly).
const TIME_TOL: f64 = 1e-3;

impl CsvSource {
    /// Open `path`, match its header to the measured signals of `ir` and fix the sample
    /// interval (from `t`, else from `opts.ts`).
    pub fn open(path: &Path, ir: &ModelIr, opts: &CsvOptions) -> Result<CsvSource, DataError> {
        let select = |names: &[String], header: &[String]| {
            let mut wanted = Vec::new();
            for s in ir.measured_signals() {
                let name = &ir.signal(s).name;
                match names.iter().position(|n| n == name) {
                    Some(k) => wanted.push((s.index(), k)),
                    None => {
                        return Err(DataError::MissingColumn {
                            path: path.display().to_string(),
                            signal: name.clone(),
                            present: header.join(", "),
                        })
                    }
                }
            }
            Ok((wanted, ir.signals.len()))
        };
        Self::open_with(path, opts, select, MIN_SAMPLES)
    }

    /// Open with a caller's choice of columns: `select(names, header)` returns the
    /// `(slot, column)` pairs to stream and the number of slots; `names` is the header after
    /// the `--map` renamings.
    fn open_with(
        path: &Path,
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
        let mut rdr = Self::reader(path)?;
        let header: Vec<String> = match rdr.headers() {
            Ok(h) => h.iter().map(|s| s.trim().to_string()).collect(),
            Err(e) => return Err(csv_err(path, e)),
        };
        if header.is_empty() || header.iter().all(|h| h.is_empty()) {
            return Err(DataError::Empty { path: p });
        }
        let mut names = header.clone();
        for (c, s) in &opts.map {
            if let Some(k) = header.iter().position(|h| h == c) {
                names[k] = s.clone();
            } else {
                return Err(DataError::MissingColumn {
                    path: p,
                    signal: c.clone(),
                    present: header.join(", "),
                });
            }
        }
        for (k, n) in names.iter().enumerate() {
            if names[..k].contains(n) {
                return Err(DataError::DuplicateColumn {
                    path: p,
                    column: n.clone(),
                });
            }
        }
        let (wanted, n_slots) = select(&names, &header)?;
        let t_col = names.iter().position(|n| n == "t");
        // Read the first two samples for the sample interval (and to tell an empty body).
        let mut rec = csv::ByteRecord::new();
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
            (Some(ts), _) => ts,
            (None, [a, b]) => {
                let ts = b - a;
                if ts.is_nan() || ts <= 0.0 {
                    return Err(DataError::NonUniformTime {
                        path: p,
                        line: 3,
                        step: ts,
                        ts: f64::NAN,
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
                    f64::from_le_bytes(b.try_into().expect("8 bytes"))
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

    fn reader(path: &Path) -> Result<csv::Reader<Box<dyn Read + Send>>, DataError> {
        let f = std::fs::File::open(path).map_err(|e| io_err(path, e))?;
        let buf: Box<dyn Read + Send> = Box::new(std::io::BufReader::with_capacity(1 << 20, f));
        Ok(csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .trim(csv::Trim::All)
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
        let mut rdr = Self::reader(path)?;
        let mut bufs: Vec<Vec<f64>> = vec![Vec::new(); self.n_slots];
        for &(s, _) in &self.wanted {
            bufs[s].reserve(max_len);
        }
        let mut rec = csv::ByteRecord::new();
        let mut n = 0usize;
        let mut in_chunk = 0usize;
        let mut t_prev = f64::NAN;
        let flush =
            |bufs: &mut Vec<Vec<f64>>, len: &mut usize, sink: &mut dyn FnMut(&[&[f64]], usize)| {
                if *len > 0 {
                    let cols: Vec<&[f64]> = bufs.iter().map(Vec::as_slice).collect();
                    sink(&cols, *len);
                    bufs.iter_mut().for_each(Vec::clear);
                    *len = 0;
                }
            };
        // Streaming means an error can surface after earlier chunks were handed on; callers
        // discard their partial results on error.
        loop {
            match rdr.read_byte_record(&mut rec) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_err(path, e)),
            }
            let line = rec.position().map_or(0, |p| p.line());
            if rec.len() != self.n_fields {
                // A trailing blank line is not data.
                if rec.len() == 1 && rec[0].is_empty() {
                    continue;
                }
                return Err(DataError::Ragged {
                    path: p(),
                    line,
                    expected: self.n_fields,
                    found: rec.len(),
                });
            }
            for &(s, c) in &self.wanted {
                let v = parse_cell(path, line, &self.header[c], &rec[c])?;
                bufs[s].push(v);
                if let Some(w) = copy {
                    if w.write_all(&v.to_le_bytes()).is_err() {
                        *copy = None;
                    }
                }
            }
            if let Some(tc) = self.t_col {
                let t = parse_cell(path, line, &self.header[tc], &rec[tc])?;
                if n > 0 {
                    let step = t - t_prev;
                    if (step - self.ts).abs() > TIME_TOL * self.ts + 1e-12 * t.abs() {
                        return Err(DataError::NonUniformTime {
                            path: p(),
                            line,
                            step,
                            ts: self.ts,
                        });
                    }
                }
                t_prev = t;
            }
            n += 1;
            in_chunk += 1;
            if in_chunk == max_len {
                flush(&mut bufs, &mut in_chunk, sink);
            }
        }
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
        flush(&mut bufs, &mut in_chunk, sink);
        Ok(())
    }
}

/// Read a whole CSV file into a [`Record`] (every named column except `t`, renamed by
/// `opts.map`), with the same validation as [`CsvSource`]: a header, equal field counts,
/// finite numbers and a uniform time step (`t` column or `opts.ts`). At least two samples.
/// For inputs that drive a simulation; identification streams with [`CsvSource`] instead.
pub fn read_record(path: &Path, opts: &CsvOptions) -> Result<Record, DataError> {
    let mut names = Vec::new();
    let src = CsvSource::open_with(
        path,
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
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
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

/// An in-memory record bound to a model (checked once on construction).
#[derive(Clone, Debug)]
pub struct RecordSource<'r> {
    origin: String,
    record: &'r Record,
    col_of: Vec<Option<usize>>,
}

impl<'r> RecordSource<'r> {
    pub fn new(
        record: &'r Record,
        ir: &ModelIr,
        origin: impl Into<String>,
    ) -> Result<Self, DataError> {
        let origin = origin.into();
        if !(record.ts.is_finite() && record.ts > 0.0) {
            return Err(DataError::BadSampleInterval { ts: record.ts });
        }
        let mut col_of = vec![None; ir.signals.len()];
        for s in ir.measured_signals() {
            let name = &ir.signal(s).name;
            match record.names.iter().position(|n| n == name) {
                Some(k) => col_of[s.index()] = Some(k),
                None => {
                    return Err(DataError::MissingColumn {
                        path: origin,
                        signal: name.clone(),
                        present: record.names.join(", "),
                    })
                }
            }
        }
        let n = record.len();
        for (name, col) in record.names.iter().zip(&record.columns) {
            if col.len() != n {
                return Err(DataError::RaggedRecord {
                    path: origin,
                    column: name.clone(),
                    expected: n,
                    found: col.len(),
                });
            }
        }
        for k in col_of.iter().flatten() {
            if let Some(i) = record.columns[*k].iter().position(|v| !v.is_finite()) {
                return Err(DataError::NonFinite {
                    path: origin,
                    line: i as u64 + 1,
                    column: record.names[*k].clone(),
                    value: record.columns[*k][i],
                });
            }
        }
        if n < MIN_SAMPLES {
            return Err(DataError::TooFewSamples {
                path: origin,
                n,
                need: MIN_SAMPLES,
            });
        }
        Ok(RecordSource {
            origin,
            record,
            col_of,
        })
    }
}

impl LevelSource for RecordSource<'_> {
    fn origin(&self) -> String {
        self.origin.clone()
    }
    fn ts(&self) -> f64 {
        self.record.ts
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        let n = self.record.len();
        let mut start = 0;
        let mut cols: Vec<&[f64]> = vec![&[]; self.col_of.len()];
        while start < n {
            let len = max_len.min(n - start);
            for (s, c) in self.col_of.iter().enumerate() {
                cols[s] = match c {
                    Some(k) => &self.record.columns[*k][start..start + len],
                    None => &[],
                };
            }
            sink(&cols, len);
            start += len;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::test_models::{sdof, SdofParams};
    use dynid_ir::ir::FormFilter;

    /// The SDOF model (signals `m1.x`, `m1.v`, `u`), optionally without a measured velocity.
    fn sdof_ir(measured_v: bool) -> ModelIr {
        let mut ir = sdof(
            &SdofParams::benchmark(),
            FormFilter::Lowpass { corner: 10.0 },
            vec![1.0],
        );
        ir.signals[1].measured = measured_v;
        ir
    }
    use std::io::Write;

    fn file(body: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(body.as_bytes()).unwrap();
        f
    }

    fn rows(n: usize, ts: f64) -> String {
        let mut s = String::from("t,m1.x,m1.v,u\n");
        for k in 0..n {
            let t = k as f64 * ts;
            s.push_str(&format!("{t},{},{},{}\n", t.sin(), t.cos(), 0.5));
        }
        s
    }

    /// Open and stream; the error message of the first failure.
    fn read(body: &str, opts: &CsvOptions) -> Result<usize, String> {
        let ir = sdof_ir(true);
        let f = file(body);
        let src = CsvSource::open(f.path(), &ir, opts).map_err(|e| e.to_string())?;
        let mut n = 0;
        src.stream(64, &mut |_, l| n += l)
            .map_err(|e| e.to_string())?;
        Ok(n)
    }

    #[test]
    fn reads_a_valid_file_in_chunks() {
        assert_eq!(read(&rows(300, 0.01), &CsvOptions::default()), Ok(300));
    }

    /// One streamed chunk: its length and the chunk's columns.
    type Chunk = (usize, Vec<Vec<f64>>);

    /// Every chunk of one pass.
    fn pass(src: &CsvSource, max_len: usize) -> Result<Vec<Chunk>, DataError> {
        let mut chunks = Vec::new();
        src.stream(max_len, &mut |cols, len| {
            chunks.push((len, cols.iter().map(|c| c.to_vec()).collect()));
        })?;
        Ok(chunks)
    }

    #[test]
    fn later_passes_replay_exactly_what_the_first_parsed() {
        let ir = sdof_ir(true);
        let f = file(&rows(1000, 0.01));
        let src = CsvSource::open(f.path(), &ir, &CsvOptions::default()).unwrap();
        let uncopied = src.clone().without_replay();
        for max_len in [64, 1000, 4096, 7] {
            let first = pass(&src, max_len).unwrap();
            assert!(src.replay.lock().unwrap().is_some(), "no copy kept");
            assert_eq!(pass(&src, max_len).unwrap(), first, "max_len {max_len}");
            assert_eq!(pass(&uncopied, max_len).unwrap(), first);
            assert_eq!(first.iter().map(|c| c.0).sum::<usize>(), 1000);
        }
        assert!(uncopied.replay.lock().unwrap().is_none());
    }

    #[test]
    fn a_failed_pass_keeps_no_copy_and_fails_again() {
        let ir = sdof_ir(true);
        let body = rows(300, 0.01) + "3.0,1,nan,0\n";
        let f = file(&body);
        let src = CsvSource::open(f.path(), &ir, &CsvOptions::default()).unwrap();
        for _ in 0..2 {
            let e = pass(&src, 64).unwrap_err().to_string();
            assert!(e.contains("line 302"), "{e}");
            assert!(src.replay.lock().unwrap().is_none());
        }
    }

    #[test]
    fn missing_column_lists_what_is_there() {
        let body = rows(300, 0.01).replace("m1.v", "vel");
        let e = read(&body, &CsvOptions::default()).unwrap_err();
        assert!(
            e.contains("no column for the measured signal `m1.v` (columns: t, m1.x, vel, u)"),
            "{e}"
        );
        // ... and a renaming fixes it.
        let opts = CsvOptions {
            map: vec![("vel".into(), "m1.v".into())],
            ts: None,
        };
        assert_eq!(read(&body, &opts), Ok(300));
    }

    #[test]
    fn unmeasured_signals_are_not_required() {
        let ir = sdof_ir(false);
        let body = rows(300, 0.01).replace(",m1.v,", ",other,");
        let f = file(&body);
        assert!(CsvSource::open(f.path(), &ir, &CsvOptions::default()).is_ok());
    }

    #[test]
    fn nan_and_text_cells_name_line_and_column() {
        // Sample 5 (file line 7, after the header) gets a NaN position.
        let bad_line = 7;
        let body: String = rows(300, 0.01)
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i + 1 == bad_line {
                    "0.05,NaN,1,0.5".to_string()
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        let e = read(&body, &CsvOptions::default()).unwrap_err();
        assert!(
            e.contains(&format!(
                "line {bad_line}, column `m1.x`: NaN is not a finite number"
            )),
            "{e}"
        );
        let body2 = body.replace("0.05,NaN,", "0.05,abc,");
        let e = read(&body2, &CsvOptions::default()).unwrap_err();
        assert!(
            e.contains(&format!(
                "line {bad_line}, column `m1.x`: `abc` is not a number"
            )),
            "{e}"
        );
    }

    #[test]
    fn ragged_row_is_reported() {
        let mut body = rows(300, 0.01);
        body.push_str("3.0,1,2\n");
        let e = read(&body, &CsvOptions::default()).unwrap_err();
        assert!(
            e.contains("line 302: expected 4 fields as in the header, found 3"),
            "{e}"
        );
    }

    #[test]
    fn empty_and_header_only_files() {
        let e = read("", &CsvOptions::default()).unwrap_err();
        assert!(e.contains("the file is empty"), "{e}");
        let e = read("t,m1.x,m1.v,u\n", &CsvOptions::default()).unwrap_err();
        assert!(e.contains("has a header but no samples"), "{e}");
    }

    #[test]
    fn too_few_samples_says_how_many() {
        let e = read(&rows(50, 0.01), &CsvOptions::default()).unwrap_err();
        assert!(
            e.contains("only 50 samples; at least 100 are needed"),
            "{e}"
        );
    }

    #[test]
    fn non_uniform_time_names_the_first_bad_line() {
        let body: String = rows(300, 0.01)
            .lines()
            .enumerate()
            .filter(|(i, _)| *i != 120) // drop one sample: a gap of 2 Tₛ
            .map(|(_, l)| format!("{l}\n"))
            .collect();
        let e = read(&body, &CsvOptions::default()).unwrap_err();
        assert!(e.contains("line 121: the time step is"), "{e}");
    }

    #[test]
    fn sample_interval_is_required_without_t() {
        let body: String = rows(300, 0.01)
            .lines()
            .map(|l| l.split_once(',').unwrap().1.to_string() + "\n")
            .collect();
        let e = read(&body, &CsvOptions::default()).unwrap_err();
        assert!(e.contains("no sample interval"), "{e}");
        let opts = CsvOptions {
            map: vec![],
            ts: Some(0.01),
        };
        assert_eq!(read(&body, &opts), Ok(300));
    }

    #[test]
    fn a_trailing_comma_is_not_a_column() {
        // As written by some exporters (the Silverbox file): `"V1","V2",` and `a,b,`.
        let f = file("\"V1\",\"V2\",\n0.5,1.5,\n-0.25,2,\n0,0,\n");
        let opts = CsvOptions {
            map: vec![],
            ts: Some(0.1),
        };
        let rec = read_record(f.path(), &opts).unwrap();
        assert_eq!(rec.names, ["V1", "V2"]);
        assert_eq!(rec.column("V2").unwrap(), [1.5, 2.0, 0.0]);
    }
}
