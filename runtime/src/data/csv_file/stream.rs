//! The passes of a [`CsvSource`]: the first complete one parses the text, validating every
//! row, and writes the selected columns as a binary copy; later passes replay the copy.

use super::super::csv_parse::{parse_body, Layout, Role};
use super::super::{DataError, LevelSource, TIME_TOL};
use super::{io_err, open_text, CsvSource};
use std::io::{BufReader, BufWriter, Read, Seek, Write};

impl LevelSource for CsvSource {
    fn origin(&self) -> String {
        self.path.display().to_string()
    }
    fn ts(&self) -> f64 {
        self.ts
    }
    fn locate(&self, k: usize) -> String {
        super::super::locate_sample(self.t0, self.ts, k)
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

    /// Stream by parsing the text, validating every row; with `copy`, also write the binary
    /// copy (dropped, and the text parsed next time, at the first write error).
    ///
    /// Slightly longer than most functions here: the chunking closure and the copy writer
    /// share the column buffers, so they live in one scope.
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
