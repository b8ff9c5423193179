//! The estimator run on simulated data: the head of every measured level (its inputs),
//! the model with a candidate effect added, identified from the measured levels
//! ([`identified`]), at p = factor × its identified p,
//! driven by those inputs and fitted per level exactly as the data were. Each run gives
//! the curves that [`super::score`] compares with the measured ones.

use rayon::prelude::*;

use dynid_ir::edit::NewTerm;
use dynid_ir::ir::{BinaryOp, ExprArena, ExprId, ExprNode, ModelIr, SignalKind, UnaryOp};

use super::P_FACTORS;
use crate::data::{LevelSource, RecordSource};
use crate::detect::candidate::Candidate;
use crate::detect::from_data::level_fits;
use crate::detect::types::{ElementFinding, HeldParam, TemplateFit, Verdict};
use crate::ident::IdentifyOptions;
use crate::record::Record;
use crate::sim::{simulate_driven_from, Start};
use std::sync::atomic::{AtomicUsize, Ordering};

/// RK4 steps per sample of the driven runs.
const SUBSTEPS: usize = 4;

/// Builds a force basis from the element's s and v.
type BasisFn = Box<dyn Fn(&mut ExprArena, ExprId, ExprId) -> ExprId>;

/// A single-effect template of the element: effect, coefficient name, its estimate, the
/// shape θ and the values set on the base before a run — the element's linear parts as
/// the statistical linearisation fitted them ([`singles_of`]), or every unknown of the
/// model as the pooled identification with the effect gave them ([`identified`]).
pub(super) struct Single {
    pub(super) effect: String,
    pub(super) coef: String,
    pub(super) p: f64,
    pub(super) theta: f64,
    pub(super) linear_parts: Vec<(String, f64)>,
}

/// A candidate evaluated through the estimator.
pub(super) struct Trial {
    pub(super) effect: String,
    pub(super) coef_name: String,
    /// p at every factor of [`P_FACTORS`].
    pub(super) ps: Vec<f64>,
    /// Per factor, the curves of the simulated fits.
    pub(super) curves: Vec<Curves>,
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
pub(super) fn head_record(
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
pub(super) type Curves = Vec<(String, Vec<f64>, Vec<f64>)>;

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
    let fits = level_fits(ir, &levels, ident, hold_inertia).ok()?;
    Some(
        fits.input
            .curves
            .into_iter()
            .map(|c| (c.param, c.values, c.stderrs))
            .collect(),
    )
}

/// A template of two effects, the verdict of an element that no single effect explains
/// through the estimator: its effects with their coefficients and shapes, and the element's
/// linear parts, as the statistical linearisation fitted them.
pub(super) struct Pair {
    /// `backlash + Coulomb friction`.
    pub(super) effect: String,
    /// `(effect, coefficient name, coefficient, shape θ)` per effect.
    pub(super) terms: Vec<(String, String, f64, f64)>,
    pub(super) linear_parts: Vec<(String, f64)>,
}

/// The pair of `finding`'s verdict — the verdict itself where it is a pair, the pair of
/// the suspected second effect where the verdict is a single effect with one suspected —
/// as its template in the ranking fitted it (two built-in effects with finite, non-zero
/// coefficients), or `None`.
pub(super) fn pair_of(finding: &ElementFinding, builtins: &[Candidate]) -> Option<Pair> {
    let Verdict::Nonlinear { best, .. } = &finding.verdict else {
        return None;
    };
    let name = finding.suspected.as_ref().map_or(best, |s| &s.pair);
    let f = finding
        .ranking
        .iter()
        .find(|f| &f.name == name)
        .filter(|f| f.effects.len() == 2)?;
    let terms = f
        .effects
        .iter()
        .map(|effect| {
            let (c, p, theta) = effect_term(f, effect, builtins)?;
            Some((c.name.clone(), c.coef_name.clone(), p, theta))
        })
        .collect::<Option<Vec<_>>>()?;
    Some(Pair {
        effect: f.effects.join(" + "),
        terms,
        linear_parts: linear_parts(f),
    })
}

/// Effect `effect` of template `f` as the estimator runs it: its built-in candidate, the
/// coefficient the template fitted (finite and non-zero) and its shape θ (0 for an effect
/// without one); `None` where any is missing.
fn effect_term<'c>(
    f: &TemplateFit,
    effect: &str,
    builtins: &'c [Candidate],
) -> Option<(&'c Candidate, f64, f64)> {
    let c = builtins.iter().find(|c| c.name == effect)?;
    let est = f.effect_estimates();
    let value = |name: &str| est.iter().find(|e| e.name == name).map(|e| e.value);
    let p = value(&c.coef_name).filter(|p| p.is_finite() && *p != 0.0)?;
    let theta = c.shape.as_ref().map_or(Some(0.0), |s| value(&s.name))?;
    Some((c, p, theta))
}

