//! A measured model: the moments of all its levels with the structure of its problem, ready
//! to be solved pooled, per level, over chosen levels, or with some parameters held; and
//! the sub-models read from the same moments (see `super::restrict`).

use super::columns::{gather, Column, ColumnStore};
use super::moments::PhaseTimes;
use super::noise::NoiseSummary;
use super::plan::Plan;
use super::solve::LsSolution;
use super::stats;
use super::types::SIGNIFICANCE_T;
use super::types::{
    EquationResidual, FilterSummary, Identification, LevelInfo, LinearSystem, ParamEstimate,
    Unidentifiable,
};
use super::velocity::VelocityEstimate;
use dynid_ir::ir::ModelIr;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Norm below which a column of the row-normalised least-squares matrix is zero: far below
/// any rounding error of a non-vanishing moment.
const ZERO_COLUMN: f64 = 1e-250;

/// The moments of all levels of one model, ready to be solved pooled or per level
/// (what [`super::measure`] returns).
pub struct Measurement<'m> {
    pub(super) ir: &'m ModelIr,
    pub(super) plan: Plan,
    /// The measured model's moments and the columns of its rows (shared with the
    /// sub-models read from it).
    pub(super) store: Arc<ColumnStore>,
    /// A sub-model's columns: its unknowns' in order, then the right-hand side. `None`:
    /// the measured model itself (its columns are the store's, kept once formed).
    pub(super) cols: Option<Vec<Arc<Column>>>,
    pub(super) infos: Vec<LevelInfo>,
    /// Per level: every signal driving the filters has zero mean (see [`CENTRED_REL`]).
    pub(super) centred: Vec<bool>,
    pub(super) estimated: Vec<VelocityEstimate>,
    pub(super) rcond: f64,
    pub(super) times: PhaseTimes,
    /// Structure search: leave out, one at a time, estimates with `|value| ≤ prune_t · stderr`
    /// (0: off).
    pub(super) prune_t: f64,
    pub(super) noise: NoiseSummary,
    /// Solve twice: the second time with every level's rows whitened by their estimated
    /// covariance ([`stats::efficient_mix`]).
    pub(super) efficient: bool,
    /// The shrinkage of that covariance towards its diagonal: [`stats::SHRINKAGE`], or 1
    /// with [`super::IdentifyOptions::diagonal_weights`].
    pub(super) shrinkage: f64,
    /// Re-estimate the weighting at each new estimate until it settles
    /// ([`super::IdentifyOptions::iterate_weights`]); else the two-step estimate.
    pub(super) iterate_weights: bool,
}
impl<'m> Measurement<'m> {
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
            corners_tried: Vec::new(),
            auto_rows: false,
            weighted_rows: false,
            weight_steps: 0,
            weights_settled: false,
            weights_collapsed: false,
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

