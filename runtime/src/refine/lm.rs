//! The Levenberg–Marquardt iteration over the problem's sub-records, and what is read off
//! its end: the parameters' standard errors (SVD of the shared factor) and the
//! whole-record score that decides whether the fitted values are applied.

use super::problem::{total, Fail, Problem};
use super::qr::{self, Block, RowQr};
use super::{Progress, RefineError, RefineOptions};

/// Where the iteration stopped.
pub(super) struct Iterated {
    /// The unknowns' values at the last accepted step.
    pub(super) theta: Vec<f64>,
    /// The sub-records' factors at those values.
    pub(super) cur: Vec<RowQr>,
    /// Local unknowns of each sub-record.
    pub(super) nls: Vec<usize>,
    /// Summed cost at the start values and at the end.
    pub(super) cost_start: f64,
    pub(super) cost: f64,
    /// Residual rows over all sub-records.
    pub(super) n_rows: usize,
    pub(super) iterations: usize,
    pub(super) converged: bool,
}

/// Levenberg–Marquardt from `start` with Moré's column scaling; `progress` after every
/// iteration.
pub(super) fn iterate(
    pb: &Problem,
    start: &[f64],
    opts: &RefineOptions,
    progress: &dyn Fn(Progress),
) -> Result<Iterated, RefineError> {
    let np = pb.unknowns.len();
    let nls: Vec<usize> = pb.segments.iter().map(|s| s.locals(pb.nb)).collect();
    let mut theta = start.to_vec();
    let mut x0: Vec<Vec<f64>> = pb.segments.iter().map(|s| pb.measured_state(*s)).collect();
    let mut cur = pb.evaluate(&theta, &x0).map_err(|f| match f {
        Fail::Diverged { record, time } => RefineError::StartDiverged { record, time },
        Fail::Model(e) => RefineError::Sim(e),
    })?;
    let cost_start = total(&cur);
    let mut cost = cost_start;
    let mut lambda = 1e-3;
    let mut d_local: Vec<Vec<f64>> = nls.iter().map(|&nl| vec![0.0; nl]).collect();
    let mut d_shared = vec![0.0; np];
    let mut iterations = 0;
    let mut converged = false;
    let n_rows: usize = cur.iter().map(|f| f.rows).sum();
    while iterations < opts.max_iter {
        iterations += 1;
        scale_columns(&cur, &nls, &mut d_local, &mut d_shared);
        let blocks: Vec<Block> = cur
            .iter()
            .zip(&nls)
            .map(|(qr, &nl)| Block { qr, nl })
            .collect();
        let (dp, dl) = qr::lm_step(&blocks, np, lambda, &d_local, &d_shared, 1e-12);
        let theta_new: Vec<f64> = theta
            .iter()
            .zip(&dp)
            .zip(&pb.pscale)
            .map(|((t, d), s)| t + d * s)
            .collect();
        // A sub-record without local unknowns keeps its measured state.
        let x0_new: Vec<Vec<f64>> = x0
            .iter()
            .zip(&dl)
            .map(|(x, d)| {
                x.iter()
                    .enumerate()
                    .map(|(i, a)| a + d.get(i).copied().unwrap_or(0.0))
                    .collect()
            })
            .collect();
        // A trial that diverges or whose model cannot be built counts as a failed step.
        converged = match pb.evaluate(&theta_new, &x0_new) {
            Ok(f) if total(&f) < cost => {
                let c = total(&f);
                let gain = (cost - c) / cost;
                theta = theta_new;
                x0 = x0_new;
                cur = f;
                cost = c;
                lambda = (lambda * 0.3).max(1e-12);
                gain < opts.tol
            }
            _ => {
                lambda *= 10.0;
                // No step in any direction lowers the cost: a (local) minimum.
                lambda > 1e10
            }
        };
        progress(Progress {
            iteration: iterations,
            max_iter: opts.max_iter,
            cost: cost / n_rows.max(1) as f64,
        });
        if converged {
            break;
        }
    }
    Ok(Iterated {
        theta,
        cur,
        nls,
        cost_start,
        cost,
        n_rows,
        iterations,
        converged,
    })
}

