//! HDF5 files and MAT-files of version 7.3 (HDF5 with MATLAB's layout), through the
//! pure-Rust `hdf5-pure` reader. The datasets at the file's root are the variables.
//!
//! A dataset is read in windows of samples along its first HDF5 dimension, and only the
//! chunks a window overlaps are read and inflated. Where the samples run along the second
//! dimension (a MATLAB column vector, stored by MATLAB as HDF5 `[1, N]`, or a MATLAB `N×k`
//! matrix, stored as `[k, N]`), a window of samples is not a window of rows, and every pass
//! reads the dataset whole (its memory is that of the columns read).

use super::binary::{describe, format_err, names_from_chars, Column, Store, Windows};
use super::*;
use hdf5_pure::{AttrValue, DType, Dataset};
use std::collections::HashMap;

/// How a column is laid out in its dataset.
#[derive(Clone, Copy, Debug)]
enum Lay {
    /// Samples along the first dimension: rows of `width` values, the column at `index`.
    Rows { width: usize, index: usize },
    /// Samples along the second dimension: the column is row `row` (read whole).
    Whole { row: usize, len: usize },
}

struct Ds {
    name: String,
    shape: Vec<usize>,
    what: String,
    numeric: bool,
    handle: Dataset,
}

impl std::fmt::Debug for Ds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ds")
            .field("name", &self.name)
            .field("shape", &self.shape)
            .finish()
    }
}

/// An HDF5 file (or MAT v7.3 file) opened for streaming reads.
#[derive(Debug)]
pub(super) struct H5 {
    path: PathBuf,
    format: &'static str,
    sets: Vec<Ds>,
    columns: Vec<Column>,
    col_src: Vec<(usize, Lay)>,
}

fn attr_text(v: &AttrValue) -> Option<String> {
    match v {
        AttrValue::String(s) | AttrValue::AsciiString(s) => Some(s.clone()),
        AttrValue::StringSized { value, .. } | AttrValue::AsciiStringSized { value, .. } => {
            Some(value.clone())
        }
        _ => None,
    }
}

impl H5 {
    /// Open `path` (`mat` for a MAT v7.3 file) and find its columns.
    pub(super) fn open(path: &Path, mat: bool) -> Result<H5, DataError> {
        let format = if mat { "MAT v7.3" } else { "HDF5" };
        let err = |e: &dyn std::fmt::Display| format_err(path, format, e);
        let file = hdf5_pure::File::open_streaming(path).map_err(|e| err(&e))?;
        let root = file.root();
        let mut sets = Vec::new();
        for name in root.datasets().map_err(|e| err(&e))? {
            let handle = file.dataset(&name).map_err(|e| err(&e))?;
            let shape: Vec<usize> = handle
                .shape()
                .map_err(|e| err(&e))?
                .iter()
                .map(|&d| d as usize)
                .collect();
            let dtype = handle.dtype().map_err(|e| err(&e))?;
            let class = matlab_class(&handle);
            let numeric = matches!(
                dtype,
                DType::F32
                    | DType::F64
                    | DType::I8
                    | DType::I16
                    | DType::I32
                    | DType::I64
                    | DType::U8
                    | DType::U16
                    | DType::U32
                    | DType::U64
            ) && class.as_deref().is_none_or(|c| c != "char");
            let what = class.unwrap_or_else(|| dtype.to_string());
            if numeric {
                check_chunk_grid(&handle, &shape).map_err(|m| err(&format!("`{name}`: {m}")))?;
            }
            sets.push(Ds {
                name,
                shape,
                what,
                numeric,
                handle,
            });
        }
        let mut h = H5 {
            path: path.to_path_buf(),
            format,
            sets,
            columns: Vec::new(),
            col_src: Vec::new(),
        };
        h.find_columns()?;
        Ok(h)
    }

    fn err(&self, m: impl std::fmt::Display) -> DataError {
        format_err(&self.path, self.format, m)
    }

