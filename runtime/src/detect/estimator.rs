//! Templates of the estimator itself (indirect inference).
//!
//! Statistical linearisation predicts what an *ideal* equivalent-linear system would do.
//! The covariance fit of a linear model to a strongly non-Gaussian response does not
//! quite do that: on a hardening spring its damping rises with the level too, and a
//! strong nonlinearity leaks drift into the parameters of the elements next to it. Read
//! as data, those artefacts become a second effect or a flagged neighbour.
//!
//! So every candidate effect of a drifting element is also tried as the estimator sees it:
//! the linear model, at the parameters the levels gave, plus the candidate `p·φ(s, v)` at
//! the element is driven by the *measured* inputs of every level (their first
//! [`DetectOptions::sim_samples`] samples, from the measured initial state) and identified
//! per level exactly as the data were (same linear model, same filter corners and order,
//! masses held the same way). The difference of each parameter's curve from the run with
//! p = 0 — same inputs, so the estimator's own scatter cancels — is the drift the candidate
//! predicts for this fit on these data, for every parameter of the element and of its
//! neighbours (elements sharing a body). p is fitted so that the measured curves minus
//! the predicted drift are as constant as possible (weighted χ² about each curve's mean,
//! over the element and its neighbours), interpolating the drift linearly between
//! [`P_FACTORS`] multiples of the statistical-linearisation estimate.
//!
//! A candidate *explains* the element when, after its predicted drift is removed, no curve
//! of the element drifts by the constancy test. The best explaining single effect
//! (smallest χ²) becomes the verdict, and a pair or an `also suspected` second effect is
//! kept only when no single effect explains the element. A neighbour whose curves no
//! longer drift once the candidate's predicted leak is removed is reported linear, with
//! the reason.

use rayon::prelude::*;

use dynid_ir::edit::NewTerm;
use dynid_ir::ir::{BinaryOp, ExprArena, ExprId, ExprNode, ModelIr, Node, SignalKind, UnaryOp};

use super::{constancy_test, fmt_pm, Candidate, DetectOptions, Detection, ParamCurve, Role};
use super::{EstimatorFit, LevelFits, Verdict};
use crate::data::{LevelSource, RecordSource};
use crate::ident::IdentifyOptions;
use crate::record::Record;
use crate::sim::{simulate_driven_from, Start};

/// Multiples of the statistical-linearisation estimate of p at which the estimator is run
/// (0 is the reference run: the linear model alone on the same inputs).
pub const P_FACTORS: [f64; 6] = [0.0, 0.4, 0.8, 1.2, 1.7, 2.4];

/// Steps of the fine grid in p over which the interpolated χ² is minimised.
const P_STEPS: usize = 240;

/// RK4 steps per sample of the driven runs.
const SUBSTEPS: usize = 4;

/// Builds a force basis from the element's s and v.
type BasisFn = Box<dyn Fn(&mut ExprArena, ExprId, ExprId) -> ExprId>;

/// A single-effect template of the element: effect, coefficient name, its estimate, the
/// shape θ and the element's linear parts, as the statistical linearisation fitted them.
struct Single {
    effect: String,
    coef: String,
    p: f64,
    theta: f64,
    linear_parts: Vec<(String, f64)>,
}

/// The force basis of a built-in candidate as an expression of the element's s and v, with
/// its shape θ; `None` for a candidate the language cannot write (a user-declared one).
fn basis_of(name: &str, theta: f64) -> Option<BasisFn> {
    Some(match name {
        "cubic stiffness" => Box::new(|a: &mut ExprArena, s, _| a.intern(ExprNode::Powi(s, 3))),
        "Coulomb friction" => Box::new(|a: &mut ExprArena, _, v| a.unary(UnaryOp::Sign, v)),
        "quadratic damping" => Box::new(|a: &mut ExprArena, _, v| {
            let av = a.unary(UnaryOp::Abs, v);
            a.binary(BinaryOp::Mul, v, av)
        }),
        "prestress" => Box::new(|a: &mut ExprArena, s, _| a.unary(UnaryOp::Sign, s)),
        "backlash" if theta.is_finite() && theta > 0.0 => {
            Box::new(move |a: &mut ExprArena, s, _| {
                a.intern(ExprNode::Deadzone(s, theta.to_bits()))
            })
        }
        _ => return None,
    })
}

