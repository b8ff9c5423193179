//! Simulated records as text: the CSV format of a level and the `truth.json` record of
//! what a simulation used. Formatting only, into any `io::Write`; the caller opens files.

use super::{PdControl, SampleSink, SimConfig};
use crate::record::Record;
use dynid_ir::ir::{FormFilter, ModelIr};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;

/// What a simulation used: enough to reproduce it and to score an identification.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    pub model: String,
    /// Value of every parameter used by the simulation.
    pub parameters: BTreeMap<String, f64>,
    /// The parameters the model declares unknown, in declaration order.
    pub unknown: Vec<String>,
    /// Intensities of the experiments (the override, or the first `excite` line's).
    pub levels: Vec<f64>,
    pub excitation: Vec<ExcitationTruth>,
    pub seed: u64,
    pub noise: f64,
    pub noise_on_inputs: bool,
    pub duration: f64,
    pub sample: f64,
    pub substeps: usize,
    pub burn_in: f64,
    /// Steps of the input processes per sample interval (1 = linear between samples).
    #[serde(default = "one")]
    pub input_oversample: usize,
    /// Encoder resolution the recorded positions were rounded to.
    #[serde(default)]
    pub quantise: Option<f64>,
    /// The position controller of a closed-loop run; its reference is the column
    /// `<body>.x_ref`.
    #[serde(default)]
    pub control: Option<PdControl>,
    /// Data files written, in level order (filled in by the writer of the files).
    #[serde(default)]
    pub files: Vec<String>,
    /// The multisine or sweep that replaced the form filters of the inputs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signal: Option<super::TestSignal>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExcitationTruth {
    pub input: String,
    pub filter: FormFilter,
    pub levels: Vec<f64>,
}

impl Truth {
    pub(crate) fn new(
        ir: &ModelIr,
        cfg: &SimConfig,
        params: &[f64],
        excitation: &[(String, FormFilter, Vec<f64>)],
        levels: &[f64],
    ) -> Self {
        Truth {
            model: ir.name.clone(),
            parameters: ir
                .params
                .iter()
                .zip(params)
                .map(|(p, &v)| (p.name.clone(), v))
                .collect(),
            unknown: ir
                .unknowns()
                .iter()
                .map(|&p| ir.params[p.index()].name.clone())
                .collect(),
            levels: levels.to_vec(),
            excitation: excitation
                .iter()
                .map(|(input, filter, levels)| ExcitationTruth {
                    input: input.clone(),
                    filter: filter.clone(),
                    levels: levels.clone(),
                })
                .collect(),
            seed: cfg.seed,
            noise: cfg.noise,
            noise_on_inputs: cfg.noise_on_inputs,
            duration: cfg.duration,
            sample: cfg.sample,
            substeps: cfg.substeps,
            burn_in: cfg.burn_in,
            input_oversample: cfg.input_oversample,
            quantise: cfg.quantise,
            control: cfg.control.clone(),
            files: Vec::new(),
            signal: None,
        }
    }
}

fn one() -> usize {
    1
}

/// File names of `n` levels, so that lexical order is level order:
/// `level_1.csv … level_9.csv`, or `level_01.csv … level_12.csv`, and so on.
pub fn level_file_names(n: usize) -> Vec<String> {
    let width = n.max(1).to_string().len();
    (1..=n).map(|i| format!("level_{i:0width$}.csv")).collect()
}

/// Write `record` as CSV with header `t,<signals>` (t = t0 + i·ts) and numbers in their
/// shortest round-trip form (buffer `w`: this writes field by field).
pub fn write_csv(w: &mut dyn Write, record: &Record) -> std::io::Result<()> {
    let mut sink = CsvSink::new(w);
    sink.start(&record.names, record.ts, record.t0)?;
    let cols: Vec<&[f64]> = record.columns.iter().map(Vec::as_slice).collect();
    sink.rows(&cols, record.len())
}

/// A [`SampleSink`] writing CSV (the format of [`write_csv`]) as the samples arrive.
pub struct CsvSink<W: Write> {
    w: W,
    ts: f64,
    t0: f64,
    decimals: Option<usize>,
    /// Samples written so far.
    pub written: usize,
}

impl<W: Write> CsvSink<W> {
    pub fn new(w: W) -> Self {
        CsvSink {
            w,
            ts: 1.0,
            t0: 0.0,
            decimals: None,
            written: 0,
        }
    }

    /// Write the header; times are `t0 + i·ts`.
    pub fn start(&mut self, names: &[String], ts: f64, t0: f64) -> std::io::Result<()> {
        write!(self.w, "t")?;
        for n in names {
            write!(self.w, ",{n}")?;
        }
        writeln!(self.w)?;
        self.ts = ts;
        self.t0 = t0;
        self.decimals = time_decimals(ts)
            .zip(time_decimals(t0))
            .map(|(a, b)| a.max(b));
        Ok(())
    }
}

impl<W: Write + Send> SampleSink for CsvSink<W> {
    fn begin(&mut self, names: &[String], ts: f64) -> std::io::Result<()> {
        self.start(names, ts, 0.0)
    }

    fn push(&mut self, cols: &[&[f64]], len: usize) -> std::io::Result<()> {
        self.rows(cols, len)
    }
}

