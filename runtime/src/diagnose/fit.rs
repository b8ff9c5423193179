//! Fitting: the moments of a model on every level, its covariance estimate on all levels
//! and on the training levels of every withheld level, and the cross-validated covariance
//! residual — for the model as given and for every candidate, either measured on its own
//! or, many candidates at once, in one shared pass over the data (the two differ only in
//! how a candidate's moments are measured: `fit_each` takes that step as an argument).

use super::effects::{add_effect, Effect, Location, Variant};
use super::levels::{sources, training, Data};
use super::score::cov_residual;
use super::types::{CandidateScore, DiagnoseError, DiagnoseOptions};
use crate::data::LevelSource;
use crate::ident::{measure, Identification, Measurement};
use crate::tape::Tape;
use dynid_ir::ir::{BodyId, ModelIr};
use rayon::prelude::*;

/// The moments of `ir` on every level, terms within their standard error of zero pruned.
pub(super) fn measure_all<'m>(
    ir: &'m ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
) -> Result<Measurement<'m>, DiagnoseError> {
    let srcs = sources(ir, data)?;
    let refs: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let tape = Tape::compile(ir, &ir.eval_roots());
    let mut m = measure(ir, &tape, &refs, &opts.ident)?;
    // The structure search treats a term whose estimate is within its standard error of
    // zero as absent, and scores the variant without it.
    m.prune_insignificant(true);
    Ok(m)
}

/// The unknowns of `ir` at the values of `id` (the nominal, or 0, where `id` has none).
fn param_vector(ir: &ModelIr, id: &Identification) -> Vec<f64> {
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
pub(super) fn cross_validate(
    m: &Measurement,
    ir: &ModelIr,
    n: usize,
) -> (f64, Vec<Identification>) {
    let mut fits = Vec::with_capacity(n);
    let (mut res, mut k) = (0.0, 0);
    for w in 0..n {
        let fit = m.identify_levels(&training(n, w));
        let p = param_vector(ir, &fit);
        // A level whose rows are all zero (no excitation) has no residual.
        if let Some(r) = cov_residual(m, &p, w, None) {
            res += r;
            k += 1;
        }
        fits.push(fit);
    }
    // No level with a residual: rank last.
    (if k > 0 { res / k as f64 } else { f64::INFINITY }, fits)
}

/// A fitted candidate: its score (estimate and cross-validated covariance residual), its
/// model, its training fit per withheld level and its fit on all levels.
pub(super) struct Fitted {
    pub(super) score: CandidateScore,
    pub(super) variant: Variant,
    pub(super) fits: Vec<Identification>,
    pub(super) fit: Identification,
}

/// Whether a candidate's estimate earns it a free run (and a place in a pair): finite, with
/// a physical sign, and significant (`|p|/σ` above `t_min`).
pub(super) fn admissible(c: &CandidateScore, t_min: f64) -> bool {
    c.sign_ok && c.t_ratio > t_min
}

/// `c` with the estimate `value ± stderr` of its coefficient (not a number: not resolved).
fn with_estimate(mut c: CandidateScore, value: f64, stderr: f64) -> CandidateScore {
    c.t_ratio = if value.is_finite() {
        value.abs() / stderr.max(f64::MIN_POSITIVE)
    } else {
        0.0
    };
    c.sign_ok = value.is_finite() && c.effect.sign_ok(value);
    (c.value, c.stderr) = (value, stderr);
    c
}

/// Fit every candidate `(effect, location)` on top of `base`; `tick` after each. With
/// `opts.shared_pass` the candidates are measured in shared passes (grouped by the rests
/// their models leave out, at most [`SHARED_PASS_GROUP`] a pass), else each on its own. A
/// candidate whose model cannot be built or measured is left out.
pub(super) fn fit_candidates(
    base: &Variant,
    cands: &[(Effect, Location)],
    data: &Data,
    opts: &DiagnoseOptions,
    tick: &(dyn Fn() + Sync),
) -> Vec<Fitted> {
    if !opts.shared_pass {
        return own_passes(base, cands, data, opts, tick);
    }
    let mut out = Vec::with_capacity(cands.len());
    for same_rests in by_rests(&base.ir, cands, opts) {
        for group in same_rests.chunks(SHARED_PASS_GROUP) {
            match shared_pass(base, group, data, opts, tick) {
                Some(r) => out.extend(r),
                None => out.extend(own_passes(base, group, data, opts, tick)),
            }
        }
    }
    out
}

/// Every candidate measured on its own.
fn own_passes(
    base: &Variant,
    cands: &[(Effect, Location)],
    data: &Data,
    opts: &DiagnoseOptions,
    tick: &(dyn Fn() + Sync),
) -> Vec<Fitted> {
    fit_each(base, cands, data.records.len(), tick, &|_, cir| {
        measure_all(cir, data, opts).ok()
    })
}

/// How a candidate's moments are measured, given its place in the list and its model: a
/// pass of its own, or its columns read from a shared pass.
type MeasureCandidate<'a> =
    dyn for<'c> Fn(usize, &'c ModelIr) -> Option<Measurement<'c>> + Sync + 'a;

