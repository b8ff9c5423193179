//! MATLAB MAT-files of level 5 (`save -v6`, `-v7`; the default before v7.3): variables are
//! found from the file's element tags without reading their data, and the data of the
//! columns used is streamed: an uncompressed variable is read in windows from its place in
//! the file, a compressed one (`-v7`) is inflated as it is read, once per pass.
//!
//! This module finds the variables and the columns in them; `elements` reads the file's
//! elements, `store` streams the columns' data.

mod elements;
mod store;

use super::binary::{names_from_chars, Column, Store};
use super::*;
use elements::{chars_of, mi_size, Counted, Parser};
use std::io::SeekFrom;

const FORMAT: &str = "MAT v5";
/// Data types of the tags (the MAT-file format's `mi*` numbers).
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
/// Largest `names` variable read (its text is read whole).
const MAX_NAMES_BYTES: u64 = 1 << 20;

/// Where a variable's data (its real part) starts.
#[derive(Clone, Debug)]
enum Place {
    /// At this offset of the file.
    Raw(u64),
    /// In the zlib stream of `len` bytes at `offset`, `skip` bytes into the inflated data.
    Zip { offset: u64, len: u64, skip: u64 },
    /// In the tag itself (at most 4 bytes).
    Inline(Vec<u8>),
}

#[derive(Clone, Debug)]
struct Var {
    name: String,
    /// MATLAB class number (6 double, 7 single, 8..=15 integers, 4 char, 1 cell, 2 struct, 5 sparse).
    class: u8,
    complex: bool,
    dims: Vec<usize>,
    /// Data type of the real part (`mi*`) and its byte count; `None` for classes without one.
    data: Option<(u32, u64, Place)>,
}

/// A MAT v5 file: its variables, found without reading their data.
#[derive(Debug)]
pub(super) struct Mat5 {
    path: PathBuf,
    vars: Vec<Var>,
    columns: Vec<Column>,
    /// For each column: the variable, and the element offset of its first sample.
    col_var: Vec<(usize, u64)>,
}

impl Mat5 {
    /// Find the variables of the MAT v5 file at `path` (its first 128 bytes were checked to
    /// be a MAT v5 header).
    pub(super) fn open(path: &Path) -> Result<Mat5, DataError> {
        let ps = Parser { path };
        let io = |e: std::io::Error| DataError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let size = file.metadata().map_err(io)?.len();
        let mut head = [0u8; 128];
        ps.read_exact(&mut file, &mut head, "the 128-byte header")?;
        if &head[126..128] == b"MI" {
            return Err(ps.err("the file is big-endian, which is not read: save it again on a little-endian machine (any PC or Mac)"));
        }
        if &head[126..128] != b"IM" {
            return Err(
                ps.err("the header's endian indicator is not `IM`: this is not a MAT v5 file")
            );
        }
        let mut vars = Vec::new();
        let mut pos = 128u64;
        while pos + 8 <= size {
            file.seek(SeekFrom::Start(pos)).map_err(io)?;
            let mut r = BufReader::with_capacity(1 << 12, &mut file);
            let (mi, n, inline) = ps.tag(&mut r, "a variable's tag")?;
            let start = pos + 8;
            let next = if inline.is_some() { pos + 8 } else { start + n };
            if inline.is_none() && next > size {
                return Err(ps.err(format!(
                    "a variable at byte {pos} claims {n} bytes, but the file ends {} bytes later: it is truncated",
                    size - start
                )));
            }
            if let Some(v) = read_variable(&ps, &mut r, mi, n, start, size)? {
                vars.push(v);
            }
            // Elements are 8-byte aligned; compressed ones are not padded.
            pos = if mi == MI_COMPRESSED {
                next
            } else {
                next.div_ceil(8) * 8
            };
        }
        let mut m = Mat5 {
            path: path.to_path_buf(),
            vars,
            columns: Vec::new(),
            col_var: Vec::new(),
        };
        m.find_columns()?;
        Ok(m)
    }

    /// Numeric, real, non-sparse: a variable that can hold samples.
    fn usable(v: &Var) -> bool {
        (6..=15).contains(&v.class)
            && !v.complex
            && v.dims.len() == 2
            && v.data
                .as_ref()
                .is_some_and(|(mi, _, _)| mi_size(*mi).is_some())
    }

