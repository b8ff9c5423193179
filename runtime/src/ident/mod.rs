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
//! kind of term they multiply are reported in [`Identification::warnings`]; a residual the
//! model cannot explain (a large relative residual, a pooled estimate outside every
//! level's) in [`Identification::fit_warnings`], with its likely cause (see [`guard`]).
//!
//! Noise in a measured signal inside a nonlinear static term (`s³`, `sign(v)`) biases its
//! moments; the first pass estimates each signal's noise level and the moments of such
//! terms are de-biased where it is significant (see [`noise`]).

mod accel;
mod columns;
pub mod design;
pub mod filter;
pub mod guard;
mod measure;
pub mod memory;
mod moments;
pub mod noise;
mod plan;
pub mod print;
mod restrict;
pub mod rests;
mod screen;
pub mod shape;
mod solve;
mod stats;
mod types;
pub mod velocity;

pub use filter::Hold;
pub use guard::{FitCheck, FitWarning, LikelyCause};
pub use measure::measure;
pub use memory::MemoryEstimate;
pub use moments::PhaseTimes;
pub use stats::{Quantity, Warning};
pub use types::*;
pub use velocity::VelocityEstimate;

/// A level counts as centred (its mean removed) when every signal driving the filters has
/// `|mean| ≤ CENTRED_REL · std`: far below any sampling spread of a mean, far above the
/// rounding left by subtracting one.
pub const CENTRED_REL: f64 = 1e-9;

/// An estimate counts as significant when `|value| > SIGNIFICANCE_T · stderr` (about 95 %
/// two-sided for a normal estimate).
pub const SIGNIFICANCE_T: f64 = 2.0;

/// Norm below which a column of the row-normalised least-squares matrix is zero: far below
/// any rounding error of a non-vanishing moment.
const ZERO_COLUMN: f64 = 1e-250;
pub use noise::NoiseSummary;
pub use rests::RestSummary;

use crate::basis::BasisEval;
use crate::data::{DataError, LevelSource};
use crate::tape::Tape;
use columns::{gather, Column, ColumnStore};
use dynid_ir::ir::{ModelIr, SignalId, SignalKind};
use moments::{LevelAccumulator, LevelMoments};
use plan::{BankChoice, Plan};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Moments of all levels of one model, ready to be solved pooled or per level.
pub struct Moments<'m> {
    ir: &'m ModelIr,
    plan: Plan,
    /// The measured model's moments and the columns of its rows (shared with the
    /// sub-models read from it).
    store: Arc<ColumnStore>,
    /// A sub-model's columns: its unknowns' in order, then the right-hand side. `None`:
    /// the measured model itself (its columns are the store's, kept once formed).
    cols: Option<Vec<Arc<Column>>>,
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
    /// Solve twice: the second time with every level's rows whitened by their estimated
    /// covariance ([`stats::efficient_mix`]).
    efficient: bool,
}

/// Identify the unknown parameters of `ir` from records at one or more excitation levels,
/// pooling all levels into one least-squares problem (paper eq. 9).
pub fn identify(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    if !ir.shapes.is_empty() {
        return Ok(shape::profile(ir, levels, opts)?.1);
    }
    let tape = Tape::compile(ir, &ir.eval_roots());
    let m = measure(ir, &tape, levels, opts)?;
    Ok(guarded(&m, levels, opts))
}

/// Factor by which [`corner_moves`] moves the highest filter corner down and up.
pub const CORNER_CHECK_FACTOR: f64 = 4.0;

/// The smallest relative move [`CornerMove::moved`] reports: on clean simulated records
/// the discretisation alone moves estimates by about 0.05 % over the corners, many times
/// their standard errors there (`tests/silent_nonsense.rs`), which is no model error worth a
/// warning.
pub const CORNER_CHECK_MIN_REL: f64 = 0.01;

/// One parameter's estimates with the highest filter corner a factor
/// [`CORNER_CHECK_FACTOR`] below and above the one used (the lowest corner kept: the
/// record length or the dominant frequencies bound it), see [`corner_moves`].
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CornerMove {
    pub param: String,
    /// The estimate with the highest corner lowered, as used, raised.
    pub values: [f64; 3],
    /// Their standard errors.
    pub stderrs: [f64; 3],
    /// The highest corner of each (rad/s).
    pub upper: [f64; 3],
}

