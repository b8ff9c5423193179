//! Parameter identification by the covariance (filter) method.
//!
//! Each equation of motion of body `l` is linear in the unknown parameters,
//! `Σᵢ coefᵢ · basisᵢ = 0`, with `basis ∈ {static g(signals), ẋₖ, ẍₖ}`. Multiplying by an
//! instrument `ι(t)` and averaging over a record of length `T` gives one linear equation per
//! (instrument, equation, level). Derivatives are moved onto the instrument by the exact
//! finite-record identities
//!
//! ```text
//! ⟨ι ẋ⟩ = −⟨ι' x⟩ + [ι x]₀ᵀ/T,    ⟨ι ẍ⟩ = ⟨ι'' x⟩ − [ι' x]₀ᵀ/T + [ι ẋ]₀ᵀ/T,
//! ```
//!
//! so no measured signal is ever differentiated. Instruments are the states of a bank of
//! low-pass chains driven by measured positions and inputs (see [`filter`]); a state of
//! relative degree `r` has `ι'` (r ≥ 2) and `ι''` (r ≥ 3) free of the driving signal, which
//! keeps white measurement noise out of every product. Where velocities are measured the
//! balance instruments `xₖ` (virial, `⟨x ẍ⟩ = −⟨v²⟩ + [x v]/T`) and `v_l` (power balance,
//! `⟨v_l ẍ_l⟩ = [v_l²/2]/T`) can be added. Rows of all levels are stacked into one
//! least-squares problem `C p = c`, solved by SVD after row normalisation and column
//! scaling.
//!
//! # Standard errors
//!
//! A batch-means sandwich (see [`stats`]): the weighted residual rows `W (C p̂ − c)` are
//! exactly the sum of the contributions of overlapping hat-shaped time windows, each an
//! exact estimating equation of its own (see the `moments` module), levels are
//! independent, and `Cov p̂ = Σ_levels A⁺ Ŝ A⁺ᵀ` with `A = W C` and `Ŝ` the spread of the
//! window contributions. It is linear in the per-level terms, so the same record given
//! twice gives the same estimate and standard errors smaller by exactly √2. A
//! delete-one-block jackknife, used before, is not: a deleted block leaves a gap whose two
//! boundary terms (point values of a noisy velocity times an instrument) no longer cancel,
//! so every replicate carries noise the estimate itself does not have, and the replicates
//! re-solve a nonlinear problem in which that noise does not scale with the level count.
//!
//! Only rank loss removes a parameter (a zero column, or collinear columns by the condition
//! number); an estimate within [`SIGNIFICANCE_T`] standard errors of zero stays in the fit
//! and is flagged ([`ParamEstimate::significant`]). Estimates that are unphysical for the
//! kind of term they multiply are reported in [`Identification::warnings`].
//!
//! Noise in a measured signal inside a nonlinear static term (`s³`, `sign(v)`) biases its
//! moments; the first pass estimates each signal's noise level and the moments of such
//! terms are de-biased where it is significant (see [`noise`]).

pub mod design;
pub mod filter;
mod moments;
pub mod noise;
mod plan;
pub mod print;
mod solve;
mod stats;
pub mod velocity;

pub use filter::Hold;
pub use moments::PhaseTimes;
pub use stats::{Quantity, Warning};
pub use velocity::VelocityEstimate;

/// A level counts as centred (its mean removed) when every signal driving the filters has
/// `|mean| ≤ CENTRED_REL · std`: far below any sampling spread of a mean, far above the
/// rounding left by subtracting one.
pub const CENTRED_REL: f64 = 1e-9;

/// An estimate counts as significant when `|value| > SIGNIFICANCE_T · stderr` (about 95 %
/// two-sided for a normal estimate).
pub const SIGNIFICANCE_T: f64 = 2.0;
pub use noise::NoiseSummary;

use crate::basis::BasisEval;
use crate::data::{DataError, LevelSource};
use crate::tape::Tape;
use dynid_ir::ir::{ModelIr, SignalId, SignalKind};
use moments::{LevelAccumulator, LevelMoments, MomentView};
use plan::{BankChoice, BasisMoment, Instrument, Plan, TermCoef};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Choices of the identification; `Default` gives the method's recommended settings.
#[derive(Clone, Debug)]
pub struct IdentifyOptions {
    /// Filter corners in rad/s. `None`: the model's filter block, else designed from the data.
    pub corners: Option<Vec<f64>>,
    /// Number of corners when they are designed from the data.
    pub n_corners: usize,
    /// Sections per low-pass chain. `None`: 3, or 4 when accelerations must come from
    /// positions alone (so the instruments keep relative degree ≥ 3).
    pub order: Option<usize>,
    /// Signals driving the filter bank. `None`: the model's filter block, else the measured
    /// positions and inputs.
    pub drivers: Option<Vec<SignalId>>,
    /// Add virial and power-balance rows where velocities are measured. `None`: off — they
    /// were measured not to improve the pooled estimate (see the crate tests).
    pub balance: Option<bool>,
    /// Time blocks per level for the standard errors (hat windows span two blocks).
    pub n_blocks: usize,
    /// Samples per chunk of streamed work (memory use is proportional to this, not to the
    /// record length).
    pub chunk_len: usize,
    /// Singular values below `rcond · σ_max` count as rank loss.
    pub rcond: f64,
    /// Inter-sample model of the filter input (first-order hold; zero-order for comparison).
    pub hold: Hold,
    /// De-bias the moments of nonlinear static terms in signals whose estimated measurement
    /// noise is significant (see [`noise`]). The noise is estimated and reported either way.
    pub noise_correction: bool,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            corners: None,
            n_corners: 6,
            order: None,
            drivers: None,
            balance: None,
            n_blocks: 20,
            chunk_len: 8192,
            rcond: 1e-10,
            hold: Hold::FirstOrder,
            noise_correction: true,
        }
    }
}