impl<W: Write> CsvSink<W> {
    /// Write `len` samples; `cols[j]` is column `j`.
    pub fn rows(&mut self, cols: &[&[f64]], len: usize) -> std::io::Result<()> {
        let w = &mut self.w;
        for i in 0..len {
            let t = self.t0 + (self.written + i) as f64 * self.ts;
            match self.decimals {
                // `35 · 0.01` is 0.35000000000000003 in binary; print the decimal grid instead.
                Some(d) => write!(w, "{t:.d$}")?,
                None => write_number(w, t)?,
            }
            for c in cols {
                w.write_all(b",")?;
                write_number(w, c[i])?;
            }
            w.write_all(b"\n")?;
        }
        self.written += len;
        Ok(())
    }

    /// The writer, e.g. to flush it.
    pub fn into_inner(self) -> W {
        self.w
    }
}

/// Number of decimals of `x` if it is a short decimal (≤ 9 decimals), e.g. 2 for 0.01.
fn time_decimals(x: f64) -> Option<usize> {
    (0..=9).find(|&d| {
        let scaled = x * 10f64.powi(d as i32);
        scaled.abs() < 1e15 && (scaled - scaled.round()).abs() <= 1e-6
    })
}

/// Shortest round-trip representation; exponent form outside [1e-4, 1e15) so tiny and
/// huge values stay short.
///
/// Inside that range the digits come from `ryu` (several times faster than `Display`;
/// plain decimals there too, an integer marked with `.0`, which is dropped): the text is
/// `format!("{x}")` but where two shortest digit strings are equally near the number, of
/// which the two pick different ones; both read back to the same number (test
/// `fast_digits_are_display_digits`).
#[inline]
fn write_number(w: &mut (impl Write + ?Sized), x: f64) -> std::io::Result<()> {
    let a = x.abs();
    if (1e-4..1e15).contains(&a) {
        let mut buf = ryu::Buffer::new();
        let s = buf.format_finite(x);
        w.write_all(s.strip_suffix(".0").unwrap_or(s).as_bytes())
    } else if x == 0.0 || !x.is_finite() {
        write!(w, "{x}")
    } else {
        write!(w, "{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_digits_are_display_digits() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        // Random bit patterns, random decimals of every scale in range, and the edges.
        let mut xs: Vec<f64> = vec![1e-4, 1e15_f64.next_down(), 1.0, 0.1, 123456.0, 0.3];
        xs.extend((0..200_000).map(|_| f64::from_bits(rng.random::<u64>())));
        xs.extend((0..200_000).map(|_| {
            let e = rng.random_range(-4..15);
            rng.random_range(1.0..10.0) * 10f64.powi(e)
        }));
        xs.extend((0..20_000).map(|_| rng.random_range(-1_000_000i64..1_000_000) as f64));
        let mut ties = 0;
        for x in xs {
            let mut buf = Vec::new();
            write_number(&mut buf, x).unwrap();
            let s = String::from_utf8(buf).unwrap();
            let want = if x == 0.0 || (1e-4..1e15).contains(&x.abs()) || !x.is_finite() {
                format!("{x}")
            } else {
                format!("{x:e}")
            };
            if s != want {
                // Equally short, equally near (only the last digit differs), the same number.
                assert_eq!(s.len(), want.len(), "{s} against {want}");
                assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{s}");
                assert_eq!(
                    s[..s.len() - 1],
                    want[..want.len() - 1],
                    "{s} against {want}"
                );
                ties += 1;
            }
        }
        // Measured: 930 of the 420 006 values (0.2 %).
        assert!(ties < 2_000, "{ties} ties");
    }

    #[test]
    fn numbers_round_trip() {
        for &x in &[
            0.0,
            -0.0,
            1.0,
            0.1,
            -3.25e-7,
            1.0 / 3.0,
            6.02e23,
            1e-300,
            123456.789,
        ] {
            let mut buf = Vec::new();
            write_number(&mut buf, x).unwrap();
            let s = String::from_utf8(buf).unwrap();
            assert_eq!(s.parse::<f64>().unwrap(), x, "{s}");
            assert!(s.len() < 26, "{s}");
        }
    }

    #[test]
    fn file_names_sort_in_level_order() {
        assert_eq!(
            level_file_names(3),
            ["level_1.csv", "level_2.csv", "level_3.csv"]
        );
        let n = level_file_names(12);
        assert_eq!(n[0], "level_01.csv");
        let mut sorted = n.clone();
        sorted.sort();
        assert_eq!(sorted, n);
    }

    #[test]
    fn csv_has_header_time_and_exact_values() {
        let rec = Record {
            names: vec!["m1.x".into(), "u".into()],
            columns: vec![vec![0.1, 1.0 / 3.0], vec![-2.0, 1e-9]],
            ts: 0.01,
            t0: 0.0,
        };
        let mut buf = Vec::new();
        write_csv(&mut buf, &rec).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t,m1.x,u");
        assert_eq!(lines[1], "0.00,0.1,-2");
        let row: Vec<f64> = lines[2].split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(row, [0.01, 1.0 / 3.0, 1e-9]);
        assert_eq!(time_decimals(0.01), Some(2));
        assert_eq!(time_decimals(1.0 / 3.0), None);
    }
}
