//! The measured FRF of a record, streamed: Welch H1 over Hann-windowed segments, or
//! per-period averaging at the excited lines of a periodic input (see the parent module for
//! the estimators' maths).

use super::{Frf, FrfMethod};
use crate::data::{DataError, LevelSource};
use dynid_ir::ir::SignalId;
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use std::f64::consts::PI;
use std::sync::Arc;

/// Streaming accumulator of the auto- and cross-spectra of one input and `m` responses.
pub struct H1Accumulator {
    n: usize,
    hop: usize,
    window: Vec<f64>,
    method: FrfMethod,
    /// Current segment: `buf[0]` the input, `buf[1 + j]` response `j`.
    buf: Vec<Vec<f64>>,
    filled: usize,
    fft: Arc<dyn RealToComplex<f64>>,
    scratch_in: Vec<f64>,
    spec_u: Vec<Complex<f64>>,
    spec_y: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    suu: Vec<f64>,
    syy: Vec<Vec<f64>>,
    suy: Vec<Vec<Complex<f64>>>,
    count: usize,
}

impl H1Accumulator {
    /// `m` responses; Welch segments of `n ≥ 8` samples.
    pub fn welch(m: usize, n: usize) -> Self {
        let n = n.max(8);
        let window = (0..n)
            .map(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos())
            .collect();
        Self::new(m, n, n / 2, window, FrfMethod::Welch { segment: n })
    }

    /// `m` responses; periods of `period ≥ 8` samples.
    pub fn periodic(m: usize, period: usize) -> Self {
        let n = period.max(8);
        Self::new(m, n, n, vec![1.0; n], FrfMethod::Periodic { period: n })
    }

    fn new(m: usize, n: usize, hop: usize, window: Vec<f64>, method: FrfMethod) -> Self {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        let bins = n / 2 + 1;
        H1Accumulator {
            n,
            hop,
            window,
            method,
            buf: vec![vec![0.0; n]; m + 1],
            filled: 0,
            scratch_in: fft.make_input_vec(),
            spec_u: fft.make_output_vec(),
            spec_y: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            suu: vec![0.0; bins],
            syy: vec![vec![0.0; bins]; m],
            suy: vec![vec![Complex::new(0.0, 0.0); bins]; m],
            count: 0,
        }
    }

    /// Append `len` samples: `u[..len]` and `ys[j][..len]`.
    pub fn push(&mut self, u: &[f64], ys: &[&[f64]], len: usize) {
        let mut k = 0;
        while k < len {
            let take = (self.n - self.filled).min(len - k);
            self.buf[0][self.filled..self.filled + take].copy_from_slice(&u[k..k + take]);
            for (b, y) in self.buf[1..].iter_mut().zip(ys) {
                b[self.filled..self.filled + take].copy_from_slice(&y[k..k + take]);
            }
            self.filled += take;
            k += take;
            if self.filled == self.n {
                self.segment();
                for b in &mut self.buf {
                    b.copy_within(self.hop.., 0);
                }
                self.filled = self.n - self.hop;
            }
        }
    }

    fn transform(&mut self, signal: usize, out_y: bool) {
        let b = &self.buf[signal];
        let mean = b.iter().sum::<f64>() / self.n as f64;
        for ((x, &v), w) in self.scratch_in.iter_mut().zip(b).zip(&self.window) {
            *x = (v - mean) * w;
        }
        let out = if out_y {
            &mut self.spec_y
        } else {
            &mut self.spec_u
        };
        self.fft
            .process_with_scratch(&mut self.scratch_in, out, &mut self.scratch)
            .expect("invariant: buffers made by the plan");
    }

    fn segment(&mut self) {
        self.transform(0, false);
        for (a, x) in self.suu.iter_mut().zip(&self.spec_u) {
            *a += x.norm_sqr();
        }
        for j in 0..self.syy.len() {
            self.transform(1 + j, true);
            for k in 0..self.suu.len() {
                let (u, y) = (self.spec_u[k], self.spec_y[k]);
                self.syy[j][k] += y.norm_sqr();
                self.suy[j][k] += u.conj() * y;
            }
        }
        self.count += 1;
    }

    /// Segments averaged so far.
    pub fn averages(&self) -> usize {
        self.count
    }

    /// The FRF at sample interval `ts`, over the bins where the input has power (above
    /// `1e-3` of its largest for periodic data, `1e-2` for Welch), DC excluded. `None`
    /// before the first whole segment or without input power.
    pub fn finish(&self, ts: f64) -> Option<Frf> {
        if self.count == 0 {
            return None;
        }
        let max = self.suu.iter().skip(1).fold(0.0f64, |a, &b| a.max(b));
        if !(max > 0.0 && max.is_finite()) {
            return None;
        }
        let floor = match self.method {
            FrfMethod::Periodic { .. } => 1e-3,
            FrfMethod::Welch { .. } => 1e-2,
        } * max;
        let keep: Vec<usize> = (1..self.suu.len())
            .filter(|&k| self.suu[k] > floor)
            .collect();
        let df = 1.0 / (self.n as f64 * ts);
        Some(Frf {
            method: self.method,
            averages: self.count,
            freq_hz: keep.iter().map(|&k| k as f64 * df).collect(),
            h: self
                .suy
                .iter()
                .map(|s| {
                    keep.iter()
                        .map(|&k| {
                            let h = s[k] / self.suu[k];
                            [h.re, h.im]
                        })
                        .collect()
                })
                .collect(),
            coherence: self
                .suy
                .iter()
                .zip(&self.syy)
                .map(|(s, yy)| {
                    keep.iter()
                        .map(|&k| {
                            let d = self.suu[k] * yy[k];
                            if d > 0.0 {
                                (s[k].norm_sqr() / d).clamp(0.0, 1.0)
                            } else {
                                0.0
                            }
                        })
                        .collect()
                })
                .collect(),
        })
    }
}

/// Welch segment length for a record of `len` samples: the largest power of two with at
/// least 8 segments' worth of data, between 256 and 16384 (shorter records: the record).
pub fn welch_segment(len: usize) -> usize {
    let mut n = 256usize;
    while n * 2 <= len / 8 && n < 16384 {
        n *= 2;
    }
    n.min(len.max(8))
}

/// The measured FRF of `input` to `outputs` (signals of the record), streaming `source`:
/// Welch H1, or per-period averaging when the record holds `periods` whole periods.
pub fn measured_frf(
    source: &dyn LevelSource,
    input: SignalId,
    outputs: &[SignalId],
    periods: Option<usize>,
) -> Result<Option<Frf>, DataError> {
    let mut len = 0usize;
    source.stream(1 << 16, &mut |_, n| len += n)?;
    let mut acc = match periods {
        Some(p) if p >= 1 && len / p >= 8 => H1Accumulator::periodic(outputs.len(), len / p),
        _ => H1Accumulator::welch(outputs.len(), welch_segment(len)),
    };
    source.stream(1 << 16, &mut |cols, n| {
        let u = cols[input.index()];
        let ys: Vec<&[f64]> = outputs.iter().map(|s| cols[s.index()]).collect();
        if u.len() >= n && ys.iter().all(|y| y.len() >= n) {
            acc.push(u, &ys, n);
        }
    })?;
    Ok(acc.finish(source.ts()))
}
