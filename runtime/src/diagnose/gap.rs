//! Gap scoring: free-run simulation against the measured records (per signal NRMSE,
//! standard-deviation error and spectral distance), the covariance-equation residual, and
//! both cross-validated over withheld levels.

use super::metrics;
use super::types::{DiagnoseError, DiagnoseOptions, LevelGap, ModelGap, SignalGap};
use crate::data::{DataError, LevelSource, RecordSource};
use crate::ident::{measure, Identification, Moments};
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

/// Free-run gap of `ir` (with its nominal values) on level `w`.
#[allow(clippy::type_complexity)]
pub(super) fn level_gap(
    ir: &ModelIr,
    data: &Data,
    w: usize,
    opts: &DiagnoseOptions,
    want_psd: bool,
) -> (
    LevelGap,
    Option<Vec<(String, Vec<f64>, Vec<f64>, Vec<f64>)>>,
) {
    let rec = &data.records[w];
    let diverged = |origin: &str| LevelGap {
        level: w,
        origin: origin.to_string(),
        gap: f64::INFINITY,
        signals: vec![],
        diverged: true,
    };
    let sim = match simulate_driven_from(ir, rec, opts.substeps, Start::Measured) {
        Ok(s) => s,
        Err(_) => return (diverged(&data.origins[w]), None),
    };
    let start = ((rec.len() as f64) * opts.discard) as usize;
    let mut signals = Vec::new();
    let mut spectra = Vec::new();
    for name in &data.response {
        let (Some(y), Some(m)) = (sim.column(name), rec.column(name)) else {
            continue;
        };
        let (y, m) = (&y[start..], &m[start..]);
        let (f, pm) = metrics::welch(m, rec.ts, 4096);
        let (_, ps) = metrics::welch(y, rec.ts, 4096);
        let sm = metrics::std_dev(m);
        signals.push(SignalGap {
            signal: name.clone(),
            nrmse: 100.0 * metrics::nrmse(y, m),
            std_error: 100.0 * (metrics::std_dev(y) - sm) / sm,
            psd_gap: metrics::psd_gap(&ps, &pm),
        });
        if want_psd {
            spectra.push((name.clone(), f, pm, ps));
        }
    }
    let gap = signals.iter().map(|s| s.nrmse).sum::<f64>() / signals.len().max(1) as f64;
    let gap = if gap.is_finite() { gap } else { f64::INFINITY };
    (
        LevelGap {
            level: w,
            origin: data.origins[w].clone(),
            gap,
            signals,
            diverged: !gap.is_finite(),
        },
        want_psd.then_some(spectra),
    )
}

pub(super) fn mean_gap(levels: &[LevelGap]) -> f64 {
    levels.iter().map(|l| l.gap).sum::<f64>() / levels.len().max(1) as f64
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
) -> Result<Moments<'m>, DiagnoseError> {
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
/// optionally restricted to the rows of one equation.
pub(super) fn cov_residual(m: &Moments, p: &[f64], w: usize, equation: Option<&str>) -> f64 {
    let sys = m.system();
    let n_levels = m.levels().len();
    let per = sys.rows / n_levels;
    let (mut num, mut den) = (0.0, 0.0);
    for r in w * per..(w + 1) * per {
        if let Some(eq) = equation {
            if !sys.row_labels[r].ends_with(&format!("→ {eq}")) {
                continue;
            }
        }
        let row = &sys.c_matrix[r * sys.cols..(r + 1) * sys.cols];
        let norm = (row.iter().map(|x| x * x).sum::<f64>() + sys.rhs[r] * sys.rhs[r]).sqrt();
        if norm == 0.0 {
            continue;
        }
        let cp = row.iter().zip(p).map(|(a, b)| a * b).sum::<f64>();
        let e = cp - sys.rhs[r];
        num += (e / norm).powi(2);
        // Relative to the size of the individual terms: an equation without input has a
        // zero right-hand side, so `c` alone is no scale.
        let terms: f64 =
            row.iter().zip(p).map(|(a, b)| (a * b).powi(2)).sum::<f64>() + sys.rhs[r] * sys.rhs[r];
        den += terms / (norm * norm);
    }
    if den > 0.0 {
        100.0 * (num / den).sqrt()
    } else {
        f64::NAN
    }
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
pub(super) fn cross_validate(m: &Moments, ir: &ModelIr, n: usize) -> (f64, Vec<Identification>) {
    let mut fits = Vec::with_capacity(n);
    let mut res = 0.0;
    for w in 0..n {
        let fit = m.identify_levels(&training(n, w));
        let p = param_vector(ir, &fit);
        res += cov_residual(m, &p, w, None);
        fits.push(fit);
    }
    (res / n as f64, fits)
}

/// Free-run gap with the training fits, each scored on its withheld level.
pub(super) fn cv_gap(
    ir: &ModelIr,
    fits: &[Identification],
    data: &Data,
    opts: &DiagnoseOptions,
    label: &str,
) -> ModelGap {
    let levels: Vec<LevelGap> = fits
        .par_iter()
        .enumerate()
        .map(|(w, fit)| level_gap(&with_values(ir, fit), data, w, opts, false).0)
        .collect();
    ModelGap {
        label: label.into(),
        gap: mean_gap(&levels),
        levels,
    }
}
