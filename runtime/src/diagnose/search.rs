//! The candidate search: every effect at every site on top of the current model, ranked by
//! the cross-validated covariance residual; the best few scored by the withheld free-run gap.

use super::effects::{add_effect, constant_force_sites, locations, Effect, Location, Variant};
use super::gap::Data;
use super::gap::{cross_validate, cv_gap, measure_all};
use super::types::{CandidateScore, DiagnoseOptions, FoundEffect, ModelGap};
use super::{fmt_gap, metrics};
use crate::ident::{Identification, Measurement};
use dynid_ir::ir::{ModelIr, SignalKind};
use dynid_ir::num;
use rayon::prelude::*;

pub(super) struct Search {
    pub(super) ranking: Vec<CandidateScore>,
    /// The accepted candidate: its score, model, withheld gap, fit on all levels and the
    /// training fit for each withheld level.
    pub(super) best: Option<Accepted>,
}

pub(super) struct Accepted {
    pub(super) score: CandidateScore,
    pub(super) variant: Variant,
    pub(super) gap: ModelGap,
    pub(super) fit: Identification,
    pub(super) fits: Vec<Identification>,
}

/// A scored candidate: its score, model, training fits per withheld level and fit on all
/// levels.
type Scored = (CandidateScore, Variant, Vec<Identification>, Identification);

