//! A MAT v5 file as a [`Store`]: its usable columns, and windows of their data streamed
//! (read from the file, or inflated from a compressed variable) and decoded to `f64`.

use super::super::binary::{describe, Column, Store, Windows};
use super::super::DataError;
use super::elements::{class_name, decode, mi_size, Parser};
use super::{Mat5, FORMAT};
use std::io::Read;
use std::path::Path;

impl Store for Mat5 {
    fn format(&self) -> &'static str {
        FORMAT
    }
    fn columns(&self) -> &[Column] {
        &self.columns
    }
    fn contents(&self) -> String {
        if self.vars.is_empty() {
            return "no variables".into();
        }
        self.vars
            .iter()
            .map(|v| {
                let what = if v.complex {
                    format!("complex {}", class_name(v.class))
                } else {
                    class_name(v.class).to_string()
                };
                describe(&v.name, &what, &v.dims)
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
    fn open(&self, cols: &[usize]) -> Result<Box<dyn Windows + '_>, DataError> {
        let ps = Parser { path: &self.path };
        let mut readers = Vec::with_capacity(cols.len());
        for &c in cols {
            let (vi, first) = self.col_var[c];
            let v = &self.vars[vi];
            let (mi, n, place) = v
                .data
                .as_ref()
                .expect("invariant: usable variables have data");
            let size =
                mi_size(*mi).expect("invariant: usable variables have a numeric type") as u64;
            let len = self.columns[c].len as u64;
            // (Saturating: the dimensions come from the file.)
            if first.saturating_add(len).saturating_mul(size) > *n {
                return Err(ps.err(format!(
                    "`{}` is {} but its data holds only {n} bytes of {}-byte values",
                    v.name,
                    v.dims
                        .iter()
                        .map(|d| d.to_string())
                        .collect::<Vec<_>>()
                        .join("×"),
                    size
                )));
            }
            let mut r = self.data_reader(place)?;
            ps.skip(&mut r, first * size, "a variable's data")?;
            readers.push(ColReader {
                r,
                mi: *mi,
                size: size as usize,
                left: len,
                name: v.name.clone(),
            });
        }
        Ok(Box::new(Mat5Windows {
            path: &self.path,
            readers,
            buf: Vec::new(),
        }))
    }
}

/// One column's data being read: its element type and size, and the values left.
struct ColReader {
    r: Box<dyn Read + Send>,
    mi: u32,
    size: usize,
    left: u64,
    name: String,
}

/// The windows of the columns of one pass.
struct Mat5Windows<'a> {
    path: &'a Path,
    readers: Vec<ColReader>,
    buf: Vec<u8>,
}

impl Windows for Mat5Windows<'_> {
    fn next(&mut self, out: &mut [Vec<f64>], max: usize) -> Result<usize, DataError> {
        let ps = Parser { path: self.path };
        let mut got = 0;
        for (k, c) in self.readers.iter_mut().enumerate() {
            let take = (max as u64).min(c.left) as usize;
            self.buf.resize(take * c.size, 0);
            ps.read_exact(
                &mut c.r,
                &mut self.buf,
                &format!("the data of `{}`", c.name),
            )?;
            decode(c.mi, &self.buf, &mut out[k]);
            c.left -= take as u64;
            got = take;
        }
        Ok(got)
    }
}
