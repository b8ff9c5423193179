//! Diagnosis of the sim-to-real gap: where a simulation model misses measured data, which
//! unmodelled effect explains it, and how far the gap shrinks once that effect is added.
//!
//! The gap is measured by simulation (the model driven by the measured input from the
//! measured initial state, free run, compared with the measured response) and by the
//! covariance-equation residual.
//! Candidate effects from a small library are added as new unknown force elements by editing
//! the model's IR (`dynid_ir::edit`), so that names stay those of the user's model; the
//! corrected model is written as ordinary `.dyn` text by the IR's source printer. Every candidate is fitted
//! on all levels but one and scored on the withheld level, rotating the withheld level, so
//! that an extra term is never rewarded for fitting noise. Definitions and thresholds are
//! documented in `docs/diagnosis.md`.

pub mod effects;
mod force;
mod gap;
pub mod metrics;
mod profile;
mod search;
mod summary;
pub mod types;

pub use effects::{Effect, Location};
pub use gap::read_record;
pub use summary::{fmt_shrink, signal_means};
pub use types::*;

use crate::ident::Identification;
use crate::record::Record;
use dynid_ir::ir::{ModelIr, SignalKind};
use dynid_ir::num;
use effects::Variant;
use gap::{
    cov_residual, cross_validate, cv_gap, level_gap, measure_all, model_gap, with_values, Data,
};
use rayon::prelude::*;
use search::search_step;

/// Statistical gap (%) below which a model matches the data.
const CONSISTENT_GAP: f64 = 5.0;

/// Values in the diagnosis' text and report: five significant digits.
pub fn fmt_num(v: f64) -> String {
    num::sig(v, 5, false)
}

/// Gaps above this (in %) are printed as "> 1000 %": a prediction ten times the size of
/// the signal is simply wrong, and its digits say nothing more (the JSON keeps them).
pub const GAP_SHOWN_MAX: f64 = 1000.0;

/// A gap in % for the text and report: one decimal, "> 1000 %" beyond [`GAP_SHOWN_MAX`],
/// "diverged" for an infinite gap (a run that diverged), "unavailable" for one that cannot
/// be computed.
pub fn fmt_gap(v: f64) -> String {
    if v.is_finite() && v > GAP_SHOWN_MAX {
        format!("> {GAP_SHOWN_MAX:.0} %")
    } else if v.is_finite() {
        format!("{v:.1} %")
    } else if v == f64::INFINITY {
        "diverged".into()
    } else {
        "unavailable".into()
    }
}

/// A value in `unit` with the SI prefix that puts three significant digits before the
/// point or near it: `1.23e-5` m → "12.3 µm", `35.2` N → "35.2 N", `0.004` m/s → "4 mm/s";
/// "unavailable" when not finite.
pub fn fmt_si(v: f64, unit: &str) -> String {
    if !v.is_finite() {
        return "unavailable".into();
    }
    if v == 0.0 || unit.is_empty() {
        return format!("{} {unit}", num::sig(v, 3, false))
            .trim_end()
            .into();
    }
    const PREFIXES: [(f64, &str); 6] = [
        (1e6, "M"),
        (1e3, "k"),
        (1.0, ""),
        (1e-3, "m"),
        (1e-6, "µ"),
        (1e-9, "n"),
    ];
    let a = v.abs();
    let (scale, prefix) = PREFIXES
        .iter()
        .find(|(s, _)| a >= *s * 0.9995)
        .copied()
        .unwrap_or((1e-9, "n"));
    format!("{} {prefix}{unit}", num::sig(v / scale, 3, false))
}

/// [`fmt_gap`] of a gap that may be unavailable.
pub fn fmt_opt_gap(v: Option<f64>) -> String {
    v.map_or("unavailable".into(), fmt_gap)
}

/// `1 − after / before`; `None` when either gap is not finite or `before` is 0.
pub fn shrink(before: f64, after: f64) -> Option<f64> {
    (before.is_finite() && after.is_finite() && before > 0.0).then(|| 1.0 - after / before)
}

