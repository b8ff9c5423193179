//! Output-error refinement: starting from the covariance estimate, minimise the free-run
//! (simulation) error of the model over its unknown parameters.
//!
//! # What is minimised
//!
//! Every record (level) is cut into sub-records of at most [`RefineOptions::segment`]
//! samples (multiple shooting; by default one sub-record per record). Each sub-record is
//! simulated from its own initial state, driven by the measured inputs exactly as
//! [`crate::sim::simulate_driven_from`] does (RK4, `substeps` steps per sample interval,
//! inputs linear between samples). Every record's first sub-record starts from the
//! measured state ([`FREE_RUN_START`]), as every free-run score of dynid does, so that the
//! cost minimised over whole records is the score printed afterwards. With multiple
//! shooting the initial states of the later sub-records are unknowns of their sub-record,
//! started from the measured state; a divergence or a drifting phase then spoils only one
//! sub-record. The cost is
//!
//! ```text
//! J(p, x0_1, …) = Σ_records Σ_samples Σ_signals (w_s (y_s,sim − y_s,meas) / σ_s)²
//! ```
//!
//! over the measured positions and velocities `s` (σ_s: the signal's standard deviation over
//! all records, so signals of different units weigh alike; `w_s` = 1 unless given).
//!
//! # How
//!
//! Levenberg–Marquardt with Moré's column scaling. The Jacobian comes from forward
//! sensitivities of the simulation ([`sens`]: dual numbers through the model's tape and the
//! RK4 steps), never from finite differences of whole simulations. Its rows are folded into
//! a triangular factor by Givens rotations as they are produced (the Jacobian is not
//! stored and `JᵀJ` is never formed); each sub-record's initial state is eliminated from
//! its own factor by QR, and the shared step is solved by SVD ([`qr`]).
//!
//! # Standard errors
//!
//! From the final Jacobian with the initial states profiled out:
//! `cov(p) = σ̂² (FᵀF)⁻¹` (SVD of `F`), `σ̂² = J / (N − n_unknowns)`. They assume white
//! residuals; free-run residuals are correlated in time, so read them as lower bounds and
//! compare them between parameters, not with the covariance method's batch-means errors.
//!
//! # The score
//!
//! Cut into sub-records, the cost is not the free run of whole records: a fit whose
//! whole-record free-run cost (from the measured state, the same weights) ends above its
//! start is not applied — the start values are kept and [`Refinement::note`] says why.
//!
//! Shape parameters (`deadzone(s, g ~ …)`) stay at their values; models with control laws
//! are refused (the law would have to be differentiated as well).

mod qr;
mod sens;

use crate::describe::std_dev;
use crate::ident::Identification;
use crate::record::Record;
pub use crate::sim::FREE_RUN_START;
use crate::sim::{parameter_values, simulate_driven_from, SimError, Start};
use dynid_ir::ir::{ModelIr, SignalKind};
use qr::{Block, RowQr};
use rayon::prelude::*;
use sens::{SensModel, SensRk4};
use serde::Serialize;

/// Settings of [`refine`].
#[derive(Clone, Debug)]
pub struct RefineOptions {
    /// RK4 sub-steps per sample interval (as in the driven simulation).
    pub substeps: usize,
    /// Longest sub-record in samples (multiple shooting); `None`: one per record.
    pub segment: Option<usize>,
    /// Weights `(signal, w)` of measured positions or velocities; others weigh 1.
    pub weights: Vec<(String, f64)>,
    /// Most Levenberg–Marquardt iterations (accepted or rejected steps).
    pub max_iter: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub tol: f64,
    /// Fit every record's initial state too (a procedure with a score of its own, such as
    /// the Silverbox benchmark's from rest); by default a record's first sub-record starts
    /// from the measured state ([`FREE_RUN_START`]) as every free-run score does, and a
    /// fit whose score ends worse than its start is not applied.
    pub estimate_initial: bool,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            substeps: crate::sim::DEFAULT_SUBSTEPS,
            segment: None,
            weights: Vec::new(),
            max_iter: 60,
            tol: 1e-9,
            estimate_initial: false,
        }
    }
}