    /// The efficient solve: each level's weighted rows `(a, b)` are whitened by the
    /// long-run covariance of its rows, estimated from the window contributions at an
    /// estimate and shrunk towards its diagonal ([`stats::efficient_mix`]), and solved
    /// again — first at the first step's solution `first` (the two-step estimate), then at
    /// each new estimate until no parameter moves by more than [`WEIGHTS_SETTLED`] of its
    /// first-step standard error `first_se` (iterated weighting, at most
    /// [`MAX_WEIGHT_STEPS`] solves). Where the estimate does not settle, or an iterate
    /// collapses ([`collapsed`]), the two-step estimate is kept. The standard errors are
    /// the sandwich of the last whitened rows, corrected for a weighting estimated at the
    /// estimate before it ([`stats::efficient_stderr`]). `None` (keep the first step) where
    /// a level's covariance cannot be whitened, the second solve fails or the two-step
    /// estimate itself collapses.
    #[allow(clippy::too_many_arguments)]
    fn efficient_step(
        &self,
        first: &super::solve::LsSolution,
        first_se: &[f64],
        active: &[usize],
        held: &[(usize, f64)],
        (a, b): &(Vec<f64>, Vec<f64>),
        weights: &[f64],
        columns: &[Arc<Column>],
        which: &[usize],
    ) -> Option<Weighted> {
        let nr = self.plan.rows.len();
        let levels = &self.store.levels;
        let alpha = self.shrinkage;
        let windows_at = |x: &[f64], mixes: Option<&[Vec<f64>]>| {
            stats::level_windows(x, active, held, nr, weights, mixes, columns, which, levels)
        };
        let weigh = |x: &[f64]| -> Option<WeightStep> {
            let from_windows = windows_at(x, None);
            let mixes: Vec<Vec<f64>> = from_windows
                .iter()
                .map(|lw| stats::efficient_mix(lw, nr, alpha))
                .collect::<Option<_>>()?;
            let sol = whitened_solve(a, b, &mixes, nr, active.len(), self.rcond)?;
            Some(WeightStep {
                from_windows,
                mixes,
                sol,
            })
        };
        let scale: Vec<f64> = first_se
            .iter()
            .zip(&first.x)
            .map(|(s, x)| s.max(1e-12 * x.abs()).max(f64::MIN_POSITIVE))
            .collect();
        let two_step = weigh(&first.x)?;
        // The unknown masses among the active columns: what a collapse takes to zero.
        let masses: Vec<bool> = active
            .iter()
            .map(|&j| {
                let p = self.plan.unknowns[j];
                self.ir
                    .bodies
                    .iter()
                    .any(|b| b.mass.param.map(|q| q.index()) == Some(p))
            })
            .collect();
        let lost = |x: &[f64]| collapsed(x, &first.x, first_se, &masses);
        if lost(&two_step.sol.x) {
            return None;
        }
        let mut collapse = false;
        // Iterated: `cur` the last solve (`None`: the two-step one), `prev` the one its
        // weighting was read at (`None`: the two-step one, or the first step's where `cur`
        // is `None`).
        let (mut prev, mut cur): (Option<WeightStep>, Option<WeightStep>) = (None, None);
        let mut steps = 1;
        let mut settled = false;
        while self.iterate_weights && steps < MAX_WEIGHT_STEPS {
            let last = cur.as_ref().unwrap_or(&two_step);
            let Some(next) = weigh(&last.sol.x) else {
                break;
            };
            if lost(&next.sol.x) {
                collapse = true;
                break;
            }
            let change = next
                .sol
                .x
                .iter()
                .zip(&last.sol.x)
                .zip(&scale)
                .map(|((n, c), s)| (n - c).abs() / s)
                .fold(0.0, f64::max);
            prev = cur.replace(next);
            steps += 1;
            if change <= WEIGHTS_SETTLED {
                settled = true;
                break;
            }
        }
        if !settled {
            (prev, cur, steps) = (None, None, 1);
        }
        let last = cur.as_ref().unwrap_or(&two_step);
        let prev_windows;
        let (from, from_cov_windows): (_, &[stats::LevelWindows]) = match (&prev, &cur) {
            (_, None) => (first, &two_step.from_windows),
            (p, Some(_)) => {
                let p = p.as_ref().unwrap_or(&two_step);
                prev_windows = windows_at(&p.sol.x, Some(&p.mixes));
                (&p.sol, &prev_windows)
            }
        };
        let windows = windows_at(&last.sol.x, Some(&last.mixes));
        let se = stats::efficient_stderr(
            from,
            &last.sol,
            a,
            b,
            &last.mixes,
            alpha,
            active,
            nr,
            weights,
            &last.from_windows,
            from_cov_windows,
            &windows,
            columns,
            which,
            levels,
        );
        let sol = cur.map_or(two_step.sol, |c| c.sol);
        let finite = sol.x.iter().chain(&se.se).all(|v| v.is_finite());
        finite.then_some(Weighted {
            sol,
            se,
            steps,
            settled,
            collapse,
        })
    }

