//! Writing simulated records: one CSV per level and `truth.json`, atomically.

use super::{PdControl, SimConfig, SimError, SimOutput};
use crate::record::Record;
use dynid_ir::ir::{FormFilter, ModelIr};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

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
    /// Data files written, in level order (filled in by [`write_outputs`]).
    #[serde(default)]
    pub files: Vec<String>,
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
/// shortest round-trip form. Written to a temporary file in the same directory and renamed,
/// so a failed write leaves no partial file behind.
pub fn write_level_csv(path: &Path, record: &Record) -> Result<(), SimError> {
    let tmp = temp_path(path);
    write_csv_to(&tmp, record)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|source| {
            let _ = std::fs::remove_file(&tmp);
            SimError::Write {
                path: path.to_path_buf(),
                source,
            }
        })
}

/// Write `DIR/level_k.csv` for every level and `DIR/truth.json`. All files are first
/// written under temporary names and only renamed once every write succeeded; on error
/// the temporaries are removed. Returns the paths written (truth.json last).
pub fn write_outputs(dir: &Path, out: &SimOutput) -> Result<Vec<PathBuf>, SimError> {
    let names = level_file_names(out.records.len());
    let mut truth = out.truth.clone();
    truth.files = names.clone();
    let mut finals: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
    finals.push(dir.join("truth.json"));
    let temps: Vec<PathBuf> = finals.iter().map(|p| temp_path(p)).collect();
    let cleanup = |temps: &[PathBuf]| {
        for t in temps {
            let _ = std::fs::remove_file(t);
        }
    };
    for ((rec, tmp), fin) in out.records.iter().zip(&temps).zip(&finals) {
        if let Err(source) = write_csv_to(tmp, rec) {
            cleanup(&temps);
            return Err(SimError::Write {
                path: fin.clone(),
                source,
            });
        }
    }
    let json_tmp = temps.last().expect("truth.json");
    let json = serde_json::to_string_pretty(&truth).expect("truth serialises");
    if let Err(source) = std::fs::write(json_tmp, json + "\n") {
        cleanup(&temps);
        return Err(SimError::Write {
            path: finals.last().expect("truth.json").clone(),
            source,
        });
    }
    for (tmp, fin) in temps.iter().zip(&finals) {
        if let Err(source) = std::fs::rename(tmp, fin) {
            cleanup(&temps);
            return Err(SimError::Write {
                path: fin.clone(),
                source,
            });
        }
    }
    Ok(finals)
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

fn write_csv_to(path: &Path, record: &Record) -> std::io::Result<()> {
    let file = std::fs::File::create(path)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
    write!(w, "t")?;
    for n in &record.names {
        write!(w, ",{n}")?;
    }
    writeln!(w)?;
    let decimals = time_decimals(record.ts).zip(time_decimals(record.t0));
    for i in 0..record.len() {
        let t = record.t0 + i as f64 * record.ts;
        match decimals {
            // `35 · 0.01` is 0.35000000000000003 in binary; print the decimal grid instead.
            Some((a, b)) => write!(w, "{t:.*}", a.max(b))?,
            None => write_number(&mut w, t)?,
        }
        for c in &record.columns {
            w.write_all(b",")?;
            write_number(&mut w, c[i])?;
        }
        w.write_all(b"\n")?;
    }
    w.into_inner().map_err(|e| e.into_error())?.sync_all()
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
#[inline]
fn write_number(w: &mut impl Write, x: f64) -> std::io::Result<()> {
    let a = x.abs();
    if x == 0.0 || (1e-4..1e15).contains(&a) || !x.is_finite() {
        write!(w, "{x}")
    } else {
        write!(w, "{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let dir = tempfile_dir();
        let path = dir.join("a.csv");
        let rec = Record {
            names: vec!["m1.x".into(), "u".into()],
            columns: vec![vec![0.1, 1.0 / 3.0], vec![-2.0, 1e-9]],
            ts: 0.01,
            t0: 0.0,
        };
        write_level_csv(&path, &rec).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t,m1.x,u");
        assert_eq!(lines[1], "0.00,0.1,-2");
        let row: Vec<f64> = lines[2].split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(row, [0.01, 1.0 / 3.0, 1e-9]);
        assert_eq!(time_decimals(0.01), Some(2));
        assert_eq!(time_decimals(1.0 / 3.0), None);
        // No temporary left behind.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile_dir();
        let path = dir.join("missing-subdir").join("a.csv");
        let rec = Record {
            names: vec!["x".into()],
            columns: vec![vec![1.0]],
            ts: 1.0,
            t0: 0.0,
        };
        assert!(matches!(
            write_level_csv(&path, &rec),
            Err(SimError::Write { .. })
        ));
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        std::fs::remove_dir_all(dir).unwrap();
    }

    fn tempfile_dir() -> PathBuf {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let d = std::env::temp_dir().join(format!(
            "dynid-sim-out-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
