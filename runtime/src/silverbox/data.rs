//! The Silverbox measurement: loading with the means removed, the multisine realisations
//! found from the pauses of the input, the split into arrow, estimation and multisine test,
//! and records of sample ranges (as measured, or band-limited upsampled).

use super::error::SilverboxError;
use crate::data::CsvOptions;
use crate::describe::mean;
use crate::record::Record;
use dynid_ir::ir::{ModelIr, SignalKind};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Sample interval: the clock 10 MHz divided by 2¹⁴.
pub const TS: f64 = 16384.0 / 1e7;
/// The data file inside the data directory.
pub const FILE: &str = "SNLS80mV.csv";
/// Benchmark convention: the arrow (test set) is the first 40 000 samples.
pub const ARROW_LEN: usize = 40_000;
/// A pause is a run of at least this many samples with |u| below [`PAUSE_LEVEL`].
pub const PAUSE_MIN_LEN: usize = 20;
/// Input amplitude (V, after mean removal) below which a sample counts as quiet. The
/// multisines have an input standard deviation of about 22 mV, so 20 quiet samples in a row
/// do not happen inside a realisation.
pub const PAUSE_LEVEL: f64 = 1e-3;
/// Realisations shorter than this are not multisines (there are short bursts at the end).
pub const MIN_REALISATION: usize = 5000;
/// Share of the multisine samples (at the end) kept back as the multisine test.
pub const TEST_SHARE: f64 = 0.25;

/// The measurement after mean removal.
#[derive(Clone, Debug)]
pub struct SilverboxData {
    pub path: PathBuf,
    /// Input V1 − mean, volts.
    pub u: Vec<f64>,
    /// Output V2 − mean, volts.
    pub y: Vec<f64>,
    /// The removed means (V1, V2), volts.
    pub means: (f64, f64),
}

/// A half-open sample range `[start, end)` (0-based sample indices).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Segment {
    pub start: usize,
    pub end: usize,
}

impl Segment {
    pub fn len(&self) -> usize {
        self.end - self.start
    }
    pub fn is_empty(&self) -> bool {
        self.end <= self.start
    }
}

/// Read `DIR/SNLS80mV.csv` and remove the means of both columns.
pub fn load(dir: &Path) -> Result<SilverboxData, SilverboxError> {
    let path = dir.join(FILE);
    if let Err(source) = std::fs::metadata(&path) {
        return Err(SilverboxError::Io { path, source });
    }
    // The project's one CSV reader: header, equal field counts, finite numbers.
    let opts = CsvOptions {
        map: Vec::new(),
        ts: Some(TS),
        ..Default::default()
    };
    let rec = crate::data::read_record(&path, &opts)?;
    let column = |name: &str| {
        rec.column(name).ok_or_else(|| SilverboxError::Malformed {
            path: path.clone(),
            line: 1,
            what: format!(
                "no column {name} (found {}), expected \"V1\",\"V2\"",
                rec.names.join(", ")
            ),
        })
    };
    let (mut u, mut y) = (column("V1")?.to_vec(), column("V2")?.to_vec());
    if u.len() <= ARROW_LEN {
        return Err(SilverboxError::Malformed {
            path,
            line: u.len() as u64 + 1,
            what: format!("only {} samples, the benchmark has 131 072", u.len()),
        });
    }
    let (mu, my) = (mean(&u), mean(&y));
    u.iter_mut().for_each(|v| *v -= mu);
    y.iter_mut().for_each(|v| *v -= my);
    Ok(SilverboxData {
        path,
        u,
        y,
        means: (mu, my),
    })
}

