//! Parquet files through the `parquet` crate's column readers (no Arrow): row group by row
//! group, each column's pages decoded as they are read, so that memory use is bounded by a
//! page and a window, not by the record. Pages compressed with Snappy, gzip, LZ4 or ZSTD
//! are read; Brotli pages give an error saying so.

use super::binary::{describe, format_err, guarded, Column, Store, Windows};
use super::*;
use parquet::basic::Type as Physical;
use parquet::column::reader::{ColumnReader, ColumnReaderImpl};
use parquet::data_type::{DataType, DoubleType, FloatType, Int32Type, Int64Type};
use parquet::file::reader::{FileReader, SerializedFileReader};

const FORMAT: &str = "Parquet";

/// A Parquet file opened for reading.
pub(super) struct Pq {
    path: PathBuf,
    reader: SerializedFileReader<std::fs::File>,
    /// Every leaf column: name, type in words, and whether it is read (its index among the
    /// file's leaves).
    leaves: Vec<(String, String)>,
    columns: Vec<Column>,
    /// Leaf index of each column.
    col_leaf: Vec<usize>,
}

impl std::fmt::Debug for Pq {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pq").field("path", &self.path).finish()
    }
}

impl Pq {
    pub(super) fn open(path: &Path) -> Result<Pq, DataError> {
        guarded(path, FORMAT, || Self::open_unguarded(path))
    }

    fn open_unguarded(path: &Path) -> Result<Pq, DataError> {
        let err = |e: &dyn std::fmt::Display| format_err(path, FORMAT, e);
        let file = std::fs::File::open(path).map_err(|e| DataError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let reader = SerializedFileReader::new(file).map_err(|e| err(&e))?;
        let meta = reader.metadata();
        let rows = meta.file_metadata().num_rows().max(0) as usize;
        let mut leaves = Vec::new();
        let mut columns = Vec::new();
        let mut col_leaf = Vec::new();
        for (i, c) in meta
            .file_metadata()
            .schema_descr()
            .columns()
            .iter()
            .enumerate()
        {
            let name = c.path().parts().join(".");
            let ty = c.physical_type();
            let usable = c.max_rep_level() == 0
                && matches!(
                    ty,
                    Physical::DOUBLE | Physical::FLOAT | Physical::INT32 | Physical::INT64
                );
            leaves.push((name.clone(), ty.to_string().to_lowercase()));
            if usable {
                columns.push(Column { name, len: rows });
                col_leaf.push(i);
            }
        }
        Ok(Pq {
            path: path.to_path_buf(),
            reader,
            leaves,
            columns,
            col_leaf,
        })
    }
}

impl Store for Pq {
    fn format(&self) -> &'static str {
        FORMAT
    }
    fn columns(&self) -> &[Column] {
        &self.columns
    }
    fn contents(&self) -> String {
        if self.leaves.is_empty() {
            return "no columns".into();
        }
        let rows = self.reader.metadata().file_metadata().num_rows().max(0) as usize;
        self.leaves
            .iter()
            .map(|(n, t)| describe(n, t, &[rows]))
            .collect::<Vec<_>>()
            .join(", ")
    }
    fn open(&self, cols: &[usize]) -> Result<Box<dyn Windows + '_>, DataError> {
        Ok(Box::new(PqWindows {
            pq: self,
            leaves: cols.iter().map(|&c| self.col_leaf[c]).collect(),
            group: 0,
            left: 0,
            readers: Vec::new(),
            row: 0,
        }))
    }
}

enum Typed {
    F64(ColumnReaderImpl<DoubleType>),
    F32(ColumnReaderImpl<FloatType>),
    I32(ColumnReaderImpl<Int32Type>),
    I64(ColumnReaderImpl<Int64Type>),
}

struct PqWindows<'a> {
    pq: &'a Pq,
    leaves: Vec<usize>,
    /// The next row group to open.
    group: usize,
    /// Rows left in the open row group.
    left: usize,
    readers: Vec<(Typed, i16)>,
    /// Rows handed on so far.
    row: usize,
}