/// Diagnose the gap between the model in `source` and measured `levels` (one record per
/// excitation level, at least 2). `progress(done, total)` reports the candidate search.
pub fn diagnose(
    model: &ModelIr,
    levels: &[Record],
    origins: &[String],
    opts: &DiagnoseOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Diagnosis, DiagnoseError> {
    let ir = model.clone();
    let n = levels.len();
    if n < 2 {
        return Err(DiagnoseError::TooFewLevels(n));
    }
    if let Some(p) = ir.params.iter().find(|p| p.nominal().is_none()) {
        return Err(DiagnoseError::MissingNominal(p.name.clone()));
    }
    // The responses: body signals, and in closed loop the inputs a law computes (the drive
    // force answers the plant as much as the position does). Open-loop inputs and
    // references are given, not responses.
    let response: Vec<String> = ir
        .measured_signals()
        .iter()
        .map(|s| ir.signal(*s))
        .filter(|s| match s.kind {
            SignalKind::Position(_) | SignalKind::Velocity(_) | SignalKind::Acceleration(_) => true,
            SignalKind::Input(i) => ir.control_of(i).is_some(),
            SignalKind::Reference(_) => false,
        })
        .map(|s| s.name.clone())
        .collect();
    if response.is_empty() {
        return Err(DiagnoseError::NoResponse);
    }
    let origins: Vec<String> = (0..n)
        .map(|i| {
            origins
                .get(i)
                .cloned()
                .unwrap_or(format!("level {}", i + 1))
        })
        .collect();
    let data = Data {
        records: levels,
        origins: &origins,
        response: response.clone(),
    };
    let mut notes: Vec<String> = Vec::new();

    // Before: the nominal model on every level.
    let nominal_runs: Vec<_> = (0..n)
        .into_par_iter()
        .map(|w| level_gap(&ir, &data, w, opts, false))
        .collect();
    let nominal_levels: Vec<LevelGap> = nominal_runs.iter().map(|r| r.0.clone()).collect();
    if nominal_levels.iter().all(|l| l.gap.is_none()) {
        return Err(DiagnoseError::NoVariance);
    }
    for l in nominal_levels.iter().filter(|l| l.gap.is_none()) {
        notes.push(format!(
            "{}: no response signal varies, so its gap is unavailable and left out of the means",
            l.origin
        ));
    }
    let nominal = model_gap("nominal", nominal_levels);
    // Where: covariance residual per equation with the nominal values; drift per level.
    let m = measure_all(&ir, &data, opts)?;
    let p_nom: Vec<f64> = ir
        .unknowns()
        .iter()
        .map(|p| ir.params[p.index()].nominal().unwrap_or(0.0))
        .collect();
    let equations = ir
        .bodies
        .iter()
        .map(|b| EquationGap {
            equation: b.name.clone(),
            per_level: (0..n)
                .map(|w| cov_residual(&m, &p_nom, w, Some(&b.name)))
                .collect(),
        })
        .collect();
    let pooled = m.identify_pooled();
    // What the identification's guard says of the data (a sensor offset, a wrong fixed
    // mass, a record given twice) holds for every fit below. A missing force (a constant
    // one included) is what the diagnosis itself looks for, so that warning is left to
    // the search.
    {
        let srcs = gap::sources(&ir, &data)?;
        let refs: Vec<&dyn crate::data::LevelSource> = srcs
            .iter()
            .map(|s| s as &dyn crate::data::LevelSource)
            .collect();
        use crate::ident::LikelyCause;
        for w in crate::ident::guard::check(&m, &pooled, &refs, &opts.ident)
            .into_iter()
            .filter(|w| {
                matches!(
                    w.cause,
                    LikelyCause::SensorOffset
                        | LikelyCause::WrongMass
                        | LikelyCause::SameRecordTwice
                )
            })
        {
            notes.push(format!("identification warning: {w}"));
        }
        // Levels too alike to show a drift (the warning of `dynid detect`, with its
        // settings): an effect the search does not find may be one the levels cannot
        // resolve. A model that detection cannot fit per level gets no such warning.
        let detect_opts = crate::ident::IdentifyOptions {
            n_blocks: crate::ident::IdentifyOptions::default().n_blocks,
            ..opts.ident.clone()
        };
        if let Ok(alike) = crate::detect::levels_too_alike_in(&ir, &refs, &detect_opts) {
            for w in alike {
                notes.push(format!("detection warning: {}", w.message));
            }
        }
    }
    // Masses held at one value, as detection does: a mass fitted freely per level trades
    // off against the stiffness and hides its drift (Silverbox: m and a each scatter by
    // 10 % while their ratio rises 8 %).
    let held: Vec<(String, f64)> = crate::detect::held_inertia(&ir, &m)
        .into_iter()
        .map(|h| (h.param, h.value))
        .collect();
    let per_level: Vec<Identification> =
        (0..n).map(|i| m.identify_level_holding(i, &held)).collect();
    let drift: Vec<ParamDrift> = ir
        .unknowns()
        .iter()
        .filter(|p| !held.iter().any(|(h, _)| *h == ir.params[p.index()].name))
        .map(|p| {
            let name = ir.params[p.index()].name.clone();
            let vals: Vec<Option<f64>> = per_level
                .iter()
                .map(|id| id.param(&name).map(|e| e.value))
                .collect();
            let errs: Vec<Option<f64>> = per_level
                .iter()
                .map(|id| id.param(&name).map(|e| e.stderr))
                .collect();
            let missing: Vec<Option<String>> = per_level
                .iter()
                .map(|id| {
                    id.param(&name).is_none().then(|| {
                        id.unidentifiable
                            .iter()
                            .find(|u| u.name == name)
                            .map_or_else(|| "not identified".into(), |u| u.reason.clone())
                    })
                })
                .collect();
            let v: Vec<f64> = vals.iter().flatten().copied().collect();
            let e: Vec<f64> = errs.iter().flatten().copied().collect();
            let (lo, hi) = v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
            let spread = hi - lo;
            let se = e.iter().map(|x| x * x).sum::<f64>().sqrt();
            ParamDrift {
                nominal: ir.params[p.index()].nominal(),
                pooled: pooled.param(&name).map(|e| e.value),
                drift: if v.len() > 1 && mean != 0.0 {
                    100.0 * spread / mean.abs()
                } else {
                    0.0
                },
                significant: v.len() > 1 && spread > 4.0 * se,
                name,
                per_level: vals,
                stderr: errs,
                missing,
            }
        })
        .collect();
    let moved = ir
        .unknowns()
        .iter()
        .filter_map(|p| {
            let pr = &ir.params[p.index()];
            let nom = pr.nominal()?;
            let e = pooled.param(&pr.name)?;
            Some(MovedParam {
                name: pr.name.clone(),
                nominal: nom,
                identified: e.value,
                change: (nom != 0.0).then(|| 100.0 * (e.value - nom) / nom.abs()),
            })
        })
        .collect();
    let (_, base_fits) = cross_validate(&m, &ir, n);
    let reidentified = cv_gap(&ir, &base_fits, &data, opts, "re-identified");
    let reid_fits = base_fits.clone();
    drop(m);

    // Which effect: greedy search.
    let mut current = Variant {
        ir: ir.clone(),
        added: vec![],
    };
    let mut current_gap = reidentified.clone();
    let mut current_fit = pooled.clone();
    let mut current_fits = base_fits.clone();
    let mut found = Vec::new();
    let mut ranking = Vec::new();
    let mut residual_ranking = Vec::new();
    for step in 0..opts.max_effects {
        if found.len() >= opts.max_effects {
            break;
        }
        let s = search_step(
            &current,
            &found,
            &data,
            &current_gap,
            opts,
            &mut notes,
            progress,
        );
        if step == 0 {
            ranking = s.ranking;
        } else if s.best.is_none() {
            residual_ranking = s.ranking;
        }
        // No single effect at the first step: two effects that hide each other may be
        // missing together (`search::pair_step`).
        if step == 0 && s.best.is_none() && opts.max_effects >= 2 {
            if let Some(pair) = search::pair_step(&current, &ranking, &data, &current_gap, opts) {
                let names: Vec<String> = pair
                    .scores
                    .iter()
                    .map(|c| format!("{} at {}", c.effect.name(), c.location.label()))
                    .collect();
                for (k, c) in pair.scores.iter().enumerate() {
                    if let Some(r) = ranking
                        .iter_mut()
                        .find(|r| r.effect == c.effect && r.location == c.location)
                    {
                        r.accepted = true;
                        r.gap = Some(pair.gap.gap);
                        r.pathwise_gap = Some(pair.gap.pathwise);
                        r.note = format!("accepted together with {}", names[1 - k]);
                    }
                }
                let base_elements = current.ir.elements.len();
                for (k, c) in pair.scores.iter().enumerate() {
                    found.push(FoundEffect {
                        effect: c.effect,
                        location: c.location.clone(),
                        element: pair
                            .variant
                            .ir
                            .elements
                            .get(base_elements + k)
                            .map(|e| e.name.clone())
                            .unwrap_or_default(),
                        param: pair.variant.added[pair.variant.added.len() - 2 + k].clone(),
                        value: c.value,
                        stderr: c.stderr,
                        unit: c.effect.unit(),
                        shape_stderr: None,
                        gap_before: current_gap.gap,
                        gap_after: pair.gap.gap,
                        pathwise_gap_before: current_gap.pathwise,
                        pathwise_gap_after: pair.gap.pathwise,
                    });
                }
                notes.push(format!(
                    "no single effect reduced the gap; {} added together did ({} → {}): each \
                     alone absorbs part of the other's force",
                    names.join(" and "),
                    fmt_gap(current_gap.gap),
                    fmt_gap(pair.gap.gap)
                ));
                current = pair.variant;
                current_gap = pair.gap;
                current_fit = pair.fit;
                current_fits = pair.fits;
                continue;
            }
        }
        let Some(search::Accepted {
            score: mut c,
            variant: mut v,
            gap: mut g,
            mut fit,
            mut fits,
        }) = s.best
        else {
            break;
        };
        let param = v.added.last().cloned().unwrap_or_default();
        let mut shape_stderr = None;
        if let (Effect::Backlash { gap: grid }, true) = (c.effect, opts.profile_shapes) {
            match profile::profile_gap(&v.ir, grid, &data, opts, &g.label) {
                Ok(p) => {
                    // The profile's estimate: its error carries the gap's along the profile.
                    if let Some(e) = p.profile_fit.param(&param) {
                        (c.value, c.stderr) = (e.value, e.stderr);
                    }
                    // Five significant digits, as the corrected model's values.
                    c.effect = Effect::Backlash {
                        gap: num::round_sig(p.gap, 5),
                    };
                    shape_stderr = p.stderr;
                    v.ir = p.ir;
                    (g, fit, fits) = (p.model_gap, p.fit, p.fits);
                }
                Err(why) => notes.push(format!(
                    "the backlash gap at {} was not profiled ({why}); the grid value {} is kept",
                    c.location.label(),
                    num::exact(grid)
                )),
            }
        }
        let element =
            v.ir.elements
                .iter()
                .rev()
                .find(|e| e.name.starts_with("gap_fix"))
                .map(|e| e.name.clone())
                .unwrap_or_default();
        found.push(FoundEffect {
            effect: c.effect,
            location: c.location.clone(),
            element,
            param,
            value: c.value,
            stderr: c.stderr,
            unit: c.effect.unit(),
            shape_stderr,
            gap_before: current_gap.gap,
            gap_after: g.gap,
            pathwise_gap_before: current_gap.pathwise,
            pathwise_gap_after: g.pathwise,
        });
        current = v;
        current_gap = g;
        current_fit = fit;
        current_fits = fits;
    }

    // Effects that leave the gap larger than the nominal model's, where that already
    // matches, are no finding: the re-identified parameters moved away from a model that
    // holds (a biased fit, e.g. on data with a sensor offset), and the effects only made up
    // part of that move. (A gap that is not a number is not smaller either.) Judged on the
    // whole search, not step by step: a constant force and a friction both missing each
    // leave part of the bias until the other is added. The statistical gap does not see a
    // signal's mean, which is all a constant force changes in a model that holds
    // otherwise: a corrected model with a constant force that still matches (a gap below
    // `CONSISTENT_GAP`, or within the acceptance margin `min_abs_shrink` of the nominal
    // one — the rule the search accepts a constant force by) and follows the measured paths
    // more closely (pathwise gap) is a finding — on a body no force of which depends on
    // its position: on one held by a spring, a zero offset `x0` of the position sensor
    // gives the same mean as a constant force `−k·x0`, and the guard's note names both.
    if !found.is_empty() && nominal.gap < CONSISTENT_GAP {
        let smaller = current_gap.gap < nominal.gap;
        let mean_shown = found.iter().any(|f| {
            f.effect == Effect::ConstantForce
                && !crate::ident::guard::position_dependent(&ir, Some(&f.location.b))
        }) && (current_gap.gap < CONSISTENT_GAP
            || current_gap.gap <= nominal.gap + opts.min_abs_shrink)
            && current_gap.pathwise < nominal.pathwise;
        if !(smaller || mean_shown) {
            let names: Vec<String> = found
                .iter()
                .map(|f| format!("{} at {}", f.effect.name(), f.location.label()))
                .collect();
            notes.push(format!(
                "the nominal model already matches the data (gap {}); the re-identified \
                 model with the best effect{} ({}) leaves a larger gap ({}), so no effect is \
                 needed — the re-identified parameters are biased (see the identification \
                 warnings)",
                fmt_gap(nominal.gap),
                if found.len() > 1 { "s" } else { "" },
                names.join(", "),
                fmt_gap(current_gap.gap)
            ));
            for r in ranking.iter_mut().filter(|r| r.accepted) {
                r.accepted = false;
                r.note = "not needed: the nominal model already matches".into();
            }
            found.clear();
            current = Variant {
                ir: ir.clone(),
                added: vec![],
            };
            current_gap = reidentified.clone();
            current_fit = pooled.clone();
            current_fits = reid_fits.clone();
            residual_ranking.clear();
        }
    }

    // Each found effect's value as the corrected model has it (identified on all levels
    // with every found effect): a constant force found before a friction carries part of
    // the friction's bias until the friction is added.
    for f in &mut found {
        if let Some(e) = current_fit.param(&f.param) {
            (f.value, f.stderr) = (e.value, e.stderr);
        }
    }
    let parameters = current_fit
        .params
        .iter()
        .map(|e| {
            let original = ir.params.iter().find(|p| p.name == e.name);
            CorrectedParam {
                name: e.name.clone(),
                value: e.value,
                stderr: e.stderr,
                nominal: original.and_then(|p| p.nominal()),
                kind: if original.is_some() {
                    "model"
                } else {
                    "found effect"
                },
            }
        })
        .collect();
    // The corrected model: identified on all levels, values written as nominals.
    // Five significant digits: the standard errors are far larger than the rounding.
    let mut fixed_ir = current.ir.clone();
    for e in &current_fit.params {
        // An unknown of the model by construction; a non-finite value keeps the nominal.
        let _ = fixed_ir.set_nominal(&e.name, num::round_sig(e.value, 5));
    }
    let shapes: Vec<f64> = fixed_ir
        .shapes
        .iter()
        .map(|sh| num::round_sig(sh.nominal, 5))
        .collect();
    let fixed_ir = fixed_ir.with_shapes(&shapes);
    let fixed = dynid_ir::print::to_source(&fixed_ir);
    let corrected = ModelGap {
        label: "corrected".into(),
        ..current_gap.clone()
    };

    // Spectra on the level where the nominal model misses most: the nominal model, and the
    // re-identified and corrected models fitted without that level (as scored).
    let big = (0..n)
        .max_by(|&a, &b| {
            let g = |w: usize| nominal.levels[w].gap.unwrap_or(f64::NEG_INFINITY);
            g(a).total_cmp(&g(b))
        })
        .unwrap_or(0);
    let reid_runs = level_gap(&with_values(&ir, &reid_fits[big]), &data, big, opts, true);
    let corrected_runs = if found.is_empty() {
        None
    } else {
        Some(level_gap(
            &with_values(&current.ir, &current_fits[big]),
            &data,
            big,
            opts,
            true,
        ))
    };
    let nominal_run = level_gap(&ir, &data, big, opts, true).1;
    let mut spectra = Vec::new();
    let mut traces = Vec::new();
    if let (Some(nom), Some(re)) = (&nominal_run, &reid_runs.1) {
        let cor = corrected_runs.as_ref().and_then(|r| r.1.as_ref());
        for (k, (n, r)) in nom.iter().zip(re).enumerate() {
            let c = cor.and_then(|c| c.get(k));
            let mut models = vec![
                ("nominal".to_string(), n.sim_psd.clone()),
                (
                    "re-identified (level withheld)".to_string(),
                    r.sim_psd.clone(),
                ),
            ];
            let mut runs = vec![
                ("nominal".to_string(), n.sim.clone()),
                ("re-identified (level withheld)".to_string(), r.sim.clone()),
            ];
            if let Some(c) = c {
                models.push(("corrected (level withheld)".into(), c.sim_psd.clone()));
                runs.push(("corrected (level withheld)".into(), c.sim.clone()));
            }
            spectra.push(Spectrum {
                signal: n.signal.clone(),
                level: big,
                freqs: n.freqs.clone(),
                measured: n.measured_psd.clone(),
                models,
            });
            traces.push(Trace {
                signal: n.signal.clone(),
                unit: gap::unit_of(&ir, &n.signal).into(),
                level: big,
                t0: n.t0,
                ts: levels[big].ts,
                measured: n.measured.clone(),
                models: runs,
            });
        }
    }

    // The force channel of each recorded force (open loop): the nominal model, and the
    // re-identified and corrected models fitted without each level, on that level.
    let force_gaps: Vec<ForceGap> = force::channels(&ir)
        .into_iter()
        .map(|(input, body)| {
            let channels: Vec<Option<force::Channel>> =
                levels.par_iter().map(|r| force::channel(&ir, r)).collect();
            let per_model = |model: &(dyn Fn(usize) -> ModelIr + Sync)| -> Option<ForceGapValue> {
                let v: Vec<Option<(f64, f64)>> = (0..n)
                    .into_par_iter()
                    .map(|w| {
                        let ch = channels[w].as_ref()?;
                        force::gap(&model(w), ch, &input, &body)
                    })
                    .collect();
                force::mean(&v)
            };
            ForceGap {
                band_hz: force::band_hz(levels[0].ts),
                nominal: per_model(&|_| ir.clone()),
                reidentified: per_model(&|w| with_values(&ir, &reid_fits[w])),
                corrected: (!found.is_empty())
                    .then(|| per_model(&|w| with_values(&current.ir, &current_fits[w])))
                    .flatten(),
                unit: "N".into(),
                input,
                equation: body,
            }
        })
        .collect();

    let gap_before = nominal.gap;
    let gap_after = corrected.gap;
    let verdict = if !found.is_empty() {
        Verdict::MissingEffect
    } else if reidentified.gap < 0.5 * gap_before && gap_before > opts.min_abs_shrink * 2.0 {
        if reidentified.gap < 5.0 {
            Verdict::MistunedParameters
        } else {
            Verdict::Unexplained
        }
    } else if reidentified.gap.min(gap_before) < CONSISTENT_GAP {
        Verdict::Consistent
    } else {
        Verdict::Unexplained
    };
    Ok(Diagnosis {
        model: ir.name.clone(),
        levels: origins.clone(),
        response_signals: response,
        verdict,
        gap_before,
        gap_reidentified: reidentified.gap,
        gap_after,
        shrink: shrink(gap_before, gap_after),
        effect_shrink: if found.is_empty() {
            Some(0.0)
        } else {
            shrink(reidentified.gap, gap_after)
        },
        pathwise_gap_before: nominal.pathwise,
        pathwise_gap_reidentified: reidentified.pathwise,
        pathwise_gap_after: corrected.pathwise,
        nominal,
        reidentified,
        corrected,
        equations,
        force_gaps,
        drift,
        moved,
        parameters,
        found,
        ranking,
        residual_ranking,
        notes,
        fixed_source: fixed,
        spectra,
        traces,
    })
}