    fn find_columns(&mut self) -> Result<(), DataError> {
        for (k, d) in self.sets.iter().enumerate() {
            if !d.numeric {
                continue;
            }
            let lay = match d.shape.as_slice() {
                [n] => Some((Lay::Rows { width: 1, index: 0 }, *n)),
                [n, 1] => Some((Lay::Rows { width: 1, index: 0 }, *n)),
                [1, n] => Some((Lay::Whole { row: 0, len: *n }, *n)),
                _ => None,
            };
            if let Some((lay, len)) = lay {
                self.columns.push(Column {
                    name: d.name.clone(),
                    len,
                });
                self.col_src.push((k, lay));
            }
        }
        let Some(ni) = self.sets.iter().position(|d| d.name == "names") else {
            return Ok(());
        };
        let names = self.read_names(ni)?;
        let k = names.len();
        let two_d = |d: &Ds| d.numeric && d.shape.len() == 2 && d.shape[0] != 1 && d.shape[1] != 1;
        let fits: Vec<(usize, bool)> = self
            .sets
            .iter()
            .enumerate()
            .filter(|(_, d)| two_d(d) && (d.shape[1] == k || d.shape[0] == k))
            .map(|(i, d)| (i, d.shape[1] == k))
            .collect();
        match fits.as_slice() {
            [(m, by_rows)] => {
                let shape = self.sets[*m].shape.clone();
                for (j, name) in names.into_iter().enumerate() {
                    let (lay, len) = if *by_rows {
                        (Lay::Rows { width: k, index: j }, shape[0])
                    } else {
                        (Lay::Whole { row: j, len: shape[1] }, shape[1])
                    };
                    self.columns.push(Column { name, len });
                    self.col_src.push((*m, lay));
                }
                Ok(())
            }
            [] => Err(self.err(format!(
                "`names` holds {k} names ({}) but no two-dimensional dataset has {k} columns; the file holds {}",
                names.join(", "),
                self.contents()
            ))),
            _ => Err(self.err(format!(
                "more than one dataset has {k} columns ({}): keep one matrix with the `names` dataset",
                fits.iter().map(|&(i, _)| self.sets[i].name.as_str()).collect::<Vec<_>>().join(", ")
            ))),
        }
    }

    /// The `names` dataset: strings (one per name, or one holding names separated by
    /// commas), or a MATLAB char array (one name per row, or one row of names separated by
    /// commas).
    fn read_names(&self, i: usize) -> Result<Vec<String>, DataError> {
        let d = &self.sets[i];
        let bad = |e: &dyn std::fmt::Display| {
            self.err(format!("`names` is not readable as text ({e}): store it as strings, or as a MATLAB char array"))
        };
        if d.what == "char" {
            // MATLAB's `r×c` char array is stored as HDF5 `[c, r]`.
            let rows = d.shape.get(1).copied().unwrap_or(1);
            return Ok(names_from_chars(
                &utf16_chars(&d.handle).map_err(|e| bad(&e))?,
                rows,
            ));
        }
        if d.what == "cell" {
            return self.read_cell_names(d);
        }
        let strings = d.handle.read_string().map_err(|e| bad(&e))?;
        Ok(match strings.as_slice() {
            [one] => names_from_chars(&one.chars().collect::<Vec<_>>(), 1),
            _ => strings
                .iter()
                .map(|s| s.trim_matches(['\0', ' ']).to_string())
                .collect(),
        })
    }
}

impl H5 {
    /// A MATLAB cell array of char vectors (`names = {'t', 'm.x', ...}` saved with
    /// `-v7.3`): a dataset of object references, each naming one char dataset under
    /// `#refs#`. The cells are taken in storage order, which for a row or a column of
    /// cells is the order MATLAB shows.
    fn read_cell_names(&self, d: &Ds) -> Result<Vec<String>, DataError> {
        let help = "store `names` as a cell array of char vectors, a char row of names \
                    separated by commas, or a char matrix with one name per row";
        if d.shape.len() > 2 || d.shape.iter().filter(|&&n| n > 1).count() > 1 {
            return Err(self.err(format!(
                "`names` is a cell array of shape {:?}, not a row or a column: {help}",
                d.shape
            )));
        }
        // A names list is short; a damaged shape must not make the reader follow
        // millions of references.
        let count: usize = d.shape.iter().product();
        if count > MAX_NAMES {
            return Err(self.err(format!(
                "`names` is a cell array of {count} cells, more than {MAX_NAMES} names: {help}"
            )));
        }
        let cells = d.handle.dereference().map_err(|e| {
            self.err(format!(
                "`names` is a cell array whose cells cannot be followed ({e}): {help}"
            ))
        })?;
        let mut names = Vec::with_capacity(cells.len());
        for (k, cell) in cells.into_iter().enumerate() {
            let hdf5_pure::Object::Dataset(ds) = cell else {
                return Err(self.err(format!(
                    "cell {} of `names` is a group, not a char vector: {help}",
                    k + 1
                )));
            };
            let class = matlab_class(&ds);
            if class.as_deref() != Some("char") {
                return Err(self.err(format!(
                    "cell {} of `names` holds {}, not a char vector: {help}",
                    k + 1,
                    class.as_deref().unwrap_or("something other than text")
                )));
            }
            let chars = utf16_chars(&ds).map_err(|e| {
                self.err(format!(
                    "cell {} of `names` is not readable as text ({e}): {help}",
                    k + 1
                ))
            })?;
            names.push(
                chars
                    .iter()
                    .collect::<String>()
                    .trim_matches(['\0', ' '])
                    .to_string(),
            );
        }
        Ok(names)
    }
}

/// The most cells a `names` cell array may hold.
const MAX_NAMES: usize = 100_000;

/// A dataset's `MATLAB_class` attribute (`double`, `char`, `cell`, …), where it has one.
fn matlab_class(ds: &Dataset) -> Option<String> {
    ds.attrs()
        .ok()
        .and_then(|a| a.get("MATLAB_class").and_then(attr_text))
}