/// Every candidate of `cands` added to `base` and fitted on the `n` levels, in parallel,
/// its moments measured by `moments`; `tick` after each. A candidate whose model cannot be
/// built or measured is left out.
fn fit_each(
    base: &Variant,
    cands: &[(Effect, Location)],
    n: usize,
    tick: &(dyn Fn() + Sync),
    moments: &MeasureCandidate,
) -> Vec<Fitted> {
    cands
        .par_iter()
        .enumerate()
        .filter_map(|(k, (eff, loc))| {
            let out = (|| {
                let (cir, p) = add_effect(&base.ir, *eff, loc)?;
                let (score, fits, fit) = {
                    let m = moments(k, &cir)?;
                    fit_of(*eff, loc, &p, &m, &cir, n)
                };
                Some(Fitted {
                    score,
                    variant: base.with(cir, p),
                    fits,
                    fit,
                })
            })();
            tick();
            out
        })
        .collect()
}

/// Fit a candidate from the moments `m` of its model `cir` (parameter `p`): the estimate
/// on all levels and the cross-validated covariance residual over the `n` levels.
fn fit_of(
    eff: Effect,
    loc: &Location,
    p: &str,
    m: &Measurement,
    cir: &ModelIr,
    n: usize,
) -> (CandidateScore, Vec<Identification>, Identification) {
    let all = m.identify_pooled();
    let (value, stderr) = all
        .param(p)
        .map_or((f64::NAN, f64::NAN), |e| (e.value, e.stderr));
    let (cv, fits) = cross_validate(m, cir, n);
    let score = CandidateScore {
        effect: eff,
        location: loc.clone(),
        value: f64::NAN,
        stderr: f64::NAN,
        t_ratio: 0.0,
        sign_ok: false,
        cv_residual: cv,
        gap: None,
        pathwise_gap: None,
        accepted: false,
        note: String::new(),
    };
    (with_estimate(score, value, stderr), fits, all)
}

/// The candidates in groups whose models leave the rests of the same bodies out of their
/// moments (identification does so for a body whose own velocity is the argument of a
/// `sign`, see [`crate::ident::rests`]), in their order. A shared pass measures the model
/// holding every candidate of a group: were a Coulomb candidate in it, every other
/// candidate would be measured without the rests its own pass keeps — a different problem
/// (on planned moves with long dwells, one whose solve is not even finite).
fn by_rests(
    ir: &ModelIr,
    cands: &[(Effect, Location)],
    opts: &DiagnoseOptions,
) -> Vec<Vec<(Effect, Location)>> {
    type Group = (Vec<BodyId>, Vec<(Effect, Location)>);
    let mut groups: Vec<Group> = Vec::new();
    for c in cands {
        let key = match add_effect(ir, c.0, &c.1) {
            Some((cir, _)) if !opts.ident.keep_rests => crate::ident::rests::bodies(&cir),
            _ => Vec::new(),
        };
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => g.1.push(c.clone()),
            None => groups.push((key, vec![c.clone()])),
        }
    }
    groups.into_iter().map(|g| g.1).collect()
}

