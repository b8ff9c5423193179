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

mod lm;
mod problem;
mod qr;
mod report;
mod sens;

use crate::ident::Identification;
use crate::record::Record;
use crate::sim::SimError;
pub use crate::sim::FREE_RUN_START;
use dynid_ir::ir::ModelIr;
use problem::Problem;
pub use report::{free_run_errors, refine_corrected, FreeRunError, RefineReport};
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

/// Where the refinement stands after an iteration (for a progress display).
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Iterations done and the most allowed.
    pub iteration: usize,
    pub max_iter: usize,
    /// The cost (weighted mean square per residual) at the current values.
    pub cost: f64,
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
    let it = lm::iterate(&pb, start, opts, progress)?;
    let (stderr, condition) = lm::standard_errors(&pb, &it);
    let score = lm::score(&pb, records.len(), start, opts, &it);
    let values = if score.applied { &it.theta[..] } else { start };
    let n_rows = it.n_rows as f64;
    Ok(Refinement {
        params: pb
            .unknowns
            .iter()
            .enumerate()
            .map(|(k, p)| RefinedParam {
                name: ir.params[p.index()].name.clone(),
                start: start[k],
                value: values[k],
                stderr: stderr[k],
            })
            .collect(),
        iterations: it.iterations,
        converged: it.converged,
        cost_start: it.cost_start / n_rows,
        cost_end: it.cost / n_rows,
        segments: pb.segments.len(),
        samples: it.n_rows / pb.outputs[0].len().max(1),
        signals: pb.signals.clone(),
        condition,
        free_run_start: score.free_run_start,
        free_run_end: if score.free_run_end.is_finite() {
            score.free_run_end
        } else {
            f64::MAX
        },
        applied: score.applied,
        note: score.note,
        initial_state: FREE_RUN_START,
    })
}

#[cfg(test)]
mod tests;