/// Errors of the refinement.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum RefineError {
    #[error("the model has no unknown parameters to refine")]
    #[diagnostic(
        code(dynid::refine::no_unknowns),
        help("declare the parameters to refine without a value (e.g. `param k`)")
    )]
    NoUnknowns,
    #[error(
        "the model `{model}` has control laws; the refinement simulates open-loop models only \
         (refused before any work)"
    )]
    #[diagnostic(
        code(dynid::refine::control),
        help("refine the plant model without its `reference` and `control` lines, driven by the recorded controller output (the controlled input's column), in sub-records of a fraction of a second (`--shooting 0.5`: a plant that integrates its force drifts over a whole record driven by it); or leave out --refine")
    )]
    ControlLaws { model: String },
    #[error("{got} start values for {expected} unknown parameters")]
    #[diagnostic(
        code(dynid::refine::start),
        help("give one start value per unknown parameter, in declaration order")
    )]
    StartLength { got: usize, expected: usize },
    #[error("the start value of `{name}` is {value}")]
    #[diagnostic(
        code(dynid::refine::start),
        help("start from finite values, e.g. the covariance estimate")
    )]
    BadStart { name: String, value: f64 },
    #[error("the model measures no position or velocity to compare with a simulation")]
    #[diagnostic(
        code(dynid::refine::no_output),
        help("add a measured position to the model's `measure` line")
    )]
    NoOutput,
    #[error("weight of `{signal}`: {what}")]
    #[diagnostic(
        code(dynid::refine::weight),
        help("weigh the measured positions or velocities of the model ({choices}) with finite values ≥ 0, at least one > 0")
    )]
    BadWeight {
        signal: String,
        what: String,
        choices: String,
    },
    #[error("record {record} has no column `{signal}`")]
    #[diagnostic(
        code(dynid::refine::column),
        help("every record needs the model's measured signals and inputs (found: {found})")
    )]
    MissingColumn {
        record: usize,
        signal: String,
        found: String,
    },
    #[error("record {record}: {what}")]
    #[diagnostic(
        code(dynid::refine::record),
        help("give uniformly sampled records with at least 3 finite samples per sub-record (`segment` ≥ 3)")
    )]
    BadRecord { record: usize, what: String },
    #[error("the simulation at the start values diverges in record {record} near t = {time:.6} s")]
    #[diagnostic(
        code(dynid::refine::start_diverged),
        help("the start model is unstable on this data: use shorter sub-records (multiple shooting, `segment`), or check the start values")
    )]
    StartDiverged { record: usize, time: f64 },
    #[error(transparent)]
    #[diagnostic(transparent)]
    Sim(#[from] SimError),
}

/// One refined parameter.
#[derive(Clone, Debug, Serialize)]
pub struct RefinedParam {
    pub name: String,
    /// The start value (the covariance estimate).
    pub start: f64,
    pub value: f64,
    /// From the final Jacobian, assuming white residuals (a lower bound).
    pub stderr: f64,
}

/// Result of [`refine`].
#[derive(Clone, Debug, Serialize)]
pub struct Refinement {
    pub params: Vec<RefinedParam>,
    /// Levenberg–Marquardt iterations (simulations with sensitivities after the first).
    pub iterations: usize,
    /// An accepted step changed the cost by less than `tol` (else: iteration limit, or no
    /// step lowers the cost any more).
    pub converged: bool,
    /// Weighted mean-square free-run error per residual at the start and at the end.
    pub cost_start: f64,
    pub cost_end: f64,
    /// Sub-records (shooting segments) over all records, and residual samples.
    pub segments: usize,
    pub samples: usize,
    /// The compared signals with their weights `w_s / σ_s`.
    pub signals: Vec<(String, f64)>,
    /// Condition number of the parameters' scaled Jacobian (initial states profiled out).
    pub condition: f64,
    /// The weighted mean-square free-run error per residual of whole records, every
    /// record simulated from its measured state ([`FREE_RUN_START`]), at the start values
    /// and at the values the fit reached. Without sub-records these are `cost_start` and
    /// `cost_end`. `free_run_end` is `f64::MAX` when the fitted values' free run diverges.
    pub free_run_start: f64,
    pub free_run_end: f64,
    /// The fitted values were kept; `false`: their whole-record free run is worse than the
    /// start's (or diverges), and `params[..].value` are the start values.
    pub applied: bool,
    /// Why the fitted values were not applied.
    pub note: Option<String>,
    /// How every free run of the score starts.
    pub initial_state: &'static str,
}

