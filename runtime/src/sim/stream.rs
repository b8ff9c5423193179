//! Where simulated samples go: a [`SampleSink`] receives a level's columns chunk by chunk,
//! so a record of any length is written without holding it in memory.
//!
//! The measurement noise is `noise · std(signal)` with the std of the whole clean record,
//! and its random draws go column after column. So with noise on, the clean columns are
//! first spilled to anonymous temporary files (one per column, raw `f64`); then, column by
//! column, their std is taken and the noise added exactly as an in-memory column would get
//! it (the same sums in the same order, the same draws); finally the finished columns are
//! read back together and passed on in chunks. Without noise the samples go straight to the
//! sink. Either way the output is bit-identical to simulating in memory.

use super::control::quantise;
use super::SimError;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};

/// Samples per chunk handed to a sink.
pub(super) const CHUNK: usize = 8192;

/// Receives one level's record in order.
pub trait SampleSink: Send {
    /// Called once before any sample: the column names and the sample interval.
    fn begin(&mut self, names: &[String], ts: f64) -> std::io::Result<()>;
    /// The next `len` samples; `cols[j]` is column `j`.
    fn push(&mut self, cols: &[&[f64]], len: usize) -> std::io::Result<()>;
}

/// Collects the record in memory (what [`super::simulate`] returns).
impl SampleSink for crate::record::Record {
    fn begin(&mut self, names: &[String], ts: f64) -> std::io::Result<()> {
        self.names = names.to_vec();
        self.columns = vec![Vec::new(); names.len()];
        self.ts = ts;
        self.t0 = 0.0;
        Ok(())
    }
    fn push(&mut self, cols: &[&[f64]], len: usize) -> std::io::Result<()> {
        for (dst, src) in self.columns.iter_mut().zip(cols) {
            dst.extend_from_slice(&src[..len]);
        }
        Ok(())
    }
}

/// What happens to a column after the simulation: noise and quantisation.
#[derive(Clone, Copy, Debug)]
pub(super) struct ColumnFinish {
    /// Add measurement noise to this column.
    pub noisy: bool,
    /// Round this column (a position) to the encoder resolution.
    pub quantised: bool,
}

/// Buffers a level's clean samples and delivers the finished record to a sink.
pub(super) struct LevelWriter<'s> {
    sink: &'s mut dyn SampleSink,
    finish: Vec<ColumnFinish>,
    noise: f64,
    quantum: Option<f64>,
    buf: Vec<Vec<f64>>,
    /// One spill file per column when noise is added.
    spill: Option<Vec<BufWriter<File>>>,
    context: String,
    names: Vec<String>,
    /// Per column: the range of the values before quantisation and whether the quantised
    /// values varied (a resolution coarser than the motion rounds it all to one value).
    quantised_range: Vec<QuantisedRange>,
}

/// What quantisation did to one column: see [`LevelWriter::quantised_range`].
#[derive(Clone, Copy, Debug)]
struct QuantisedRange {
    lo: f64,
    hi: f64,
    first: Option<f64>,
    varied: bool,
}

impl Default for QuantisedRange {
    fn default() -> Self {
        QuantisedRange {
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            first: None,
            varied: false,
        }
    }
}

fn io_error(context: &str, e: std::io::Error) -> SimError {
    SimError::Scratch {
        context: context.to_string(),
        source: e,
    }
}

impl<'s> LevelWriter<'s> {
    pub fn new(
        sink: &'s mut dyn SampleSink,
        names: &[String],
        ts: f64,
        finish: Vec<ColumnFinish>,
        noise: f64,
        quantum: Option<f64>,
        context: String,
    ) -> Result<Self, SimError> {
        sink.begin(names, ts).map_err(|e| io_error(&context, e))?;
        let spill = if noise > 0.0 && finish.iter().any(|f| f.noisy) {
            let files = (0..names.len())
                .map(|_| tempfile::tempfile().map(|f| BufWriter::with_capacity(1 << 16, f)))
                .collect::<std::io::Result<Vec<_>>>()
                .map_err(|e| io_error(&context, e))?;
            Some(files)
        } else {
            None
        };
        Ok(LevelWriter {
            sink,
            buf: vec![Vec::with_capacity(CHUNK); names.len()],
            finish,
            noise,
            quantum,
            spill,
            context,
            names: names.to_vec(),
            quantised_range: vec![QuantisedRange::default(); names.len()],
        })
    }