/// Errors of identification. Data errors pass through with their file and line.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum IdentifyError {
    #[error(
        "the term `{term}` of the equation of `{equation}` needs `{signal}`, which is not measured"
    )]
    #[diagnostic(
        code(dynid::identify::unmeasured),
        help("measure `{signal}`, or write the term so that it depends only on measured signals (terms linear in a velocity can be moved onto the filters)")
    )]
    UnmeasuredInTerm {
        equation: String,
        term: String,
        signal: String,
    },
    #[error("the filter bank is driven by `{signal}`, which is not measured")]
    #[diagnostic(
        code(dynid::identify::driver),
        help("drive the filters by measured positions and inputs")
    )]
    UnmeasuredDriver { signal: String },
    #[error("the model has no unknown parameters")]
    #[diagnostic(
        code(dynid::identify::no_unknowns),
        help("declare the parameters to identify without a value (e.g. `param k`)")
    )]
    NoUnknowns,
    #[error("no data: identification needs at least one record")]
    #[diagnostic(
        code(dynid::identify::no_data),
        help("pass one data file per excitation level")
    )]
    NoLevels,
    #[error("{origin}: {n} samples span {duration:.3} s, too short for the slowest filter (time constant {tau:.3} s)")]
    #[diagnostic(code(dynid::identify::too_short), help("{advice}"))]
    TooShort {
        origin: String,
        n: usize,
        duration: f64,
        tau: f64,
        need: usize,
        /// What to do: the samples needed, and corners that fit this record where any do.
        advice: String,
    },
    #[error("{rows} equations for {cols} unknown parameters")]
    #[diagnostic(
        code(dynid::identify::too_few_rows),
        help("add filter corners or excitation levels")
    )]
    TooFewRows { rows: usize, cols: usize },
    #[error("invalid option: {message}")]
    #[diagnostic(code(dynid::identify::option), help("{help}"))]
    BadOption { message: String, help: String },
    #[error(transparent)]
    #[diagnostic(transparent)]
    Data(#[from] DataError),
}

/// An identified parameter.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ParamEstimate {
    pub name: String,
    pub value: f64,
    /// Batch-means sandwich standard error (see the module doc).
    pub stderr: f64,
    /// `|value| > SIGNIFICANCE_T · stderr`. An insignificant estimate stays in the fit: the
    /// data do not show the term, but its column was not dropped and the others were not
    /// refitted without it.
    pub significant: bool,
}

/// A parameter the data cannot determine (a zero column, or collinear with others); no
/// value is reported for it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Unidentifiable {
    pub name: String,
    pub reason: String,
}

/// Relative residual `‖W (C p − c)‖ / ‖W c‖` over the rows of one equation, per level.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EquationResidual {
    pub equation: String,
    pub per_level: Vec<f64>,
}

/// What was seen of one level.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LevelInfo {
    pub origin: String,
    pub samples: usize,
    pub ts: f64,
    /// Standard deviation per measured signal.
    pub std: BTreeMap<String, f64>,
    /// Estimated white measurement-noise standard deviation per measured signal.
    pub noise: BTreeMap<String, f64>,
}

/// The filter bank that was used.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FilterSummary {
    pub corners: Vec<f64>,
    pub order: usize,
    pub drivers: Vec<String>,
    /// Relative degrees of the states used as instruments.
    pub instrument_degrees: Vec<usize>,
    pub balance_rows: bool,
}

/// Result of an identification.
#[derive(Clone, Debug, Serialize)]
pub struct Identification {
    pub params: Vec<ParamEstimate>,
    pub unidentifiable: Vec<Unidentifiable>,
    /// Estimates that are unphysical for their kind of term (negative mass, damping,
    /// friction coefficient or stiffness).
    pub warnings: Vec<Warning>,
    /// Condition number of the row-normalised, column-scaled matrix.
    pub condition: f64,
    pub residual: Vec<EquationResidual>,
    pub levels: Vec<LevelInfo>,
    pub filter: FilterSummary,
    /// Unmeasured velocities estimated from measured positions for nonlinear terms.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub estimated: Vec<VelocityEstimate>,
    /// Rows of the stacked system.
    pub rows: usize,
    /// Estimated measurement noise and the terms de-biased for it.
    pub noise: NoiseSummary,
    #[serde(skip)]
    pub times: PhaseTimes,
}

