//! The element level of a MAT v5 file: tags (long and small-data), the header of a matrix
//! element (flags, dimensions, name), the numeric types and their decoding to `f64`, and
//! char data.

use super::super::binary::format_err;
use super::super::DataError;
use super::{FORMAT, MAX_NAMES_BYTES};
use std::io::Read;
use std::path::Path;

/// The MATLAB class name of class number `c`.
pub(super) fn class_name(c: u8) -> &'static str {
    match c {
        1 => "cell",
        2 => "struct",
        3 => "object",
        4 => "char",
        5 => "sparse",
        6 => "double",
        7 => "single",
        8 => "int8",
        9 => "uint8",
        10 => "int16",
        11 => "uint16",
        12 => "int32",
        13 => "uint32",
        14 => "int64",
        15 => "uint64",
        _ => "unknown class",
    }
}

/// Bytes per element of an `mi*` data type.
pub(super) fn mi_size(mi: u32) -> Option<usize> {
    Some(match mi {
        1 | 2 | 16 => 1,
        3 | 4 | 17 => 2,
        5..=7 => 4,
        9 | 12 | 13 => 8,
        _ => return None,
    })
}

/// Decode little-endian elements of type `mi` into `out`.
pub(super) fn decode(mi: u32, bytes: &[u8], out: &mut Vec<f64>) {
    macro_rules! conv {
        ($t:ty, $n:expr) => {
            out.extend(bytes.chunks_exact($n).map(|b| {
                <$t>::from_le_bytes(b.try_into().expect("invariant: chunk of the type's size"))
                    as f64
            }))
        };
    }
    match mi {
        1 => conv!(i8, 1),
        2 | 16 => conv!(u8, 1),
        3 => conv!(i16, 2),
        4 | 17 => conv!(u16, 2),
        5 => conv!(i32, 4),
        6 => conv!(u32, 4),
        7 => conv!(f32, 4),
        9 => conv!(f64, 8),
        12 => conv!(i64, 8),
        13 => conv!(u64, 8),
        _ => {}
    }
}

/// A reader that counts the bytes read.
pub(super) struct Counted<R> {
    pub(super) inner: R,
    pub(super) pos: u64,
}

impl<R: Read> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let k = self.inner.read(buf)?;
        self.pos += k as u64;
        Ok(k)
    }
}

pub(super) fn u32_at(b: &[u8], k: usize) -> u32 {
    u32::from_le_bytes(b[k..k + 4].try_into().expect("invariant: 4 bytes"))
}

/// The element reader of one file: tags, small data and matrix headers, with errors that
/// name the file.
pub(super) struct Parser<'a> {
    pub(super) path: &'a Path,
}

impl Parser<'_> {
    pub(super) fn err(&self, m: impl std::fmt::Display) -> DataError {
        format_err(self.path, FORMAT, m)
    }

    pub(super) fn read_exact(
        &self,
        r: &mut dyn Read,
        buf: &mut [u8],
        what: &str,
    ) -> Result<(), DataError> {
        r.read_exact(buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                self.err(format!("the file ends inside {what}: it is truncated"))
            } else {
                self.err(format!("cannot read {what}: {e}"))
            }
        })
    }

    /// A tag: `(type, byte count, inline data)`; skips the padding after inline data.
    pub(super) fn tag(
        &self,
        r: &mut dyn Read,
        what: &str,
    ) -> Result<(u32, u64, Option<Vec<u8>>), DataError> {
        let mut b = [0u8; 8];
        self.read_exact(r, &mut b, what)?;
        let first = u32_at(&b, 0);
        if first >> 16 != 0 {
            // Small data element: type and size in the first word, data in the second.
            let n = (first >> 16) as usize;
            if n > 4 {
                return Err(self.err(format!("{what} has an invalid tag")));
            }
            return Ok((first & 0xffff, n as u64, Some(b[4..4 + n].to_vec())));
        }
        Ok((first, u32_at(&b, 4) as u64, None))
    }

    /// Skip `n` bytes.
    pub(super) fn skip(&self, r: &mut dyn Read, n: u64, what: &str) -> Result<(), DataError> {
        let got = std::io::copy(&mut r.take(n), &mut std::io::sink())
            .map_err(|e| self.err(format!("cannot read {what}: {e}")))?;
        if got < n {
            return Err(self.err(format!("the file ends inside {what}: it is truncated")));
        }
        Ok(())
    }

    /// The data of a (non-inline) sub-element of `n` bytes, padded to 8 bytes.
    pub(super) fn small_data(
        &self,
        r: &mut dyn Read,
        n: u64,
        what: &str,
    ) -> Result<Vec<u8>, DataError> {
        if n > MAX_NAMES_BYTES {
            return Err(self.err(format!("{what} is implausibly large ({n} bytes)")));
        }
        let mut v = vec![0u8; n as usize];
        self.read_exact(r, &mut v, what)?;
        self.skip(r, (8 - n % 8) % 8, what)?;
        Ok(v)
    }

    /// A sub-element read whole (array flags, dimensions, name).
    pub(super) fn element(
        &self,
        r: &mut dyn Read,
        what: &str,
    ) -> Result<(u32, Vec<u8>), DataError> {
        let (mi, n, inline) = self.tag(r, what)?;
        match inline {
            Some(d) => Ok((mi, d)),
            None => Ok((mi, self.small_data(r, n, what)?)),
        }
    }

    /// The header of a matrix element (after its tag): flags, dimensions, name; then, for
    /// numeric and char classes, the tag of the real part. `r` is positioned at the data
    /// (or, for other classes, at the rest of the element) on return.
    #[allow(clippy::type_complexity)]
    pub(super) fn matrix(
        &self,
        r: &mut dyn Read,
    ) -> Result<
        (
            String,
            u8,
            bool,
            Vec<usize>,
            Option<(u32, u64, Option<Vec<u8>>)>,
        ),
        DataError,
    > {
        let (mi, flags) = self.element(r, "a variable's array flags")?;
        if mi != 6 || flags.len() < 8 {
            return Err(self.err("a variable's array flags are malformed"));
        }
        let f = u32_at(&flags, 0);
        let class = (f & 0xff) as u8;
        let complex = f & 0x800 != 0;
        let (mi, dims) = self.element(r, "a variable's dimensions")?;
        if mi != 5 || dims.len() % 4 != 0 || dims.is_empty() {
            return Err(self.err("a variable's dimensions are malformed"));
        }
        let dims: Vec<usize> = dims
            .chunks_exact(4)
            .map(|b| i32::from_le_bytes(b.try_into().expect("invariant: 4 bytes")).max(0) as usize)
            .collect();
        let (_, name) = self.element(r, "a variable's name")?;
        let name = String::from_utf8_lossy(&name).into_owned();
        let numeric = (6..=15).contains(&class) || class == 4;
        let data = if numeric {
            Some(self.tag(r, "a variable's data")?)
        } else {
            None
        };
        Ok((name, class, complex, dims, data))
    }
}

/// The characters of a char array's data of type `mi`.
pub(super) fn chars_of(mi: u32, bytes: &[u8]) -> Option<Vec<char>> {
    match mi {
        1 | 2 | 16 => Some(String::from_utf8_lossy(bytes).chars().collect()),
        3 | 4 | 17 => {
            let units: Vec<u16> = bytes
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect();
            Some(
                char::decode_utf16(units)
                    .map(|c| c.unwrap_or('\u{fffd}'))
                    .collect(),
            )
        }
        _ => None,
    }
}
