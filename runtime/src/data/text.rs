//! Limits on the text read from a level file before it is parsed: no line longer than
//! [`MAX_LINE`], no NUL byte (so `/dev/zero`, a binary or a UTF-16 file is refused after a
//! few bytes instead of being buffered whole in search of a line end), and a copy of a
//! pipe or device (which can be read only once) for the several passes over a level.

use super::DataError;
use std::io::{Read, Write};
use std::path::Path;
use std::sync::Arc;

/// Longest line (the header included) read before a line end: 1 MiB, far more than a
/// header of thousands of columns or a row of thousands of numbers needs.
pub const MAX_LINE: usize = 1 << 20;

/// Why [`LineCap`] stopped reading (carried inside an `io::Error`).
#[derive(Debug)]
enum Refused {
    LineTooLong { line: u64 },
    Nul { line: u64 },
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::LineTooLong { line } => write!(f, "line {line} is too long"),
            Refused::Nul { line } => write!(f, "line {line} holds a NUL byte"),
        }
    }
}

impl std::error::Error for Refused {}

/// A reader that fails (with an `io::Error` that [`read_error`] turns into a
/// [`DataError`]) at a line longer than [`MAX_LINE`] or at a NUL byte.
pub(super) struct LineCap<R> {
    inner: R,
    /// Bytes since the last line end.
    run: usize,
    /// The line being read (from 1).
    line: u64,
    limit: usize,
}

impl<R: Read> LineCap<R> {
    pub fn new(inner: R) -> Self {
        Self::with_limit(inner, MAX_LINE)
    }

    pub fn with_limit(inner: R, limit: usize) -> Self {
        LineCap {
            inner,
            run: 0,
            line: 1,
            limit,
        }
    }
}

impl<R: Read> Read for LineCap<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let k = self.inner.read(buf)?;
        let got = &buf[..k];
        let fail = |why: Refused| Err(std::io::Error::new(std::io::ErrorKind::InvalidData, why));
        if let Some(z) = got.iter().position(|&b| b == 0) {
            let line = self.line + got[..z].iter().filter(|&&b| b == b'\n').count() as u64;
            return fail(Refused::Nul { line });
        }
        let mut from = 0;
        for end in got
            .iter()
            .enumerate()
            .filter(|(_, &b)| b == b'\n')
            .map(|(i, _)| i)
        {
            if self.run + (end - from) > self.limit {
                return fail(Refused::LineTooLong { line: self.line });
            }
            self.run = 0;
            self.line += 1;
            from = end + 1;
        }
        self.run += k - from;
        if self.run > self.limit {
            return fail(Refused::LineTooLong { line: self.line });
        }
        Ok(k)
    }
}

/// A limit in bytes in words (`1 MiB`).
fn bytes_in_words(n: usize) -> String {
    if n >= 1 << 20 && n.is_multiple_of(1 << 20) {
        format!("{} MiB", n >> 20)
    } else if n >= 1 << 10 && n.is_multiple_of(1 << 10) {
        format!("{} KiB", n >> 10)
    } else {
        format!("{n} bytes")
    }
}

/// The error for a failed read of `path`: a refusal by [`LineCap`] as its own kind, any
/// other failure as [`DataError::Io`].
pub(super) fn read_error(path: &Path, e: &std::io::Error) -> DataError {
    let p = path.display().to_string();
    match e.get_ref().and_then(|r| r.downcast_ref::<Refused>()) {
        Some(Refused::LineTooLong { line }) => DataError::LineTooLong {
            path: p,
            line: *line,
            limit: bytes_in_words(MAX_LINE),
        },
        Some(Refused::Nul { line }) => DataError::Binary {
            path: p,
            line: *line,
        },
        None => DataError::Io {
            path: p,
            message: e.to_string(),
        },
    }
}

/// For a pipe, a device or anything else that is not a regular file (it can be opened and
/// read only once, and a second open of a FIFO waits for a writer forever): its text copied
/// to a temporary file (deleted when the last holder drops it), read through [`LineCap`].
/// `None` for a regular file, read in place.
pub(super) fn copy_if_stream(
    path: &Path,
) -> Result<Option<Arc<tempfile::NamedTempFile>>, DataError> {
    let io = |e: std::io::Error| read_error(path, &e);
    let meta = std::fs::metadata(path).map_err(io)?;
    if meta.is_file() || meta.is_dir() {
        return Ok(None);
    }
    let f = std::fs::File::open(path).map_err(io)?;
    let mut tmp = tempfile::NamedTempFile::new().map_err(|e| DataError::Io {
        path: path.display().to_string(),
        message: format!("cannot create a temporary copy of the stream: {e}"),
    })?;
    let mut reader = LineCap::new(f);
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let k = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(k) => k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io(e)),
        };
        tmp.write_all(&buf[..k]).map_err(|e| DataError::Io {
            path: path.display().to_string(),
            message: format!("cannot write the temporary copy of the stream: {e}"),
        })?;
    }
    tmp.flush().map_err(|e| DataError::Io {
        path: path.display().to_string(),
        message: format!("cannot write the temporary copy of the stream: {e}"),
    })?;
    Ok(Some(Arc::new(tmp)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_all(text: &[u8], limit: usize) -> Result<Vec<u8>, DataError> {
        let mut out = Vec::new();
        LineCap::with_limit(text, limit)
            .read_to_end(&mut out)
            .map_err(|e| read_error(Path::new("f.csv"), &e))?;
        Ok(out)
    }

    #[test]
    fn lines_up_to_the_limit_pass_and_longer_ones_are_refused_with_their_number() {
        assert_eq!(read_all(b"abcd\nefgh\n", 4).unwrap(), b"abcd\nefgh\n");
        assert_eq!(read_all(b"abcd\r\nef", 5).unwrap().len(), 8);
        match read_all(b"ab\ncd\nefghij\nk", 4) {
            Err(DataError::LineTooLong { line, .. }) => assert_eq!(line, 3),
            other => panic!("{other:?}"),
        }
        match read_all(b"ab\ncd\x00\n", 4) {
            Err(DataError::Binary { line, .. }) => assert_eq!(line, 2),
            other => panic!("{other:?}"),
        }
    }
}