    /// Append one sample (`row[j]` = column `j`).
    pub fn sample(&mut self, row: impl Iterator<Item = f64>) -> Result<(), SimError> {
        for (col, v) in self.buf.iter_mut().zip(row) {
            col.push(v);
        }
        if self.buf[0].len() == CHUNK {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), SimError> {
        let len = self.buf.first().map_or(0, Vec::len);
        if len == 0 {
            return Ok(());
        }
        match &mut self.spill {
            Some(files) => {
                for (f, col) in files.iter_mut().zip(&self.buf) {
                    for v in col {
                        f.write_all(&v.to_le_bytes())
                            .map_err(|e| io_error(&self.context, e))?;
                    }
                }
            }
            None => {
                quantise_columns(
                    &mut self.buf,
                    &self.finish,
                    self.quantum,
                    &mut self.quantised_range,
                );
                let cols: Vec<&[f64]> = self.buf.iter().map(Vec::as_slice).collect();
                self.sink
                    .push(&cols, len)
                    .map_err(|e| io_error(&self.context, e))?;
            }
        }
        self.buf.iter_mut().for_each(Vec::clear);
        Ok(())
    }

    /// Deliver the rest: with noise, add it column by column from `rng` and pass the
    /// finished columns on.
    pub fn finish(mut self, rng: &mut impl rand::Rng) -> Result<(), SimError> {
        self.flush()?;
        let Some(files) = self.spill.take() else {
            return self.check_quantised();
        };
        let ctx = self.context.clone();
        let err = |e| io_error(&ctx, e);
        let mut files: Vec<File> = files
            .into_iter()
            .map(|f| f.into_inner().map_err(|e| e.into_error()))
            .collect::<std::io::Result<_>>()
            .map_err(err)?;
        let mut chunk = vec![0.0; CHUNK];
        for (f, fin) in files.iter_mut().zip(&self.finish) {
            if !fin.noisy {
                continue;
            }
            // std of the clean column: the sums of `describe::std_dev`, in its order.
            let (mut n, mut sum) = (0usize, 0.0);
            for_chunks(f, &mut chunk, |c| {
                n += c.len();
                sum = c.iter().fold(sum, |a, v| a + v);
            })
            .map_err(err)?;
            let mean = if n == 0 { 0.0 } else { sum / n as f64 };
            let mut ss = 0.0;
            for_chunks(f, &mut chunk, |c| {
                ss = c.iter().fold(ss, |a, v| a + (v - mean) * (v - mean));
            })
            .map_err(err)?;
            let sd = self.noise * if n == 0 { 0.0 } else { (ss / n as f64).sqrt() };
            add_noise(f, &mut chunk, sd, rng).map_err(err)?;
        }
        // The finished columns, read together.
        let mut readers: Vec<BufReader<File>> = files
            .into_iter()
            .map(|mut f| {
                f.seek(SeekFrom::Start(0))
                    .map(|_| BufReader::with_capacity(1 << 16, f))
            })
            .collect::<std::io::Result<_>>()
            .map_err(err)?;
        loop {
            let mut len = usize::MAX;
            for (r, col) in readers.iter_mut().zip(self.buf.iter_mut()) {
                col.resize(CHUNK, 0.0);
                let got = read_f64s(r, col).map_err(err)?;
                col.truncate(got);
                len = len.min(got);
            }
            if len == 0 || len == usize::MAX {
                break;
            }
            quantise_columns(
                &mut self.buf,
                &self.finish,
                self.quantum,
                &mut self.quantised_range,
            );
            let cols: Vec<&[f64]> = self.buf.iter().map(Vec::as_slice).collect();
            self.sink.push(&cols, len).map_err(err)?;
        }
        self.check_quantised()
    }

    /// Refuse a resolution that rounded a moving position to one value (the record would
    /// hold a constant, silently).
    fn check_quantised(&self) -> Result<(), SimError> {
        let Some(q) = self.quantum else {
            return Ok(());
        };
        for (name, r) in self.names.iter().zip(&self.quantised_range) {
            if r.first.is_some() && r.hi > r.lo && !r.varied {
                return Err(SimError::InvalidConfig {
                    what: format!(
                        "{}: the position resolution {q} exceeds the range of `{name}` \
                         ({:e} … {:e}): every recorded sample rounds to the same value",
                        self.context, r.lo, r.hi
                    ),
                    help: format!(
                        "give an encoder resolution far below the motion, e.g. `--quantise {:.0e}`",
                        (r.hi - r.lo) / 1000.0
                    ),
                });
            }
        }
        Ok(())
    }
}

fn quantise_columns(
    buf: &mut [Vec<f64>],
    finish: &[ColumnFinish],
    quantum: Option<f64>,
    ranges: &mut [QuantisedRange],
) {
    if quantum.is_none() {
        return;
    }
    for ((col, fin), r) in buf.iter_mut().zip(finish).zip(ranges) {
        if fin.quantised {
            for x in col.iter_mut() {
                r.lo = r.lo.min(*x);
                r.hi = r.hi.max(*x);
                *x = quantise(*x, quantum);
                match r.first {
                    None => r.first = Some(*x),
                    Some(f) => r.varied |= *x != f,
                }
            }
        }
    }
}

/// Read up to `out.len()` values; returns how many (fewer only at the end of the file).
fn read_f64s(r: &mut impl Read, out: &mut [f64]) -> std::io::Result<usize> {
    let mut bytes = [0u8; 8];
    for (k, v) in out.iter_mut().enumerate() {
        match r.read_exact(&mut bytes) {
            Ok(()) => *v = f64::from_le_bytes(bytes),
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(k),
            Err(e) => return Err(e),
        }
    }
    Ok(out.len())
}

/// Call `f` on the column in `file` chunk by chunk, from the start.
fn for_chunks(
    file: &mut File,
    chunk: &mut [f64],
    mut f: impl FnMut(&[f64]),
) -> std::io::Result<()> {
    file.seek(SeekFrom::Start(0))?;
    let mut r = BufReader::with_capacity(1 << 16, &*file);
    loop {
        let got = read_f64s(&mut r, chunk)?;
        if got == 0 {
            return Ok(());
        }
        f(&chunk[..got]);
    }
}

/// Add `sd ·` standard normal draws to the column in `file`, in place, in order.
fn add_noise(
    file: &mut File,
    chunk: &mut [f64],
    sd: f64,
    rng: &mut impl rand::Rng,
) -> std::io::Result<()> {
    let mut pos = 0u64;
    loop {
        file.seek(SeekFrom::Start(pos))?;
        let got = read_f64s(&mut BufReader::with_capacity(1 << 16, &*file), chunk)?;
        if got == 0 {
            return Ok(());
        }
        for x in &mut chunk[..got] {
            *x += sd * rng.sample::<f64, _>(rand_distr::StandardNormal);
        }
        file.seek(SeekFrom::Start(pos))?;
        let mut w = BufWriter::with_capacity(1 << 16, &*file);
        for x in &chunk[..got] {
            w.write_all(&x.to_le_bytes())?;
        }
        w.flush()?;
        pos += 8 * got as u64;
    }
}
