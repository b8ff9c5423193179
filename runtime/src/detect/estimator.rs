//! Templates of the estimator itself (indirect inference).
//!
//! Statistical linearisation predicts what an *ideal* equivalent-linear system would do.
//! The covariance fit of a linear model to a strongly non-Gaussian response does not
//! quite do that: on a hardening spring its damping rises with the level too, and a
//! strong nonlinearity leaks drift into the parameters of the elements next to it. Read
//! as data, those artefacts become a second effect or a flagged neighbour.
//!
//! So every candidate effect of a drifting element is also tried as the estimator sees it.
//! The model with the candidate `p·φ(s, v)` added at the element is first identified once,
//! all levels pooled, from the measured data (`runs::identified`): every parameter and p as
//! the data support them under this hypothesis. That model is driven by the *measured*
//! inputs of every level (their first [`DetectOptions::sim_samples`] samples, from the
//! measured initial state) and identified per level exactly as the data were (same linear
//! model, same filter corners and order, masses held the same way). The difference of
//! each parameter's curve from the run with p = 0 — same inputs, so the estimator's own
//! scatter cancels — is the drift the candidate predicts for this fit on these data, for
//! every parameter of the element and of its neighbours (elements sharing a body). p is
//! fitted so that the measured curves minus the predicted drift are as constant as
//! possible (weighted χ² about each curve's mean, over the element and its neighbours),
//! interpolating the drift linearly between [`P_FACTORS`] multiples of the identified p.
//!
//! Not the per-level fits' mean parameters as the base: those fits lack the effect and are
//! biased by it, most from accelerations (the two-mass structure with friction at its
//! coupling, noiseless, seed 41, unit-norm rows: k1 = 4.80, m2 held at 1.71, truth 4 and
//! 2; the identified model 4.02, 1.99), and the drift predicted from them is that of
//! another system. Where the identification fails or gives p of the other sign, an
//! unphysical value or masses shrunk below `runs::MASS_SHRINK_LIMIT` of those held (the
//! sign of a hypothesis that does not fit), the statistical linearisation's values are
//! the base (the levels' means, the element's linear part and p from the template).
//!
//! A candidate *explains* the element when, after its predicted drift is removed, no curve
//! of the element drifts by the constancy test. The best explaining single effect
//! (smallest χ²) becomes the verdict, and a pair or an `also suspected` second effect is
//! kept only when no single effect explains the element. Any other element whose curves no
//! longer drift once the candidate's predicted leak is removed is reported linear, with
//! the reason. Where no single effect explains the element and its verdict is a pair of
//! effects (or a single one with the pair's second effect suspected), the pair is run once
//! for that check alone, from the model identified with both effects (else at the
//! linearisation's coefficients).
//!
//! This module picks the elements and applies the verdicts; `runs` simulates the estimator
//! on each candidate, `score` fits p to the measured curves and tests what is left.

mod runs;
mod score;

use dynid_ir::ir::{ModelIr, Node};

use super::candidate::Candidate;
use super::format::{fmt_g, fmt_pm};
use super::from_data::{groups, LevelFits};
use super::types::{DetectOptions, Detection, EstimatorFit, Role, Verdict};
use crate::data::LevelSource;
use crate::ident::IdentifyOptions;
use crate::record::Record;
use rayon::prelude::*;
use runs::{
    head_record, held_masses, identified, identified_pair, pair_of, singles_of, Pooled, Runner,
    Trial,
};
use score::{fit_p, still_drifting, Scoped};
use std::sync::atomic::AtomicUsize;

/// Multiples of the identified p (or of the statistical linearisation's, where the
/// identification fails) at which the estimator is run; 0 is the reference run, the linear
/// model alone on the same inputs. Dense about 1: the per-level fits can respond to p far
/// from linearly (from accelerations, a coupling's k2 fell from 2.94 to 1.21 between 0.8
/// and 1.2 times p on the two-mass friction record, measured once), and the identified p
/// is close to the one that fits.
pub const P_FACTORS: [f64; 9] = [0.0, 0.4, 0.8, 0.9, 1.0, 1.1, 1.2, 1.7, 2.4];

/// Steps of the fine grid in p over which the interpolated χ² is minimised.
const P_STEPS: usize = 240;