/// One greedy step: try every effect at every location on top of `base`, except the kinds
/// already `found` at a location (a second copy of a term is collinear with the first).
pub(super) fn search_step(
    base: &Variant,
    found: &[FoundEffect],
    data: &Data,
    current: &ModelGap,
    opts: &DiagnoseOptions,
    notes: &mut Vec<String>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Search {
    let ir = &base.ir;
    let n = data.records.len();
    // A velocity term needs each velocity measured or estimable from a measured position
    // (identification then differentiates the position, see `ident::velocity`).
    let vel_measured = ir.signals.iter().all(|s| match s.kind {
        SignalKind::Velocity(b) => s.measured || ir.signal(ir.position(b)).measured,
        _ => true,
    });
    // Gaps of the backlash grid are relative to each location's σ_s on the largest level.
    let sigma_s = |loc: &Location| -> f64 {
        let big = (0..n)
            .max_by(|&a, &b| {
                let sa = data.records[a]
                    .columns
                    .iter()
                    .map(|c| metrics::std_dev(c))
                    .sum::<f64>();
                let sb = data.records[b]
                    .columns
                    .iter()
                    .map(|c| metrics::std_dev(c))
                    .sum::<f64>();
                sa.total_cmp(&sb)
            })
            .unwrap_or(0);
        let rec = &data.records[big];
        let col = |node: &str| rec.column(&format!("{node}.x"));
        let s: Vec<f64> = match (loc.a.as_str(), col(&loc.a), col(&loc.b)) {
            ("ground", _, Some(xb)) => xb.to_vec(),
            (_, Some(xa), Some(xb)) => xb.iter().zip(xa).map(|(b, a)| b - a).collect(),
            (_, Some(xa), None) if loc.b == "ground" => xa.iter().map(|a| -a).collect(),
            _ => return 0.0,
        };
        metrics::std_dev(&s)
    };
    let locs = locations(ir);
    let mut cands: Vec<(Effect, Location)> = Vec::new();
    let mut skipped_velocity = false;
    // A nonlinear force in the motion of a body measured only by its acceleration cannot
    // be formed yet (identification refuses it): such sites are not searched, and said so.
    let accel_only = |node: &str| {
        ir.bodies
            .iter()
            .position(|b| b.name == node)
            .is_some_and(|b| ir.acceleration_only(dynid_ir::ir::BodyId(b as u32)))
    };
    let mut skipped_accel: Vec<String> = Vec::new();
    let already = |kind: &str, loc: &Location| {
        found
            .iter()
            .any(|f| f.effect.kind() == kind && f.location.a == loc.a && f.location.b == loc.b)
    };
    for loc in &locs {
        if accel_only(&loc.a) || accel_only(&loc.b) {
            skipped_accel.push(loc.label());
            continue;
        }
        for eff in [
            Effect::Cubic,
            Effect::QuadraticStiffness,
            Effect::Coulomb,
            Effect::QuadraticDamping,
            Effect::Prestress,
        ] {
            if eff.needs_velocity() && !vel_measured {
                skipped_velocity = true;
                continue;
            }
            if already(eff.kind(), loc) {
                continue;
            }
            cands.push((eff, loc.clone()));
        }
        let sg = sigma_s(loc);
        if sg > 0.0 && !already("backlash", loc) {
            for f in [0.1, 0.25, 0.5, 1.0] {
                cands.push((
                    Effect::Backlash {
                        gap: num::round_sig(f * sg, 3),
                    },
                    loc.clone(),
                ));
            }
        }
    }
    // A constant force on each body. Where the data carry no mean (centred records) its
    // column is zero and identification names it unidentifiable: the candidate then has
    // no value and is not scored ("not resolved by the data").
    for loc in constant_force_sites(ir, &locs) {
        if !already(Effect::ConstantForce.kind(), &loc) {
            cands.push((Effect::ConstantForce, loc));
        }
    }
    if !skipped_accel.is_empty() && !notes.iter().any(|s| s.contains("accelerations alone")) {
        notes.push(format!(
            "no nonlinear effect was searched at {}: a body there is measured by accelerations \
             alone, whose displacement and velocity the nonlinear terms need (measure its \
             position to search there)",
            skipped_accel.join(", ")
        ));
    }
    if skipped_velocity && !notes.iter().any(|s| s.contains("velocities")) {
        notes.push(
            "velocities are neither measured nor estimable from positions: Coulomb friction and \
             quadratic damping candidates were skipped (cubic, quadratic stiffness, backlash, prestress and constant force were searched)"
                .into(),
        );
    }
    // The total grows when the backlash gaps are refined (a second round of candidates).
    use std::sync::atomic::{AtomicUsize, Ordering};
    let total = AtomicUsize::new(cands.len());
    let done = AtomicUsize::new(0);
    let tick = || {
        let k = done.fetch_add(1, Ordering::Relaxed) + 1;
        progress(k, total.load(Ordering::Relaxed).max(k));
    };
    let own_passes = |cands: &[(Effect, Location)]| -> Vec<Scored> {
        cands
            .par_iter()
            .filter_map(|(eff, loc)| {
                let out = (|| {
                    let (cir, p) = add_effect(ir, *eff, loc)?;
                    let (score, fits, all) = {
                        let m = measure_all(&cir, data, opts).ok()?;
                        score_of(*eff, loc, &p, &m, &cir, n)
                    };
                    Some((score, variant(base, cir, p), fits, all))
                })();
                tick();
                out
            })
            .collect()
    };
    let run = |cands: &[(Effect, Location)]| -> Vec<Scored> {
        if !opts.shared_pass {
            return own_passes(cands);
        }
        let mut out = Vec::with_capacity(cands.len());
        for same_rests in by_rests(ir, cands, opts) {
            for group in same_rests.chunks(SHARED_PASS_GROUP) {
                match shared_pass(base, group, data, opts, &tick) {
                    Some(r) => out.extend(r),
                    None => out.extend(own_passes(group)),
                }
            }
        }
        out
    };
    let mut results = run(&cands);
    // Refine the backlash gap around the best grid point of each location.
    let mut refined = Vec::new();
    for loc in &locs {
        let best = results
            .iter()
            .filter(|r| r.0.location == *loc && matches!(r.0.effect, Effect::Backlash { .. }))
            .min_by(|a, b| a.0.cv_residual.total_cmp(&b.0.cv_residual));
        if let Some((s, ..)) = best {
            if let Effect::Backlash { gap } = s.effect {
                for f in [0.75, 1.35] {
                    refined.push((
                        Effect::Backlash {
                            gap: num::round_sig(gap * f, 3),
                        },
                        loc.clone(),
                    ));
                }
            }
        }
    }
    if !refined.is_empty() {
        total.fetch_add(refined.len(), Ordering::Relaxed);
        results.extend(run(&refined));
    }
    // Keep one backlash (the best gap) per location in the ranking.
    results.sort_by(|a, b| a.0.cv_residual.total_cmp(&b.0.cv_residual));
    let mut seen_bl: Vec<Location> = Vec::new();
    results.retain(|r| {
        if matches!(r.0.effect, Effect::Backlash { .. }) {
            if seen_bl.contains(&r.0.location) {
                return false;
            }
            seen_bl.push(r.0.location.clone());
        }
        true
    });
    // Free-run score for the best few physically admissible candidates.
    let mut scored = 0;
    let mut gaps: Vec<(usize, ModelGap)> = Vec::new();
    #[allow(clippy::needless_range_loop)]
    for i in 0..results.len() {
        if scored >= opts.top_k {
            break;
        }
        let r = &results[i];
        if !r.0.sign_ok || r.0.t_ratio <= opts.t_min {
            results[i].0.note = if !r.0.value.is_finite() {
                "not resolved by the data".into()
            } else if !r.0.sign_ok {
                "unphysical sign".into()
            } else {
                format!("not significant (|p|/σ = {:.1})", r.0.t_ratio)
            };
            continue;
        }
        scored += 1;
        let g = cv_gap(&r.1.ir, &r.2, data, opts, "corrected");
        results[i].0.gap = Some(g.gap);
        results[i].0.pathwise_gap = Some(g.pathwise);
        gaps.push((i, g));
    }
    // Free-run gaps within 10 % of the best are a tie (a wide dead zone mimics a cubic
    // spring): the cross-validated covariance residual, which sees every instrument, breaks it.
    let best_gap = gaps.iter().map(|g| g.1.gap).fold(f64::INFINITY, f64::min);
    let best = gaps
        .iter()
        .filter(|(_, g)| g.gap <= 1.1 * best_gap)
        .min_by(|a, b| {
            results[a.0]
                .0
                .cv_residual
                .total_cmp(&results[b.0].0.cv_residual)
        })
        .map(|(i, _)| *i);
    let material = |before: f64, after: f64| material(before, after, opts);
    let gap_of = |i: usize| &gaps.iter().find(|g| g.0 == i).expect("invariant: scored").1;
    // The statistical gap compares spectra and standard deviations, and does not see a
    // signal's mean — all that a constant force changes in a model that holds otherwise. A
    // constant force is judged on the pathwise gap instead, where its statistical gap stays
    // that of a matching model ([`super::CONSISTENT_GAP`], or no more than the acceptance
    // margin above the current one): when the best candidate is not material, the best
    // constant force that is so is accepted.
    let mean_material = |i: usize| {
        let g = gap_of(i);
        results[i].0.effect == Effect::ConstantForce
            && g.gap.is_finite()
            && (g.gap < super::CONSISTENT_GAP || g.gap <= current.gap + opts.min_abs_shrink)
            && material(current.pathwise, g.pathwise)
    };
    let by_statistics = best.filter(|&i| material(current.gap, gap_of(i).gap));
    let accepted = by_statistics.or_else(|| {
        gaps.iter()
            .map(|g| g.0)
            .filter(|&i| mean_material(i))
            .min_by(|&a, &b| gap_of(a).pathwise.total_cmp(&gap_of(b).pathwise))
    });
    if let Some(i) = best.filter(|&b| Some(b) != accepted) {
        results[i].0.note = format!(
            "gap {} vs {} without it: not a material reduction",
            fmt_gap(gap_of(i).gap),
            fmt_gap(current.gap)
        );
    }
    let mut out_best = None;
    if let Some(i) = accepted {
        let g = gap_of(i).clone();
        results[i].0.accepted = true;
        results[i].0.note = if Some(i) == by_statistics {
            "accepted".into()
        } else {
            format!(
                "accepted: a mean the statistical gap does not see (pathwise {} → {})",
                fmt_gap(current.pathwise),
                fmt_gap(g.pathwise)
            )
        };
        let r = &results[i];
        out_best = Some(Accepted {
            score: r.0.clone(),
            variant: Variant {
                ir: r.1.ir.clone(),
                added: r.1.added.clone(),
            },
            gap: g,
            fit: r.3.clone(),
            fits: r.2.clone(),
        });
    }
    Search {
        ranking: results.into_iter().map(|r| r.0).collect(),
        best: out_best,
    }
}

/// How many of the first step's best candidates (by the cross-validated covariance
/// residual) are tried in pairs when no single effect is accepted: at most
/// `PAIR_POOL · (PAIR_POOL − 1) / 2 = 28` more measuring passes, and free runs only for the
/// pairs whose two coefficients are both significant.
const PAIR_POOL: usize = 8;

/// Two effects accepted together by [`pair_step`].
pub(super) struct AcceptedPair {
    /// The two candidates as the pair's fit on all levels gives them.
    pub(super) scores: [CandidateScore; 2],
    pub(super) variant: Variant,
    pub(super) gap: ModelGap,
    pub(super) fit: Identification,
    pub(super) fits: Vec<Identification>,
}

/// Whether the gap falls materially from `before` to `after` (both in %): by more than the
/// absolute and the relative acceptance margins; any finite gap beats a diverged one.
fn material(before: f64, after: f64, opts: &DiagnoseOptions) -> bool {
    let shrink_abs = before - after;
    after.is_finite()
        && (before == f64::INFINITY
            || (shrink_abs > opts.min_abs_shrink && shrink_abs > opts.min_rel_shrink * before))
}

/// Pairs of the first step's best candidates added together, tried when no single effect
/// was accepted. Two effects missing at once can hide each other: on a servo axis missing
/// both its Coulomb friction and a constant force, each alone absorbs part of the other's
/// bias and neither is significant (|p|/σ below 2), while the pair is. A pair is accepted
/// when both coefficients are significant with a physical sign and the withheld gap falls
/// materially — statistically, or, for a pair holding a constant force, pathwise while the
/// statistical gap stays that of a matching model (the rule of a single constant force).
/// The best such pair by withheld gap wins.
pub(super) fn pair_step(
    base: &Variant,
    ranking: &[CandidateScore],
    data: &Data,
    current: &ModelGap,
    opts: &DiagnoseOptions,
) -> Option<AcceptedPair> {
    let n = data.records.len();
    // A candidate the search left without a value (within its error of zero, its column
    // pruned) may still be half of a pair: those follow the valued ones, in ranking order.
    let pool: Vec<&CandidateScore> = ranking
        .iter()
        .filter(|c| c.value.is_finite())
        .chain(ranking.iter().filter(|c| !c.value.is_finite()))
        .take(PAIR_POOL)
        .collect();
    let mut pairs = Vec::new();
    for i in 0..pool.len() {
        for j in i + 1..pool.len() {
            if pool[i].location != pool[j].location
                || pool[i].effect.kind() != pool[j].effect.kind()
            {
                pairs.push((pool[i], pool[j]));
            }
        }
    }
    type Fitted = (
        [CandidateScore; 2],
        Variant,
        Vec<Identification>,
        Identification,
    );
    let fitted: Vec<Fitted> = pairs
        .par_iter()
        .filter_map(|(a, b)| {
            let (ir1, p1) = add_effect(&base.ir, a.effect, &a.location)?;
            let (ir2, p2) = add_effect(&ir1, b.effect, &b.location)?;
            let m = measure_all(&ir2, data, opts).ok()?;
            let all = m.identify_pooled();
            let score = |c: &CandidateScore, p: &str| -> Option<CandidateScore> {
                let e = all.param(p)?;
                let t = e.value.abs() / e.stderr.max(f64::MIN_POSITIVE);
                (e.value.is_finite() && c.effect.sign_ok(e.value) && t > opts.t_min).then(|| {
                    CandidateScore {
                        value: e.value,
                        stderr: e.stderr,
                        t_ratio: t,
                        sign_ok: true,
                        ..(*c).clone()
                    }
                })
            };
            let scores = [score(a, &p1)?, score(b, &p2)?];
            let (_, fits) = cross_validate(&m, &ir2, n);
            let mut added = base.added.clone();
            added.extend([p1, p2]);
            Some((scores, Variant { ir: ir2, added }, fits, all))
        })
        .collect();
    let has_constant_force =
        |s: &[CandidateScore; 2]| s.iter().any(|c| c.effect == Effect::ConstantForce);
    fitted
        .into_iter()
        .filter_map(|(scores, variant, fits, fit)| {
            let g = cv_gap(&variant.ir, &fits, data, opts, "corrected");
            let by_statistics = material(current.gap, g.gap, opts);
            let by_mean = has_constant_force(&scores)
                && g.gap.is_finite()
                && (g.gap < super::CONSISTENT_GAP || g.gap <= current.gap + opts.min_abs_shrink)
                && material(current.pathwise, g.pathwise, opts);
            (by_statistics || by_mean).then_some(AcceptedPair {
                scores,
                variant,
                gap: g,
                fit,
                fits,
            })
        })
        .min_by(|a, b| {
            a.gap
                .gap
                .total_cmp(&b.gap.gap)
                .then(a.gap.pathwise.total_cmp(&b.gap.pathwise))
        })
}

/// `base` with the candidate's model `cir` and parameter `p` appended.
fn variant(base: &Variant, cir: ModelIr, p: String) -> Variant {
    let mut added = base.added.clone();
    added.push(p);
    Variant { ir: cir, added }
}

/// Score a candidate from the moments `m` of its model `cir` (parameter `p`): the estimate
/// on all levels and the cross-validated covariance residual over the `n` levels.
fn score_of(
    eff: Effect,
    loc: &Location,
    p: &str,
    m: &Measurement,
    cir: &ModelIr,
    n: usize,
) -> (CandidateScore, Vec<Identification>, Identification) {
    let all = m.identify_pooled();
    let est = all
        .param(p)
        .cloned()
        .unwrap_or(crate::ident::ParamEstimate {
            name: p.to_string(),
            value: f64::NAN,
            stderr: f64::NAN,
            significant: false,
        });
    let (cv, fits) = cross_validate(m, cir, n);
    let t = if est.value.is_finite() {
        est.value.abs() / est.stderr.max(f64::MIN_POSITIVE)
    } else {
        0.0
    };
    let score = CandidateScore {
        effect: eff,
        location: loc.clone(),
        value: est.value,
        stderr: est.stderr,
        t_ratio: t,
        sign_ok: est.value.is_finite() && eff.sign_ok(est.value),
        cv_residual: cv,
        gap: None,
        pathwise_gap: None,
        accepted: false,
        note: String::new(),
    };
    (score, fits, all)
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
    type Group = (Vec<dynid_ir::ir::BodyId>, Vec<(Effect, Location)>);
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
/// candidate's column — `levels × (3 n_blocks + 1) × n_i × 8` bytes each, about 0.35 MB
/// for the 16-mass chain of `benches/diagnose_chain.rs` (≈ 240 instruments, 3 levels) — so a large
/// model's candidates are measured in groups: each group costs one more pass over the data,
/// and the memory stays that of one group.
const SHARED_PASS_GROUP: usize = 64;

/// Every candidate of a group scored from ONE measuring pass: the model `base` with all candidate
/// terms added is measured once, and each candidate is solved from its own columns of
/// those moments ([`Measurement::restricted`]), exactly the problem its own pass would give.
/// `None` when that model cannot be measured (the caller then measures every candidate on
/// its own, which drops only the candidates that fail).
fn shared_pass(
    base: &Variant,
    cands: &[(Effect, Location)],
    data: &Data,
    opts: &DiagnoseOptions,
    tick: &(dyn Fn() + Sync),
) -> Option<Vec<Scored>> {
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
    let out = cands
        .par_iter()
        .zip(&in_all)
        .filter_map(|((eff, loc), p_all)| {
            let out = (|| {
                let col = m.column(p_all.as_ref()?)?;
                let (cir, p) = add_effect(ir, *eff, loc)?;
                let cols: Vec<usize> = base_cols.iter().copied().chain([col]).collect();
                let (score, fits, all) = {
                    let mc = m.restricted(&cir, &cols)?;
                    score_of(*eff, loc, &p, &mc, &cir, n)
                };
                Some((score, variant(base, cir, p), fits, all))
            })();
            tick();
            out
        })
        .collect();
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::super::{diagnose, DiagnoseOptions, Diagnosis};
    use crate::sim::{simulate, SimConfig};
    use dynid_ir::ir::ModelIr;

    /// The model `base` with `lines` inserted before its closing brace.
    fn with_lines(base: &str, lines: &[&str]) -> String {
        let k = base.rfind('}').unwrap();
        let mut s = base[..k].to_string();
        for l in lines {
            s.push_str(&format!("    {l}\n"));
        }
        s + &base[k..]
    }

    /// Diagnose data of `base` + `common` + `truth` with the model `base` + `common`, once
    /// with the shared pass and once with one pass per candidate.
    fn both(base: &str, common: &[&str], truth: &[&str], noise: f64) -> (Diagnosis, Diagnosis) {
        let model = dsl_parser::compile_str("model", &with_lines(base, common)).unwrap();
        let all: Vec<&str> = common.iter().chain(truth).copied().collect();
        let truth = dsl_parser::compile_str("truth", &with_lines(base, &all)).unwrap();
        let cfg = SimConfig {
            duration: 120.0,
            burn_in: 50.0,
            seed: 11,
            noise,
            ..Default::default()
        };
        both_on(&model, &truth, &cfg)
    }

    /// Diagnose the records `cfg` simulates of `truth` with `model`, once with the shared
    /// pass and once with one pass per candidate.
    fn both_on(model: &ModelIr, truth: &ModelIr, cfg: &SimConfig) -> (Diagnosis, Diagnosis) {
        let recs = simulate(truth, cfg).unwrap().records;
        let origins: Vec<String> = (1..=recs.len()).map(|k| format!("level{k}")).collect();
        let run = |shared: bool| {
            let opts = DiagnoseOptions {
                shared_pass: shared,
                ..Default::default()
            };
            diagnose(model, &recs, &origins, &opts, &|_, _| {}).unwrap()
        };
        (run(true), run(false))
    }

    /// Same ranking (order, effects, locations, notes), verdict and found effects; the
    /// estimates, standard errors and residuals agree to rounding (the moments of a column
    /// are the same sums, accumulated beside other columns).
    fn assert_same(a: &Diagnosis, b: &Diagnosis) {
        assert_eq!(
            a.verdict,
            b.verdict,
            "{}\n---\n{}",
            a.summary(),
            b.summary()
        );
        let close = |x: f64, y: f64| {
            (x.is_nan() && y.is_nan()) || x == y || (x - y).abs() <= 1e-7 * x.abs().max(y.abs())
        };
        for (ra, rb) in [
            (&a.ranking, &b.ranking),
            (&a.residual_ranking, &b.residual_ranking),
        ] {
            assert_eq!(ra.len(), rb.len());
            for (x, y) in ra.iter().zip(rb.iter()) {
                let what = format!("{} at {}", x.effect.name(), x.location.label());
                assert_eq!(x.effect, y.effect, "{what}");
                assert_eq!(x.location, y.location, "{what}");
                assert_eq!(x.note, y.note, "{what}");
                assert_eq!(x.accepted, y.accepted, "{what}");
                assert!(
                    close(x.value, y.value),
                    "{what}: {} vs {}",
                    x.value,
                    y.value
                );
                assert!(
                    close(x.stderr, y.stderr),
                    "{what}: {} vs {}",
                    x.stderr,
                    y.stderr
                );
                assert!(
                    close(x.cv_residual, y.cv_residual),
                    "{what}: {} vs {}",
                    x.cv_residual,
                    y.cv_residual
                );
                let (ga, gb) = (x.gap.unwrap_or(0.0), y.gap.unwrap_or(0.0));
                assert!(
                    (ga - gb).abs() <= 1e-3 * ga.abs().max(1.0),
                    "{what}: {ga} vs {gb}"
                );
            }
        }
        assert_eq!(a.found.len(), b.found.len());
        for (x, y) in a.found.iter().zip(&b.found) {
            assert_eq!((x.effect, &x.location), (y.effect, &y.location));
            assert_eq!(x.param, y.param);
            assert!(close(x.value, y.value), "{} vs {}", x.value, y.value);
        }
        assert_eq!(
            a.fixed_source.lines().count(),
            b.fixed_source.lines().count()
        );
    }

    /// Planned moves with dwells, a model without its Coulomb friction: the Coulomb
    /// candidate's model leaves the rests out of its moments, the others' keep them, so
    /// they are measured in separate shared passes (`by_rests`) and rank as their own
    /// passes do. (Measured in one shared pass, every candidate but the Coulomb one came out
    /// "not resolved by the data".)
    #[test]
    fn the_shared_pass_ranks_as_one_pass_per_candidate_on_planned_moves_with_rests() {
        let planned = include_str!("../../../models/servo_axis_planned.dyn");
        let friction = planned
            .lines()
            .find(|l| l.trim_start().starts_with("force friction"))
            .expect("the planned axis has a Coulomb friction");
        let model = dsl_parser::compile_str("model", &planned.replace(friction, "")).unwrap();
        let truth = dsl_parser::compile_str(
            "truth",
            &with_lines(planned, &["force off (ground, m) = f0 ~ -3.2"]),
        )
        .unwrap();
        let cfg = SimConfig {
            duration: 25.0,
            sample: 1e-3,
            burn_in: 0.0,
            input_oversample: 10,
            quantise: Some(1e-6),
            ..Default::default()
        };
        let (a, b) = both_on(&model, &truth, &cfg);
        assert_same(&a, &b);
        let resolved = a.ranking.iter().filter(|c| c.value.is_finite()).count();
        assert!(
            resolved >= 5,
            "{resolved} of {} resolved\n{}",
            a.ranking.len(),
            a.summary()
        );
    }

    #[test]
    fn the_shared_pass_ranks_as_one_pass_per_candidate() {
        let (a, b) = both(
            include_str!("../../../models/two_mass_linear.dyn"),
            &[],
            &["force nl (m1, m2) = k3 ~ 1.5 * s^3"],
            0.0,
        );
        assert_same(&a, &b);
        assert_eq!(a.found[0].effect.kind(), "cubic", "{}", a.summary());
    }

    /// Measurement noise (the noise corrections of the nonlinear columns) and velocities
    /// estimated from positions (displacement-only data): the same ranking too.
    #[test]
    fn the_shared_pass_ranks_as_one_pass_per_candidate_with_noise_and_estimated_velocities() {
        // Displacement-only identification needs filter chains of order ≥ 3: let it choose.
        let base: String = include_str!("../../../models/two_mass_linear.dyn")
            .lines()
            .filter(|l| !l.trim_start().starts_with("filter"))
            .map(|l| format!("{l}\n"))
            .collect();
        let (a, b) = both(
            &base,
            &["measure m1.x, m2.x, u"],
            &["force fr (m1, m2) = r ~ 0.3 * sign(v)"],
            0.02,
        );
        assert_same(&a, &b);
    }
}