/// The multisine realisations after `from`: maximal stretches between pauses (runs of at
/// least [`PAUSE_MIN_LEN`] samples with |u| < [`PAUSE_LEVEL`]) that are at least
/// [`MIN_REALISATION`] samples long.
pub fn find_realisations(u: &[f64], from: usize) -> Vec<Segment> {
    let mut out = Vec::new();
    let mut quiet = 0usize;
    let mut active_start: Option<usize> = None;
    let close = |start: usize, end: usize, out: &mut Vec<Segment>| {
        if end - start >= MIN_REALISATION {
            out.push(Segment { start, end });
        }
    };
    for (k, &v) in u.iter().enumerate().skip(from) {
        if v.abs() < PAUSE_LEVEL {
            quiet += 1;
            if quiet == PAUSE_MIN_LEN {
                if let Some(s) = active_start.take() {
                    close(s, k + 1 - PAUSE_MIN_LEN, &mut out);
                }
            }
        } else {
            if quiet >= PAUSE_MIN_LEN || (active_start.is_none() && k == from) {
                active_start = Some(k);
            }
            quiet = 0;
        }
    }
    if let Some(s) = active_start {
        close(s, u.len(), &mut out);
    }
    out
}

/// How the record is split.
#[derive(Clone, Debug, Serialize)]
pub struct Split {
    pub arrow: Segment,
    /// The ten multisine realisations found.
    pub realisations: Vec<Segment>,
    /// Estimation parts (the first 75 % of the multisine samples), one per realisation.
    pub estimation: Vec<Segment>,
    /// Test parts (the last 25 %).
    pub test: Vec<Segment>,
}

/// Split the data into arrow, estimation and multisine test.
pub fn split(data: &SilverboxData) -> Result<Split, SilverboxError> {
    let realisations = find_realisations(&data.u, ARROW_LEN);
    if realisations.len() != 10 {
        return Err(SilverboxError::Segments {
            path: data.path.clone(),
            found: realisations.len(),
            expected: 10,
        });
    }
    let total: usize = realisations.iter().map(Segment::len).sum();
    let n_est = ((1.0 - TEST_SHARE) * total as f64).round() as usize;
    let (mut estimation, mut test) = (Vec::new(), Vec::new());
    let mut seen = 0usize;
    for r in &realisations {
        let cut = (r.start + n_est.saturating_sub(seen)).min(r.end);
        if cut > r.start {
            estimation.push(Segment {
                start: r.start,
                end: cut,
            });
        }
        if cut < r.end {
            test.push(Segment {
                start: cut,
                end: r.end,
            });
        }
        seen += r.len();
    }
    Ok(Split {
        arrow: Segment {
            start: 0,
            end: ARROW_LEN,
        },
        realisations,
        estimation,
        test,
    })
}

/// Signal names of the model's output (first body's position) and input.
pub(super) fn names(ir: &ModelIr) -> Result<(String, String), SilverboxError> {
    let bad = |what: &str| SilverboxError::Model {
        model: ir.name.clone(),
        what: what.into(),
    };
    if ir.bodies.len() != 1 {
        return Err(bad(&format!(
            "{} bodies; the Silverbox has one output",
            ir.bodies.len()
        )));
    }
    if ir.inputs.len() != 1 {
        return Err(bad(&format!(
            "{} inputs; the Silverbox has one input",
            ir.inputs.len()
        )));
    }
    let y = ir
        .signals
        .iter()
        .find(|s| matches!(s.kind, SignalKind::Position(_)))
        .ok_or_else(|| bad("no position signal"))?;
    if !y.measured {
        return Err(bad(&format!("`{}` is not measured", y.name)));
    }
    if ir
        .signals
        .iter()
        .any(|s| matches!(s.kind, SignalKind::Velocity(_)) && s.measured)
    {
        return Err(bad("the data has no velocity; add `measure y.x, u`"));
    }
    Ok((y.name.clone(), ir.inputs[0].name.clone()))
}