/// Refine the verdicts of `det` by the estimator's own templates (module doc). Elements
/// whose candidates cannot be simulated (user-declared effects, closed loops) keep the
/// statistical-linearisation verdict. `progress(done, total)` is called as the template
/// simulations finish (`total` grows as elements are reached; one call per simulation, from
/// the worker threads).
///
/// Longer than most functions here: one pass over the drifting elements, strongest first,
/// in which an element explained as another's leak is skipped; the pass's state (the
/// explained flags, the progress counters, the shared inputs) would otherwise travel
/// through every step as arguments.
pub(crate) fn refine(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    ident: &IdentifyOptions,
    opts: &DetectOptions,
    fits: &LevelFits,
    det: &mut Detection,
    progress: &(dyn Fn(usize, usize) + Sync),
) {
    if opts.sim_samples < 2 || !ir.controls.is_empty() || !ir.references.is_empty() {
        return;
    }
    let mut targets: Vec<usize> = (0..det.elements.len())
        .filter(|&i| {
            !matches!(
                det.elements[i].verdict,
                Verdict::Linear | Verdict::TooFewLevels { .. }
            ) && !det.elements[i].ranking.is_empty()
        })
        .collect();
    if targets.is_empty() {
        return;
    }
    targets.sort_by(|&a, &b| {
        det.elements[b]
            .constant_chi2
            .total_cmp(&det.elements[a].constant_chi2)
    });
    let Some(heads) = levels
        .iter()
        .map(|s| head_record(ir, *s, opts.sim_samples, ident.chunk_len))
        .collect::<Option<Vec<_>>>()
    else {
        return;
    };
    let share: Vec<f64> = heads
        .iter()
        .map(|(r, n)| (r.len() as f64 / (*n).max(1) as f64).min(1.0))
        .collect();
    let inputs: Vec<Record> = heads.into_iter().map(|(r, _)| r).collect();
    // The same filter bank and rows as the measured fits (the corners given, the rows
    // would no longer be chosen: they are asked for).
    let mut sim_ident = ident.clone();
    if let Some(f) = fits.fits.first() {
        sim_ident.corners = Some(f.filter.corners.clone());
        sim_ident.order = Some(f.filter.order);
    }
    sim_ident.efficient = fits.rows.weighted();
    let sites = groups(ir);
    let held = held_masses(ir, &fits.input.held);
    let pooled = Pooled {
        ir,
        levels,
        ident: &sim_ident,
        held_masses: &held,
    };
    // The linear part at the levels' values: held masses at their held values, every other
    // unknown at the weighted mean of its curve.
    let mut base = ir.clone();
    for h in &fits.input.held {
        let _ = base.set_nominal(&h.param, h.value);
    }
    for r in &det.params {
        let _ = base.set_nominal(&r.curve.param, r.mean);
    }
    let builtins = Candidate::builtins();
    let names: Vec<String> = det.elements.iter().map(|e| e.element.clone()).collect();
    let params = det.params.clone();
    let mut explained: Vec<bool> = vec![false; det.elements.len()];
    let done = AtomicUsize::new(0);
    let total = AtomicUsize::new(0);
    for &ti in &targets {
        if explained[ti] {
            continue;
        }
        let name = det.elements[ti].element.clone();
        let Some(site) = sites.iter().find(|s| s.name == name) else {
            continue;
        };
        let neighbours: Vec<usize> = (0..det.elements.len())
            .filter(|&j| j != ti)
            .filter(|&j| {
                sites
                    .iter()
                    .find(|s| s.name == det.elements[j].element)
                    .is_some_and(|s| shares_body(s.nodes, site.nodes))
            })
            .collect();
        // Single-effect templates of the element, with their p and shape.
        let singles = singles_of(&det.elements[ti], &builtins);
        if singles.is_empty() {
            continue;
        }
        let (a, b) = (
            ir.node_name(site.nodes.0).to_string(),
            ir.node_name(site.nodes.1).to_string(),
        );
        let singles: Vec<_> = singles
            .into_par_iter()
            .map(|s| identified(&pooled, (&a, &b), s))
            .collect();
        let runner = Runner {
            ir,
            base: &base,
            site: (&a, &b),
            inputs: &inputs,
            sim_ident: &sim_ident,
            hold_inertia: opts.hold_inertia,
            done: &done,
            total: &total,
            progress,
        };
        let trials = runner.trials(&singles);
        let in_scope = |el: usize| -> Vec<Scoped> {
            params
                .iter()
                .filter(|r| {
                    r.curve.element == names[el]
                        && matches!(r.curve.role, Role::Stiffness | Role::Damping)
                })
                .map(|r| Scoped {
                    curve: &r.curve,
                    se: &r.stderrs_used,
                })
                .collect()
        };
        let mut scope = in_scope(ti);
        for &j in &neighbours {
            scope.extend(in_scope(j));
        }
        // Curves of `el` with the trial's drift at p removed, and whether any still drifts.
        let corrected =
            |t: &Trial, el: usize, p: f64| still_drifting(&params, &names[el], t, p, &share, opts);
        let fitted = rank_trials(&trials, &scope, &share, &builtins, |t, p| {
            corrected(t, ti, p)
        });
        let winner = fitted.first().filter(|f| f.explains).cloned();
        let Some(w) = winner else {
            det.elements[ti].estimator = fitted;
            // No single effect explains the element. Where its verdict is a pair, or a
            // single effect with the pair's second one suspected, the pair run through
            // the estimator — at the model identified with both, else at the
            // linearisation's coefficients — says which drifts of other elements are its
            // leak.
            let Some(pair) = pair_of(&det.elements[ti], &builtins) else {
                continue;
            };
            let (pair, from_data) = identified_pair(&pooled, (&a, &b), pair);
            let Some(t) = runner.pair(&pair) else {
                continue;
            };
            let coefs: Vec<String> = pair
                .terms
                .iter()
                .map(|(_, name, p, _)| format!("{name} = {}", fmt_g(*p)))
                .collect();
            let cause = format!(
                "{} at {name} predicts in this fit ({}, {})",
                pair.effect,
                coefs.join(", "),
                if from_data {
                    "as identified"
                } else {
                    "as linearised"
                }
            );
            quiet_leaks(det, &mut explained, ti, &cause, |j| corrected(&t, j, 1.0));
            continue;
        };
        let t = trials
            .iter()
            .find(|t| t.effect == w.effect)
            .expect("invariant: the winner is one of the trials");
        let finding = &mut det.elements[ti];
        finding.estimator = fitted;
        finding.verdict = Verdict::Nonlinear {
            best: w.effect.clone(),
            summary: format!(
                "{} = {} (drift predicted for this fit by simulating it; no curve of the \
                 element drifts once it is removed)",
                w.coef_name,
                fmt_pm(w.value, w.stderr)
            ),
        };
        finding.suspected = None;
        let cause = format!(
            "{} at {} predicts in this fit ({} = {})",
            w.effect,
            name,
            w.coef_name,
            fmt_pm(w.value, w.stderr)
        );
        quiet_leaks(det, &mut explained, ti, &cause, |j| {
            corrected(t, j, w.value)
        });
    }
}