    /// The first active column the solve cannot value, with why: a column zero to double
    /// precision (or without the mean it needs), else the one most involved in a
    /// collinearity beyond the condition limit.
    fn rank_loss(
        &self,
        sol: &LsSolution,
        active: &[usize],
        names: &[String],
        meanless: &[bool],
    ) -> Option<(usize, String)> {
        // Zero to double precision: the rows are scaled to unit norm, so a column is
        // judged on its own, never against another column with other units (a term like
        // `exp(100 s)` may be 1e17 times larger than `s` and both still be identified).
        if let Some(j) =
            (0..active.len()).find(|&j| sol.col_norms[j] <= ZERO_COLUMN || meanless[active[j]])
        {
            return Some((j, self.plan.zero_column_reason(active[j])));
        }
        let cond = sol.condition();
        if cond * self.rcond <= 1.0 {
            return None;
        }
        let vmax = sol.v_min.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let j = (0..active.len())
            .max_by(|&x, &y| sol.v_min[x].abs().total_cmp(&sol.v_min[y].abs()))
            .expect("invariant: `active` is not empty here");
        let partners: Vec<String> = (0..active.len())
            .filter(|&k| k != j && sol.v_min[k].abs() >= 0.1 * vmax)
            .map(|k| format!("`{}`", names[active[k]]))
            .collect();
        let reason = format!(
            "its column is collinear with {} (cond {:.1e}) — add an excitation \
             level where the terms are excited differently",
            if partners.is_empty() {
                "the other columns".to_string()
            } else {
                partners.join(", ")
            },
            cond
        );
        Some((j, reason))
    }

    /// The first active column whose estimate cannot be reported, with why: an estimate or
    /// standard error beyond double precision (data whose products overflow: no number to
    /// print), else, in a structure search, the least significant one below the pruning
    /// threshold.
    fn unusable(&self, sol: &LsSolution, se: &[f64]) -> Option<(usize, String)> {
        let n = sol.x.len();
        if let Some(j) = (0..n).find(|&j| !(sol.x[j].is_finite() && se[j].is_finite())) {
            let reason = "its estimate or standard error is beyond double precision (the \
                          data's products overflow): rescale the data (other units)";
            return Some((j, reason.to_string()));
        }
        if self.prune_t <= 0.0 {
            return None;
        }
        let worst = (0..n)
            .filter(|&j| self.prune_t * se[j] >= sol.x[j].abs())
            .max_by(|&x, &y| (se[x] / sol.x[x].abs()).total_cmp(&(se[y] / sol.x[y].abs())))?;
        let reason = format!(
            "not significant, left out by model selection: the estimate \
             {:.3e} is within {} standard errors ({:.1e}) of zero",
            sol.x[worst], self.prune_t, se[worst]
        );
        Some((worst, reason))
    }