impl CornerMove {
    /// The estimate moves by more than the standard error of either estimate it is
    /// compared with, and by more than [`CORNER_CHECK_MIN_REL`] of its value.
    pub fn moved(&self) -> bool {
        (0..3).step_by(2).any(|k| {
            let tol = self.stderrs[1]
                .max(self.stderrs[k])
                .max(CORNER_CHECK_MIN_REL * self.values[1].abs());
            (self.values[k] - self.values[1]).abs() > tol
        })
    }

    /// One line for the report: the parameter, its range over the corners and its
    /// standard error.
    pub fn describe(&self) -> String {
        let lo = self.values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self
            .values
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        format!(
            "`{}` moves with the filter corners: {} … {} (standard error {}) over the highest \
             corner {} … {} rad/s — a model error at some frequencies, or noise above the band \
             the data carry",
            self.param,
            print::fmt_num(lo),
            print::fmt_num(hi),
            print::fmt_num(self.stderrs[1]),
            print::fmt_num(self.upper[0]),
            print::fmt_num(self.upper[2]),
        )
    }
}

/// The identification `id` (made with `opts` from `levels`) repeated with the highest
/// corner a factor [`CORNER_CHECK_FACTOR`] below and above, the other corners log-spaced
/// again from the same lowest corner; the raised corner stays below half the Nyquist
/// frequency. Per parameter of `id` estimated in all three. Costs two further
/// identifications.
pub fn corner_moves(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
    id: &Identification,
) -> Result<Vec<CornerMove>, IdentifyError> {
    let c = &id.filter.corners;
    let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = c.iter().copied().fold(0.0, f64::max);
    let ts = id.levels.iter().map(|l| l.ts).fold(f64::INFINITY, f64::min);
    let spread = |top: f64| -> Vec<f64> {
        let n = c.len();
        if n == 1 {
            return vec![top];
        }
        (0..n)
            .map(|i| lo * (top / lo).powf(i as f64 / (n - 1) as f64))
            .collect()
    };
    let down = spread((hi / CORNER_CHECK_FACTOR).max(lo * 2.0).min(hi));
    let up = spread(
        (hi * CORNER_CHECK_FACTOR)
            .min(0.5 * std::f64::consts::PI / ts)
            .max(hi),
    );
    let alt = |corners: Vec<f64>| {
        identify(
            ir,
            levels,
            &IdentifyOptions {
                corners: Some(corners),
                ..opts.clone()
            },
        )
    };
    // One after the other: a level read once from a pipe streams its kept copy to one
    // reader at a time.
    let (a, b) = (alt(down.clone())?, alt(up.clone())?);
    let top = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    Ok(id
        .params
        .iter()
        .filter_map(|p| {
            let (pa, pb) = (a.param(&p.name)?, b.param(&p.name)?);
            Some(CornerMove {
                param: p.name.clone(),
                values: [pa.value, p.value, pb.value],
                stderrs: [pa.stderr, p.stderr, pb.stderr],
                upper: [top(&down), hi, top(&up)],
            })
        })
        .collect())
}

/// The pooled identification with the guard's warnings (see [`guard`]).
fn guarded(m: &Moments<'_>, levels: &[&dyn LevelSource], opts: &IdentifyOptions) -> Identification {
    let mut id = m.identify_pooled();
    id.fit_warnings = guard::check(m, &id, levels, opts);
    id
}

