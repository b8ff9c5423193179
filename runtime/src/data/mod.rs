//! Measured data for identification: one source per excitation level, streamed in chunks so
//! that memory use does not grow with the record length.
//!
//! A file's format is told by its first bytes, else its extension ([`detect`]): delimited
//! text (CSV, or another delimiter), MATLAB MAT-files (v5, v7 and v7.3), HDF5 and Parquet
//! (docs/formats.md). A text file must have a header naming its columns; a binary file names
//! its variables, datasets or columns. Columns are matched to the model's signals by name
//! (`m1.x`, `m1.v`, `u`; an optional `t` gives the sample times, which must be uniform) or
//! through `col=signal` renamings. Every signal the model declares measured must be present;
//! unmeasured signals are never required and extra columns are ignored.

mod binary;
mod csv_file;
mod csv_parse;
mod format;
#[doc(hidden)]
pub mod fuzz;
mod h5;
mod mat5;
mod pq;
mod record;
pub mod split;
#[cfg(test)]
mod tests;
mod text;

pub use binary::BinarySource;
pub use csv_file::{read_record_bytes, CsvSource};
pub use format::{detect, read_record, read_record_within, FileSource, Format, FORMATS_READ};
pub use record::{check_columns, RecordSource};
pub use split::cycles::{self, cut_cycles, find_period, Cycles};
pub use split::{
    default_response, split_record, CutAt, Segment, Split, SplitChoice, SplitError, SplitOptions,
};
pub use text::MAX_LINE;

use crate::record::Record;
use dynid_ir::ir::ModelIr;
use std::io::{BufReader, Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
    /// Where sample `k` (0-based) is, for messages: its number and time.
    fn locate(&self, k: usize) -> String {
        locate_sample(0.0, self.ts(), k)
    }
}

/// Sample `k` (0-based) of a record starting at `t0` with step `ts`, for messages: its
/// number and time.
pub(crate) fn locate_sample(t0: f64, ts: f64, k: usize) -> String {
    format!(
        "sample {} (t = {} s)",
        k + 1,
        dynid_ir::num::sig(t0 + k as f64 * ts, 9, false)
    )
}

