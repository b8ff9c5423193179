//! Gap scoring: free-run simulation against the measured records (per signal NRMSE,
//! standard-deviation error and spectral distance), the covariance-equation residual, and
//! both cross-validated over withheld levels.

use super::metrics;
use super::types::{DiagnoseError, DiagnoseOptions, LevelGap, ModelGap, SignalGap};
use crate::data::{DataError, LevelSource, RecordSource};
use crate::ident::{measure, Identification, Measurement};
use crate::record::Record;
use crate::sim::{simulate_driven_from, Start};
use crate::tape::Tape;
use dynid_ir::ir::{ModelIr, ParamKind};
use rayon::prelude::*;

/// Read a level source into memory (the free-run comparison needs the whole record).
pub fn read_record(src: &dyn LevelSource, ir: &ModelIr) -> Result<Record, DataError> {
    let measured = ir.measured_signals();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); measured.len()];
    src.stream(8192, &mut |cols, len| {
        for (out, s) in columns.iter_mut().zip(&measured) {
            out.extend_from_slice(&cols[s.index()][..len]);
        }
    })?;
    Ok(Record {
        names: measured
            .iter()
            .map(|s| ir.signal(*s).name.clone())
            .collect(),
        columns,
        ts: src.ts(),
        t0: 0.0,
    })
}

/// Parameter values to simulate with: identified values for identified unknowns.
pub(super) fn with_values(ir: &ModelIr, id: &Identification) -> ModelIr {
    let mut out = ir.clone();
    for p in out.params.iter_mut() {
        if let ParamKind::Unknown { nominal } = &mut p.kind {
            if let Some(e) = id.param(&p.name) {
                *nominal = Some(e.value);
            } else if nominal.is_none() {
                *nominal = Some(0.0);
            }
        }
    }
    out
}

pub(super) struct Data<'a> {
    pub(super) records: &'a [Record],
    pub(super) origins: &'a [String],
    pub(super) response: Vec<String>,
}

/// One response signal of a free run, kept for the report: spectra ([`metrics::welch_fine`])
/// and time series of the measured and the simulated signal after the discard.
pub(super) struct SignalRun {
    pub(super) signal: String,
    pub(super) freqs: Vec<f64>,
    pub(super) measured_psd: Vec<f64>,
    pub(super) sim_psd: Vec<f64>,
    /// Time of the first kept sample.
    pub(super) t0: f64,
    pub(super) measured: Vec<f64>,
    pub(super) sim: Vec<f64>,
}

/// The response signals of one level's free run, for the report.
pub(super) type LevelSpectra = Vec<SignalRun>;