/// As [`identify`], with a caller-supplied basis evaluator (e.g. macro-generated code).
pub fn identify_with(
    ir: &ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let m = measure(ir, eval, levels, opts)?;
    Ok(guarded(&m, levels, opts))
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
            corners_from: self.plan.corner_source.clone(),
            corner_moves: Vec::new(),
            order: self.plan.order,
            drivers: self
                .plan
                .drivers
                .iter()
                .map(|s| self.ir.signal(*s).name.clone())
                .collect(),
            column_drivers: (self.plan.drivers.len()..self.plan.n_drivers())
                .map(|d| self.plan.driver_name(self.ir, d))
                .collect(),
            instrument_degrees: (self.plan.min_degree..=self.plan.order).collect(),
            balance_rows: self.plan.balance,
        }
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
        for i in 0..self.store.levels.len() {
            let (c, r) = self.level_system(i);
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
        let all: Vec<usize> = (0..self.store.levels.len()).collect();
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

    /// This model's columns (its unknowns in order, then the right-hand side).
    fn columns(&self) -> Vec<Arc<Column>> {
        match &self.cols {
            Some(cols) => cols.clone(),
            None => (0..=self.store.rhs())
                .into_par_iter()
                .map(|c| self.store.column(c))
                .collect(),
        }
    }

    /// The unweighted rows `(C, c)` of level `i` (row-major, one column per unknown).
    pub fn level_system(&self, i: usize) -> (Vec<f64>, Vec<f64>) {
        gather(&self.columns(), i, &[])
    }

    /// The body whose equation row `r` of a level is (rows are in the same order at
    /// every level).
    pub fn row_body(&self, r: usize) -> &str {
        &self.ir.bodies[self.plan.rows[r].1].name
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

    /// The efficient (two-step) solve: each level's weighted rows `(a, b)` of the first
    /// step's solution `first` are whitened by the long-run covariance of its rows,
    /// estimated from the window contributions at the first estimate and shrunk towards its
    /// diagonal ([`stats::efficient_mix`]), and solved again; the standard errors are the
    /// sandwich of the whitened rows. `None` (keep the first step) where a level's
    /// covariance cannot be whitened or the second solve fails.
    #[allow(clippy::too_many_arguments)]
    fn efficient_step(
        &self,
        first: &solve::LsSolution,
        active: &[usize],
        held: &[(usize, f64)],
        (a, b): &(Vec<f64>, Vec<f64>),
        weights: &[f64],
        columns: &[Arc<Column>],
        which: &[usize],
    ) -> Option<(solve::LsSolution, Vec<f64>)> {
        let nr = self.plan.rows.len();
        let na = active.len();
        let levels = &self.store.levels;
        let first_windows = stats::level_windows(
            &first.x, active, held, nr, weights, None, columns, which, levels,
        );
        let alpha = stats::SHRINKAGE;
        let mixes: Vec<Vec<f64>> = first_windows
            .iter()
            .map(|lw| stats::efficient_mix(lw, nr, alpha))
            .collect::<Option<_>>()?;
        // shape: `a` holds `which.len() · nr` rows of `na` columns, `b` as many entries, and
        // every mixing matrix is `nr × nr`: level `pos` is rows `pos · nr ..` of both.
        let mut a2 = vec![0.0; a.len()];
        let mut b2 = vec![0.0; b.len()];
        for (pos, m) in mixes.iter().enumerate() {
            let m = faer::MatRef::from_row_major_slice(&m[..], nr, nr);
            let al =
                faer::MatRef::from_row_major_slice(&a[pos * nr * na..(pos + 1) * nr * na], nr, na);
            let bl = faer::MatRef::from_column_major_slice(&b[pos * nr..(pos + 1) * nr], nr, 1);
            faer::linalg::matmul::matmul(
                faer::MatMut::from_row_major_slice_mut(
                    &mut a2[pos * nr * na..(pos + 1) * nr * na],
                    nr,
                    na,
                ),
                faer::Accum::Replace,
                m,
                al,
                1.0,
                faer::Par::Seq,
            );
            faer::linalg::matmul::matmul(
                faer::MatMut::from_column_major_slice_mut(&mut b2[pos * nr..(pos + 1) * nr], nr, 1),
                faer::Accum::Replace,
                m,
                bl,
                1.0,
                faer::Par::Seq,
            );
        }
        let sol = solve::lstsq(&a2, &b2, b.len(), na, self.rcond).ok()?;
        let windows = stats::level_windows(
            &sol.x,
            active,
            held,
            nr,
            weights,
            Some(&mixes),
            columns,
            which,
            levels,
        );
        let se = {
            stats::efficient_stderr(
                first,
                &sol,
                a,
                b,
                &mixes,
                alpha,
                active,
                nr,
                weights,
                &first_windows,
                &windows,
                columns,
                which,
                levels,
            )
        };
        let finite = sol.x.iter().chain(&se).all(|v| v.is_finite());
        finite.then_some((sol, se))
    }

    fn solve_levels_holding(&self, which: &[usize], held: &[(usize, f64)]) -> Identification {
        let t0 = Instant::now();
        let plan = &self.plan;
        let ncol = plan.unknowns.len();
        let nr = plan.rows.len();
        let columns = self.columns();
        let full: Vec<(Vec<f64>, Vec<f64>)> =
            which.iter().map(|&i| gather(&columns, i, held)).collect();
        let mut c_full = Vec::with_capacity(which.len() * nr * ncol);
        let mut r_full = Vec::with_capacity(which.len() * nr);
        for (c, r) in &full {
            c_full.extend_from_slice(c);
            r_full.extend_from_slice(r);
        }
        let rows = r_full.len();
        // Row normalisation: every row (with its right-hand side) gets unit norm, so rows of
        // weak instruments and quiet levels count as much as loud ones.
        // (Scaled by the row's largest entry first, so that squares cannot overflow.)
        let weights: Vec<f64> = (0..rows)
            .map(|r| {
                let row = || c_full[r * ncol..(r + 1) * ncol].iter().chain([&r_full[r]]);
                let big = row().fold(0.0, |m: f64, v| m.max(v.abs()));
                if !(big > 0.0 && big.is_finite()) {
                    return 0.0;
                }
                let n = big * row().map(|v| (v / big).powi(2)).sum::<f64>().sqrt();
                // A row whose norm is subnormal has no finite weight; such data are refused
                // before the solve (`IdentifyError::Underflow`), and the row counts for
                // nothing here rather than poisoning the matrix with infinities.
                let w = 1.0 / n;
                if w.is_finite() {
                    w
                } else {
                    0.0
                }
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
                // A row of weight zero (not finite, or no finite norm) counts for nothing:
                // written as zeros, never as `0 · inf`.
                let w = weights[i];
                for &j in active {
                    a.push(if w == 0.0 { 0.0 } else { w * c[i * ncol + j] });
                }
                b.push(if w == 0.0 { 0.0 } else { w * r[i] });
            }
            (a, b)
        };
        // Every pass either ends the loop or removes one column from `active`, so it runs at
        // most `ncol + 1` times; the count below makes that bound explicit.
        let mut passes = 0;
        let (sol, se) = loop {
            passes += 1;
            let (a, b) = weighted(&c_full, &r_full, &active);
            let solved = if passes > ncol + 1 {
                Err("the solve made no progress".to_string())
            } else {
                solve::lstsq(&a, &b, rows, active.len(), self.rcond)
            };
            let sol = match solved {
                Ok(sol) => sol,
                Err(why) => {
                    // Nothing can be trusted: every remaining parameter is named, none valued.
                    unident.extend(active.drain(..).map(|j| Unidentifiable {
                        name: names[j].clone(),
                        reason: format!(
                            "{why}: check the data for values far outside the physical range"
                        ),
                    }));
                    break (solve::LsSolution::empty(), vec![]);
                }
            };
            if active.is_empty() {
                break (sol, vec![]);
            }
            // Zero to double precision: the rows are scaled to unit norm, so a column is
            // judged on its own, never against another column with other units (a term like
            // `exp(100 s)` may be 1e17 times larger than `s` and both still be identified).
            if let Some(j) =
                (0..active.len()).find(|&j| sol.col_norms[j] <= ZERO_COLUMN || meanless[active[j]])
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
                    .expect("invariant: `active` is not empty here");
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
            let windows = stats::level_windows(
                &sol.x,
                &active,
                held,
                nr,
                &weights,
                None,
                &columns,
                which,
                &self.store.levels,
            );
            let se = stats::sandwich_stderr(&sol, nr, &windows);
            // An estimate or standard error beyond double precision (data whose products
            // overflow) is no number to print: the parameter is named instead.
            if let Some(j) =
                (0..active.len()).find(|&j| !(sol.x[j].is_finite() && se[j].is_finite()))
            {
                unident.push(Unidentifiable {
                    name: names[active[j]].clone(),
                    reason: "its estimate or standard error is beyond double precision (the \
                             data's products overflow): rescale the data (other units)"
                        .to_string(),
                });
                active.remove(j);
                continue;
            }
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
        let (sol, se) = match self.efficient && !active.is_empty() {
            true => self
                .efficient_step(
                    &sol,
                    &active,
                    held,
                    &weighted(&c_full, &r_full, &active),
                    &weights,
                    &columns,
                    which,
                )
                .unwrap_or((sol, se)),
            false => (sol, se),
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
                            if weights[i] == 0.0 {
                                continue; // a row that counts for nothing (see `weighted`)
                            }
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
        let ssr: f64 = (0..rows)
            .filter(|&i| weights[i] != 0.0)
            .map(|i| {
                let fit: f64 = (0..ncol).map(|j| c_full[i * ncol + j] * p_full[j]).sum();
                (weights[i] * (fit - r_full[i])).powi(2)
            })
            .sum();
        let mut times = self.times;
        times.solve = t0.elapsed();
        Identification {
            shapes: Vec::new(),
            ssr,
            warnings: stats::physical_warnings(self.ir, &params),
            fit_warnings: Vec::new(),
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

#[cfg(test)]
mod tests;