/// The element's linear parts as the template `f` fitted them (`k3 (linear part)` → `k3`).
fn linear_parts(f: &TemplateFit) -> Vec<(String, f64)> {
    f.estimates
        .iter()
        .filter_map(|e| {
            e.name
                .strip_suffix(" (linear part)")
                .map(|n| (n.to_string(), e.value))
        })
        .collect()
}

/// The single-effect templates of `finding`'s ranking that the estimator can run: a
/// built-in effect with a finite, non-zero coefficient, its shape and the element's linear
/// parts as the statistical linearisation fitted them.
pub(super) fn singles_of(finding: &ElementFinding, builtins: &[Candidate]) -> Vec<Single> {
    finding
        .ranking
        .iter()
        .filter(|f| f.effects.len() == 1)
        .filter_map(|f| {
            let (c, p, theta) = effect_term(f, &f.effects[0], builtins)?;
            Some(Single {
                effect: c.name.clone(),
                coef: c.coef_name.clone(),
                p,
                theta,
                linear_parts: linear_parts(f),
            })
        })
        .collect()
}

/// `model` with a force of `terms` `(effect, shape θ, coefficient)` added between the
/// nodes `site`, one new unknown coefficient per term (`p_candidate`, `p_candidate_2`, …,
/// at the term's coefficient), and the coefficients' names; `None` where an effect cannot
/// be written.
fn with_force(
    model: &ModelIr,
    site: (&str, &str),
    terms: &[(&str, f64, f64)],
) -> Option<(ModelIr, Vec<String>)> {
    let mut model = model.clone();
    let bases: Vec<BasisFn> = terms
        .iter()
        .map(|(effect, theta, _)| basis_of(effect, *theta))
        .collect::<Option<_>>()?;
    let names: Vec<String> = (0..terms.len())
        .map(|i| match i {
            0 => model.fresh_name("p_candidate"),
            _ => model.fresh_name(&format!("p_candidate_{}", i + 1)),
        })
        .collect();
    let new_terms: Vec<NewTerm> = terms
        .iter()
        .zip(&bases)
        .zip(&names)
        .map(|(((_, _, p), basis), param)| NewTerm {
            param,
            nominal: Some(*p),
            basis: &**basis,
        })
        .collect();
    let fname = model.fresh_name("candidate");
    model.add_force(&fname, site, &new_terms).ok()?;
    Some((model, names))
}

/// What [`identify_terms`] gives: each term's coefficient, and every other unknown's name
/// and value.
type Identified = (Vec<f64>, Vec<(String, f64)>);

/// Below this, an identification with a candidate is not the base of the candidate's runs:
/// the geometric mean, over the model's unknown masses, of the identified mass over the
/// mass the per-level fits hold ([`mass_ratio`]). An effect of a spring or a damper changes
/// no inertia. Where the hypothesis does not fit the records, the pooled fit absorbs its
/// misfit by shrinking the equations of the bodies without a force together, their masses
/// with them, and such a model, simulated, drives its runs to a p of about zero. On the
/// five-body structure with a joint (`models/structure5_joint_accel.dyn`, 5 % noise, seeds
/// 1–12; CLI, measured once) the single effects gave 0.19–0.80 (0.70 the largest among
/// those not refused for an unphysical coefficient anyway), the pair of effects named
/// 0.84–0.99. Only a drop counts: the per-level fits lack the effect and their held masses
/// can be biased by it the other way (the two-mass structure with friction, from
/// accelerations: the friction identified with masses 1.0–4.9 times those held, and r
/// within 3 % of the truth).
pub(super) const MASS_SHRINK_LIMIT: f64 = 0.8;

/// What the pooled identification of a candidate reads: the linear model, the measured
/// levels, the options of the per-level fits and the masses they hold (unknown masses
/// only, at their held values; [`held_masses`]).
pub(super) struct Pooled<'a> {
    pub(super) ir: &'a ModelIr,
    pub(super) levels: &'a [&'a dyn LevelSource],
    pub(super) ident: &'a IdentifyOptions,
    pub(super) held_masses: &'a [(String, f64)],
}