/// Free-run gap of `ir` (with its nominal values) on level `w`.
pub(super) fn level_gap(
    ir: &ModelIr,
    data: &Data,
    w: usize,
    opts: &DiagnoseOptions,
    want_psd: bool,
) -> (LevelGap, Option<LevelSpectra>) {
    let rec = &data.records[w];
    let start = ((rec.len() as f64) * opts.discard) as usize;
    // Signals whose measured response varies after the discard: the others have no gap.
    let usable: Vec<&String> = data
        .response
        .iter()
        .filter(|name| {
            rec.column(name).is_some_and(|m| {
                let s = metrics::std_dev(&m[start.min(m.len())..]);
                s.is_finite() && s > 0.0
            })
        })
        .collect();
    let unavailable = |signals: Vec<SignalGap>| LevelGap {
        level: w,
        origin: data.origins[w].clone(),
        gap: None,
        pathwise: None,
        signals,
        diverged: false,
    };
    if usable.is_empty() {
        return (unavailable(vec![]), None);
    }
    let sim = match simulate_driven_from(ir, rec, opts.substeps, Start::Measured) {
        Ok(s) => s,
        Err(_) => {
            let diverged = LevelGap {
                level: w,
                origin: data.origins[w].clone(),
                gap: Some(f64::INFINITY),
                pathwise: Some(f64::INFINITY),
                signals: vec![],
                diverged: true,
            };
            return (diverged, None);
        }
    };
    let mut signals = Vec::new();
    let mut spectra = Vec::new();
    for name in usable {
        let (Some(y), Some(m)) = (sim.column(name), rec.column(name)) else {
            continue;
        };
        let (y, m) = (&y[start..], &m[start..]);
        let (_, pm) = metrics::welch(m, rec.ts, 4096);
        let (_, ps) = metrics::welch(y, rec.ts, 4096);
        let sm = metrics::std_dev(m);
        if pm.iter().skip(1).sum::<f64>().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            // Too short for a spectrum, or no power outside DC: no gap for this signal.
            continue;
        }
        let psd_gap = metrics::psd_gap(&ps, &pm);
        let std_diff = metrics::std_dev(y) - sm;
        let std_error = 100.0 * std_diff / sm;
        let rms_error = (y.iter().zip(m).map(|(a, b)| (a - b) * (a - b)).sum::<f64>()
            / m.len().max(1) as f64)
            .sqrt();
        let spectral = metrics::spectral_error(psd_gap);
        signals.push(SignalGap {
            signal: name.clone(),
            nrmse: 100.0 * metrics::nrmse(y, m),
            std_error,
            psd_gap,
            spectral,
            statistical: 0.5 * (spectral + std_error.abs()),
            unit: unit_of(ir, name).into(),
            rms_error,
            std_diff,
        });
        if want_psd {
            let (freqs, measured_psd) = metrics::welch_fine(m, rec.ts);
            let (_, sim_psd) = metrics::welch_fine(y, rec.ts);
            spectra.push(SignalRun {
                signal: name.clone(),
                freqs,
                measured_psd,
                sim_psd,
                t0: rec.t0 + start as f64 * rec.ts,
                measured: m.to_vec(),
                sim: y.to_vec(),
            });
        }
    }
    if signals.is_empty() {
        return (unavailable(signals), None);
    }
    let mean = |f: fn(&SignalGap) -> f64| {
        let v = signals.iter().map(f).sum::<f64>() / signals.len() as f64;
        // Not finite only when the simulated response is (a run that escaped the
        // divergence check): count it as diverged.
        if v.is_finite() {
            v
        } else {
            f64::INFINITY
        }
    };
    let gap = mean(|s| s.statistical);
    let pathwise = mean(|s| s.nrmse);
    (
        LevelGap {
            level: w,
            origin: data.origins[w].clone(),
            gap: Some(gap),
            pathwise: Some(pathwise),
            signals,
            diverged: !gap.is_finite() || !pathwise.is_finite(),
        },
        want_psd.then_some(spectra),
    )
}

/// The SI unit of the signal `name` of `ir` (see [`SignalGap::unit`]).
pub(super) fn unit_of(ir: &ModelIr, name: &str) -> &'static str {
    use dynid_ir::ir::SignalKind;
    match ir.signals.iter().find(|s| s.name == name).map(|s| s.kind) {
        Some(SignalKind::Position(_)) => "m",
        Some(SignalKind::Velocity(_)) => "m/s",
        Some(SignalKind::Input(_)) => "N",
        _ => "",
    }
}

/// A model's gap from its per-level gaps: the means over the levels where the gap is
/// available (infinite when a run diverged).
pub(super) fn model_gap(label: &str, levels: Vec<LevelGap>) -> ModelGap {
    let mean = |f: fn(&LevelGap) -> Option<f64>| {
        let v: Vec<f64> = levels.iter().filter_map(f).collect();
        if v.iter().any(|x| !x.is_finite()) {
            f64::INFINITY
        } else {
            v.iter().sum::<f64>() / v.len().max(1) as f64
        }
    };
    ModelGap {
        label: label.into(),
        gap: mean(|l| l.gap),
        pathwise: mean(|l| l.pathwise),
        levels,
    }
}

pub(super) fn sources<'r>(
    ir: &ModelIr,
    data: &'r Data,
) -> Result<Vec<RecordSource<'r>>, DataError> {
    data.records
        .iter()
        .zip(data.origins)
        .map(|(r, o)| RecordSource::new(r, ir, o.clone()))
        .collect()
}

