//! Level sources over binary data files (MAT v5, MAT v7.3, HDF5, Parquet): the columns a
//! file offers are matched to the model's signals by name as a CSV header is, and streamed
//! in windows of samples.

use super::*;

/// One column a binary file offers: its name (a variable, dataset or column name, or a
/// name from a `names` variable) and its number of samples.
#[derive(Clone, Debug)]
pub(super) struct Column {
    pub name: String,
    pub len: usize,
}

/// A binary data file opened for reading: the columns it offers, read in windows.
pub(super) trait Store: Send + Sync + std::fmt::Debug {
    /// The format in words, for messages (`MAT v5`, `HDF5`, ...).
    fn format(&self) -> &'static str;
    /// The columns the file offers.
    fn columns(&self) -> &[Column];
    /// What the file holds (each variable or column with its type and shape, usable or
    /// not), for a message when a signal is not found.
    fn contents(&self) -> String;
    /// A reader of the columns `cols` (indices into [`Self::columns`]) from the first sample.
    fn open(&self, cols: &[usize]) -> Result<Box<dyn Windows + '_>, DataError>;
}

/// Consecutive windows of some columns of a [`Store`].
pub(super) trait Windows {
    /// Append the next at most `max` samples of each column to `out[k]` (the `k`-th column
    /// asked for); returns how many (0 at the end).
    fn next(&mut self, out: &mut [Vec<f64>], max: usize) -> Result<usize, DataError>;
}

/// An error in a binary file's structure (truncated, inconsistent or unsupported).
pub(super) fn format_err(path: &Path, format: &str, message: impl std::fmt::Display) -> DataError {
    DataError::Format {
        path: path.display().to_string(),
        format: format.to_string(),
        message: message.to_string(),
    }
}

/// A binary data file bound to a model (or to all its columns, for [`read_record`]):
/// columns chosen, lengths checked, sample interval fixed. Samples are checked (finite,
/// uniform time step) while streaming.
#[derive(Clone, Debug)]
pub struct BinarySource {
    path: PathBuf,
    store: Arc<dyn Store>,
    ts: f64,
    t0: f64,
    /// `(slot, column)`: slot `s` of every streamed chunk is read from column `c`.
    wanted: Vec<(usize, usize)>,
    n_slots: usize,
    t_col: Option<usize>,
    n: usize,
}

impl BinarySource {
    /// Bind `store` to the measured signals of `ir`.
    pub(super) fn open(
        path: &Path,
        store: Arc<dyn Store>,
        ir: &ModelIr,
        opts: &CsvOptions,
    ) -> Result<BinarySource, DataError> {
        let holds = store.contents();
        let p = path.display().to_string();
        Self::open_with(path, store, opts, MIN_SAMPLES, |names| {
            let mut wanted = Vec::new();
            for s in ir.measured_signals() {
                let name = &ir.signal(s).name;
                match names.iter().position(|n| n == name) {
                    Some(k) => wanted.push((s.index(), k)),
                    None => {
                        return Err(DataError::MissingVariable {
                            path: p.clone(),
                            signal: name.clone(),
                            holds: holds.clone(),
                        })
                    }
                }
            }
            Ok((wanted, ir.signals.len()))
        })
    }

    /// Bind `store` to every column but `t` (renamed by `opts.map`), for [`read_record`].
    pub(super) fn open_all(
        path: &Path,
        store: Arc<dyn Store>,
        opts: &CsvOptions,
        names_out: &mut Vec<String>,
    ) -> Result<BinarySource, DataError> {
        // Scalars beside the record (a gain, a sample rate MATLAB users save with it) are
        // not columns of it.
        let lens: Vec<usize> = store.columns().iter().map(|c| c.len).collect();
        let scalar = |k: usize| lens[k] <= 1 && lens.iter().any(|&l| l > 1);
        Self::open_with(path, store, opts, 2, |names| {
            let wanted: Vec<(usize, usize)> = names
                .iter()
                .enumerate()
                .filter(|&(k, n)| n != "t" && !n.is_empty() && !scalar(k))
                .enumerate()
                .map(|(slot, (k, n))| {
                    names_out.push(n.clone());
                    (slot, k)
                })
                .collect();
            let n = wanted.len();
            Ok((wanted, n))
        })
    }

