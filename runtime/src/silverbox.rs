//! The Silverbox benchmark (Wigren & Schoukens 2013): a real electronic Duffing oscillator,
//! `m y'' + d y' + (a + b y²) y = u`, measured as input voltage `V1 = u` and output voltage
//! `V2 = y` only.
//!
//! Procedure (see `docs/silverbox.md`): load `SNLS80mV.csv`, remove the means of both
//! columns, find the ten multisine realisations after the arrow from the pauses of the input
//! (runs of near-zero input), identify on the first 75 % of the multisine samples (one
//! level per realisation, so each realisation's start-up transient is covered by the
//! finite-record boundary terms), and score the identified continuous-time model by
//! free-run simulation driven by the measured input: on the arrow (the first 40 000
//! samples, from rest) and on the last 25 % of the multisine samples.

use crate::data::{CsvOptions, DataError, LevelSource, RecordSource};
use crate::describe::{mean, std_dev};
use crate::ident::{measure, Identification, IdentifyError, IdentifyOptions, SIGNIFICANCE_T};
use crate::record::Record;
use crate::sim::{simulate_driven, SimError};
use crate::tape::Tape;
use dynid_ir::ir::{ModelIr, ParamKind, SignalKind};
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

/// Errors of the Silverbox procedure.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum SilverboxError {
    #[error("cannot read the Silverbox data `{}`", path.display())]
    #[diagnostic(
        code(dynid::silverbox::io),
        help("put the original SNLS80mV.csv (Wigren & Schoukens 2013) into the data directory, or point to its directory with `--data DIR`")
    )]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}, line {line}: {what}", path.display())]
    #[diagnostic(
        code(dynid::silverbox::malformed),
        help("the file must be the original SNLS80mV.csv: a header \"V1\",\"V2\" and two numbers (volts) per line")
    )]
    Malformed {
        path: PathBuf,
        line: u64,
        what: String,
    },
    #[error("{}: found {found} multisine realisations after the arrow, expected {expected}", path.display())]
    #[diagnostic(
        code(dynid::silverbox::segments),
        help("the file is not the original SNLS80mV.csv, or it was cut; use the unchanged file")
    )]
    Segments {
        path: PathBuf,
        found: usize,
        expected: usize,
    },
    #[error("the model `{model}` does not fit the Silverbox data: {what}")]
    #[diagnostic(
        code(dynid::silverbox::model),
        help("use one body whose position is measured and one measured input (e.g. `body y`, `input u on y`, `measure y.x, u`)")
    )]
    Model { model: String, what: String },
    #[error("{what} would need {estimate}")]
    #[diagnostic(code(dynid::silverbox::too_large), help("{help}"))]
    TooLarge {
        what: String,
        estimate: String,
        help: String,
    },
    #[error(transparent)]
    #[diagnostic(transparent)]
    Identify(#[from] IdentifyError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    #[diagnostic(transparent)]
    Refine(#[from] crate::refine::RefineError),
}

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
fn names(ir: &ModelIr) -> Result<(String, String), SilverboxError> {
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

/// Identification options used for the Silverbox: corners spread around the resonance
/// (≈ 69 Hz ≈ 430 rad/s) and well below Nyquist (1917 rad/s), fourth-order chains, driven
/// by the input only. The multisine input is exact (a DAC signal), while the output
/// carries noise and unmodelled dynamics: instruments built from the input alone are not
/// correlated with either (an instrumental-variable choice); with the output among the
/// drivers the estimates moved by several per cent with the corners.
pub fn default_options(ir: &ModelIr) -> IdentifyOptions {
    IdentifyOptions {
        corners: Some(vec![200.0, 300.0, 400.0, 500.0, 700.0, 1000.0]),
        order: Some(4),
        drivers: Some(
            (0..ir.inputs.len() as u32)
                .map(|i| ir.input_signal(dynid_ir::ir::InputId(i)))
                .collect(),
        ),
        ..Default::default()
    }
}

/// Identify on the estimation parts, one level per realisation.
pub fn identify_estimation(
    ir: &ModelIr,
    data: &SilverboxData,
    split: &Split,
    opts: &IdentifyOptions,
    upsample_factor: usize,
) -> Result<(Identification, Vec<(String, f64)>), SilverboxError> {
    let records = split
        .estimation
        .iter()
        .map(|s| record_upsampled(ir, data, *s, upsample_factor))
        .collect::<Result<Vec<_>, _>>()?;
    let sources = records
        .iter()
        .zip(&split.estimation)
        .map(|(r, s)| RecordSource::new(r, ir, format!("{FILE}[{}..{}]", s.start, s.end)))
        .collect::<Result<Vec<_>, _>>()?;
    let levels: Vec<&dyn LevelSource> = sources.iter().map(|s| s as &dyn LevelSource).collect();
    // A structure choice: a term the data do not show (|value| ≤ 2 standard errors) is
    // left out (0) and the others refitted, rather than simulated at a noise-dominated
    // value (an unresolved quadratic stiffness, fitted anyway, moved the cubic coefficient
    // by 12 % and tripled the arrow error). Plain `identify` keeps such terms, flagged.
    let tape = Tape::compile(ir, &ir.eval_roots());
    let mut moments = measure(ir, &tape, &levels, opts)?;
    moments.prune_below(SIGNIFICANCE_T);
    let id = moments.identify_pooled();
    let values = ir
        .unknowns()
        .iter()
        .map(|p| {
            let name = ir.params[p.index()].name.clone();
            let v = id.param(&name).map_or(0.0, |e| e.value);
            (name, v)
        })
        .collect();
    Ok((id, values))
}

/// `ir` with every unknown parameter's nominal value replaced by its estimate.
pub fn with_estimates(ir: &ModelIr, values: &[(String, f64)]) -> ModelIr {
    let mut out = ir.clone();
    for p in &mut out.params {
        if let ParamKind::Unknown { nominal } = &mut p.kind {
            if let Some((_, v)) = values.iter().find(|(n, _)| *n == p.name) {
                *nominal = Some(*v);
            }
        }
    }
    out
}

/// Free-run simulation of `ir` (at its nominal values) driven by the measured input over
/// `sim` from rest; RMS error in volts over `score` (⊆ `sim`) and the simulated output.
pub fn free_run_rms(
    ir: &ModelIr,
    data: &SilverboxData,
    sim: Segment,
    score: Segment,
    substeps: usize,
    upsample_factor: usize,
) -> Result<(f64, Vec<f64>), SilverboxError> {
    let l = upsample_factor.max(1);
    let rec = record_upsampled(ir, data, sim, l)?;
    let out = simulate_driven(ir, &rec, substeps)?;
    let (yn, _) = names(ir)?;
    let ys: Vec<f64> = out
        .column(&yn)
        .expect("invariant: simulated output column")
        .iter()
        .step_by(l)
        .copied()
        .collect();
    let s2: f64 = ys[score.start - sim.start..score.end - sim.start]
        .iter()
        .zip(&data.y[score.start..score.end])
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    Ok(((s2 / score.len() as f64).sqrt(), ys))
}

/// Published free-run RMS errors on the arrow (mV).
pub const PUBLISHED: [(&str, f64); 6] = [
    ("best linear approximation", 13.7),
    (
        "grey-box, 5 parameters (Hjalmarsson & Schoukens 2004)",
        0.96,
    ),
    ("nonlinear feedback, 10 parameters", 0.38),
    ("polynomial LFR, 11 parameters", 0.35),
    ("NLARX", 0.30),
    ("PNLSS, 37 parameters", 0.26),
];

/// Result of the procedure for one model.
#[derive(Clone, Debug, Serialize)]
pub struct SilverboxReport {
    pub model: String,
    pub n_params: usize,
    pub params: Vec<crate::ident::ParamEstimate>,
    pub unidentifiable: Vec<crate::ident::Unidentifiable>,
    /// The simulated values: identified unknowns, 0 for those the data does not resolve.
    pub simulated: Vec<(String, f64)>,
    pub condition: f64,
    pub filter_corners: Vec<f64>,
    pub filter_order: usize,
    pub split: Split,
    pub substeps: usize,
    /// Free-run RMS error on the arrow (first 40 000 samples), mV.
    pub arrow_rms_mv: f64,
    /// Free-run RMS error on the last 25 % of the multisine samples, mV.
    pub multisine_test_rms_mv: f64,
    /// RMS of the output over the same ranges (mV), for scale.
    pub arrow_output_rms_mv: f64,
    pub multisine_test_output_rms_mv: f64,
    /// The output-error refinement started from the covariance estimate, if asked for.
    pub refined: Option<RefinedReport>,
}

/// The refined estimate and its free-run errors (same simulations as the covariance ones).
#[derive(Clone, Debug, Serialize)]
pub struct RefinedReport {
    pub refinement: crate::refine::Refinement,
    pub arrow_rms_mv: f64,
    pub multisine_test_rms_mv: f64,
}

/// Settings of [`run`].
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub identify: IdentifyOptions,
    /// RK4 sub-steps per (upsampled) sample in the free-run simulations.
    pub substeps: usize,
    /// Band-limited interpolation factor applied before identification and simulation
    /// (1: the measured samples with linear interpolation in between).
    pub upsample: usize,
    /// Refine the covariance estimate on the estimation parts (output error, one
    /// sub-record per part started from its fitted initial state); `substeps` of these
    /// options is replaced by [`RunOptions::substeps`].
    pub refine: Option<crate::refine::RefineOptions>,
}

/// The whole procedure for one model.
pub fn run(
    ir: &ModelIr,
    data: &SilverboxData,
    opts: &RunOptions,
) -> Result<SilverboxReport, SilverboxError> {
    let split = split(data)?;
    let (id, point) = identify_estimation(ir, data, &split, &opts.identify, opts.upsample)?;
    let fitted = with_estimates(ir, &point);
    let (arrow, test, test_out) = scores(&fitted, data, &split, opts)?;
    let refined = match &opts.refine {
        Some(ropts) => {
            let records = split
                .estimation
                .iter()
                .map(|s| record_upsampled(ir, data, *s, opts.upsample))
                .collect::<Result<Vec<_>, _>>()?;
            let start: Vec<f64> = point.iter().map(|(_, v)| *v).collect();
            // The benchmark scores its own way (from rest, the transients discarded): the
            // refinement fits the records' initial states as well.
            let ropts = crate::refine::RefineOptions {
                substeps: opts.substeps,
                estimate_initial: true,
                ..ropts.clone()
            };
            let r = crate::refine::refine(ir, &records, &start, &ropts)?;
            let fitted = ir.with_nominals(&r.values());
            let (arrow, test, _) = scores(&fitted, data, &split, opts)?;
            Some(RefinedReport {
                refinement: r,
                arrow_rms_mv: 1e3 * arrow,
                multisine_test_rms_mv: 1e3 * test,
            })
        }
        None => None,
    };
    let arrow_out =
        (data.y[..ARROW_LEN].iter().map(|v| v * v).sum::<f64>() / ARROW_LEN as f64).sqrt();
    Ok(SilverboxReport {
        model: ir.name.clone(),
        n_params: ir.unknowns().len(),
        params: id.params.clone(),
        unidentifiable: id.unidentifiable.clone(),
        simulated: point,
        condition: id.condition,
        filter_corners: id.filter.corners.clone(),
        filter_order: id.filter.order,
        split,
        substeps: opts.substeps,
        arrow_rms_mv: 1e3 * arrow,
        multisine_test_rms_mv: 1e3 * test,
        arrow_output_rms_mv: 1e3 * arrow_out,
        multisine_test_output_rms_mv: 1e3 * test_out,
        refined,
    })
}

/// Free-run RMS errors (V) of `fitted` on the arrow and on the multisine test, and the
/// output RMS over the multisine test.
fn scores(
    fitted: &ModelIr,
    data: &SilverboxData,
    split: &Split,
    opts: &RunOptions,
) -> Result<(f64, f64, f64), SilverboxError> {
    let (arrow, _) = free_run_rms(
        fitted,
        data,
        split.arrow,
        split.arrow,
        opts.substeps,
        opts.upsample,
    )?;
    // Each test part is simulated from the start of its realisation (from the rest of the
    // preceding pause) and scored on the test samples only.
    let mut s2 = 0.0;
    let mut n = 0usize;
    let mut o2 = 0.0;
    for t in &split.test {
        let r = split
            .realisations
            .iter()
            .find(|r| r.start <= t.start && t.end <= r.end)
            .copied()
            .expect("invariant: test part inside a realisation");
        let (rms, _) = free_run_rms(
            fitted,
            data,
            Segment {
                start: r.start,
                end: t.end,
            },
            *t,
            opts.substeps,
            opts.upsample,
        )?;
        s2 += rms * rms * t.len() as f64;
        n += t.len();
        o2 += data.y[t.start..t.end].iter().map(|v| v * v).sum::<f64>();
    }
    Ok((arrow, (s2 / n as f64).sqrt(), (o2 / n as f64).sqrt()))
}

/// One excitation level cut from the arrow, with the per-level linear fit.
#[derive(Clone, Debug, Serialize)]
pub struct ArrowLevel {
    pub segment: Segment,
    /// Standard deviations of input and output over the segment, mV.
    pub u_std_mv: f64,
    pub y_std_mv: f64,
    /// Per-level identification of the (linear) model.
    pub params: Vec<crate::ident::ParamEstimate>,
}

/// Cut the arrow into `n` consecutive equal segments: excitation levels of growing
/// amplitude (the arrow's input amplitude grows linearly with time).
pub fn arrow_levels(n: usize) -> Vec<Segment> {
    (0..n)
        .map(|i| Segment {
            start: i * ARROW_LEN / n,
            end: (i + 1) * ARROW_LEN / n,
        })
        .collect()
}

fn std_mv(x: &[f64]) -> f64 {
    1e3 * std_dev(x)
}

/// Records of the arrow levels (band-limited interpolated by `upsample_factor`, see
/// [`record_upsampled`]) and the per-level identification of `ir` (for detection: the
/// equivalent linear stiffness of a hardening spring rises with the level).
pub fn arrow_level_fits(
    ir: &ModelIr,
    data: &SilverboxData,
    n: usize,
    opts: &IdentifyOptions,
    upsample_factor: usize,
) -> Result<(Vec<Record>, Vec<ArrowLevel>), SilverboxError> {
    let segs = arrow_levels(n);
    let records = segs
        .iter()
        .map(|s| record_upsampled(ir, data, *s, upsample_factor))
        .collect::<Result<Vec<_>, _>>()?;
    let sources = records
        .iter()
        .zip(&segs)
        .map(|(r, s)| RecordSource::new(r, ir, format!("arrow[{}..{}]", s.start, s.end)))
        .collect::<Result<Vec<_>, _>>()?;
    let levels: Vec<&dyn LevelSource> = sources.iter().map(|s| s as &dyn LevelSource).collect();
    let fits = crate::ident::identify_per_level(ir, &levels, opts)?;
    let out = segs
        .iter()
        .zip(fits)
        .map(|(s, f)| ArrowLevel {
            segment: *s,
            u_std_mv: std_mv(&data.u[s.start..s.end]),
            y_std_mv: std_mv(&data.y[s.start..s.end]),
            params: f.params,
        })
        .collect();
    Ok((records, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realisations_between_pauses() {
        let mut u = vec![0.05; 100];
        u.extend(vec![0.0; 30]);
        u.extend((0..6000).map(|k| if k % 2 == 0 { 0.02 } else { -0.02 }));
        u.extend(vec![0.0; 25]);
        u.extend(vec![0.03; 5500]);
        u.extend(vec![0.0; 40]);
        u.extend(vec![0.03; 100]);
        let r = find_realisations(&u, 50);
        assert_eq!(
            r,
            vec![
                Segment {
                    start: 130,
                    end: 6130
                },
                Segment {
                    start: 6155,
                    end: 11655
                }
            ]
        );
    }
}