impl Refinement {
    /// Refined values in the order of [`ModelIr::unknowns`].
    pub fn values(&self) -> Vec<f64> {
        self.params.iter().map(|p| p.value).collect()
    }
}

/// The covariance estimate as start values (order of [`ModelIr::unknowns`]); a parameter
/// the identification left out or could not resolve starts at 0.
pub fn start_from(ir: &ModelIr, id: &Identification) -> Vec<f64> {
    ir.unknowns()
        .iter()
        .map(|p| {
            id.param(&ir.params[p.index()].name)
                .map_or(0.0, |e| e.value)
        })
        .collect()
}

/// A sub-record: samples `[start, end)` of record `record`.
#[derive(Clone, Copy, Debug)]
struct Segment {
    record: usize,
    start: usize,
    end: usize,
    /// The initial state is fitted even for a record's first sub-record.
    estimated: bool,
}

impl Segment {
    /// Local unknowns (initial positions and velocities) of the sub-record: none for a
    /// record's first, which starts from the measured state.
    fn locals(&self, nb: usize) -> usize {
        if self.start == 0 && !self.estimated {
            0
        } else {
            2 * nb
        }
    }
}

/// Where the refinement stands after an iteration (for a progress display).
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Iterations done and the most allowed.
    pub iteration: usize,
    pub max_iter: usize,
    /// The cost (weighted mean square per residual) at the current values.
    pub cost: f64,
}

/// The fixed part of the problem: data columns, segments and weights.
/// A compared signal of one record: `(state index, is velocity, column, weight)`.
type Compared<'a> = (usize, bool, &'a [f64], f64);

struct Problem<'a> {
    ir: &'a ModelIr,
    nb: usize,
    unknowns: Vec<dynid_ir::ir::ParamId>,
    /// Per record: input columns (model input order).
    inputs: Vec<Vec<&'a [f64]>>,
    /// Per record: `(state index, is velocity, column, weight)` of the compared signals.
    outputs: Vec<Vec<Compared<'a>>>,
    ts: Vec<f64>,
    t0: Vec<f64>,
    segments: Vec<Segment>,
    /// Parameter column scales (|start|, or 1 for a start at 0).
    pscale: Vec<f64>,
    limit: f64,
    substeps: usize,
    signals: Vec<(String, f64)>,
}

/// Minimise the free-run error of `ir` on `records` over its unknown parameters, from
/// `start` (one value per unknown in [`ModelIr::unknowns`] order, e.g. [`start_from`]).
/// Known parameters keep their values.
pub fn refine(
    ir: &ModelIr,
    records: &[Record],
    start: &[f64],
    opts: &RefineOptions,
) -> Result<Refinement, RefineError> {
    refine_with_progress(ir, records, start, opts, &|_| {})
}