/// The characters of a MATLAB char dataset (UTF-16 code units; unpaired surrogates
/// become U+FFFD).
fn utf16_chars(ds: &Dataset) -> Result<Vec<char>, hdf5_pure::Error> {
    let units = ds.read_u16()?;
    Ok(char::decode_utf16(units)
        .map(|c| c.unwrap_or('\u{fffd}'))
        .collect())
}

impl Store for H5 {
    fn format(&self) -> &'static str {
        self.format
    }
    fn columns(&self) -> &[Column] {
        &self.columns
    }
    fn contents(&self) -> String {
        if self.sets.is_empty() {
            return "no datasets at its root".into();
        }
        self.sets
            .iter()
            .map(|d| {
                // MATLAB's dimensions are HDF5's reversed.
                let mut dims = d.shape.clone();
                if self.format == "MAT v7.3" {
                    dims.reverse();
                }
                describe(&d.name, &d.what, &dims)
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
    fn open(&self, cols: &[usize]) -> Result<Box<dyn Windows + '_>, DataError> {
        let mut whole = HashMap::new();
        for &c in cols {
            let (ds, lay) = self.col_src[c];
            if let Lay::Whole { .. } = lay {
                if let std::collections::hash_map::Entry::Vacant(e) = whole.entry(ds) {
                    let v = self.sets[ds].handle.read_f64().map_err(|e| self.err(e))?;
                    e.insert(v);
                }
            }
        }
        let len = cols.first().map_or(0, |&c| self.columns[c].len);
        Ok(Box::new(H5Windows {
            h: self,
            cols: cols.to_vec(),
            whole,
            pos: 0,
            len,
        }))
    }
}

struct H5Windows<'a> {
    h: &'a H5,
    cols: Vec<usize>,
    whole: HashMap<usize, Vec<f64>>,
    pos: usize,
    len: usize,
}

impl Windows for H5Windows<'_> {
    fn next(&mut self, out: &mut [Vec<f64>], max: usize) -> Result<usize, DataError> {
        let count = max.min(self.len - self.pos);
        if count == 0 {
            return Ok(0);
        }
        let mut rows: HashMap<usize, Vec<f64>> = HashMap::new();
        for (k, &c) in self.cols.iter().enumerate() {
            let (ds, lay) = self.h.col_src[c];
            match lay {
                Lay::Rows { width, index } => {
                    if let std::collections::hash_map::Entry::Vacant(e) = rows.entry(ds) {
                        let v = self.h.sets[ds]
                            .handle
                            .read_f64_rows(self.pos as u64, count as u64)
                            .map_err(|e| self.h.err(e))?;
                        if v.len() != count * width {
                            return Err(self.h.err(format!(
                                "`{}`: a read of {count} rows gave {} values, not {}",
                                self.h.sets[ds].name,
                                v.len(),
                                count * width
                            )));
                        }
                        e.insert(v);
                    }
                    let v = &rows[&ds];
                    out[k].extend((0..count).map(|i| v[i * width + index]));
                }
                Lay::Whole { row, len } => {
                    let v = &self.whole[&ds];
                    let from = row * len + self.pos;
                    match v.get(from..from + count) {
                        Some(s) => out[k].extend_from_slice(s),
                        None => {
                            return Err(self.h.err(format!(
                                "`{}` holds {} values, fewer than its shape says",
                                self.h.sets[ds].name,
                                v.len()
                            )))
                        }
                    }
                }
            }
        }
        self.pos += count;
        Ok(count)
    }
}

/// The most chunks a dataset read may be cut into: `hdf5-pure` lays out a slot per chunk of
/// the whole extent before reading, and a damaged layout (a huge extent, tiny chunks) would
/// ask for petabytes — an allocation failure that aborts the process (found by the `binary`
/// fuzz target). Real files hold far fewer: h5py's automatic chunks of about 1 MB cut even
/// 10⁹ samples into some 10⁴.
const MAX_CHUNKS: f64 = 1e7;

/// Refuse a chunked dataset whose chunk grid over `shape` has more than [`MAX_CHUNKS`] cells
/// (or a chunk dimension of zero).
fn check_chunk_grid(handle: &Dataset, shape: &[usize]) -> Result<(), String> {
    let Ok(Some(chunk)) = handle.chunk_shape() else {
        return Ok(());
    };
    let mut cells = 1.0f64;
    for (k, &n) in shape.iter().enumerate() {
        let c = chunk.get(k).copied().unwrap_or(1);
        if c == 0 {
            return Err("its chunk layout has a dimension of zero (a damaged file)".into());
        }
        cells *= (n as f64 / c as f64).ceil().max(1.0);
    }
    if cells > MAX_CHUNKS {
        return Err(format!(
            "its chunk layout cuts it into {cells:.1e} chunks (more than {MAX_CHUNKS:.0e}): a \
             damaged file, or one saved with tiny chunks — re-save it contiguous or with larger chunks"
        ));
    }
    Ok(())
}