/// The unknown masses of `ir` among `held` (the per-level fits' held values).
pub(super) fn held_masses(ir: &ModelIr, held: &[HeldParam]) -> Vec<(String, f64)> {
    ir.bodies
        .iter()
        .filter_map(|b| b.mass.param)
        .filter_map(|p| {
            let name = &ir.params[p.index()].name;
            held.iter()
                .find(|h| &h.param == name)
                .map(|h| (name.clone(), h.value))
        })
        .collect()
}

/// The geometric mean of `values`' masses over `held`'s, over the masses positive in both;
/// `None` where there is none.
fn mass_ratio(values: &[(String, f64)], held: &[(String, f64)]) -> Option<f64> {
    let logs: Vec<f64> = held
        .iter()
        .filter_map(|(name, h)| {
            let v = values.iter().find(|(n, _)| n == name)?.1;
            (v > 0.0 && *h > 0.0).then(|| (v / h).ln())
        })
        .collect();
    (!logs.is_empty()).then(|| (logs.iter().sum::<f64>() / logs.len() as f64).exp())
}

/// The model `pooled.ir` with a force of `terms` `(effect, shape θ, coefficient)` added at
/// `site`, identified once, all levels pooled, from the measured levels with the per-level
/// fits' options: each term's coefficient and every other unknown's value. `None` where
/// the identification fails, or gives a coefficient of the other sign than the term's, a
/// value that is not finite, one unphysical for its kind (a negative mass, damping or
/// stiffness more than two standard errors below zero: no model to simulate), or masses
/// shrunk below [`MASS_SHRINK_LIMIT`] of those held. A negative coefficient within its
/// standard errors of zero is kept: a small ground damper of the five-body structure came
/// out so in the identification with the very pair that made the records (seed 9).
fn identify_terms(
    pooled: &Pooled,
    site: (&str, &str),
    terms: &[(&str, f64, f64)],
) -> Option<Identified> {
    let (model, names) = with_force(pooled.ir, site, terms)?;
    let id = crate::ident::identify(&model, pooled.levels, pooled.ident).ok()?;
    let ps: Vec<f64> = names
        .iter()
        .map(|n| id.params.iter().find(|e| &e.name == n).map(|e| e.value))
        .collect::<Option<_>>()?;
    let same_sign = ps.iter().zip(terms).all(|(p, (_, _, q))| p * q > 0.0);
    let finite = id.params.iter().all(|e| e.value.is_finite());
    let physical = !id.warnings.iter().any(|w| w.unphysical);
    if !(same_sign && finite && physical) {
        return None;
    }
    let values: Vec<(String, f64)> = id
        .params
        .iter()
        .filter(|e| !names.contains(&e.name))
        .map(|e| (e.name.clone(), e.value))
        .collect();
    if mass_ratio(&values, pooled.held_masses).is_some_and(|r| r < MASS_SHRINK_LIMIT) {
        return None;
    }
    Some((ps, values))
}

/// `single` with its coefficient and every unknown of the model taken from one pooled
/// identification of the model with the effect added (`ir` plus `p·φ` at `site`, the
/// shape held at the linearisation's; [`identify_terms`]), from the measured levels with
/// the options of the per-level fits. The runs then simulate the model the data support
/// under this hypothesis, not the per-level fits' mean, which a fit that lacks the effect
/// biases (module doc). The linearisation's values are kept where that identification
/// gives none.
pub(super) fn identified(pooled: &Pooled, site: (&str, &str), single: Single) -> Single {
    let terms = [(single.effect.as_str(), single.theta, single.p)];
    match identify_terms(pooled, site, &terms) {
        Some((ps, values)) => Single {
            p: ps[0],
            linear_parts: values,
            ..single
        },
        None => single,
    }
}

/// [`identified`] for a pair: both coefficients and every other unknown from one pooled
/// identification of the model with both effects added, and whether they came from it
/// (else the linearisation's are kept).
pub(super) fn identified_pair(pooled: &Pooled, site: (&str, &str), pair: Pair) -> (Pair, bool) {
    let terms: Vec<(&str, f64, f64)> = pair
        .terms
        .iter()
        .map(|(effect, _, p, theta)| (effect.as_str(), *theta, *p))
        .collect();
    match identify_terms(pooled, site, &terms) {
        Some((ps, values)) => (
            Pair {
                terms: pair
                    .terms
                    .iter()
                    .zip(ps)
                    .map(|((effect, coef, _, theta), p)| (effect.clone(), coef.clone(), p, *theta))
                    .collect(),
                linear_parts: values,
                ..pair
            },
            true,
        ),
        None => (pair, false),
    }
}