/// Read exactly `n` values of a column into `out` (as `f64`); a null is an error.
fn read_n<T: DataType>(
    r: &mut ColumnReaderImpl<T>,
    max_def: i16,
    n: usize,
    out: &mut Vec<f64>,
    conv: impl Fn(&T::T) -> f64,
) -> Result<Option<usize>, parquet::errors::ParquetError>
where
    Vec<T::T>: Default,
    ColumnReaderImpl<T>: ReadRecords<T>,
{
    let mut done = 0;
    let mut defs: Vec<i16> = Vec::new();
    let mut vals: Vec<T::T> = Vec::new();
    while done < n {
        defs.clear();
        vals.clear();
        let (recs, nv) = r.read_into(n - done, max_def, &mut defs, &mut vals)?;
        if recs == 0 {
            break;
        }
        if max_def > 0 {
            if let Some(i) = defs.iter().position(|&d| d < max_def) {
                return Ok(Some(done + i));
            }
        }
        out.extend(vals.iter().take(nv).map(&conv));
        done += recs;
    }
    if done < n {
        return Err(parquet::errors::ParquetError::General(format!(
            "a column ends after {done} of {n} rows of its row group"
        )));
    }
    Ok(None)
}

/// `read_records` for the value buffer types of the numeric columns.
trait ReadRecords<T: DataType> {
    fn read_into(
        &mut self,
        n: usize,
        max_def: i16,
        defs: &mut Vec<i16>,
        vals: &mut Vec<T::T>,
    ) -> Result<(usize, usize), parquet::errors::ParquetError>;
}

macro_rules! read_records {
    ($t:ty) => {
        impl ReadRecords<$t> for ColumnReaderImpl<$t> {
            fn read_into(
                &mut self,
                n: usize,
                max_def: i16,
                defs: &mut Vec<i16>,
                vals: &mut Vec<<$t as DataType>::T>,
            ) -> Result<(usize, usize), parquet::errors::ParquetError> {
                let d = if max_def > 0 { Some(defs) } else { None };
                let (recs, nv, _) = self.read_records(n, d, None, vals)?;
                Ok((recs, nv))
            }
        }
    };
}
read_records!(DoubleType);
read_records!(FloatType);
read_records!(Int32Type);
read_records!(Int64Type);

impl Windows for PqWindows<'_> {
    fn next(&mut self, out: &mut [Vec<f64>], max: usize) -> Result<usize, DataError> {
        // The crate's decoders assert on some damaged pages (a dictionary page missing:
        // found by the `binary` fuzz target).
        let path = self.pq.path.clone();
        guarded(&path, FORMAT, || self.next_unguarded(out, max))
    }
}

impl PqWindows<'_> {
    fn next_unguarded(&mut self, out: &mut [Vec<f64>], max: usize) -> Result<usize, DataError> {
        let path = &self.pq.path;
        let err = |e: &dyn std::fmt::Display| format_err(path, FORMAT, e);
        while self.left == 0 {
            let meta = self.pq.reader.metadata();
            if self.group >= meta.num_row_groups() {
                return Ok(0);
            }
            let g = self
                .pq
                .reader
                .get_row_group(self.group)
                .map_err(|e| err(&e))?;
            self.left = g.metadata().num_rows().max(0) as usize;
            self.readers.clear();
            for &leaf in &self.leaves {
                let max_def = meta
                    .file_metadata()
                    .schema_descr()
                    .column(leaf)
                    .max_def_level();
                let typed = match g.get_column_reader(leaf).map_err(|e| err(&e))? {
                    ColumnReader::DoubleColumnReader(r) => Typed::F64(r),
                    ColumnReader::FloatColumnReader(r) => Typed::F32(r),
                    ColumnReader::Int32ColumnReader(r) => Typed::I32(r),
                    ColumnReader::Int64ColumnReader(r) => Typed::I64(r),
                    _ => return Err(err(&"a column changed its type between row groups")),
                };
                self.readers.push((typed, max_def));
            }
            self.group += 1;
        }
        let n = max.min(self.left);
        for (k, (r, max_def)) in self.readers.iter_mut().enumerate() {
            let o = &mut out[k];
            let null = match r {
                Typed::F64(r) => read_n(r, *max_def, n, o, |v| *v),
                Typed::F32(r) => read_n(r, *max_def, n, o, |v| *v as f64),
                Typed::I32(r) => read_n(r, *max_def, n, o, |v| *v as f64),
                Typed::I64(r) => read_n(r, *max_def, n, o, |v| *v as f64),
            }
            .map_err(|e| err(&e))?;
            if let Some(i) = null {
                let name = &self.pq.columns[self
                    .pq
                    .col_leaf
                    .iter()
                    .position(|&l| l == self.leaves[k])
                    .unwrap_or(0)]
                .name;
                return Err(err(&format!(
                    "column `{name}` has no value (null) at sample {}: fill or cut out the gap",
                    self.row + i + 1
                )));
            }
        }
        self.left -= n;
        self.row += n;
        Ok(n)
    }
}