    /// The relative residual `‖W (C p − c)‖ / ‖W c‖` of each equation at each of `n_levels`
    /// stacked levels, for the full parameter vector `p_full`.
    fn equation_residuals(
        &self,
        n_levels: usize,
        weights: &[f64],
        c_full: &[f64],
        r_full: &[f64],
        p_full: &[f64],
        windows: &[stats::LevelWindows],
    ) -> Vec<EquationResidual> {
        let plan = &self.plan;
        let nr = plan.rows.len();
        // Per level and row: the estimated variance of the weighted residual row.
        let variances: Vec<Vec<f64>> = if windows.len() == n_levels {
            windows.iter().map(|lw| lw.row_variances(nr)).collect()
        } else {
            Vec::new()
        };
        (0..self.ir.equations.len())
            .map(|l| {
                let (per_level, noise) = (0..n_levels)
                    .map(|pos| {
                        let ncol = p_full.len();
                        let (mut num, mut den) = (0.0, 0.0);
                        // Per unknown: the norm² of its term in this equation's rows.
                        let mut terms = vec![0.0; ncol];
                        for (r, &(_, eq)) in plan.rows.iter().enumerate() {
                            if eq != l {
                                continue;
                            }
                            let i = pos * nr + r;
                            if weights[i] == 0.0 {
                                continue; // a row that counts for nothing (see `weighted_rows`)
                            }
                            num += weighted_residual(c_full, r_full, weights[i], p_full, i).powi(2);
                            den += (weights[i] * r_full[i]).powi(2);
                            for (j, t) in terms.iter_mut().enumerate() {
                                *t += (weights[i] * c_full[i * ncol + j] * p_full[j]).powi(2);
                            }
                        }
                        // An equation without a known term (no input, an unknown mass):
                        // against its largest term instead.
                        if den == 0.0 {
                            den = terms.iter().copied().fold(0.0, f64::max);
                        }
                        let scale = if den > 0.0 { den } else { 1.0 };
                        let noise = variances.get(pos).map(|v| {
                            let s: f64 = plan
                                .rows
                                .iter()
                                .enumerate()
                                .filter(|(_, &(_, eq))| eq == l)
                                .map(|(r, _)| v[r])
                                .sum();
                            (s / scale).sqrt()
                        });
                        ((num / scale).sqrt(), noise)
                    })
                    .unzip::<_, _, Vec<f64>, Vec<Option<f64>>>();
                EquationResidual {
                    equation: self.ir.bodies[l].name.clone(),
                    per_level,
                    noise: noise.into_iter().flatten().collect(),
                }
            })
            .collect()
    }

    /// Solve the levels `which` pooled with the parameters `held` fixed at their values.
    ///
    /// Long: the loop that leaves out one column per pass (rank loss, estimates that cannot
    /// be reported) keeps the active columns and the reasons across passes, and the result
    /// is assembled from all of it.
    fn solve_levels_holding(&self, which: &[usize], held: &[(usize, f64)]) -> Identification {
        let t0 = Instant::now();
        let plan = &self.plan;
        let ncol = plan.unknowns.len();
        let nr = plan.rows.len();
        let columns = self.columns();
        let (c_full, r_full) = stack_rows(&columns, which, held, nr * ncol, nr);
        let rows = r_full.len();
        let weights = row_weights(&c_full, &r_full, ncol);
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
        let weighted =
            |c: &[f64], r: &[f64], active: &[usize]| weighted_rows(c, r, &weights, ncol, active);
        // Every pass either ends the loop or removes one column from `active`, so it runs at
        // most `ncol + 1` times; the count below makes that bound explicit.
        let mut passes = 0;
        let (sol, se, windows) = loop {
            passes += 1;
            let (a, b) = weighted(&c_full, &r_full, &active);
            let solved = if passes > ncol + 1 {
                Err("the solve made no progress".to_string())
            } else {
                super::solve::lstsq(&a, &b, rows, active.len(), self.rcond)
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
                    break (
                        super::solve::LsSolution::empty(),
                        stats::Spread::none(),
                        Vec::new(),
                    );
                }
            };
            if active.is_empty() {
                break (sol, stats::Spread::none(), Vec::new());
            }
            if let Some((j, reason)) = self.rank_loss(&sol, &active, &names, &meanless) {
                unident.push(Unidentifiable {
                    name: names[active[j]].clone(),
                    reason,
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
            if let Some((j, reason)) = self.unusable(&sol, &se.se) {
                unident.push(Unidentifiable {
                    name: names[active[j]].clone(),
                    reason,
                });
                active.remove(j);
                continue;
            }
            break (sol, se, windows);
        };
        let second = (self.efficient && !active.is_empty())
            .then(|| {
                self.efficient_step(
                    &sol,
                    &se.se,
                    &active,
                    held,
                    &weighted(&c_full, &r_full, &active),
                    &weights,
                    &columns,
                    which,
                )
            })
            .flatten();
        let weighted_rows = second.is_some();
        let weight_steps = second.as_ref().map_or(0, |w| w.steps);
        let weights_settled = second.as_ref().is_some_and(|w| w.settled);
        let weights_collapsed = second.as_ref().is_some_and(|w| w.collapse);
        let (sol, se) = second.map_or((sol, se), |w| (w.sol, w.se));

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
                stderr: se.se[k],
                significant: sol.x[k].abs() > SIGNIFICANCE_T * se.se[k],
            })
            .collect::<Vec<_>>();
        // Residuals per equation and level, on the weighted rows.
        let residual =
            self.equation_residuals(which.len(), &weights, &c_full, &r_full, &p_full, &windows);
        let ssr = weighted_ssr(&weights, &c_full, &r_full, &p_full);
        let mut times = self.times;
        times.solve = t0.elapsed();
        Identification {
            shapes: Vec::new(),
            ssr,
            warnings: stats::physical_warnings(self.ir, &params),
            fit_warnings: Vec::new(),
            params,
            covariance: se.cov,
            unidentifiable: unident,
            condition: sol.condition(),
            residual,
            levels: which.iter().map(|&i| self.infos[i].clone()).collect(),
            filter: FilterSummary {
                weighted_rows,
                weight_steps,
                weights_settled,
                weights_collapsed,
                ..self.filter_summary()
            },
            estimated: self.estimated.clone(),
            rows,
            noise: self.noise.clone(),
            times,
        }
    }
}