/// [`refine`], calling `progress` after every iteration.
pub fn refine_with_progress(
    ir: &ModelIr,
    records: &[Record],
    start: &[f64],
    opts: &RefineOptions,
    progress: &dyn Fn(Progress),
) -> Result<Refinement, RefineError> {
    let pb = Problem::new(ir, records, start, opts)?;
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
        // Moré's scaling: the largest column norms seen so far.
        for (d, f) in d_local.iter_mut().zip(&cur) {
            for (k, dk) in d.iter_mut().enumerate() {
                *dk = f64::max(*dk, f.column_norm(k)).max(f64::MIN_POSITIVE);
            }
        }
        for (k, dk) in d_shared.iter_mut().enumerate() {
            let n2: f64 = cur
                .iter()
                .zip(&nls)
                .map(|(f, &nl)| f.column_norm(nl + k).powi(2))
                .sum();
            *dk = f64::max(*dk, n2.sqrt()).max(f64::MIN_POSITIVE);
        }
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
    let blocks: Vec<Block> = cur
        .iter()
        .zip(&nls)
        .map(|(qr, &nl)| Block { qr, nl })
        .collect();
    let f = qr::shared_factor(&blocks, np);
    let svd = f.svd(false, true);
    let dof = n_rows.saturating_sub(np + nls.iter().sum::<usize>()).max(1);
    let sigma2 = cost / dof as f64;
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
    // The score: whole records from their measured states. Without sub-records it is the
    // cost itself, which only accepted (lower) steps changed.
    let whole = pb.segments.len() == records.len() && !opts.estimate_initial;
    let (free_run_start, free_run_end) = if whole {
        (cost_start / n_rows as f64, cost / n_rows as f64)
    } else {
        (
            pb.free_run_cost(start) / n_rows as f64,
            pb.free_run_cost(&theta) / n_rows as f64,
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
    if !applied {
        theta = start.to_vec();
    }
    Ok(Refinement {
        params: pb
            .unknowns
            .iter()
            .enumerate()
            .map(|(k, p)| RefinedParam {
                name: ir.params[p.index()].name.clone(),
                start: start[k],
                value: theta[k],
                stderr: stderr[k],
            })
            .collect(),
        iterations,
        converged,
        cost_start: cost_start / n_rows as f64,
        cost_end: cost / n_rows as f64,
        segments: pb.segments.len(),
        samples: n_rows / pb.outputs[0].len().max(1),
        signals: pb.signals.clone(),
        condition: if smin > 0.0 {
            smax / smin
        } else {
            f64::INFINITY
        },
        free_run_start,
        free_run_end: if free_run_end.is_finite() {
            free_run_end
        } else {
            f64::MAX
        },
        applied,
        note,
        initial_state: FREE_RUN_START,
    })
}

fn total(f: &[RowQr]) -> f64 {
    f.iter().map(|q| q.cost).sum()
}

/// Why a simulation with sensitivities gave no rows.
enum Fail {
    /// Record (1-based) and time where a sub-record diverged.
    Diverged { record: usize, time: f64 },
    /// The model cannot be simulated at these values (e.g. a zero mass).
    Model(SimError),
}

impl<'a> Problem<'a> {
    fn new(
        ir: &'a ModelIr,
        records: &'a [Record],
        start: &[f64],
        opts: &RefineOptions,
    ) -> Result<Self, RefineError> {
        let unknowns = ir.unknowns();
        if unknowns.is_empty() {
            return Err(RefineError::NoUnknowns);
        }
        if !ir.controls.is_empty() {
            return Err(RefineError::ControlLaws {
                model: ir.name.clone(),
            });
        }
        if start.len() != unknowns.len() {
            return Err(RefineError::StartLength {
                got: start.len(),
                expected: unknowns.len(),
            });
        }
        for (p, v) in unknowns.iter().zip(start) {
            if !v.is_finite() {
                return Err(RefineError::BadStart {
                    name: ir.params[p.index()].name.clone(),
                    value: *v,
                });
            }
        }
        if opts.substeps == 0 {
            return Err(SimError::BadInputData {
                what: "substeps is 0 (use at least 1)".into(),
            }
            .into());
        }
        // The compared signals: measured positions and velocities.
        let compared: Vec<(usize, bool, String)> = ir
            .signals
            .iter()
            .filter(|s| s.measured)
            .filter_map(|s| match s.kind {
                SignalKind::Position(b) => Some((b.index(), false, s.name.clone())),
                SignalKind::Velocity(b) => Some((b.index(), true, s.name.clone())),
                _ => None,
            })
            .collect();
        if compared.is_empty() {
            return Err(RefineError::NoOutput);
        }
        let choices = compared
            .iter()
            .map(|c| c.2.as_str())
            .collect::<Vec<_>>()
            .join(", ");
        let mut weight = vec![1.0; compared.len()];
        for (name, w) in &opts.weights {
            let bad = |what: String| RefineError::BadWeight {
                signal: name.clone(),
                what,
                choices: choices.clone(),
            };
            let i = compared
                .iter()
                .position(|c| c.2 == *name)
                .ok_or_else(|| bad("not a measured position or velocity of the model".into()))?;
            if !(w.is_finite() && *w >= 0.0) {
                return Err(bad(format!("{w} is not a finite value ≥ 0")));
            }
            weight[i] = *w;
        }
        if weight.iter().all(|w| *w == 0.0) {
            return Err(RefineError::BadWeight {
                signal: choices.clone(),
                what: "every weight is 0".into(),
                choices,
            });
        }
        if records.is_empty() {
            return Err(RefineError::BadRecord {
                record: 0,
                what: "no records".into(),
            });
        }
        let column = |r: usize, name: &str| -> Result<&'a [f64], RefineError> {
            let rec = &records[r];
            let c = rec.column(name).ok_or_else(|| RefineError::MissingColumn {
                record: r + 1,
                signal: name.to_string(),
                found: rec.names.join(", "),
            })?;
            if let Some(i) = c.iter().position(|x| !x.is_finite()) {
                return Err(RefineError::BadRecord {
                    record: r + 1,
                    what: format!(
                        "column `{name}` has the non-finite value {} at sample {i}",
                        c[i]
                    ),
                });
            }
            Ok(c)
        };
        let mut inputs = Vec::new();
        let mut cols: Vec<Vec<&[f64]>> = Vec::new();
        let (mut ts, mut t0) = (Vec::new(), Vec::new());
        for (r, rec) in records.iter().enumerate() {
            if !(rec.ts.is_finite() && rec.ts > 0.0) {
                return Err(RefineError::BadRecord {
                    record: r + 1,
                    what: format!("sample interval {} is not positive", rec.ts),
                });
            }
            inputs.push(
                ir.inputs
                    .iter()
                    .map(|i| column(r, &i.name))
                    .collect::<Result<Vec<_>, _>>()?,
            );
            cols.push(
                compared
                    .iter()
                    .map(|c| column(r, &c.2))
                    .collect::<Result<Vec<_>, _>>()?,
            );
            ts.push(rec.ts);
            t0.push(rec.t0);
        }
        // σ_s over all records.
        let sigma: Vec<f64> = (0..compared.len())
            .map(|i| {
                let all: Vec<f64> = cols.iter().flat_map(|c| c[i].iter().copied()).collect();
                let s = std_dev(&all);
                if s > 0.0 && s.is_finite() {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        let scale: Vec<f64> = weight.iter().zip(&sigma).map(|(w, s)| w / s).collect();
        let outputs = cols
            .iter()
            .map(|c| {
                compared
                    .iter()
                    .zip(c)
                    .zip(&scale)
                    .map(|((cmp, col), w)| (cmp.0, cmp.1, *col, *w))
                    .collect()
            })
            .collect();
        let mut segments = Vec::new();
        for (r, rec) in records.iter().enumerate() {
            let n = rec.len();
            let max = opts.segment.unwrap_or(n).max(1);
            let k = n.div_ceil(max).max(1);
            for j in 0..k {
                let (a, b) = (j * n / k, (j + 1) * n / k);
                if b - a < 3 {
                    return Err(RefineError::BadRecord {
                        record: r + 1,
                        what: format!("a sub-record of {} samples", b - a),
                    });
                }
                segments.push(Segment {
                    record: r,
                    start: a,
                    end: b,
                    estimated: opts.estimate_initial,
                });
            }
        }
        let spread = inputs
            .iter()
            .flatten()
            .chain(cols.iter().flatten())
            .map(|c| std_dev(c))
            .fold(0.0, f64::max);
        Ok(Problem {
            ir,
            nb: ir.bodies.len(),
            pscale: start
                .iter()
                .map(|v| if *v != 0.0 { v.abs() } else { 1.0 })
                .collect(),
            unknowns,
            inputs,
            outputs,
            ts,
            t0,
            segments,
            limit: 1e6 * (1.0 + spread),
            substeps: opts.substeps,
            signals: compared
                .iter()
                .zip(&scale)
                .map(|(c, w)| (c.2.clone(), *w))
                .collect(),
        })
    }

    /// Every parameter's value with the unknowns at `theta`.
    fn params(&self, theta: &[f64]) -> Vec<f64> {
        let mut ir_values: Vec<f64> = self
            .ir
            .params
            .iter()
            .map(|p| p.nominal().unwrap_or(0.0))
            .collect();
        for (p, v) in self.unknowns.iter().zip(theta) {
            ir_values[p.index()] = *v;
        }
        ir_values
    }

    /// The state at the first sample of `s`, as `Start::Measured` takes it.
    fn measured_state(&self, s: Segment) -> Vec<f64> {
        let nb = self.nb;
        let mut x0 = vec![0.0; 2 * nb];
        let ts = self.ts[s.record];
        for &(b, vel, col, _) in &self.outputs[s.record] {
            if !vel {
                let x = &col[s.start..];
                x0[b] = x[0];
                if x0[nb + b] == 0.0 {
                    x0[nb + b] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * ts);
                }
            }
        }
        for &(b, vel, col, _) in &self.outputs[s.record] {
            if vel {
                x0[nb + b] = col[s.start];
            }
        }
        x0
    }

    /// Σ of the squared weighted residuals of whole records simulated from their measured
    /// states at `theta` (the score; infinite when a run diverges or cannot be built).
    fn free_run_cost(&self, theta: &[f64]) -> f64 {
        let fitted = self.ir.with_nominals(theta);
        let runs = (0..self.inputs.len())
            .into_par_iter()
            .map(|r| {
                let rec = self.record(r);
                let sim = simulate_driven_from(&fitted, &rec, self.substeps, Start::Measured)
                    .map_err(|_| ())?;
                let mut c = 0.0;
                for &(b, vel, col, wt) in &self.outputs[r] {
                    let name = &self.ir.signals[2 * b + usize::from(vel)].name;
                    let y = sim.column(name).ok_or(())?;
                    c += y
                        .iter()
                        .zip(col)
                        .map(|(a, m)| (wt * (a - m)).powi(2))
                        .sum::<f64>();
                }
                Ok::<f64, ()>(c)
            })
            .collect::<Vec<_>>();
        runs.into_iter().map(|c| c.unwrap_or(f64::INFINITY)).sum()
    }

    /// Record `r` with the columns the driven run reads: the inputs and compared signals.
    fn record(&self, r: usize) -> Record {
        let mut names = Vec::new();
        let mut columns = Vec::new();
        for (i, c) in self.ir.inputs.iter().zip(&self.inputs[r]) {
            names.push(i.name.clone());
            columns.push(c.to_vec());
        }
        for &(b, vel, col, _) in &self.outputs[r] {
            names.push(self.ir.signals[2 * b + usize::from(vel)].name.clone());
            columns.push(col.to_vec());
        }
        Record {
            names,
            columns,
            ts: self.ts[r],
            t0: self.t0[r],
        }
    }

    /// Simulate all segments with sensitivities and fold their rows.
    fn evaluate(&self, theta: &[f64], x0: &[Vec<f64>]) -> Result<Vec<RowQr>, Fail> {
        let params = self.params(theta);
        let mut direction = vec![None; self.ir.params.len()];
        for (k, p) in self.unknowns.iter().enumerate() {
            direction[p.index()] = Some(k);
        }
        let model = SensModel::new(self.ir, &params, &direction).map_err(Fail::Model)?;
        crate::first_error_in_order(
            self.segments
                .par_iter()
                .zip(x0)
                .map(|(s, x)| self.segment_with(&model, *s, x)),
        )
    }

    fn segment_with(&self, m: &SensModel, s: Segment, x0: &[f64]) -> Result<RowQr, Fail> {
        let (nb, q) = (self.nb, m.q);
        let w = 1 + q;
        let ts = self.ts[s.record];
        let mut rk = SensRk4::new(m, &x0[..nb], &x0[nb..]);
        // The columns kept: the initial state's only where it is a local unknown.
        let skip = 2 * nb - s.locals(nb);
        let mut qr = RowQr::new(q - skip);
        let mut row = vec![0.0; q - skip];
        let inputs = &self.inputs[s.record];
        let mut u0 = vec![0.0; inputs.len()];
        let mut u1 = vec![0.0; inputs.len()];
        for k in s.start..s.end {
            for &(b, vel, col, wt) in &self.outputs[s.record] {
                let st = if vel { &rk.v } else { &rk.x };
                let res = wt * (st[b * w] - col[k]);
                for (i, r) in row.iter_mut().enumerate() {
                    let j = i + skip;
                    let scale = if j < 2 * nb {
                        1.0
                    } else {
                        self.pscale[j - 2 * nb]
                    };
                    *r = wt * st[b * w + 1 + j] * scale;
                }
                qr.push(&mut row, res);
            }
            if k + 1 == s.end {
                break;
            }
            for (j, c) in inputs.iter().enumerate() {
                u0[j] = c[k];
                u1[j] = c[k + 1];
            }
            rk.advance(m, &u0, &u1, ts, self.substeps);
            let mag = rk.magnitude(w);
            if !(mag.is_finite() && mag <= self.limit) {
                return Err(Fail::Diverged {
                    record: s.record + 1,
                    time: self.t0[s.record] + ts * (k + 1) as f64,
                });
            }
        }
        Ok(qr)
    }
}

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

#[cfg(test)]
mod tests;