impl Identification {
    pub fn param(&self, name: &str) -> Option<&ParamEstimate> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// The assembled system `C p = c` (before weighting), for parity checks between evaluators.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearSystem {
    /// Row-major `rows × cols`; columns are `ir.unknowns()` in order.
    pub c_matrix: Vec<f64>,
    pub rhs: Vec<f64>,
    pub rows: usize,
    pub cols: usize,
    /// `level i: instrument → equation` per row.
    pub row_labels: Vec<String>,
}

/// Moments of all levels of one model, ready to be solved pooled or per level.
pub struct Moments<'m> {
    ir: &'m ModelIr,
    plan: Plan,
    levels: Vec<LevelMoments>,
    infos: Vec<LevelInfo>,
    /// Per level: every signal driving the filters has zero mean (see [`CENTRED_REL`]).
    centred: Vec<bool>,
    estimated: Vec<VelocityEstimate>,
    rcond: f64,
    times: PhaseTimes,
    /// Structure search: leave out, one at a time, estimates with `|value| ≤ prune_t · stderr`
    /// (0: off).
    prune_t: f64,
    noise: NoiseSummary,
}

/// Identify the unknown parameters of `ir` from records at one or more excitation levels,
/// pooling all levels into one least-squares problem (paper eq. 9).
pub fn identify(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let tape = Tape::compile(ir, &ir.eval_roots());
    Ok(measure(ir, &tape, levels, opts)?.identify_pooled())
}

/// As [`identify`], with a caller-supplied basis evaluator (e.g. macro-generated code).
pub fn identify_with(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    Ok(measure(ir, eval, levels, opts)?.identify_pooled())
}