/// A weighted estimate of a mass below this fraction of the unit-norm rows' significant
/// estimate has collapsed, not measured it ([`collapsed`]).
const COLLAPSE: f64 = 0.1;

/// Whether the weighted estimate `x` has collapsed onto the trivial solution of an
/// equation without a known term: a body's unknown mass (`masses`: which of the columns
/// are) that the unit-norm rows' estimate `first` (standard errors `first_se`) found
/// significant has lost more than nine tenths of its magnitude. Only a body with an
/// unknown mass and no input has such an equation, and zero satisfies it whatever the
/// data: unit-norm rows attenuate its parameters towards zero and weighting undoes that
/// (on every well-modelled record measured the masses grew, by up to a factor two at 5 %
/// noise), but where the model lacks a force the data show (Coulomb friction withheld from
/// a two-mass structure measured by accelerometers) no nonzero parameters satisfy it,
/// weights re-estimated at each new estimate grow on the rows that small parameters
/// satisfy, and the iteration settled with the body's mass and coupling at 1e-11 (seeds
/// 1–6, measured with the CLI). Other parameters are not judged: a small damping that the
/// unit-norm rows overestimate significantly may rightly lose most of it.
fn collapsed(x: &[f64], first: &[f64], first_se: &[f64], masses: &[bool]) -> bool {
    x.iter()
        .zip(first)
        .zip(first_se)
        .zip(masses)
        .any(|(((x, f), s), &mass)| {
            mass && f.abs() > super::types::SIGNIFICANCE_T * s && x.abs() < COLLAPSE * f.abs()
        })
}

/// Most solves of the iterated weighting ([`Measurement::efficient_step`]), the two-step
/// solve included.
const MAX_WEIGHT_STEPS: usize = 20;
/// The iterated weighting has settled when no parameter moves by more than this fraction
/// of its first-step standard error from one solve to the next.
const WEIGHTS_SETTLED: f64 = 1e-3;

/// One weighting step: the windows at the estimate it was estimated at, each level's
/// whitening and the solve of the whitened rows.
struct WeightStep {
    from_windows: Vec<stats::LevelWindows>,
    mixes: Vec<Vec<f64>>,
    sol: super::solve::LsSolution,
}

/// The weighted solve kept: its solution and standard errors, how many weighting steps it
/// took and whether they settled.
struct Weighted {
    sol: super::solve::LsSolution,
    se: stats::Spread,
    steps: usize,
    settled: bool,
    /// The iteration stopped where an estimate collapsed ([`collapsed`]); the two-step
    /// estimate is kept.
    collapse: bool,
}