/// Relative tolerance on the time step of a file's time column, every format (times
/// printed with few digits jitter slightly).
pub(crate) const TIME_TOL: f64 = 1e-3;

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
    #[error("{path}: the header `{header}` is one column: the file is not comma-separated (it uses `{separator}`)")]
    #[diagnostic(
        code(dynid::data::separator),
        help("give `--delimiter '{separator}'` to read it as it is (numbers need `.` as the decimal point), or write the file with commas between the columns")
    )]
    Separator {
        path: String,
        header: String,
        separator: String,
    },
    #[error("{path}: column `{column}` appears twice in the header")]
    #[diagnostic(
        code(dynid::data::duplicate_column),
        help("rename or drop one of them")
    )]
    DuplicateColumn { path: String, column: String },
    #[error("{path}: line {line}: expected {expected} fields as in the header, found {found}")]
    #[diagnostic(code(dynid::data::ragged), help("{}", ragged_help(*.expected, *.found)))]
    Ragged {
        path: String,
        line: u64,
        expected: usize,
        found: usize,
    },
    #[error("{path}: line {line}, column `{column}`: `{value}` is not a number{}", .note.as_ref().map_or(String::new(), |n| format!(" ({n})")))]
    #[diagnostic(code(dynid::data::not_a_number), help("{}", number_help(value)))]
    NotANumber {
        path: String,
        line: u64,
        column: String,
        /// The field, invisible characters escaped.
        value: String,
        /// What its invisible characters are, if it has any.
        note: Option<String>,
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
    #[error("{path}: reading the record whole would take {estimate} of memory ({rows} rows × {columns} columns, estimated from the file's size and the bytes per row of its first lines), above the limit of {limit}")]
    #[diagnostic(
        code(dynid::data::too_large),
        help("this command holds the whole record in memory: keep only the columns it needs, cut the record into shorter ones, or give `--allow-large` to read it anyway")
    )]
    TooLarge {
        path: String,
        estimate: String,
        rows: String,
        columns: usize,
        limit: String,
    },
    #[error("{path}: line {line}: the time step is {step} s, but the sample interval is {ts} s")]
    #[diagnostic(
        code(dynid::data::non_uniform_time),
        help("identification needs uniformly sampled data: resample the record onto a uniform time grid; only if the time stamps merely jitter around a uniform grid (the samples themselves are uniform) drop the `t` column and give `--sample TS`")
    )]
    NonUniformTime {
        path: String,
        line: u64,
        step: f64,
        ts: f64,
    },
    #[error("{path}: line {line}: the time stamp {t} s does not increase (the line before has {previous} s)")]
    #[diagnostic(
        code(dynid::data::non_uniform_time),
        help("the samples must be in time order without repeats: sort the file by `t` and drop repeated samples")
    )]
    TimeNotIncreasing {
        path: String,
        line: u64,
        t: f64,
        previous: f64,
    },
    #[error("{path}: line {line}: {gone} missing between t = {t_before} s and t = {t_after} s (the time step there is {step} s, the sample interval {dt} s)",
        gone = if *.missing == 1 { "a sample is".to_string() } else { format!("{} samples are", .missing) },
        t_before = dynid_ir::num::sig(*.before, 9, false),
        t_after = dynid_ir::num::sig(*.after, 9, false),
        step = dynid_ir::num::sig(*.after - *.before, 6, false),
        dt = dynid_ir::num::sig(*.ts, 6, false))]
    #[diagnostic(
        code(dynid::data::non_uniform_time),
        help("the filters need a record without gaps, and joining the two sides would splice the motion across the gap: cut the file at line {line} into two files (each with the header) and give both, as separate records")
    )]
    MissingSamples {
        path: String,
        line: u64,
        before: f64,
        after: f64,
        missing: u64,
        ts: f64,
    },
    #[error("{path}: `--sample {}` conflicts with the file's `t` column, whose time step is {} s", dynid_ir::num::sig(*.ts, 9, false), dynid_ir::num::sig(*.step, 6, false))]
    #[diagnostic(
        code(dynid::data::sample_conflict),
        help("leave out `--sample`: the `t` column gives the sample interval (`--sample` is for files without a `t` column)")
    )]
    SampleConflict { path: String, ts: f64, step: f64 },
    #[error("{path}: the file is {kind} text; dynid reads UTF-8 (or ASCII) CSV")]
    #[diagnostic(
        code(dynid::data::encoding),
        help("save the file as UTF-8 (e.g. `iconv -f UTF-16 -t UTF-8 FILE > NEW.csv`, or \"CSV UTF-8\" when exporting)")
    )]
    Encoding { path: String, kind: String },
    #[error("{path}: the lines end in a carriage return alone (old Mac OS line ends), so the file reads as one long line")]
    #[diagnostic(
        code(dynid::data::line_ends),
        help("convert the line ends to line feeds (`\\n`), e.g. `tr '\\r' '\\n' < FILE > NEW.csv`; Windows line ends (`\\r\\n`) are read as they are")
    )]
    CarriageReturns { path: String },
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
    #[error("{path}: `--map {spec}`: the file already has the time column `t`, so column `{column}` cannot become a second one")]
    #[diagnostic(
        code(dynid::data::bad_map),
        help("`t` is the time column and cannot be mapped to a signal or from one; `--map COLUMN=t` names the time column of a file that has no `t`. To read a signal from a column, write `--map COLUMN=SIGNAL` (e.g. `--map disp={column}` reads signal `{column}` from column `disp`)")
    )]
    MapOntoTime {
        path: String,
        spec: String,
        column: String,
    },
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
    #[error("{path}: line {line} is longer than {limit} without a line end")]
    #[diagnostic(
        code(dynid::data::line_too_long),
        help("a level file is text with one sample per line (ending in `\\n` or `\\r\\n`); check that this is the right file and that its line ends survived the transfer")
    )]
    LineTooLong {
        path: String,
        line: u64,
        /// The limit in words (e.g. `1 MiB`).
        limit: String,
    },
    #[error("{path}: {what}: not a format dynid reads")]
    #[diagnostic(
        code(dynid::data::unknown_format),
        help("dynid reads {}; export the data to one of these (one column or variable per signal, named as in the model)", FORMATS_READ)
    )]
    UnknownFormat { path: String, what: String },
    #[error("{path}: cannot read this {format} file: {message}")]
    #[diagnostic(
        code(dynid::data::format),
        help("check that the file was written completely (not truncated in a copy) and opens in the program that wrote it; docs/formats.md lists what is read of each format")
    )]
    Format {
        path: String,
        format: String,
        message: String,
    },
    #[error(
        "{path}: no variable or column for the measured signal `{signal}`; the file holds: {holds}"
    )]
    #[diagnostic(
        code(dynid::data::missing_column),
        help("name a variable (or column) `{signal}`, map one with `--map NAME={signal}`, store one matrix (one sample per row) with a `names` variable naming its columns, or declare `{signal}` unmeasured in the model")
    )]
    MissingVariable {
        path: String,
        signal: String,
        holds: String,
    },
    #[error("{path}: sample {sample}, column `{column}`: {value} is not a finite number")]
    #[diagnostic(
        code(dynid::data::non_finite),
        help("remove or repair samples with NaN or infinite values (cut the record into clean pieces)")
    )]
    SampleNonFinite {
        path: String,
        sample: u64,
        column: String,
        value: f64,
    },
    #[error("{path}: sample {sample}: {message}")]
    #[diagnostic(
        code(dynid::data::non_uniform_time),
        help("identification needs uniformly sampled data without gaps, in time order: resample the record onto a uniform time grid, or cut it at the gap into separate records")
    )]
    SampleTime {
        path: String,
        sample: u64,
        message: String,
    },
    #[error("{path}: line {line} holds a NUL byte: this is not a text file")]
    #[diagnostic(
        code(dynid::data::binary),
        help(
            "a text level file is ASCII or UTF-8 (a UTF-16 file must be saved as UTF-8 first); the binary formats read are MATLAB .mat, HDF5 and Parquet"
        )
    )]
    Binary { path: String, line: u64 },
}