    fn open_with(
        path: &Path,
        store: Arc<dyn Store>,
        opts: &CsvOptions,
        min_samples: usize,
        select: impl FnOnce(&[String]) -> Result<(Vec<(usize, usize)>, usize), DataError>,
    ) -> Result<BinarySource, DataError> {
        let p = path.display().to_string();
        if let Some(ts) = opts.ts {
            if !(ts.is_finite() && ts > 0.0) {
                return Err(DataError::BadSampleInterval { ts });
            }
        }
        let columns = store.columns();
        let original: Vec<String> = columns.iter().map(|c| c.name.clone()).collect();
        let mut names = original.clone();
        for (c, s) in &opts.map {
            match original.iter().position(|h| h == c) {
                Some(k) => names[k] = s.clone(),
                None => {
                    return Err(DataError::MissingVariable {
                        path: p,
                        signal: dynid_ir::text::escape(c),
                        holds: store.contents(),
                    })
                }
            }
        }
        let keeps_t = original.iter().any(|h| h == "t") && !opts.map.iter().any(|(c, _)| c == "t");
        if let (true, Some((c, _))) = (keeps_t, opts.map.iter().find(|(c, s)| s == "t" && c != "t"))
        {
            return Err(DataError::MapOntoTime {
                path: p,
                spec: format!("{}=t", dynid_ir::text::escape(c)),
                column: dynid_ir::text::escape(c),
            });
        }
        for (k, n) in names.iter().enumerate() {
            if names[..k].contains(n) {
                return Err(DataError::DuplicateColumn {
                    path: p,
                    column: dynid_ir::text::quote(n),
                });
            }
        }
        let (wanted, n_slots) = select(&names)?;
        let t_col = names.iter().position(|n| n == "t");
        // Every column read must have the same length.
        let used: Vec<usize> = wanted.iter().map(|&(_, c)| c).chain(t_col).collect();
        let n = used.first().map_or(0, |&c| columns[c].len);
        for &c in &used {
            if columns[c].len != n {
                return Err(DataError::RaggedRecord {
                    path: p,
                    column: names[c].clone(),
                    expected: n,
                    found: columns[c].len,
                });
            }
        }
        if used.is_empty() {
            // Nothing to read: the length is that of the file's first column.
            if let Some(c) = columns.first() {
                if c.len < min_samples {
                    return Err(DataError::TooFewSamples {
                        path: p,
                        n: c.len,
                        need: min_samples,
                    });
                }
            }
        } else if n < min_samples {
            return Err(DataError::TooFewSamples {
                path: p,
                n,
                need: min_samples,
            });
        }
        // The first two time stamps give the sample interval.
        let mut first_t = Vec::new();
        if let Some(tc) = t_col {
            let mut out = vec![Vec::new()];
            let mut w = store.open(&[tc])?;
            loop {
                let need = 2usize.saturating_sub(out[0].len());
                if need == 0 || w.next(&mut out, need)? == 0 {
                    break;
                }
            }
            first_t = out.swap_remove(0);
            for (k, &v) in first_t.iter().enumerate() {
                if !v.is_finite() {
                    return Err(DataError::SampleNonFinite {
                        path: p,
                        sample: k as u64 + 1,
                        column: "t".into(),
                        value: v,
                    });
                }
            }
        }
        let ts = match (opts.ts, first_t.as_slice()) {
            (Some(ts), [a, b]) => {
                let step = b - a;
                if step > 0.0 && (step - ts).abs() > TIME_TOL * ts {
                    return Err(DataError::SampleConflict { path: p, ts, step });
                }
                ts
            }
            (Some(ts), _) => ts,
            (None, [a, b]) => {
                if b - a <= 0.0 {
                    return Err(DataError::SampleTime {
                        path: p,
                        sample: 2,
                        message: format!(
                            "the time stamp {b} s does not increase (the sample before has {a} s)"
                        ),
                    });
                }
                b - a
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
        Ok(BinarySource {
            path: path.to_path_buf(),
            store,
            ts,
            t0: first_t.first().copied().unwrap_or(0.0),
            wanted,
            n_slots,
            t_col,
            n,
        })
    }

    /// The number of samples (known from the file's metadata before reading).
    pub fn samples(&self) -> usize {
        self.n
    }

    /// The memory, in bytes, of the streamed columns read whole.
    pub fn whole_bytes(&self) -> f64 {
        self.n as f64 * self.wanted.len() as f64 * 8.0
    }

    /// The file's format in words (`MAT v5`, `MAT v7.3`, `HDF5`, `Parquet`).
    pub fn format(&self) -> &'static str {
        self.store.format()
    }

    pub(super) fn time0(&self) -> f64 {
        self.t0
    }
}

impl LevelSource for BinarySource {
    fn origin(&self) -> String {
        self.path.display().to_string()
    }
    fn ts(&self) -> f64 {
        self.ts
    }
    fn locate(&self, k: usize) -> String {
        super::locate_sample(self.t0, self.ts, k)
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        let max_len = max_len.max(1);
        let p = || self.path.display().to_string();
        let names: Vec<&str> = self
            .store
            .columns()
            .iter()
            .map(|c| c.name.as_str())
            .collect();
        // Columns read: the wanted ones, then `t`.
        let mut cols: Vec<usize> = self.wanted.iter().map(|&(_, c)| c).collect();
        cols.extend(self.t_col);
        let mut out: Vec<Vec<f64>> = (0..cols.len())
            .map(|_| Vec::with_capacity(max_len))
            .collect();
        let mut slots: Vec<Vec<f64>> = vec![Vec::new(); self.n_slots];
        let mut reader = self.store.open(&cols)?;
        let mut done = 0usize;
        let mut last_t: Option<f64> = None;
        loop {
            out.iter_mut().for_each(Vec::clear);
            let mut len = 0;
            while len < max_len {
                let got = reader.next(&mut out, max_len - len)?;
                if got == 0 {
                    break;
                }
                len += got;
            }
            if len == 0 {
                break;
            }
            for (k, col) in out.iter().enumerate() {
                if let Some(i) = col.iter().position(|v| !v.is_finite()) {
                    return Err(DataError::SampleNonFinite {
                        path: p(),
                        sample: (done + i) as u64 + 1,
                        column: names[cols[k]].to_string(),
                        value: col[i],
                    });
                }
            }
            if self.t_col.is_some() {
                let t = &out[cols.len() - 1];
                for (i, &v) in t.iter().enumerate() {
                    if let Some(prev) = last_t {
                        let step = v - prev;
                        if step.is_nan()
                            || step <= 0.0
                            || (step - self.ts).abs() > TIME_TOL * self.ts
                        {
                            return Err(DataError::SampleTime {
                                path: p(),
                                sample: (done + i) as u64 + 1,
                                message: format!(
                                    "the time step is {} s, but the sample interval is {} s",
                                    dynid_ir::num::sig(step, 6, false),
                                    dynid_ir::num::sig(self.ts, 6, false)
                                ),
                            });
                        }
                    }
                    last_t = Some(v);
                }
            }
            for (k, &(s, _)) in self.wanted.iter().enumerate() {
                std::mem::swap(&mut slots[s], &mut out[k]);
            }
            let view: Vec<&[f64]> = slots.iter().map(Vec::as_slice).collect();
            sink(&view, len);
            for (k, &(s, _)) in self.wanted.iter().enumerate() {
                std::mem::swap(&mut slots[s], &mut out[k]);
            }
            done += len;
        }
        if done != self.n {
            return Err(DataError::RaggedRecord {
                path: p(),
                column: cols
                    .first()
                    .map_or(String::new(), |&c| names[c].to_string()),
                expected: self.n,
                found: done,
            });
        }
        Ok(())
    }
}

/// Read every column but `t` of a binary file into a [`Record`].
pub(super) fn read_whole(
    path: &Path,
    store: Arc<dyn Store>,
    opts: &CsvOptions,
    allow_large: bool,
) -> Result<Record, DataError> {
    let mut names = Vec::new();
    let src = BinarySource::open_all(path, store, opts, &mut names)?;
    let bytes = src.whole_bytes();
    if !allow_large && bytes > crate::limits::MAX_BYTES {
        use crate::limits::{bytes_in_words, MAX_BYTES};
        return Err(DataError::TooLarge {
            path: path.display().to_string(),
            estimate: bytes_in_words(bytes),
            rows: format!("{:.1e}", src.n as f64),
            columns: names.len(),
            limit: bytes_in_words(MAX_BYTES),
        });
    }
    let mut columns: Vec<Vec<f64>> = (0..names.len())
        .map(|_| Vec::with_capacity(src.n))
        .collect();
    src.stream(1 << 16, &mut |cols, len| {
        for (c, chunk) in columns.iter_mut().zip(cols) {
            c.extend_from_slice(&chunk[..len]);
        }
    })?;
    Ok(Record {
        names,
        columns,
        ts: src.ts,
        t0: src.time0(),
    })
}

/// A column's shape and type for [`Store::contents`]: `name (double 1000×1)`.
pub(super) fn describe(name: &str, what: &str, dims: &[usize]) -> String {
    let shape: Vec<String> = dims.iter().map(|d| d.to_string()).collect();
    format!(
        "{} ({what} {})",
        dynid_ir::text::escape(name),
        shape.join("×")
    )
}

/// Names from a `names` variable's text: one name per row of a character matrix (`rows`
/// rows, column-major `chars`), or, for a single row, names separated by commas.
pub(super) fn names_from_chars(chars: &[char], rows: usize) -> Vec<String> {
    if rows <= 1 {
        let s: String = chars.iter().collect();
        return s.split(',').map(|n| n.trim().to_string()).collect();
    }
    let cols = chars.len() / rows;
    (0..rows)
        .map(|r| {
            (0..cols)
                .map(|c| chars[r + rows * c])
                .collect::<String>()
                .trim_matches(|c: char| c.is_whitespace() || c == '\0')
                .to_string()
        })
        .collect()
}

thread_local! {
    /// Set while a third-party decoder runs under [`guarded`]: its panics are caught and
    /// reported as errors, so the panic hook stays silent for them.
    static IN_DECODER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Run a third-party decoder on the bytes of `path`, turning a panic inside it (a decoder
/// that asserts on damaged input instead of returning an error) into a format error that
/// calls the file damaged. The default panic message is kept off the terminal for these.
pub(super) fn guarded<T>(
    path: &Path,
    format: &str,
    f: impl FnOnce() -> Result<T, DataError>,
) -> Result<T, DataError> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_DECODER.with(|d| d.get()) {
                previous(info);
            }
        }));
    });
    let was = IN_DECODER.with(|d| d.replace(true));
    let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    IN_DECODER.with(|d| d.set(was));
    out.unwrap_or_else(|payload| {
        let why = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "an internal assertion".into());
        Err(format_err(
            path,
            format,
            format!("the file is damaged (its decoder failed: {why})"),
        ))
    })
}