/// The rows `(a, b)` (row-major `a` of `na` columns; `nr` rows per level, level after
/// level) whitened level by level by `mixes` (each `nr × nr`) and solved by SVD.
fn whitened_solve(
    a: &[f64],
    b: &[f64],
    mixes: &[Vec<f64>],
    nr: usize,
    na: usize,
    rcond: f64,
) -> Option<super::solve::LsSolution> {
    // shape: `a` holds `mixes.len() · nr` rows of `na` columns, `b` as many entries, and
    // every mixing matrix is `nr × nr`: level `pos` is rows `pos · nr ..` of both.
    let mut a2 = vec![0.0; a.len()];
    let mut b2 = vec![0.0; b.len()];
    for (pos, m) in mixes.iter().enumerate() {
        let m = faer::MatRef::from_row_major_slice(&m[..], nr, nr);
        let al = faer::MatRef::from_row_major_slice(&a[pos * nr * na..(pos + 1) * nr * na], nr, na);
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
    super::solve::lstsq(&a2, &b2, b.len(), na, rcond).ok()
}

/// The rows `(C, c)` of the levels `which` stacked, level after level (`per_level_c` and
/// `per_level_r` entries each), with the parameters `held` moved to the right-hand side.
fn stack_rows(
    columns: &[Arc<Column>],
    which: &[usize],
    held: &[(usize, f64)],
    per_level_c: usize,
    per_level_r: usize,
) -> (Vec<f64>, Vec<f64>) {
    let full: Vec<(Vec<f64>, Vec<f64>)> = which.iter().map(|&i| gather(columns, i, held)).collect();
    let mut c_full = Vec::with_capacity(which.len() * per_level_c);
    let mut r_full = Vec::with_capacity(which.len() * per_level_r);
    for (c, r) in &full {
        c_full.extend_from_slice(c);
        r_full.extend_from_slice(r);
    }
    (c_full, r_full)
}

/// Row normalisation: every row (with its right-hand side) gets unit norm, so rows of weak
/// instruments and quiet levels count as much as loud ones. (Scaled by the row's largest
/// entry first, so that squares cannot overflow.)
pub(super) fn row_weights(c_full: &[f64], r_full: &[f64], ncol: usize) -> Vec<f64> {
    (0..r_full.len())
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
        .collect()
}

/// The weighted rows `W C` (columns `active` only) and `W c`; a row of weight zero (not
/// finite, or no finite norm) counts for nothing: written as zeros, never as `0 · inf`.
fn weighted_rows(
    c: &[f64],
    r: &[f64],
    weights: &[f64],
    ncol: usize,
    active: &[usize],
) -> (Vec<f64>, Vec<f64>) {
    let rows = r.len();
    let mut a = Vec::with_capacity(rows * active.len());
    let mut b = Vec::with_capacity(rows);
    for i in 0..rows {
        let w = weights[i];
        for &j in active {
            a.push(if w == 0.0 { 0.0 } else { w * c[i * ncol + j] });
        }
        b.push(if w == 0.0 { 0.0 } else { w * r[i] });
    }
    (a, b)
}

/// The weighted residual of the fit `p_full` on row `i`, `w (C p − c)` (zero-weight rows
/// excluded by the callers).
fn weighted_residual(c_full: &[f64], r_full: &[f64], w: f64, p_full: &[f64], i: usize) -> f64 {
    let ncol = p_full.len();
    let fit: f64 = (0..ncol).map(|j| c_full[i * ncol + j] * p_full[j]).sum();
    w * (fit - r_full[i])
}

/// The weighted sum of squared residuals of the fit `p_full` over all rows.
fn weighted_ssr(weights: &[f64], c_full: &[f64], r_full: &[f64], p_full: &[f64]) -> f64 {
    (0..r_full.len())
        .filter(|&i| weights[i] != 0.0)
        .map(|i| weighted_residual(c_full, r_full, weights[i], p_full, i).powi(2))
        .sum()
}