/// Refuse a run whose upsampled records (two `f64` columns of every sample, at `upsample`
/// times the rate) would exceed [`crate::limits::MAX_BYTES`], or whose free-run
/// simulations (`substeps` RK4 steps per upsampled sample) would exceed
/// [`crate::limits::MAX_STEPS`], unless `allow`; `flag` is the option that allows it.
pub fn check_work(
    data: &SilverboxData,
    upsample: usize,
    substeps: usize,
    flag: &str,
    allow: bool,
) -> Result<(), SilverboxError> {
    use crate::limits::{bytes_in_words, duration_in_words, steps_in_words};
    use crate::limits::{MAX_BYTES, MAX_STEPS, STEPS_PER_SECOND};
    if allow {
        return Ok(());
    }
    let samples = data.u.len() as f64 * upsample.max(1) as f64;
    let bytes = samples * 2.0 * 8.0;
    if bytes > MAX_BYTES {
        return Err(SilverboxError::TooLarge {
            what: format!("upsampling {} samples by {upsample}", data.u.len()),
            estimate: format!("{} of memory", bytes_in_words(bytes)),
            help: format!(
                "runs above {} of records are refused as a likely mistyped setting: lower \
                 `--upsample` (4 is the default), or give `{flag}` to run it anyway",
                bytes_in_words(MAX_BYTES)
            ),
        });
    }
    let steps = samples * substeps as f64;
    if steps > MAX_STEPS {
        return Err(SilverboxError::TooLarge {
            what: format!("simulating {samples:.3e} upsampled samples × {substeps} RK4 sub-steps"),
            estimate: steps_in_words(steps),
            help: format!(
                "runs above {MAX_STEPS:.0e} RK4 steps ({}) are refused as a likely mistyped \
                 setting: lower `--upsample` or `--substeps`, or give `{flag}` to run it anyway",
                duration_in_words(MAX_STEPS / STEPS_PER_SECOND)
            ),
        });
    }
    Ok(())
}

/// The samples `seg` as a record with the model's signal names (`t0` = start time).
pub fn record(ir: &ModelIr, data: &SilverboxData, seg: Segment) -> Result<Record, SilverboxError> {
    record_upsampled(ir, data, seg, 1)
}

/// Half-width (in original samples) of the windowed-sinc interpolation kernel.
const SINC_HALF_WIDTH: usize = 24;

/// The samples `seg`, band-limited interpolated by the factor `l` (`l` = 1: as measured).
/// Sample `j` of the result sits at original index `seg.start + j / l`; the last original
/// sample of `seg` is the last sample of the record.
///
/// Why: both signals are band-limited (the input is a DAC signal, the output the response
/// of a low-pass circuit) and sampled at only ≈ 10 samples per resonance period, so the
/// piecewise-linear input model of the identification filters and of the simulator is
/// visibly wrong between samples; a Lanczos-windowed sinc interpolation restores the
/// in-between values, after which linear interpolation on the finer grid is accurate.
pub fn record_upsampled(
    ir: &ModelIr,
    data: &SilverboxData,
    seg: Segment,
    l: usize,
) -> Result<Record, SilverboxError> {
    let (yn, un) = names(ir)?;
    let l = l.max(1);
    Ok(Record {
        names: vec![yn, un],
        columns: vec![upsample(&data.y, seg, l), upsample(&data.u, seg, l)],
        ts: TS / l as f64,
        t0: seg.start as f64 * TS,
    })
}

fn upsample(x: &[f64], seg: Segment, l: usize) -> Vec<f64> {
    if l == 1 {
        return x[seg.start..seg.end].to_vec();
    }
    let n_out = (seg.len() - 1) * l + 1;
    let a = SINC_HALF_WIDTH as f64;
    // Kernel weights per fractional phase, computed once.
    let taps: Vec<Vec<f64>> = (0..l)
        .map(|p| {
            let frac = p as f64 / l as f64;
            (0..2 * SINC_HALF_WIDTH)
                .map(|i| {
                    let t = frac - (i as f64 - a + 1.0);
                    sinc(t) * sinc(t / a)
                })
                .collect()
        })
        .collect();
    let mut out = Vec::with_capacity(n_out);
    for j in 0..n_out {
        let k = seg.start + j / l;
        let p = j % l;
        if p == 0 {
            out.push(x[k]);
            continue;
        }
        let mut acc = 0.0;
        for (i, w) in taps[p].iter().enumerate() {
            let idx = k as isize + i as isize - SINC_HALF_WIDTH as isize + 1;
            if idx >= 0 && (idx as usize) < x.len() {
                acc += w * x[idx as usize];
            }
        }
        out.push(acc);
    }
    out
}

fn sinc(t: f64) -> f64 {
    if t.abs() < 1e-12 {
        1.0
    } else {
        let pt = std::f64::consts::PI * t;
        pt.sin() / pt
    }
}