/// Report as linear, with `cause` as the reason, every other flagged element `j` whose
/// curves no longer drift once the predicted leak is removed (`corrected(j)`: the curves
/// still drifting, and whether every one had a prediction). Every element of the model is
/// checked, not only the neighbours of `ti`: the simulated fits are of the whole model,
/// and along a chain of bodies a strong joint's leak reaches past the elements next to it.
fn quiet_leaks(
    det: &mut Detection,
    explained: &mut [bool],
    ti: usize,
    cause: &str,
    corrected: impl Fn(usize) -> (Vec<String>, bool),
) {
    let quiet: Vec<usize> = (0..det.elements.len())
        .filter(|&j| j != ti && det.elements[j].verdict != Verdict::Linear)
        .filter(|&j| {
            let (left, ok) = corrected(j);
            ok && left.is_empty()
        })
        .collect();
    for j in quiet {
        let n = &mut det.elements[j];
        n.explained_by = Some(format!(
            "its drift is the leak that {cause}; none is left once that is removed"
        ));
        n.verdict = Verdict::Linear;
        n.suspected = None;
        explained[j] = true;
    }
}

/// Every trial with p fitted to the curves in `scope`, explaining effects first (none of
/// the element's curves left drifting, by `element_left`), then by χ² plus 2 per shape
/// parameter.
fn rank_trials(
    trials: &[Trial],
    scope: &[Scoped],
    share: &[f64],
    builtins: &[Candidate],
    element_left: impl Fn(&Trial, f64) -> (Vec<String>, bool),
) -> Vec<EstimatorFit> {
    let mut fitted: Vec<EstimatorFit> = Vec::new();
    let mut scores: Vec<f64> = Vec::new();
    for t in trials {
        let Some((p, half, chi2)) = fit_p(t, scope, share) else {
            continue;
        };
        let (left, ok) = element_left(t, p);
        let explains = ok && left.is_empty();
        let n_points: usize = scope.iter().map(|s| s.curve.values.len()).sum();
        let dof = n_points.saturating_sub(scope.len() + 1);
        fitted.push(EstimatorFit {
            effect: t.effect.clone(),
            coef_name: t.coef_name.clone(),
            value: p,
            stderr: half,
            chi2,
            dof,
            still_drifting: left,
            explains,
        });
        scores.push(chi2 + 2.0 * shaped_count(builtins, &t.effect) as f64);
    }
    // Explaining effects first, then by χ² plus 2 per shape parameter (a backlash's gap
    // lets it mimic a cubic spring over a few levels).
    let mut order: Vec<usize> = (0..fitted.len()).collect();
    order.sort_by(|&a, &b| {
        fitted[b]
            .explains
            .cmp(&fitted[a].explains)
            .then(scores[a].total_cmp(&scores[b]))
    });
    order.into_iter().map(|i| fitted[i].clone()).collect()
}

/// Whether two elements act on a common body.
fn shares_body(a: (Node, Node), b: (Node, Node)) -> bool {
    [a.0, a.1]
        .iter()
        .any(|n| matches!(n, Node::Body(_)) && (*n == b.0 || *n == b.1))
}

/// 1 for a built-in effect with a shape parameter, else 0.
fn shaped_count(builtins: &[Candidate], effect: &str) -> usize {
    builtins
        .iter()
        .find(|c| c.name == effect)
        .map_or(0, |c| usize::from(c.shape.is_some()))
}