pub(super) fn measure_all<'m>(
    ir: &'m ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
) -> Result<Measurement<'m>, DiagnoseError> {
    let srcs = sources(ir, data)?;
    let refs: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let tape = Tape::compile(ir, &ir.eval_roots());
    let mut m = measure(ir, &tape, &refs, &opts.ident)?;
    // The structure search treats a term whose estimate is within its standard error of
    // zero as absent, and scores the variant without it.
    m.prune_insignificant(true);
    Ok(m)
}

pub(super) fn training(n: usize, w: usize) -> Vec<usize> {
    (0..n).filter(|&i| i != w).collect()
}

/// Relative residual (%) of the row-normalised rows of level `w` with the parameters `p`,
/// optionally restricted to the rows of one equation; `None` when those rows are all zero
/// or the residual is not finite.
pub(super) fn cov_residual(
    m: &Measurement,
    p: &[f64],
    w: usize,
    equation: Option<&str>,
) -> Option<f64> {
    let (c, rhs) = m.level_system(w);
    let cols = if rhs.is_empty() {
        0
    } else {
        c.len() / rhs.len()
    };
    let (mut num, mut den) = (0.0, 0.0);
    for (r, &b) in rhs.iter().enumerate() {
        if equation.is_some_and(|eq| m.row_body(r) != eq) {
            continue;
        }
        let row = &c[r * cols..(r + 1) * cols];
        let norm = (row.iter().map(|x| x * x).sum::<f64>() + b * b).sqrt();
        if norm == 0.0 {
            continue;
        }
        let cp = row.iter().zip(p).map(|(a, b)| a * b).sum::<f64>();
        let e = cp - b;
        num += (e / norm).powi(2);
        // Relative to the size of the individual terms: an equation without input has a
        // zero right-hand side, so `c` alone is no scale.
        let terms: f64 = row.iter().zip(p).map(|(a, b)| (a * b).powi(2)).sum::<f64>() + b * b;
        den += terms / (norm * norm);
    }
    let r = 100.0 * (num / den).sqrt();
    (den > 0.0 && r.is_finite()).then_some(r)
}

pub(super) fn param_vector(ir: &ModelIr, id: &Identification) -> Vec<f64> {
    ir.unknowns()
        .iter()
        .map(|p| {
            let name = &ir.params[p.index()].name;
            id.param(name)
                .map(|e| e.value)
                .or(ir.params[p.index()].nominal())
                .unwrap_or(0.0)
        })
        .collect()
}

/// Cross-validated scores of a variant: covariance residual (mean over withheld levels)
/// and the training fits per withheld level.
pub(super) fn cross_validate(
    m: &Measurement,
    ir: &ModelIr,
    n: usize,
) -> (f64, Vec<Identification>) {
    let mut fits = Vec::with_capacity(n);
    let (mut res, mut k) = (0.0, 0);
    for w in 0..n {
        let fit = m.identify_levels(&training(n, w));
        let p = param_vector(ir, &fit);
        // A level whose rows are all zero (no excitation) has no residual.
        if let Some(r) = cov_residual(m, &p, w, None) {
            res += r;
            k += 1;
        }
        fits.push(fit);
    }
    // No level with a residual: rank last.
    (if k > 0 { res / k as f64 } else { f64::INFINITY }, fits)
}

/// Free-run gap with the training fits, each scored on its withheld level.
pub(super) fn cv_gap(
    ir: &ModelIr,
    fits: &[Identification],
    data: &Data,
    opts: &DiagnoseOptions,
    label: &str,
) -> ModelGap {
    cv_gap_by(&|_| ir, fits, data, opts, label)
}

/// As [`cv_gap`] with a model per withheld level (`ir_of(w)`): a shape parameter profiled
/// on each fold's training levels gives each fold its own model.
pub(super) fn cv_gap_by<'i>(
    ir_of: &(dyn Fn(usize) -> &'i ModelIr + Sync),
    fits: &[Identification],
    data: &Data,
    opts: &DiagnoseOptions,
    label: &str,
) -> ModelGap {
    let levels: Vec<LevelGap> = fits
        .par_iter()
        .enumerate()
        .map(|(w, fit)| level_gap(&with_values(ir_of(w), fit), data, w, opts, false).0)
        .collect();
    model_gap(label, levels)
}