/// Identify separately at each level (for detection: an equivalent-linear parameter that
/// drifts with the level reveals a hidden nonlinearity).
pub fn identify_per_level(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Vec<Identification>, IdentifyError> {
    let tape = Tape::compile(ir, &ir.eval_roots());
    let m = measure(ir, &tape, levels, opts)?;
    Ok((0..levels.len()).map(|i| m.identify_level(i)).collect())
}

/// The stacked system `C p = c` of all levels.
pub fn assemble(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<LinearSystem, IdentifyError> {
    Ok(measure(ir, eval, levels, opts)?.system())
}

/// Stream every level once through the filters and accumulate the moments.
pub fn measure<'m>(
    ir: &'m ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Moments<'m>, IdentifyError> {
    if levels.is_empty() {
        return Err(IdentifyError::NoLevels);
    }
    if ir.unknowns().is_empty() {
        return Err(IdentifyError::NoUnknowns);
    }
    if opts.chunk_len < 2 || opts.n_blocks < 2 {
        return Err(IdentifyError::BadOption {
            message: "chunk length and number of blocks must be at least 2".into(),
            help: "use the defaults".into(),
        });
    }
    let bank = choose_bank(ir, opts)?;
    let mut plan = plan::build_structure(ir, opts.balance.unwrap_or(false), &bank)?;
    let t0 = Instant::now();
    let stats: Vec<LevelStats> = levels
        .par_iter()
        .map(|src| level_stats(&plan, *src, opts.chunk_len))
        .collect::<Result<_, _>>()?;
    let stats_time = t0.elapsed();
    let (noise_var, noise) = noise_plan(ir, &mut plan, &stats, opts.noise_correction);

    // The shortest level bounds the slowest filter.
    let min_duration = stats
        .iter()
        .map(|s| s.n.saturating_sub(1) as f64 * s.ts)
        .fold(f64::INFINITY, f64::min);
    let ts_min = stats.iter().map(|s| s.ts).fold(f64::INFINITY, f64::min);
    let omegas: Vec<f64> = stats.iter().flat_map(|s| s.omegas.clone()).collect();
    let designed = design::fit_corners(&omegas, ts_min, min_duration, bank.order, bank.n_corners);
    let corners = match (&opts.corners, ir.filter.as_ref().map(|f| &f.corners)) {
        (Some(c), _) => c.clone(),
        (None, Some(c)) if !c.is_empty() => c.clone(),
        _ => match &designed {
            Some(c) => c.clone(),
            // Not even the fastest admissible corners settle: fall through to the check,
            // which names the record length they need.
            None => {
                let cap = design::max_corner(ts_min);
                vec![cap / 2.0; bank.n_corners]
            }
        },
    };
    if corners.is_empty() || corners.iter().any(|c| !(c.is_finite() && *c > 0.0)) {
        return Err(IdentifyError::BadOption {
            message: format!("filter corners {corners:?}"),
            help: "corners are positive angular frequencies in rad/s".into(),
        });
    }
    plan.corners = vec![0.0; corners.len()];
    plan.set_corners(ir, &corners);
    let lam_min = corners.iter().copied().fold(f64::INFINITY, f64::min);
    // The slowest section must forget its start within a small part of the record.
    let tau = bank.order as f64 / lam_min;
    let settle = design::min_duration(&corners, bank.order);
    for (s, src) in stats.iter().zip(levels) {
        let duration = (s.n.saturating_sub(1)) as f64 * s.ts;
        if duration < settle * (1.0 - 1e-9) || s.n < 4 * opts.n_blocks {
            let need = ((settle / s.ts).ceil() as usize + 1).max(4 * opts.n_blocks);
            let advice = match &designed {
                Some(c) if s.n >= 4 * opts.n_blocks => format!(
                    "record at least {need} samples, or use filter corners that fit this \
                     record (the lowest at least {:.4} rad/s), e.g. `--filter-corners {}`",
                    design::min_corner(min_duration, bank.order),
                    c.iter()
                        .map(|v| format!("{v:.4}"))
                        .collect::<Vec<_>>()
                        .join(",")
                ),
                _ => {
                    // The fastest corner the design allows at this sample rate.
                    let fast = design::max_corner(s.ts) / 2.0;
                    let t_fast = design::min_duration(&[fast], bank.order);
                    format!(
                        "record at least {} samples: with {} filter sections even the fastest \
                         corner this sample rate allows ({fast:.4} rad/s) needs {t_fast:.3} s",
                        need.max((t_fast / s.ts).ceil() as usize + 1),
                        bank.order,
                    )
                }
            };
            return Err(IdentifyError::TooShort {
                origin: src.origin(),
                n: s.n,
                duration,
                tau,
                need,
                advice,
            });
        }
    }
    let cols = plan.unknowns.len();
    let rows = plan.rows.len() * levels.len();
    if rows < cols {
        return Err(IdentifyError::TooFewRows { rows, cols });
    }

    // Unmeasured velocities in nonlinear terms: estimated from the positions, per level.
    let targets: Vec<(usize, usize)> = plan
        .estimated
        .iter()
        .map(|(v, x)| (v.index(), x.index()))
        .collect();
    let estimators: Vec<velocity::EstimatedVelocity> = if targets.is_empty() {
        Vec::new()
    } else {
        levels
            .par_iter()
            .map(|src| velocity::EstimatedVelocity::design(*src, &targets, opts.chunk_len))
            .collect::<Result<_, _>>()?
    };
    let sources: Vec<&dyn LevelSource> = if estimators.is_empty() {
        levels.to_vec()
    } else {
        estimators.iter().map(|e| e as &dyn LevelSource).collect()
    };
    let estimated = plan
        .estimated
        .iter()
        .enumerate()
        .map(|(k, (v, x))| VelocityEstimate {
            signal: ir.signal(*v).name.clone(),
            from: ir.signal(*x).name.clone(),
            method: velocity::METHOD.into(),
            cutoff: estimators.iter().map(|e| e.designs()[k].1).collect(),
            half_width: estimators.iter().map(|e| e.designs()[k].2).collect(),
        })
        .collect();

    let results: Vec<(LevelMoments, PhaseTimes)> = sources
        .par_iter()
        .zip(&stats)
        .zip(&noise_var)
        .map(|((src, st), var)| {
            let mut acc = LevelAccumulator::new(&plan, eval, st.ts, st.n, opts.n_blocks, opts.hold);
            acc.set_extra_widths(noise::extra_widths(&plan, &st.noise_var, &st.std));
            let mut read = Duration::ZERO;
            let mut t_read = Instant::now();
            src.stream(opts.chunk_len, &mut |cols, len| {
                read += t_read.elapsed();
                acc.push(cols, len);
                t_read = Instant::now();
            })?;
            let (mut m, mut t) = acc.finish();
            noise::debias(&plan, &mut m, var, opts.hold);
            t.read = read;
            Ok::<_, IdentifyError>((m, t))
        })
        .collect::<Result<_, _>>()?;
    let mut times = PhaseTimes {
        read: stats_time,
        ..Default::default()
    };
    let mut lm = Vec::new();
    for (m, t) in results {
        times += t;
        lm.push(m);
    }
    let infos = stats
        .iter()
        .zip(levels)
        .map(|(s, src)| LevelInfo {
            origin: src.origin(),
            samples: s.n,
            ts: s.ts,
            std: plan
                .y
                .iter()
                .zip(&s.std)
                .map(|(sig, sd)| (ir.signal(*sig).name.clone(), *sd))
                .collect(),
            noise: plan
                .y
                .iter()
                .zip(&s.noise_var)
                .map(|(sig, v)| (ir.signal(*sig).name.clone(), v.sqrt()))
                .collect(),
        })
        .collect();
    let centred = stats
        .iter()
        .map(|s| {
            plan.drivers.iter().all(|d| {
                plan.y_of[d.index()].is_none_or(|k| {
                    s.mean[k].abs() <= CENTRED_REL * s.std[k].max(f64::MIN_POSITIVE)
                })
            })
        })
        .collect();
    Ok(Moments {
        ir,
        plan,
        levels: lm,
        infos,
        centred,
        estimated,
        rcond: opts.rcond,
        times,
        prune_t: 0.0,
        noise,
    })
}

/// Decide the noise corrections from the first-pass statistics: attach them to the plan
/// where a signal in a nonlinear term carries significant noise, and return per level the
/// noise variance of each measured signal to correct for (zero where it is not
/// significant or the correction is off), with the summary for the report.
fn noise_plan(
    ir: &ModelIr,
    plan: &mut Plan,
    stats: &[LevelStats],
    enabled: bool,
) -> (Vec<Vec<f64>>, NoiseSummary) {
    let significant = |st: &LevelStats, k: usize| {
        st.noise_flat[k]
            && st.std[k] > 0.0
            && st.noise_var[k].sqrt() >= noise::SIGNIFICANT * st.std[k]
    };
    let noisy: Vec<SignalId> = (0..plan.y.len())
        .filter(|&k| stats.iter().any(|st| significant(st, k)))
        .map(|k| plan.y[k])
        .collect();
    let mut summary = NoiseSummary {
        fraction: plan
            .y
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let f = stats
                    .iter()
                    .map(|st| {
                        if st.std[k] > 0.0 {
                            st.noise_var[k].sqrt() / st.std[k]
                        } else {
                            0.0
                        }
                    })
                    .fold(0.0, f64::max);
                (ir.signal(*s).name.clone(), f)
            })
            .collect(),
        enabled,
        uncertain: (0..plan.y.len())
            .filter(|&k| stats.iter().any(|st| !st.noise_flat[k]))
            .map(|k| ir.signal(plan.y[k]).name.clone())
            .collect(),
        ..Default::default()
    };
    if enabled && !noisy.is_empty() {
        noise::attach(plan, ir);
    }
    summary.uncorrected = noise::uncorrected(plan, ir, &noisy);
    let var = stats
        .iter()
        .map(|st| {
            (0..plan.y.len())
                .map(|k| {
                    if enabled && significant(st, k) {
                        st.noise_var[k]
                    } else {
                        0.0
                    }
                })
                .collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>();
    for f in &plan.fixes {
        if var.iter().any(|v| noise::form_variance(&f.lin, v) > 0.0) {
            summary.corrected.push(f.label.clone());
        }
    }
    (var, summary)
}

fn choose_bank(ir: &ModelIr, opts: &IdentifyOptions) -> Result<BankChoice, IdentifyError> {
    let spec = ir.filter.as_ref();
    let drivers = match (&opts.drivers, spec.map(|f| &f.driven_by)) {
        (Some(d), _) => d.clone(),
        (None, Some(d)) if !d.is_empty() => d.clone(),
        _ => ir
            .measured_signals()
            .into_iter()
            .filter(|s| !matches!(ir.signal(*s).kind, SignalKind::Velocity(_)))
            .collect(),
    };
    // Accelerations from positions alone need ι'' free of the driving signal: degree ≥ 3.
    let needs_second = ir.equations.iter().any(|eq| {
        eq.terms.iter().any(|t| match t.basis {
            dynid_ir::ir::Basis::Deriv { body, order: 2 } => !ir.signal(ir.velocity(body)).measured,
            _ => false,
        })
    });
    let min_degree = if needs_second { 3 } else { 2 };
    let order = opts
        .order
        .or(spec.map(|f| f.order as usize))
        .unwrap_or(min_degree + 1);
    if order < min_degree || order > 8 {
        return Err(IdentifyError::BadOption {
            message: format!("filter order {order}"),
            help: format!("use an order between {min_degree} and 8 for this model"),
        });
    }
    let n_corners = match (&opts.corners, spec.map(|f| &f.corners)) {
        (Some(c), _) => c.len(),
        (None, Some(c)) if !c.is_empty() => c.len(),
        _ => opts.n_corners,
    };
    Ok(BankChoice {
        drivers,
        order,
        min_degree,
        n_corners,
    })
}

/// First-pass statistics of a level: length, spread, dominant frequencies.
struct LevelStats {
    n: usize,
    ts: f64,
    std: Vec<f64>,
    /// Mean per measured signal.
    mean: Vec<f64>,
    omegas: Vec<f64>,
    /// Estimated white-noise variance per measured signal.
    noise_var: Vec<f64>,
    /// Whether that estimate comes from a flat floor ([`noise::NoiseFloor::flat`]).
    noise_flat: Vec<bool>,
}

fn level_stats(
    plan: &Plan,
    src: &dyn LevelSource,
    chunk: usize,
) -> Result<LevelStats, IdentifyError> {
    let ny = plan.y.len();
    let mut n = 0usize;
    let mut shift = vec![0.0; ny];
    let mut s1 = vec![0.0; ny];
    let mut s2 = vec![0.0; ny];
    // Hysteresis zero-crossing counts about a reference from the first chunk.
    let mut reference: Vec<(f64, f64)> = Vec::new();
    let mut side = vec![0i8; ny];
    let mut crossings = vec![0usize; ny];
    let mut floors = vec![noise::NoiseFloor::default(); ny];
    src.stream(chunk, &mut |cols, len| {
        if n == 0 {
            for (k, s) in plan.y.iter().enumerate() {
                let c = &cols[s.index()][..len];
                shift[k] = c[0];
                let mean = c.iter().sum::<f64>() / len as f64;
                let var = c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / len as f64;
                reference.push((mean, 0.25 * var.sqrt()));
            }
        }
        for (k, s) in plan.y.iter().enumerate() {
            let c = &cols[s.index()][..len];
            let (mut a, mut b) = (0.0, 0.0);
            for &v in c {
                let d = v - shift[k];
                a += d;
                b += d * d;
            }
            s1[k] += a;
            s2[k] += b;
            floors[k].push(c);
            let (mid, h) = reference[k];
            for &v in c {
                let now = if v > mid + h {
                    1
                } else if v < mid - h {
                    -1
                } else {
                    0
                };
                if now != 0 && now != side[k] {
                    if side[k] != 0 {
                        crossings[k] += 1;
                    }
                    side[k] = now;
                }
            }
        }
        n += len;
    })?;
    let ts = src.ts();
    let std = (0..ny)
        .map(|k| {
            let m = s1[k] / n.max(1) as f64;
            (s2[k] / n.max(1) as f64 - m * m).max(0.0).sqrt()
        })
        .collect();
    let mean = (0..ny)
        .map(|k| shift[k] + s1[k] / n.max(1) as f64)
        .collect();
    let duration = (n.max(2) - 1) as f64 * ts;
    let omegas = plan
        .y
        .iter()
        .enumerate()
        .filter(|(_, s)| plan.drivers.contains(s))
        .filter(|(k, _)| crossings[*k] > 0)
        .map(|(k, _)| std::f64::consts::PI * crossings[k] as f64 / duration)
        .collect();
    Ok(LevelStats {
        n,
        ts,
        std,
        mean,
        omegas,
        noise_var: floors.iter().map(|f| f.variance()).collect(),
        noise_flat: floors.iter().map(|f| f.flat()).collect(),
    })
}

impl<'m> Moments<'m> {
    /// Information on the levels that were read.
    pub fn levels(&self) -> &[LevelInfo] {
        &self.infos
    }

    /// Model selection: leave out, and refit without, any parameter whose standard error
    /// is at least its own size (worst first, one at a time); it is then listed among the
    /// parameters left out, with that reason (not significant, which is not rank
    /// deficiency). Off by default: identification keeps such a
    /// parameter and flags it. A structure search uses it to treat such a term as absent.
    pub fn prune_insignificant(&mut self, on: bool) {
        self.prune_t = if on { 1.0 } else { 0.0 };
    }

    /// As [`Self::prune_insignificant`] with the threshold `|value| ≤ t · stderr`; a
    /// structure search that keeps only significant terms uses [`SIGNIFICANCE_T`].
    pub fn prune_below(&mut self, t: f64) {
        self.prune_t = t.max(0.0);
    }

    /// Time spent so far, by phase.
    pub fn times(&self) -> PhaseTimes {
        self.times
    }

    fn filter_summary(&self) -> FilterSummary {
        FilterSummary {
            corners: self.plan.corners.clone(),
            order: self.plan.order,
            drivers: self
                .plan
                .drivers
                .iter()
                .map(|s| self.ir.signal(*s).name.clone())
                .collect(),
            instrument_degrees: (self.plan.min_degree..=self.plan.order).collect(),
            balance_rows: self.plan.balance,
        }
    }

    /// Rows `(C, c)` of one level from a moment view.
    fn level_rows(&self, view: &MomentView) -> (Vec<f64>, Vec<f64>) {
        let p = &self.plan;
        let cols = p.unknowns.len();
        let mut c = vec![0.0; p.rows.len() * cols];
        let mut rhs = vec![0.0; p.rows.len()];
        for (r, &(k, l)) in p.rows.iter().enumerate() {
            let ins = &p.instruments[k];
            for t in &p.equations[l] {
                let m = term_moment(ins, &t.basis, view);
                match t.coef {
                    TermCoef::Unknown { col, scale } => c[r * cols + col] += scale * m,
                    TermCoef::Known(v) => rhs[r] -= v * m,
                }
            }
        }
        (c, rhs)
    }

    /// The stacked system of all levels.
    pub fn system(&self) -> LinearSystem {
        let cols = self.plan.unknowns.len();
        let mut out = LinearSystem {
            c_matrix: vec![],
            rhs: vec![],
            rows: 0,
            cols,
            row_labels: vec![],
        };
        for (i, lm) in self.levels.iter().enumerate() {
            let (c, r) = self.level_rows(&lm.view());
            out.c_matrix.extend(c);
            out.rhs.extend(r);
            for &(k, l) in &self.plan.rows {
                out.row_labels.push(format!(
                    "level {}: {} → {}",
                    i + 1,
                    self.plan.instruments[k].label,
                    self.ir.bodies[l].name
                ));
            }
        }
        out.rows = out.rhs.len();
        out
    }

    /// Pool all levels into one least-squares problem.
    pub fn identify_pooled(&self) -> Identification {
        let all: Vec<usize> = (0..self.levels.len()).collect();
        self.solve_levels(&all)
    }

    /// Use level `i` alone.
    pub fn identify_level(&self, i: usize) -> Identification {
        self.solve_levels(&[i])
    }

    /// Use level `i` alone with some unknowns held at given values (moved to the
    /// right-hand side; they are not reported among the estimates). Detection holds an
    /// unknown mass at one value for all levels this way: a mass is the same at every
    /// level, and a short level cannot separate it from the stiffness.
    pub fn identify_level_holding(&self, i: usize, held: &[(String, f64)]) -> Identification {
        let cols: Vec<(usize, f64)> = held
            .iter()
            .filter_map(|(name, v)| {
                self.plan
                    .unknowns
                    .iter()
                    .position(|&p| self.ir.params[p].name == *name)
                    .map(|c| (c, *v))
            })
            .collect();
        self.solve_levels_holding(&[i], &cols)
    }

    /// Pool the given levels only (cross-validation: fit on some levels, score on another).
    pub fn identify_levels(&self, which: &[usize]) -> Identification {
        self.solve_levels(which)
    }

    fn solve_levels(&self, which: &[usize]) -> Identification {
        self.solve_levels_holding(which, &[])
    }

    /// Rows of one level with the held columns moved to the right-hand side.
    fn level_rows_holding(&self, view: &MomentView, held: &[(usize, f64)]) -> (Vec<f64>, Vec<f64>) {
        let (mut c, mut rhs) = self.level_rows(view);
        let ncol = self.plan.unknowns.len();
        for (r, b) in rhs.iter_mut().enumerate() {
            for &(j, v) in held {
                *b -= v * c[r * ncol + j];
                c[r * ncol + j] = 0.0;
            }
        }
        (c, rhs)
    }

    /// Per unknown column: a constant-force column at levels whose filter drivers all have
    /// zero mean (centred records), where its column — the filter outputs' means — is zero
    /// but for the filters' start-up: rank loss, not a weak estimate.
    fn meanless_columns(&self, which: &[usize]) -> Vec<bool> {
        let all_centred = which.iter().all(|&i| self.centred[i]);
        self.plan
            .constant
            .iter()
            .map(|&c| c && all_centred)
            .collect()
    }

    fn solve_levels_holding(&self, which: &[usize], held: &[(usize, f64)]) -> Identification {
        let t0 = Instant::now();
        let plan = &self.plan;
        let ncol = plan.unknowns.len();
        let nr = plan.rows.len();
        let full: Vec<(Vec<f64>, Vec<f64>)> = which
            .iter()
            .map(|&i| self.level_rows_holding(&self.levels[i].view(), held))
            .collect();
        let mut c_full = Vec::with_capacity(which.len() * nr * ncol);
        let mut r_full = Vec::with_capacity(which.len() * nr);
        for (c, r) in &full {
            c_full.extend_from_slice(c);
            r_full.extend_from_slice(r);
        }
        let rows = r_full.len();
        // Row normalisation: every row (with its right-hand side) gets unit norm, so rows of
        // weak instruments and quiet levels count as much as loud ones.
        let weights: Vec<f64> = (0..rows)
            .map(|r| {
                let n = (c_full[r * ncol..(r + 1) * ncol]
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    + r_full[r] * r_full[r])
                    .sqrt();
                if n > 0.0 {
                    1.0 / n
                } else {
                    0.0
                }
            })
            .collect();
        // Rows of the hat contributions of every level (for the standard errors).
        let hats: Vec<Vec<(Vec<f64>, Vec<f64>)>> = which
            .par_iter()
            .map(|&i| {
                let lm = &self.levels[i];
                (0..=lm.n_blocks())
                    .map(|j| self.level_rows_holding(&lm.hat(j), held))
                    .collect()
            })
            .collect();

        let names: Vec<String> = plan
            .unknowns
            .iter()
            .map(|&p| self.ir.params[p].name.clone())
            .collect();
        let mut active: Vec<usize> = (0..ncol)
            .filter(|j| !held.iter().any(|(h, _)| h == j))
            .collect();
        let mut unident = Vec::new();
        let meanless = self.meanless_columns(which);
        let weighted = |c: &[f64], r: &[f64], active: &[usize]| {
            let mut a = Vec::with_capacity(rows * active.len());
            let mut b = Vec::with_capacity(rows);
            for i in 0..rows {
                for &j in active {
                    a.push(weights[i] * c[i * ncol + j]);
                }
                b.push(weights[i] * r[i]);
            }
            (a, b)
        };
        let (sol, se) = loop {
            let (a, b) = weighted(&c_full, &r_full, &active);
            let sol = solve::lstsq(&a, &b, rows, active.len(), self.rcond);
            if active.is_empty() {
                break (sol, vec![]);
            }
            let cmax = sol.col_norms.iter().copied().fold(0.0, f64::max);
            if let Some(j) =
                (0..active.len()).find(|&j| sol.col_norms[j] <= 1e-12 * cmax || meanless[active[j]])
            {
                unident.push(Unidentifiable {
                    name: names[active[j]].clone(),
                    reason: plan.zero_column_reason(active[j]),
                });
                active.remove(j);
                continue;
            }
            let cond = sol.condition();
            if cond * self.rcond > 1.0 {
                let vmax = sol.v_min.iter().map(|v| v.abs()).fold(0.0, f64::max);
                let j = (0..active.len())
                    .max_by(|&x, &y| sol.v_min[x].abs().total_cmp(&sol.v_min[y].abs()))
                    .unwrap();
                let partners: Vec<String> = (0..active.len())
                    .filter(|&k| k != j && sol.v_min[k].abs() >= 0.1 * vmax)
                    .map(|k| format!("`{}`", names[active[k]]))
                    .collect();
                unident.push(Unidentifiable {
                    name: names[active[j]].clone(),
                    reason: format!(
                        "its column is collinear with {} (cond {:.1e}) — add an excitation \
                         level where the terms are excited differently",
                        if partners.is_empty() {
                            "the other columns".to_string()
                        } else {
                            partners.join(", ")
                        },
                        cond
                    ),
                });
                active.remove(j);
                continue;
            }
            let se = stats::sandwich_stderr(
                &sol,
                &active,
                ncol,
                nr,
                &weights,
                &hats,
                which.iter().map(|&i| &self.levels[i]),
            );
            if self.prune_t > 0.0 {
                let worst = (0..active.len())
                    .filter(|&j| self.prune_t * se[j] >= sol.x[j].abs())
                    .max_by(|&x, &y| (se[x] / sol.x[x].abs()).total_cmp(&(se[y] / sol.x[y].abs())));
                if let Some(j) = worst {
                    unident.push(Unidentifiable {
                        name: names[active[j]].clone(),
                        reason: format!(
                            "not significant, left out by model selection: the estimate \
                             {:.3e} is within {} standard errors ({:.1e}) of zero",
                            sol.x[j], self.prune_t, se[j]
                        ),
                    });
                    active.remove(j);
                    continue;
                }
            }
            break (sol, se);
        };

        let mut p_full = vec![0.0; ncol];
        for &(j, v) in held {
            p_full[j] = v;
        }
        for (k, &j) in active.iter().enumerate() {
            p_full[j] = sol.x[k];
        }
        let params = active
            .iter()
            .enumerate()
            .map(|(k, &j)| ParamEstimate {
                name: names[j].clone(),
                value: sol.x[k],
                stderr: se[k],
                significant: sol.x[k].abs() > SIGNIFICANCE_T * se[k],
            })
            .collect::<Vec<_>>();
        // Residuals per equation and level, on the weighted rows.
        let residual = (0..self.ir.equations.len())
            .map(|l| EquationResidual {
                equation: self.ir.bodies[l].name.clone(),
                per_level: (0..which.len())
                    .map(|pos| {
                        let (mut num, mut den) = (0.0, 0.0);
                        for (r, &(_, eq)) in plan.rows.iter().enumerate() {
                            if eq != l {
                                continue;
                            }
                            let i = pos * nr + r;
                            let fit: f64 =
                                (0..ncol).map(|j| c_full[i * ncol + j] * p_full[j]).sum();
                            num += (weights[i] * (fit - r_full[i])).powi(2);
                            den += (weights[i] * r_full[i]).powi(2);
                        }
                        if den > 0.0 {
                            (num / den).sqrt()
                        } else {
                            num.sqrt()
                        }
                    })
                    .collect(),
            })
            .collect();
        let mut times = self.times;
        times.solve = t0.elapsed();
        Identification {
            warnings: stats::physical_warnings(self.ir, &params),
            params,
            unidentifiable: unident,
            condition: sol.condition(),
            residual,
            levels: which.iter().map(|&i| self.infos[i].clone()).collect(),
            filter: self.filter_summary(),
            estimated: self.estimated.clone(),
            rows,
            noise: self.noise.clone(),
            times,
        }
    }
}

/// The moment `⟨φ ι basis⟩` of an instrument from a view (`φ ≡ 1` for the whole record;
/// the `φ'` terms of a hat window vanish there, see the `moments` module).
fn term_moment(ins: &Instrument, basis: &BasisMoment, v: &MomentView) -> f64 {
    let a = &ins.a;
    match *basis {
        BasisMoment::Static(w) => v.mean(a, w),
        BasisMoment::D1Pos(x) => {
            -v.mean(ins.a1.as_ref().unwrap(), x) + v.bnd(a, x) - v.mean_d(a, x)
        }
        BasisMoment::D2Vel(w, body) => {
            if ins.power == Some(body) {
                0.5 * (v.bnd(a, w) - v.mean_d(a, w))
            } else {
                -v.mean(ins.a1.as_ref().unwrap(), w) + v.bnd(a, w) - v.mean_d(a, w)
            }
        }
        BasisMoment::D2Pos(x, q) => {
            let a1 = ins.a1.as_ref().unwrap();
            v.mean(ins.a2.as_ref().unwrap(), x) - v.bnd(a1, x) + v.bnd(a, q) + 2.0 * v.mean_d(a1, x)
                - v.bnd_d(a, x)
        }
    }
}

#[cfg(test)]
mod tests;