    fn find_columns(&mut self) -> Result<(), DataError> {
        let ps = Parser { path: &self.path };
        // Vectors named by their variable.
        for (k, v) in self.vars.iter().enumerate() {
            if Self::usable(v) && v.dims.iter().filter(|&&d| d != 1).count() <= 1 {
                let len = v.dims.iter().fold(1usize, |a, &d| a.saturating_mul(d));
                self.columns.push(Column {
                    name: v.name.clone(),
                    len,
                });
                self.col_var.push((k, 0));
            }
        }
        // One matrix with a `names` variable.
        let Some(names_var) = self.vars.iter().position(|v| v.name == "names") else {
            return Ok(());
        };
        let names = self.read_names(names_var)?;
        let k = names.len();
        let matrices: Vec<usize> = (0..self.vars.len())
            .filter(|&i| {
                let v = &self.vars[i];
                Self::usable(v) && v.dims[0] != 1 && v.dims[1] != 1 && v.dims[1] == k
            })
            .collect();
        match matrices.as_slice() {
            [m] => {
                let rows = self.vars[*m].dims[0];
                for (j, name) in names.into_iter().enumerate() {
                    self.columns.push(Column { name, len: rows });
                    self.col_var.push((*m, (j * rows) as u64));
                }
                Ok(())
            }
            [] => {
                let transposed = self.vars.iter().find(|v| Self::usable(v) && v.dims[0] == k && v.dims[1] != 1);
                Err(ps.err(match transposed {
                    Some(v) => format!("`names` holds {k} names and `{}` is {}×{}: store one sample per row (a matrix of {}×{k}, e.g. `{} = {}.'`)", v.name, v.dims[0], v.dims[1], v.dims[1], v.name, v.name),
                    None => format!("`names` holds {k} names ({}) but no matrix has {k} columns; the file holds {}", names.join(", "), self.contents()),
                }))
            }
            _ => Err(ps.err(format!(
                "more than one matrix has {k} columns ({}): keep one matrix with the `names` variable",
                matrices.iter().map(|&i| self.vars[i].name.as_str()).collect::<Vec<_>>().join(", ")
            ))),
        }
    }

    /// The names in the `names` variable: a char array (one name per row, or a single row
    /// of names separated by commas) or a cell array of char vectors.
    fn read_names(&self, i: usize) -> Result<Vec<String>, DataError> {
        let ps = Parser { path: &self.path };
        let v = &self.vars[i];
        let bad = || {
            ps.err("`names` must be a char array (one name per row, or names separated by commas) or a cell array of char vectors")
        };
        if v.class == 1 {
            return self.read_cell_names(i);
        }
        if v.class != 4 {
            return Err(bad());
        }
        let Some((mi, n, place)) = &v.data else {
            return Err(bad());
        };
        let bytes = self.read_bytes(place, *n)?;
        let chars = chars_of(*mi, &bytes).ok_or_else(bad)?;
        Ok(names_from_chars(&chars, v.dims[0]))
    }

    fn read_cell_names(&self, i: usize) -> Result<Vec<String>, DataError> {
        let ps = Parser { path: &self.path };
        let bad = || ps.err("`names` is a cell array whose elements are not all char vectors");
        // Re-read the element: a cell's elements follow its name.
        let var = &self.vars[i];
        let count: usize = var.dims.iter().product();
        let mut r = self.element_reader(i)?;
        let _ = ps.matrix(&mut r)?;
        let mut names = Vec::with_capacity(count);
        for _ in 0..count {
            let (mi, n, _) = ps.tag(&mut r, "an element of `names`")?;
            if mi != MI_MATRIX || n > MAX_NAMES_BYTES {
                return Err(bad());
            }
            let mut sub = (&mut r).take(n);
            let (_, class, _, dims, data) = ps.matrix(&mut sub)?;
            let (mi, n, inline) = data.ok_or_else(bad)?;
            if class != 4 {
                return Err(bad());
            }
            let bytes = match inline {
                Some(d) => d,
                None => ps.small_data(&mut sub, n, "an element of `names`")?,
            };
            let chars = chars_of(mi, &bytes).ok_or_else(bad)?;
            let _ = dims;
            names.push(chars.iter().collect::<String>().trim().to_string());
            ps.skip(&mut sub, u64::MAX, "").ok();
        }
        Ok(names)
    }