fn ragged_help(expected: usize, found: usize) -> String {
    let mut h = "every line needs one value per header column".to_string();
    if found > expected {
        h += "; more fields than columns often means numbers written with a decimal comma \
               (`0,25`): write them with `.` as the decimal point";
    }
    h
}

fn number_help(value: &str) -> String {
    let v = value.trim();
    if v.contains(',') && v.replace(',', ".").parse::<f64>().is_ok() {
        format!(
            "`{v}` has a decimal comma: write numbers with `.` as the decimal point (`{}`)",
            v.replace(',', ".")
        )
    } else {
        "use plain decimal numbers such as `-1.25e-3`".into()
    }
}

/// How to read data files: renamings and the sample interval for every format; the
/// delimiter, comment lines and units rows for text.
#[derive(Clone, Debug, Default)]
pub struct CsvOptions {
    /// `(column, signal)` renamings.
    pub map: Vec<(String, String)>,
    /// Sample interval; required when there is no `t` column. With a `t` column it is
    /// checked against the time steps.
    pub ts: Option<f64>,
    /// Text: the byte between fields (`None`: a comma).
    pub delimiter: Option<u8>,
    /// Text: lines whose first non-blank character is this byte are skipped, before the
    /// header and between samples (`None`: no comment lines).
    pub comment: Option<u8>,
    /// Text: lines right after the header that are not samples (e.g. a units row
    /// `s,m,m/s,N`), skipped.
    pub skip_after_header: usize,
}

impl CsvOptions {
    /// Parse a `--delimiter` value: one ASCII character other than a quote or line end,
    /// or a name: `tab`, `semicolon`, `comma`, `space`, `\t`.
    pub fn parse_delimiter(s: &str) -> Result<u8, String> {
        match s {
            "tab" | "\\t" | "\t" => return Ok(b'\t'),
            "semicolon" => return Ok(b';'),
            "comma" => return Ok(b','),
            "space" => return Ok(b' '),
            _ => {}
        }
        match s.as_bytes() {
            [b] if b.is_ascii()
                && !matches!(b, b'"' | b'\n' | b'\r')
                && !b.is_ascii_alphanumeric()
                && *b != b'.'
                && *b != b'-'
                && *b != b'+' =>
            {
                Ok(*b)
            }
            _ => Err(format!(
                "`{s}` is not a delimiter: give one character such as `;` or `|`, or `tab`"
            )),
        }
    }
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
                spec: dynid_ir::text::escape(spec),
                message: "expected COLUMN=SIGNAL".into(),
                signals,
            });
        };
        let (c, s) = (c.trim(), s.trim());
        if c.is_empty() {
            return Err(DataError::BadMap {
                spec: dynid_ir::text::escape(spec),
                message: "the column name before `=` is empty".into(),
                signals,
            });
        }
        if c == "t" && s != "t" {
            return Err(DataError::BadMap {
                spec: dynid_ir::text::escape(spec),
                message: format!(
                    "`t` is the time column; it cannot be mapped to the signal `{}`",
                    dynid_ir::text::escape(s)
                ),
                signals,
            });
        }
        if ir.signal_id(s).is_none() && s != "t" {
            return Err(DataError::BadMap {
                spec: dynid_ir::text::escape(spec),
                message: format!("{} is not a signal of the model", dynid_ir::text::quote(s)),
                signals,
            });
        }
        Ok((c.to_string(), s.to_string()))
    }
}
