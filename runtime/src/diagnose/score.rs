//! Scores of a model against the measured levels: its free-run gap (per signal NRMSE,
//! standard-deviation error and spectral distance, simulated from the measured state
//! with the measured inputs), cross-validated over withheld levels, and the relative
//! residual of its covariance equations.

use super::levels::{unit_of, with_values, Data};
use super::metrics;
use super::types::{DiagnoseOptions, LevelGap, ModelGap, SignalGap};
use crate::ident::{Identification, Measurement};
use crate::sim::{simulate_driven_from, Start};
use dynid_ir::ir::ModelIr;
use rayon::prelude::*;

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

/// Free-run gap of `ir` (with its nominal values) on level `w`; with `want_psd` also the
/// spectra and time series of its response signals, for the report.
pub(super) fn level_gap(
    ir: &ModelIr,
    data: &Data,
    w: usize,
    opts: &DiagnoseOptions,
    want_psd: bool,
) -> (LevelGap, Option<LevelSpectra>) {
    let rec = &data.records[w];
    let start = ((rec.len() as f64) * opts.discard) as usize;
    let usable = varying(data, w, start);
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
    let Ok(sim) = simulate_driven_from(ir, rec, opts.substeps, Start::Measured) else {
        let diverged = LevelGap {
            level: w,
            origin: data.origins[w].clone(),
            gap: Some(f64::INFINITY),
            pathwise: Some(f64::INFINITY),
            signals: vec![],
            diverged: true,
        };
        return (diverged, None);
    };
    let mut signals = Vec::new();
    let mut spectra = Vec::new();
    for name in usable {
        let (Some(y), Some(m)) = (sim.column(name), rec.column(name)) else {
            continue;
        };
        let (y, m) = (&y[start..], &m[start..]);
        let Some(s) = signal_gap(name, unit_of(ir, name), y, m, rec.ts) else {
            continue;
        };
        signals.push(s);
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
    let gap = mean_over(&signals, |s| s.statistical);
    let pathwise = mean_over(&signals, |s| s.nrmse);
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

/// The response signals of level `w` whose measured response varies after the discard
/// (the first `start` samples): the others have no gap.
fn varying<'d>(data: &'d Data, w: usize, start: usize) -> Vec<&'d String> {
    let rec = &data.records[w];
    data.response
        .iter()
        .filter(|name| {
            rec.column(name).is_some_and(|m| {
                let s = metrics::std_dev(&m[start.min(m.len())..]);
                s.is_finite() && s > 0.0
            })
        })
        .collect()
}

/// The mean of `f` over the signals; infinite when not finite, which happens only when
/// the simulated response is not (a run that escaped the divergence check): it counts as
/// diverged.
fn mean_over(signals: &[SignalGap], f: fn(&SignalGap) -> f64) -> f64 {
    let v = signals.iter().map(f).sum::<f64>() / signals.len() as f64;
    if v.is_finite() {
        v
    } else {
        f64::INFINITY
    }
}

/// The gap of one signal: its simulated `y` against its measured `m` (after the discard).
/// `None` when the record is too short for a spectrum or has no power outside DC.
fn signal_gap(name: &str, unit: &str, y: &[f64], m: &[f64], ts: f64) -> Option<SignalGap> {
    let (_, pm) = metrics::welch(m, ts, 4096);
    let (_, ps) = metrics::welch(y, ts, 4096);
    let sm = metrics::std_dev(m);
    if pm.iter().skip(1).sum::<f64>().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let psd_gap = metrics::psd_gap(&ps, &pm);
    let std_diff = metrics::std_dev(y) - sm;
    let std_error = 100.0 * std_diff / sm;
    let rms_error = (y.iter().zip(m).map(|(a, b)| (a - b) * (a - b)).sum::<f64>()
        / m.len().max(1) as f64)
        .sqrt();
    let spectral = metrics::spectral_error(psd_gap);
    Some(SignalGap {
        signal: name.to_string(),
        nrmse: 100.0 * metrics::nrmse(y, m),
        std_error,
        psd_gap,
        spectral,
        statistical: 0.5 * (spectral + std_error.abs()),
        unit: unit.into(),
        rms_error,
        std_diff,
    })
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
