//! Which reader a data file needs: told by its first bytes (MAT-file header, HDF5 or
//! Parquet signature), else by its extension; anything else is read as delimited text.

use super::binary::{read_whole, BinarySource, Store};
use super::*;

/// The formats of data files read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Delimited text (CSV; `;`, tab and other delimiters through [`CsvOptions`]).
    Text,
    /// MATLAB MAT-file level 5 (`save -v6`, `-v7`).
    Mat5,
    /// MATLAB MAT-file version 7.3 (HDF5 with MATLAB's layout; `save -v7.3`).
    Mat73,
    /// HDF5.
    Hdf5,
    /// Apache Parquet.
    Parquet,
}

/// The formats read, in words, for messages.
pub const FORMATS_READ: &str =
    "CSV or other delimited text, MATLAB .mat (v5, v7 and v7.3), HDF5 (.h5) and Parquet (.parquet)";

const HDF5_SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";

/// The format of the file at `path`, from its first bytes, else from its extension.
/// Pipes and other files that are not regular are read as text.
pub fn detect(path: &Path) -> Result<Format, DataError> {
    let p = || path.display().to_string();
    let Ok(meta) = std::fs::metadata(path) else {
        // The reader reports the missing file.
        return Ok(Format::Text);
    };
    if !meta.is_file() {
        return Ok(Format::Text);
    }
    let mut head = Vec::with_capacity(1032);
    if let Ok(f) = std::fs::File::open(path) {
        // An unreadable file is reported by the reader.
        let _ = f.take(1032).read_to_end(&mut head);
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let at = |k: usize, sig: &[u8]| head.get(k..k + sig.len()) == Some(sig);
    if head.starts_with(b"MATLAB 7.3 MAT-file")
        || (at(512, HDF5_SIGNATURE) && head.starts_with(b"MATLAB"))
    {
        return Ok(Format::Mat73);
    }
    if head.starts_with(b"MATLAB 5.0 MAT-file") {
        if head.len() < 128 {
            return Err(DataError::Format {
                path: p(),
                format: "MAT v5".into(),
                message: format!(
                    "the file ends inside its 128-byte header (after {} bytes): it is truncated",
                    head.len()
                ),
            });
        }
        return Ok(Format::Mat5);
    }
    if at(0, HDF5_SIGNATURE) || at(512, HDF5_SIGNATURE) || at(1024, HDF5_SIGNATURE) {
        return Ok(Format::Hdf5);
    }
    if head.starts_with(b"PAR1") {
        return Ok(Format::Parquet);
    }
    // The extension names a binary format the content does not match.
    let claimed = match ext.as_str() {
        "mat" => Some("MAT-file"),
        "h5" | "hdf5" | "hdf" | "he5" => Some("HDF5"),
        "parquet" | "pq" => Some("Parquet"),
        _ => None,
    };
    if let Some(fmt) = claimed {
        let begins = if head.is_empty() {
            "is empty".to_string()
        } else {
            let shown: String = head
                .iter()
                .take(16)
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" ");
            format!("begins with the bytes {shown}")
        };
        return Err(DataError::Format {
            path: p(),
            format: fmt.into(),
            message: format!("the name says {fmt}, but the file {begins}, not the signature of one: it is damaged, truncated or misnamed"),
        });
    }
    // Other formats recognised, to name them.
    let other = if head.starts_with(b"TDSm") || ext == "tdms" {
        Some("an NI TDMS file")
    } else if head.starts_with(b"PK\x03\x04") {
        Some("a ZIP archive (or an .xlsx/.ods spreadsheet)")
    } else if head.starts_with(&[0x1f, 0x8b]) {
        Some("a gzip-compressed file")
    } else if head.starts_with(&[0xd0, 0xcf, 0x11, 0xe0]) {
        Some("an old Office file (.xls)")
    } else if matches!(ext.as_str(), "uff" | "unv") {
        Some("a universal file (UFF)")
    } else {
        None
    };
    if let Some(what) = other {
        return Err(DataError::UnknownFormat {
            path: p(),
            what: what.into(),
        });
    }
    Ok(Format::Text)
}