/// Candidates measured together in one shared pass. The moments held grow with every
/// candidate's column — `levels × (3 n_blocks + 1) × n_i × 8` bytes each — so a large
/// model's candidates are measured in groups: each group costs one more pass over the
/// data, and the memory stays that of one group.
const SHARED_PASS_GROUP: usize = 64;

/// Every candidate of a group fitted from ONE measuring pass: the model `base` with all
/// candidate terms added is measured once, and each candidate is solved from its own
/// columns of those moments ([`Measurement::restricted`]), exactly the problem its own pass
/// would give. `None` when that model cannot be measured (the caller then measures every
/// candidate on its own, which drops only the candidates that fail).
fn shared_pass(
    base: &Variant,
    cands: &[(Effect, Location)],
    data: &Data,
    opts: &DiagnoseOptions,
    tick: &(dyn Fn() + Sync),
) -> Option<Vec<Fitted>> {
    let ir = &base.ir;
    let n = data.records.len();
    // The candidate's parameter in the model holding every candidate.
    let mut all_ir = ir.clone();
    let mut in_all: Vec<Option<String>> = Vec::with_capacity(cands.len());
    for (eff, loc) in cands {
        in_all.push(add_effect(&all_ir, *eff, loc).map(|(next, p)| {
            all_ir = next;
            p
        }));
    }
    let m = measure_all(&all_ir, data, opts).ok()?;
    let base_cols: Vec<usize> = ir
        .unknowns()
        .iter()
        .map(|p| m.column(&ir.params[p.index()].name))
        .collect::<Option<_>>()?;
    // Every candidate reads the base model's columns: form them once.
    m.keep_columns(&base_cols);
    let out = fit_each(base, cands, n, tick, &|k, cir| {
        let col = m.column(in_all[k].as_ref()?)?;
        let cols: Vec<usize> = base_cols.iter().copied().chain([col]).collect();
        m.restricted(cir, &cols)
    });
    Some(out)
}

/// Two candidates fitted together on top of `base`.
pub(super) struct FittedPair {
    /// The two candidates with the estimates of the pair's fit on all levels.
    pub(super) scores: [CandidateScore; 2],
    pub(super) variant: Variant,
    pub(super) fits: Vec<Identification>,
    pub(super) fit: Identification,
}

/// The candidates `a` and `b` added together to `base` and fitted; `None` when the model
/// cannot be built or measured, or either coefficient is not [`admissible`].
pub(super) fn fit_pair(
    base: &Variant,
    a: &CandidateScore,
    b: &CandidateScore,
    data: &Data,
    opts: &DiagnoseOptions,
) -> Option<FittedPair> {
    let n = data.records.len();
    let (ir1, p1) = add_effect(&base.ir, a.effect, &a.location)?;
    let (ir2, p2) = add_effect(&ir1, b.effect, &b.location)?;
    let m = measure_all(&ir2, data, opts).ok()?;
    let all = m.identify_pooled();
    let score = |c: &CandidateScore, p: &str| -> Option<CandidateScore> {
        let e = all.param(p)?;
        let s = with_estimate(c.clone(), e.value, e.stderr);
        admissible(&s, opts.t_min).then_some(s)
    };
    let scores = [score(a, &p1)?, score(b, &p2)?];
    let (_, fits) = cross_validate(&m, &ir2, n);
    let mut added = base.added.clone();
    added.extend([p1, p2]);
    Some(FittedPair {
        scores,
        variant: Variant { ir: ir2, added },
        fits,
        fit: all,
    })
}