/// The first `max` samples of every measured signal of a level, as a record, and the
/// level's length. When the head is shorter than the level, its input columns are scaled
/// to the standard deviation of the whole level: the drift of an effect of s grows with
/// the level's intensity, and a head whose input happens to be a few per cent weaker than
/// the whole record would predict a drift that much smaller.
fn head_record(
    ir: &ModelIr,
    src: &dyn LevelSource,
    max: usize,
    chunk: usize,
) -> Option<(Record, usize)> {
    let measured = ir.measured_signals();
    let mut cols: Vec<Vec<f64>> = measured.iter().map(|_| Vec::new()).collect();
    // Sums about the first sample of each column, over the whole level.
    let mut shift: Vec<Option<f64>> = vec![None; measured.len()];
    let mut s1 = vec![0.0; measured.len()];
    let mut s2 = vec![0.0; measured.len()];
    let mut n = 0usize;
    src.stream(chunk, &mut |c, len| {
        for (j, s) in measured.iter().enumerate() {
            let Some(x) = c.get(s.index()).filter(|x| x.len() >= len) else {
                continue;
            };
            let take = max.saturating_sub(cols[j].len()).min(len);
            cols[j].extend_from_slice(&x[..take]);
            let sh = *shift[j].get_or_insert(x.first().copied().unwrap_or(0.0));
            for &v in &x[..len] {
                s1[j] += v - sh;
                s2[j] += (v - sh) * (v - sh);
            }
        }
        n += len;
    })
    .ok()?;
    let sd = |s1: f64, s2: f64, n: usize| {
        let nf = n.max(1) as f64;
        (s2 / nf - (s1 / nf).powi(2)).max(0.0).sqrt()
    };
    for (j, s) in measured.iter().enumerate() {
        let col = &mut cols[j];
        if col.len() >= n || !matches!(ir.signal(*s).kind, SignalKind::Input(_)) {
            continue;
        }
        let sh = col.first().copied().unwrap_or(0.0);
        let (a, b) = col.iter().fold((0.0, 0.0), |(a, b), v| {
            (a + v - sh, b + (v - sh) * (v - sh))
        });
        let (whole, head) = (sd(s1[j], s2[j], n), sd(a, b, col.len()));
        if whole > 0.0 && head > 0.0 && whole.is_finite() && head.is_finite() {
            let mean = sh + a / col.len() as f64;
            let g = whole / head;
            col.iter_mut().for_each(|v| *v = mean + g * (*v - mean));
        }
    }
    Some((
        Record {
            names: measured
                .iter()
                .map(|s| ir.signal(*s).name.clone())
                .collect(),
            columns: cols,
            ts: src.ts(),
            t0: 0.0,
        },
        n,
    ))
}

/// Per parameter name: the values and standard errors of its curve from the per-level fits
/// of simulated levels.
type Curves = Vec<(String, Vec<f64>, Vec<f64>)>;

/// Drive `model` with the level inputs and fit the linear model `ir` per level.
fn estimator_curves(
    ir: &ModelIr,
    model: &ModelIr,
    inputs: &[Record],
    ident: &IdentifyOptions,
    hold_inertia: bool,
) -> Option<Curves> {
    let sims: Vec<Record> = inputs
        .iter()
        .map(|r| simulate_driven_from(model, r, SUBSTEPS, Start::Measured).ok())
        .collect::<Option<_>>()?;
    let srcs: Vec<RecordSource> = sims
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("simulated level {}", i + 1)).ok())
        .collect::<Option<_>>()?;
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let fits = super::level_fits(ir, &levels, ident, hold_inertia).ok()?;
    Some(
        fits.input
            .curves
            .into_iter()
            .map(|c| (c.param, c.values, c.stderrs))
            .collect(),
    )
}