/// Moré's scaling: the largest column norms seen so far, local and shared.
fn scale_columns(cur: &[RowQr], nls: &[usize], d_local: &mut [Vec<f64>], d_shared: &mut [f64]) {
    for (d, f) in d_local.iter_mut().zip(cur) {
        for (k, dk) in d.iter_mut().enumerate() {
            *dk = f64::max(*dk, f.column_norm(k)).max(f64::MIN_POSITIVE);
        }
    }
    for (k, dk) in d_shared.iter_mut().enumerate() {
        let n2: f64 = cur
            .iter()
            .zip(nls)
            .map(|(f, &nl)| f.column_norm(nl + k).powi(2))
            .sum();
        *dk = f64::max(*dk, n2.sqrt()).max(f64::MIN_POSITIVE);
    }
}

/// The unknowns' standard errors (`σ̂² (FᵀF)⁻¹` with the initial states profiled out, by
/// SVD of the shared factor `F`) and the condition number of `F`.
pub(super) fn standard_errors(pb: &Problem, it: &Iterated) -> (Vec<f64>, f64) {
    let np = pb.unknowns.len();
    let blocks: Vec<Block> = it
        .cur
        .iter()
        .zip(&it.nls)
        .map(|(qr, &nl)| Block { qr, nl })
        .collect();
    let f = qr::shared_factor(&blocks, np);
    let svd = f.svd(false, true);
    let dof = it
        .n_rows
        .saturating_sub(np + it.nls.iter().sum::<usize>())
        .max(1);
    let sigma2 = it.cost / dof as f64;
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    let vt = svd.v_t.expect("invariant: V requested");
    let stderr: Vec<f64> = (0..np)
        .map(|k| {
            let var: f64 = svd
                .singular_values
                .iter()
                .enumerate()
                .map(|(i, &s)| {
                    if s > 1e-12 * smax {
                        (vt[(i, k)] / s).powi(2)
                    } else {
                        f64::INFINITY
                    }
                })
                .sum();
            (sigma2 * var).sqrt() * pb.pscale[k]
        })
        .collect();
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    (stderr, condition)
}

/// The whole-record score of the start values and of the fitted ones.
pub(super) struct Score {
    pub(super) free_run_start: f64,
    pub(super) free_run_end: f64,
    pub(super) applied: bool,
    pub(super) note: Option<String>,
}

/// The score: whole records from their measured states, at the start values and at the
/// fitted ones (`records`: how many records the problem cut into sub-records). Without
/// sub-records it is the cost itself, which only accepted (lower) steps changed.
pub(super) fn score(
    pb: &Problem,
    records: usize,
    start: &[f64],
    opts: &RefineOptions,
    it: &Iterated,
) -> Score {
    let n_rows = it.n_rows;
    let whole = pb.segments.len() == records && !opts.estimate_initial;
    let (free_run_start, free_run_end) = if whole {
        (it.cost_start / n_rows as f64, it.cost / n_rows as f64)
    } else {
        (
            pb.free_run_cost(start) / n_rows as f64,
            pb.free_run_cost(&it.theta) / n_rows as f64,
        )
    };
    let applied = opts.estimate_initial || free_run_end <= free_run_start;
    let note = (!applied).then(|| {
        format!(
            "not applied: fitted on {} sub-records (multiple shooting), the values give a \
             worse free run of whole records from their measured states ({} → {}, weighted \
             mean square); the start values are kept — refine without sub-records or with \
             longer ones",
            pb.segments.len(),
            dynid_ir::num::sig(free_run_start, 4, false),
            if free_run_end.is_finite() {
                dynid_ir::num::sig(free_run_end, 4, false)
            } else {
                "a divergence".to_string()
            }
        )
    });
    Score {
        free_run_start,
        free_run_end,
        applied,
        note,
    }
}
