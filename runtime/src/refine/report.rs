//! The refinement as the commands and the Python package report it: the free-run errors
//! of the start and the refined values on the estimation and test records, and the
//! corrected model of a diagnosis refined on every level.

use super::{refine_with_progress, Progress, RefineError, RefineOptions, Refinement};
use crate::describe::std_dev;
use crate::record::Record;
use crate::sim::{parameter_values, simulate_driven_from, SimError, Start};
use dynid_ir::ir::{ModelIr, SignalKind};
use rayon::prelude::*;
use serde::Serialize;

/// Free-run RMS error of one signal.
#[derive(Clone, Debug, Serialize)]
pub struct FreeRunError {
    pub signal: String,
    /// Root mean square of simulated − measured over all samples of all records.
    pub rms: f64,
    /// `rms` divided by the signal's standard deviation over all records.
    pub relative: f64,
}

/// Free-run errors of `ir` (unknowns at `values`) on `records`: each record simulated by
/// [`simulate_driven_from`] from the measured state of its first sample, errors pooled
/// over the records, one per measured position and velocity.
pub fn free_run_errors(
    ir: &ModelIr,
    values: &[f64],
    records: &[Record],
    substeps: usize,
) -> Result<Vec<FreeRunError>, SimError> {
    let fitted = ir.with_nominals(values);
    parameter_values(&fitted)?;
    let sims = crate::first_error_in_order(
        records
            .par_iter()
            .map(|r| simulate_driven_from(&fitted, r, substeps, Start::Measured)),
    )?;
    let mut out = Vec::new();
    for s in ir.signals.iter().filter(|s| {
        s.measured && matches!(s.kind, SignalKind::Position(_) | SignalKind::Velocity(_))
    }) {
        let (mut e2, mut n, mut all) = (0.0, 0usize, Vec::new());
        for (rec, sim) in records.iter().zip(&sims) {
            let (Some(m), Some(y)) = (rec.column(&s.name), sim.column(&s.name)) else {
                continue;
            };
            e2 += m.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            n += m.len();
            all.extend_from_slice(m);
        }
        let rms = (e2 / n.max(1) as f64).sqrt();
        out.push(FreeRunError {
            signal: s.name.clone(),
            rms,
            relative: rms / std_dev(&all),
        });
    }
    Ok(out)
}

/// The refinement and the free-run errors of both estimates (JSON `refined`).
#[derive(Debug, Serialize)]
pub struct RefineReport {
    pub refinement: Refinement,
    /// Free-run errors on the estimation records: start values, refined values.
    pub estimation: (Vec<FreeRunError>, Vec<FreeRunError>),
    /// The same on the test records (empty without them).
    pub test: (Vec<FreeRunError>, Vec<FreeRunError>),
}

impl RefineReport {
    /// Refine `start` on the estimation records `est` and score both value sets on `est`
    /// and on the `test` records; `progress` is called after every iteration.
    pub fn compute(
        ir: &ModelIr,
        start: &[f64],
        est: &[Record],
        test: &[Record],
        opts: &RefineOptions,
        progress: &dyn Fn(Progress),
    ) -> Result<Self, RefineError> {
        let r = refine_with_progress(ir, est, start, opts, progress)?;
        type Errors = (Vec<FreeRunError>, Vec<FreeRunError>);
        let score = |recs: &[Record]| -> Result<Errors, SimError> {
            if recs.is_empty() {
                return Ok((Vec::new(), Vec::new()));
            }
            Ok((
                free_run_errors(ir, start, recs, opts.substeps)?,
                free_run_errors(ir, &r.values(), recs, opts.substeps)?,
            ))
        };
        Ok(RefineReport {
            estimation: score(est)?,
            test: score(test)?,
            refinement: r,
        })
    }
}

/// The corrected model of a diagnosis (`fixed`, compiled from its text) refined by output
/// error on every level with the default settings, starting from the model's own values:
/// the report, and the model's text with the refined values (five significant digits, as
/// the diagnosis writes its values) — `None` when the refinement was not applied, so the
/// corrected model's text stands (the report's note says why).
pub fn refine_corrected(
    fixed: &ModelIr,
    records: &[Record],
    progress: &dyn Fn(Progress),
) -> Result<(RefineReport, Option<String>), RefineError> {
    let start: Vec<f64> = fixed
        .unknowns()
        .iter()
        .map(|p| fixed.params[p.index()].nominal().unwrap_or(0.0))
        .collect();
    let opts = RefineOptions::default();
    let report = RefineReport::compute(fixed, &start, records, &[], &opts, progress)?;
    if !report.refinement.applied {
        return Ok((report, None));
    }
    let mut out = fixed.clone();
    for p in &report.refinement.params {
        // An unknown of the model by construction.
        let _ = out.set_nominal(&p.name, dynid_ir::num::round_sig(p.value, 5));
    }
    Ok((report, Some(dynid_ir::print::to_source(&out))))
}