/// Open the file at `path` in format `f`: `None` for text.
fn store(path: &Path, f: Format) -> Result<Option<Arc<dyn Store>>, DataError> {
    Ok(Some(match f {
        Format::Mat5 => Arc::new(super::mat5::Mat5::open(path)?),
        Format::Mat73 => Arc::new(super::h5::H5::open(path, true)?),
        Format::Hdf5 => Arc::new(super::h5::H5::open(path, false)?),
        Format::Parquet => Arc::new(super::pq::Pq::open(path)?),
        Format::Text => return Ok(None),
    }))
}

/// A level file of any format read, bound to a model: text through [`CsvSource`], binary
/// formats through [`BinarySource`]. Choose with [`FileSource::open`].
#[derive(Clone, Debug)]
pub enum FileSource {
    Csv(CsvSource),
    Binary(BinarySource),
}

impl FileSource {
    /// Open `path` in the format its content (else its extension) tells, and match its
    /// columns to the measured signals of `ir` (see [`CsvSource::open`]).
    pub fn open(path: &Path, ir: &ModelIr, opts: &CsvOptions) -> Result<FileSource, DataError> {
        match store(path, detect(path)?)? {
            None => Ok(FileSource::Csv(CsvSource::open(path, ir, opts)?)),
            Some(s) => Ok(FileSource::Binary(BinarySource::open(path, s, ir, opts)?)),
        }
    }

    /// The samples of the record: estimated for text (see [`CsvSource::samples_hint`]),
    /// known for binary files.
    pub fn samples_hint(&self) -> Option<f64> {
        match self {
            FileSource::Csv(s) => s.samples_hint(),
            FileSource::Binary(b) => Some(b.samples() as f64),
        }
    }

    /// The memory, in bytes, of the record's streamed columns read whole.
    pub fn whole_bytes(&self) -> f64 {
        match self {
            FileSource::Csv(s) => s.whole_bytes(),
            FileSource::Binary(b) => b.whole_bytes(),
        }
    }

    /// Refuse to read the record whole when [`Self::whole_bytes`] is above
    /// [`crate::limits::MAX_BYTES`], unless `allow`.
    pub fn check_whole(&self, allow: bool) -> Result<(), DataError> {
        use crate::limits::{bytes_in_words, MAX_BYTES};
        match self {
            FileSource::Csv(s) => s.check_whole(allow),
            FileSource::Binary(b) => {
                let bytes = b.whole_bytes();
                if allow || bytes <= MAX_BYTES {
                    return Ok(());
                }
                Err(DataError::TooLarge {
                    path: b.origin(),
                    estimate: bytes_in_words(bytes),
                    rows: format!("{:.1e}", b.samples() as f64),
                    columns: (bytes / 8.0 / b.samples().max(1) as f64).round() as usize,
                    limit: bytes_in_words(MAX_BYTES),
                })
            }
        }
    }
}

impl LevelSource for FileSource {
    fn origin(&self) -> String {
        match self {
            FileSource::Csv(s) => s.origin(),
            FileSource::Binary(b) => b.origin(),
        }
    }
    fn ts(&self) -> f64 {
        match self {
            FileSource::Csv(s) => s.ts(),
            FileSource::Binary(b) => b.ts(),
        }
    }
    fn locate(&self, k: usize) -> String {
        match self {
            FileSource::Csv(s) => s.locate(k),
            FileSource::Binary(b) => b.locate(k),
        }
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        match self {
            FileSource::Csv(s) => s.stream(max_len, sink),
            FileSource::Binary(b) => b.stream(max_len, sink),
        }
    }
}

/// Read a whole data file of any format read into a [`Record`] (every named column —
/// scalars saved beside the record left out — except
/// `t`, renamed by `opts.map`), validated as [`FileSource`] streams it. At least two
/// samples. For inputs that drive a simulation; identification streams instead.
pub fn read_record(path: &Path, opts: &CsvOptions) -> Result<Record, DataError> {
    read_record_within(path, opts, false)
}

/// As [`read_record`], refused before reading when the record would take more than
/// [`crate::limits::MAX_BYTES`] of memory unless `allow_large`.
pub fn read_record_within(
    path: &Path,
    opts: &CsvOptions,
    allow_large: bool,
) -> Result<Record, DataError> {
    match store(path, detect(path)?)? {
        None => super::csv_file::read_csv_record(path, opts, allow_large),
        Some(s) => read_whole(path, s, opts, allow_large),
    }
}