fn shares_body(a: (Node, Node), b: (Node, Node)) -> bool {
    [a.0, a.1]
        .iter()
        .any(|n| matches!(n, Node::Body(_)) && (*n == b.0 || *n == b.1))
}

/// A candidate evaluated through the estimator.
struct Trial {
    effect: String,
    coef_name: String,
    /// p at every factor of [`P_FACTORS`].
    ps: Vec<f64>,
    /// Per factor, the curves of the simulated fits.
    curves: Vec<Curves>,
}

/// The measured curves in the scope of one element: (param, element, values, stderrs used).
struct Scoped<'a> {
    curve: &'a ParamCurve,
    se: &'a [f64],
}

/// Predicted drift of `param` at `p` (linear interpolation between the trial's runs) and
/// the standard error it adds: the simulated fits' own, times √(1 − n_sim/n) per level — a
/// simulated level as long as the measured one shares its input realisation and the
/// scatter cancels in the comparison; a short one does not.
fn drift(t: &Trial, param: &str, p: f64, share: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let get = |k: usize| -> Option<(&Vec<f64>, &Vec<f64>)> {
        t.curves[k]
            .iter()
            .find(|(n, _, _)| n == param)
            .map(|(_, v, e)| (v, e))
    };
    let (base, _) = get(0)?;
    // The runs' p are monotone (multiples 0 < f₁ < … of one estimate, of either sign):
    // find the interval that holds p and interpolate linearly within it.
    let n = t.ps.len() - 1;
    let (p0, plast) = (t.ps[0], t.ps[n]);
    let u = if plast != p0 {
        (p - p0) / (plast - p0)
    } else {
        0.0
    };
    let us: Vec<f64> =
        t.ps.iter()
            .map(|q| {
                if plast != p0 {
                    (q - p0) / (plast - p0)
                } else {
                    0.0
                }
            })
            .collect();
    let u = u.clamp(0.0, 1.0);
    let k = (0..n).find(|&k| u <= us[k + 1]).unwrap_or(n - 1);
    let f = if us[k + 1] > us[k] {
        ((u - us[k]) / (us[k + 1] - us[k])).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let ((a, ea), (b, eb)) = (get(k)?, get(k + 1)?);
    if base.len() != share.len() || a.len() != share.len() || b.len() != share.len() {
        return None;
    }
    Some(
        (0..base.len())
            .map(|l| {
                let d = (1.0 - f) * (a[l] - base[l]) + f * (b[l] - base[l]);
                let e = ((1.0 - f) * ea[l] + f * eb[l]) * (1.0 - share[l]).max(0.0).sqrt();
                (d, if e.is_finite() { e } else { 0.0 })
            })
            .unzip(),
    )
}

/// The curve with the predicted drift removed and the combined standard errors.
fn corrected_curve(c: &ParamCurve, se: &[f64], d: &[f64], e: &[f64]) -> ParamCurve {
    let mut c = c.clone();
    c.values.iter_mut().zip(d).for_each(|(y, d)| *y -= d);
    c.stderrs = se.iter().zip(e).map(|(a, b)| a.hypot(*b)).collect();
    c
}

/// χ² about the weighted mean of `y − Δ(p)`, summed over the scoped curves.
fn chi2_at(t: &Trial, scope: &[Scoped], p: f64, share: &[f64]) -> f64 {
    let mut chi2 = 0.0;
    for s in scope {
        let Some((d, e)) = drift(t, &s.curve.param, p, share) else {
            return f64::INFINITY;
        };
        let c = corrected_curve(s.curve, s.se, &d, &e);
        let (m, _) = super::fit::weighted_mean(&c.values, &c.stderrs);
        chi2 += c
            .values
            .iter()
            .zip(&c.stderrs)
            .map(|(y, e)| ((y - m) / e).powi(2))
            .sum::<f64>();
    }
    chi2
}

/// Refine the verdicts of `det` by the estimator's own templates (module doc). Elements
/// whose candidates cannot be simulated (user-declared effects, closed loops) keep the
/// statistical-linearisation verdict. `progress(done, total)` is called as the template
/// simulations finish (`total` grows as elements are reached; one call per simulation, from
/// the worker threads).
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
    // The same filter bank as the measured fits.
    let mut sim_ident = ident.clone();
    if let Some(f) = fits.fits.first() {
        sim_ident.corners = Some(f.filter.corners.clone());
        sim_ident.order = Some(f.filter.order);
    }
    let sites = super::from_data::groups(ir);
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
    let done = std::sync::atomic::AtomicUsize::new(0);
    let mut total = 0;
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
        let singles: Vec<Single> = det.elements[ti]
            .ranking
            .iter()
            .filter(|f| f.effects.len() == 1)
            .filter_map(|f| {
                let c = builtins.iter().find(|c| c.name == f.effects[0])?;
                let est = f.effect_estimates();
                let p = est.first()?.value;
                let theta = c
                    .shape
                    .as_ref()
                    .and_then(|s| est.iter().find(|e| e.name == s.name))
                    .map_or(0.0, |e| e.value);
                let linear_parts = f
                    .estimates
                    .iter()
                    .filter_map(|e| {
                        e.name
                            .strip_suffix(" (linear part)")
                            .map(|n| (n.to_string(), e.value))
                    })
                    .collect();
                (p.is_finite() && p != 0.0).then(|| Single {
                    effect: c.name.clone(),
                    coef: c.coef_name.clone(),
                    p,
                    theta,
                    linear_parts,
                })
            })
            .collect();
        if singles.is_empty() {
            continue;
        }
        let (a, b) = (
            ir.node_name(site.nodes.0).to_string(),
            ir.node_name(site.nodes.1).to_string(),
        );
        let jobs: Vec<(usize, usize)> = (0..singles.len())
            .flat_map(|c| (0..P_FACTORS.len()).map(move |k| (c, k)))
            .collect();
        total += jobs.len();
        let runs: Vec<Option<Curves>> = jobs
            .par_iter()
            .map(|&(c, k)| {
                let run = || -> Option<Curves> {
                    let Single {
                        effect,
                        p,
                        theta,
                        linear_parts,
                        ..
                    } = &singles[c];
                    let mut model = base.clone();
                    for (param, v) in linear_parts {
                        let _ = model.set_nominal(param, *v);
                    }
                    let basis = basis_of(effect, *theta)?;
                    let pname = model.fresh_name("p_candidate");
                    let fname = model.fresh_name("candidate");
                    model
                        .add_force(
                            &fname,
                            (&a, &b),
                            &[NewTerm {
                                param: &pname,
                                nominal: Some(P_FACTORS[k] * p),
                                basis: &*basis,
                            }],
                        )
                        .ok()?;
                    estimator_curves(ir, &model, &inputs, &sim_ident, opts.hold_inertia)
                };
                let out = run();
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n, total);
                out
            })
            .collect();
        let trials: Vec<Trial> = singles
            .iter()
            .enumerate()
            .filter_map(|(c, single)| {
                let curves: Vec<Curves> = (0..P_FACTORS.len())
                    .map(|k| runs[c * P_FACTORS.len() + k].clone())
                    .collect::<Option<_>>()?;
                Some(Trial {
                    effect: single.effect.clone(),
                    coef_name: single.coef.clone(),
                    ps: P_FACTORS.iter().map(|f| f * single.p).collect(),
                    curves,
                })
            })
            .collect();
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
        let corrected = |t: &Trial, el: usize, p: f64| -> (Vec<String>, bool) {
            let mut left = Vec::new();
            let mut ok = true;
            for r in params.iter().filter(|r| {
                r.curve.element == names[el]
                    && matches!(r.curve.role, Role::Stiffness | Role::Damping)
            }) {
                let Some((d, e)) = drift(t, &r.curve.param, p, &share) else {
                    ok = false;
                    continue;
                };
                // The stderrs the measured test used (floored) with the prediction's.
                let c = corrected_curve(&r.curve, &r.stderrs_used, &d, &e);
                if constancy_test(&c, r.sigma.clone(), &r.sigma_name, opts).drifting {
                    left.push(r.curve.param.clone());
                }
            }
            (left, ok)
        };
        let mut fitted: Vec<EstimatorFit> = Vec::new();
        let mut scores: Vec<f64> = Vec::new();
        for t in &trials {
            let (lo, hi) = (
                t.ps[0].min(t.ps[t.ps.len() - 1]),
                t.ps[0].max(t.ps[t.ps.len() - 1]),
            );
            let grid: Vec<f64> = (0..=P_STEPS)
                .map(|i| lo + (hi - lo) * i as f64 / P_STEPS as f64)
                .collect();
            let chis: Vec<f64> = grid
                .iter()
                .map(|&p| chi2_at(t, &scope, p, &share))
                .collect();
            let Some(best) = (0..grid.len()).min_by(|&i, &j| chis[i].total_cmp(&chis[j])) else {
                continue;
            };
            if !chis[best].is_finite() {
                continue;
            }
            let p = grid[best];
            // Standard error from the χ² profile (Δχ² = 1), on the fine grid.
            let within: Vec<f64> = grid
                .iter()
                .zip(&chis)
                .filter(|(_, c)| **c <= chis[best] + 1.0)
                .map(|(g, _)| *g)
                .collect();
            let step = (hi - lo) / P_STEPS as f64;
            let half = 0.5
                * (within.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                    - within.iter().copied().fold(f64::INFINITY, f64::min)
                    + step);
            let (left, ok) = corrected(t, ti, p);
            let explains = ok && left.is_empty();
            let n_points: usize = scope.iter().map(|s| s.curve.values.len()).sum();
            let dof = n_points.saturating_sub(scope.len() + 1);
            fitted.push(EstimatorFit {
                effect: t.effect.clone(),
                coef_name: t.coef_name.clone(),
                value: p,
                stderr: half,
                chi2: chis[best],
                dof,
                still_drifting: left,
                explains,
            });
            scores.push(chis[best] + 2.0 * shaped_count(&builtins, &t.effect) as f64);
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
        let fitted: Vec<EstimatorFit> = order.into_iter().map(|i| fitted[i].clone()).collect();
        let winner = fitted.first().filter(|f| f.explains).cloned();
        let Some(w) = winner else {
            det.elements[ti].estimator = fitted;
            continue;
        };
        let t = trials
            .iter()
            .find(|t| t.effect == w.effect)
            .expect("invariant: the winner is one of the trials");
        let quiet: Vec<usize> = neighbours
            .iter()
            .copied()
            .filter(|&j| det.elements[j].verdict != Verdict::Linear)
            .filter(|&j| {
                let (left, ok) = corrected(t, j, w.value);
                ok && left.is_empty()
            })
            .collect();
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
        for j in quiet {
            let n = &mut det.elements[j];
            n.explained_by = Some(format!(
                "its drift is the leak that {} at {} predicts in this fit ({} = {}); \
                 none is left once that is removed",
                w.effect,
                name,
                w.coef_name,
                fmt_pm(w.value, w.stderr)
            ));
            n.verdict = Verdict::Linear;
            n.suspected = None;
            explained[j] = true;
        }
    }
}

fn shaped_count(builtins: &[Candidate], effect: &str) -> usize {
    builtins
        .iter()
        .find(|c| c.name == effect)
        .map_or(0, |c| usize::from(c.shape.is_some()))
}