/// What every estimator run at one element shares: the linear model fitted, the model
/// simulated (`base`, the linear part at the levels' values; each run sets its single's
/// values on it), the element's nodes, the level inputs, the fit's settings and the
/// counters of the simulations for `progress`.
pub(super) struct Runner<'a> {
    pub(super) ir: &'a ModelIr,
    pub(super) base: &'a ModelIr,
    pub(super) site: (&'a str, &'a str),
    pub(super) inputs: &'a [Record],
    pub(super) sim_ident: &'a IdentifyOptions,
    pub(super) hold_inertia: bool,
    pub(super) done: &'a AtomicUsize,
    pub(super) total: &'a AtomicUsize,
    pub(super) progress: &'a (dyn Fn(usize, usize) + Sync),
}

/// One run: the element's linear parts and the terms `(effect, shape θ, coefficient)` of
/// the force added at the element.
type Job<'j> = (&'j [(String, f64)], Vec<(&'j str, f64, f64)>);

impl Runner<'_> {
    /// `base` with the job's values set and a force of the terms added at the
    /// element, driven by the inputs and fitted per level ([`estimator_curves`]); `None`
    /// where an effect cannot be written or a run fails.
    fn driven_fit(&self, (linear_parts, terms): &Job) -> Option<Curves> {
        let mut model = self.base.clone();
        for (param, v) in linear_parts.iter() {
            let _ = model.set_nominal(param, *v);
        }
        let (model, _) = with_force(&model, self.site, terms)?;
        estimator_curves(
            self.ir,
            &model,
            self.inputs,
            self.sim_ident,
            self.hold_inertia,
        )
    }

    /// Every job's curves, run in parallel, each finished run counted for `progress`.
    fn run_all(&self, jobs: &[Job]) -> Vec<Option<Curves>> {
        let total = self.total.fetch_add(jobs.len(), Ordering::Relaxed) + jobs.len();
        jobs.par_iter()
            .map(|job| {
                let out = self.driven_fit(job);
                let n = self.done.fetch_add(1, Ordering::Relaxed) + 1;
                (self.progress)(n, total);
                out
            })
            .collect()
    }

    /// The trials of `singles`: each run at every factor of [`P_FACTORS`] times its
    /// estimate; a trial whose runs all succeed is kept.
    pub(super) fn trials(&self, singles: &[Single]) -> Vec<Trial> {
        let jobs: Vec<Job> = singles
            .iter()
            .flat_map(|s| {
                P_FACTORS.iter().map(move |f| {
                    (
                        &s.linear_parts[..],
                        vec![(s.effect.as_str(), s.theta, f * s.p)],
                    )
                })
            })
            .collect();
        let runs = self.run_all(&jobs);
        singles
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
            .collect()
    }

    /// The trial of `pair`: runs without it and with it at the coefficients the
    /// linearisation fitted (factors 0 and 1, the trial's `ps`); `None` where a run fails.
    pub(super) fn pair(&self, pair: &Pair) -> Option<Trial> {
        let jobs: Vec<Job> = [0.0, 1.0]
            .iter()
            .map(|f| {
                let terms = pair
                    .terms
                    .iter()
                    .map(|(effect, _, p, theta)| (effect.as_str(), *theta, f * p))
                    .collect();
                (&pair.linear_parts[..], terms)
            })
            .collect();
        Some(Trial {
            effect: pair.effect.clone(),
            coef_name: String::new(),
            ps: vec![0.0, 1.0],
            curves: self.run_all(&jobs).into_iter().collect::<Option<_>>()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::types::Estimate;

    fn estimate(name: &str, value: f64) -> Estimate {
        Estimate {
            name: name.into(),
            value,
            stderr: 0.1 * value.abs(),
        }
    }

    fn fit(effects: &[&str], estimates: Vec<Estimate>, n_effect: usize) -> TemplateFit {
        TemplateFit {
            name: effects.join(" + "),
            effects: effects.iter().map(|e| e.to_string()).collect(),
            formula: String::new(),
            estimates,
            n_effect_estimates: n_effect,
            chi2: 1.0,
            dof: 3,
            n_params: 5,
            n_points: 8,
            reduced_chi2: 1.0,
            gof_p_value: 0.5,
            explained: 0.99,
            aicc: 0.0,
            bic: 0.0,
            delta_aicc: 0.0,
            cond: 1.0,
            coef_corr: 0.1,
            inverse_pair: false,
            predictions: Vec::new(),
        }
    }

    fn finding(ranking: Vec<TemplateFit>) -> ElementFinding {
        ElementFinding {
            element: "k3/d3 (m2, m3)".into(),
            verdict: Verdict::Nonlinear {
                best: ranking[0].name.clone(),
                summary: String::new(),
            },
            drifting: vec!["k3".into()],
            ranking,
            constant_chi2: 50.0,
            constant_aicc: 60.0,
            c_hat: 1.0,
            suspected: None,
            estimator: Vec::new(),
            explained_by: None,
        }
    }

    /// The structure's unknown masses m2…m5 as the per-level fits hold them; the known m1
    /// and a held constant force are not masses of the ratio.
    #[test]
    fn only_the_unknown_masses_are_compared_and_only_a_drop_refuses() {
        let src = include_str!("../../../../models/structure5_linear_accel.dyn");
        let ir = dsl_parser::compile_str("structure5_linear_accel.dyn", src).unwrap();
        let held: Vec<HeldParam> = [("m2", 1.5), ("m3", 1.0), ("k1", 50.0), ("m1", 2.0)]
            .iter()
            .map(|(p, v)| HeldParam {
                param: p.to_string(),
                value: *v,
                stderr: 0.01,
            })
            .collect();
        let masses = held_masses(&ir, &held);
        assert_eq!(
            masses,
            vec![("m2".to_string(), 1.5), ("m3".to_string(), 1.0)],
            "{masses:?}"
        );
        let values = |m2: f64, m3: f64| {
            vec![
                ("m2".to_string(), m2),
                ("m3".to_string(), m3),
                ("k1".to_string(), 1.0),
            ]
        };
        // Geometric mean: 0.5 and 0.98 of the held → 0.7, refused; 2× and 0.9× → 1.34, kept.
        let shrunk = mass_ratio(&values(0.75, 0.98), &masses).unwrap();
        assert!((shrunk - (0.5f64 * 0.98).sqrt()).abs() < 1e-12, "{shrunk}");
        assert!(shrunk < MASS_SHRINK_LIMIT);
        let grown = mass_ratio(&values(3.0, 0.9), &masses).unwrap();
        assert!(grown > 1.0, "{grown}");
        // A non-positive mass has no ratio (unphysical: refused on its own); no mass, none.
        assert_eq!(mass_ratio(&values(-1.0, 0.9), &masses), Some(0.9));
        assert_eq!(mass_ratio(&values(1.0, 1.0), &[]), None);
    }

    #[test]
    fn a_pair_verdict_runs_with_both_coefficients_and_the_gap() {
        let builtins = Candidate::builtins();
        let pair = fit(
            &["backlash", "Coulomb friction"],
            vec![
                estimate("k3 (linear part)", 290.0),
                estimate("d3 (linear part)", 0.35),
                estimate("kb", 276.0),
                estimate("r", 0.18),
                estimate("g", 0.028),
            ],
            3,
        );
        let single = fit(
            &["backlash"],
            vec![
                estimate("k3 (linear part)", 280.0),
                estimate("d3 (linear part)", 0.5),
                estimate("kb", 250.0),
                estimate("g", 0.03),
            ],
            2,
        );
        let p = pair_of(&finding(vec![pair.clone(), single.clone()]), &builtins).unwrap();
        assert_eq!(p.effect, "backlash + Coulomb friction");
        assert_eq!(
            p.terms,
            vec![
                ("backlash".into(), "kb".into(), 276.0, 0.028),
                ("Coulomb friction".into(), "r".into(), 0.18, 0.0),
            ]
        );
        assert_eq!(
            p.linear_parts,
            vec![("k3".to_string(), 290.0), ("d3".to_string(), 0.35)]
        );
        // A single effect first is no pair, unless the verdict suspects the pair's second
        // effect: then that pair, wherever it ranks; nor is a pair missing a coefficient.
        let mut single_first = finding(vec![single, pair.clone()]);
        assert!(pair_of(&single_first, &builtins).is_none());
        single_first.suspected = Some(crate::detect::types::Suspected {
            effect: "Coulomb friction".into(),
            curve: "d3".into(),
            curve_p_value: 1e-20,
            pair: "backlash + Coulomb friction".into(),
            pair_rank: 2,
            pair_delta_aicc: 6.7,
            pair_summary: String::new(),
        });
        let suspected = pair_of(&single_first, &builtins).unwrap();
        assert_eq!(suspected.effect, "backlash + Coulomb friction");
        assert_eq!(
            suspected.terms[1],
            ("Coulomb friction".into(), "r".into(), 0.18, 0.0)
        );
        let mut no_r = pair;
        no_r.estimates[3].value = 0.0;
        assert!(pair_of(&finding(vec![no_r]), &builtins).is_none());
    }
}