    /// A reader positioned after the tag of variable `i`'s matrix element.
    fn element_reader(&self, i: usize) -> Result<Box<dyn Read + Send>, DataError> {
        let ps = Parser { path: &self.path };
        // Find the element again by walking the tags (only used for the small `names`).
        let io = |e: std::io::Error| ps.err(e);
        let mut file = std::fs::File::open(&self.path).map_err(io)?;
        let size = file.metadata().map_err(io)?.len();
        let mut pos = 128u64;
        let mut k = 0;
        while pos + 8 <= size {
            file.seek(SeekFrom::Start(pos)).map_err(io)?;
            let (mi, n, inline) = ps.tag(&mut file, "a variable's tag")?;
            let start = pos + 8;
            if mi == MI_MATRIX || mi == MI_COMPRESSED {
                if k == i {
                    let body = file.take(n);
                    if mi == MI_MATRIX {
                        return Ok(Box::new(BufReader::new(body)));
                    }
                    let mut z =
                        BufReader::new(flate2::read::ZlibDecoder::new(BufReader::new(body)));
                    ps.tag(&mut z, "a compressed variable")?;
                    return Ok(Box::new(z));
                }
                // Only elements that became variables count.
                k += 1;
            }
            let next = if inline.is_some() { start } else { start + n };
            pos = if mi == MI_COMPRESSED {
                next
            } else {
                next.div_ceil(8) * 8
            };
        }
        Err(ps.err("a variable vanished while reading the file"))
    }

    /// Up to [`MAX_NAMES_BYTES`] bytes of data at `place`.
    fn read_bytes(&self, place: &Place, n: u64) -> Result<Vec<u8>, DataError> {
        let ps = Parser { path: &self.path };
        if n > MAX_NAMES_BYTES {
            return Err(ps.err(format!("`names` is implausibly large ({n} bytes)")));
        }
        let mut r = self.data_reader(place)?;
        let mut v = vec![0u8; n as usize];
        ps.read_exact(&mut r, &mut v, "the data of `names`")?;
        Ok(v)
    }

    /// A reader positioned at the first byte of data at `place`.
    fn data_reader(&self, place: &Place) -> Result<Box<dyn Read + Send>, DataError> {
        let ps = Parser { path: &self.path };
        let open = || {
            std::fs::File::open(&self.path).map_err(|e| DataError::Io {
                path: self.path.display().to_string(),
                message: e.to_string(),
            })
        };
        Ok(match place {
            Place::Inline(d) => Box::new(std::io::Cursor::new(d.clone())),
            Place::Raw(at) => {
                let mut f = open()?;
                f.seek(SeekFrom::Start(*at)).map_err(|e| ps.err(e))?;
                Box::new(BufReader::with_capacity(1 << 16, f))
            }
            Place::Zip { offset, len, skip } => {
                let mut f = open()?;
                f.seek(SeekFrom::Start(*offset)).map_err(|e| ps.err(e))?;
                let z =
                    flate2::read::ZlibDecoder::new(BufReader::with_capacity(1 << 16, f.take(*len)));
                let mut z = BufReader::with_capacity(1 << 16, z);
                ps.skip(&mut z, *skip, "a compressed variable")?;
                Box::new(z)
            }
        })
    }
}

/// The variable of the element at `start` (type `mi`, `n` bytes, read from `r`) in a file
/// of `size` bytes: a matrix, or the matrix inside a compressed element; `None` for any
/// other element.
fn read_variable(
    ps: &Parser,
    r: &mut dyn Read,
    mi: u32,
    n: u64,
    start: u64,
    size: u64,
) -> Result<Option<Var>, DataError> {
    match mi {
        MI_MATRIX => {
            let mut c = Counted {
                inner: Read::take(&mut *r, n),
                pos: 0,
            };
            let (name, class, complex, dims, data) = ps.matrix(&mut c)?;
            let data = data.map(|(mi, n, inline)| {
                let place = match inline {
                    Some(d) => Place::Inline(d),
                    None => Place::Raw(start + c.pos),
                };
                (mi, n, place)
            });
            if let Some((_, n, Place::Raw(at))) = &data {
                if at + n > size {
                    return Err(ps.err(format!(
                        "the data of `{name}` runs past the end of the file: it is truncated"
                    )));
                }
            }
            return Ok(Some(Var {
                name,
                class,
                complex,
                dims,
                data,
            }));
        }
        MI_COMPRESSED => {
            let z = flate2::read::ZlibDecoder::new(Read::take(&mut *r, n));
            let mut c = Counted { inner: z, pos: 0 };
            let (mi, _, _) = ps.tag(&mut c, "a compressed variable")?;
            if mi == MI_MATRIX {
                let (name, class, complex, dims, data) = ps.matrix(&mut c)?;
                let data = data.map(|(mi, n2, inline)| {
                    let place = match inline {
                        Some(d) => Place::Inline(d),
                        None => Place::Zip {
                            offset: start,
                            len: n,
                            skip: c.pos,
                        },
                    };
                    (mi, n2, place)
                });
                return Ok(Some(Var {
                    name,
                    class,
                    complex,
                    dims,
                    data,
                }));
            }
        }
        _ => {}
    }
    Ok(None)
}
