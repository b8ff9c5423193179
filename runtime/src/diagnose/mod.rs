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
mod gap;
pub mod metrics;
mod search;
mod summary;
pub mod types;

pub use effects::{Effect, Location};
pub use gap::read_record;
pub use types::*;

use crate::ident::Identification;
use crate::record::Record;
use dynid_ir::ir::{ModelIr, SignalKind};
use dynid_ir::num;
use effects::Variant;
use gap::{cov_residual, cross_validate, cv_gap, level_gap, mean_gap, measure_all, Data};
use rayon::prelude::*;
use search::search_step;

/// Values in the diagnosis' text and report: five significant digits.
pub fn fmt_num(v: f64) -> String {
    num::sig(v, 5, false)
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
    let response: Vec<String> = ir
        .measured_signals()
        .iter()
        .map(|s| ir.signal(*s))
        .filter(|s| !matches!(s.kind, SignalKind::Input { .. }))
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
    let mut notes = Vec::new();

    // Before: the nominal model on every level.
    let nominal_runs: Vec<_> = (0..n)
        .into_par_iter()
        .map(|w| level_gap(&ir, &data, w, opts, true))
        .collect();
    let nominal_levels: Vec<LevelGap> = nominal_runs.iter().map(|r| r.0.clone()).collect();
    let nominal = ModelGap {
        label: "nominal".into(),
        gap: mean_gap(&nominal_levels),
        levels: nominal_levels,
    };
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
    drop(m);

    // Which effect: greedy search.
    let mut current = Variant {
        ir: ir.clone(),
        added: vec![],
    };
    let mut current_gap = reidentified.clone();
    let mut current_fit = pooled.clone();
    let mut found = Vec::new();
    let mut ranking = Vec::new();
    let mut residual_ranking = Vec::new();
    for step in 0..opts.max_effects {
        let s = search_step(
            &current,
            &found,
            &data,
            current_gap.gap,
            opts,
            &mut notes,
            progress,
        );
        if step == 0 {
            ranking = s.ranking;
        } else if s.best.is_none() {
            residual_ranking = s.ranking;
        }
        let Some((c, v, g, fit)) = s.best else { break };
        let param = v.added.last().cloned().unwrap_or_default();
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
            gap_before: current_gap.gap,
            gap_after: g.gap,
        });
        current = v;
        current_gap = g;
        current_fit = fit;
    }

    // The corrected model: identified on all levels, values written as nominals.
    // Five significant digits: the standard errors are far larger than the rounding.
    let mut fixed_ir = current.ir.clone();
    for e in &current_fit.params {
        // An unknown of the model by construction; a non-finite value keeps the nominal.
        let _ = fixed_ir.set_nominal(&e.name, num::round_sig(e.value, 5));
    }
    let fixed = dynid_ir::print::to_source(&fixed_ir);
    let corrected = ModelGap {
        label: "corrected".into(),
        ..current_gap.clone()
    };

    // Spectra on the level where the nominal model misses most.
    let big = (0..n)
        .max_by(|&a, &b| nominal.levels[a].gap.total_cmp(&nominal.levels[b].gap))
        .unwrap_or(0);
    let corrected_runs = level_gap(&fixed_ir, &data, big, opts, true);
    let mut spectra = Vec::new();
    if let (Some(nom), Some(cor)) = (&nominal_runs[big].1, &corrected_runs.1) {
        for ((sig, f, pm, ps), (_, _, _, pc)) in nom.iter().zip(cor) {
            spectra.push(Spectrum {
                signal: sig.clone(),
                level: big,
                freqs: f.clone(),
                measured: pm.clone(),
                models: vec![
                    ("nominal".into(), ps.clone()),
                    ("corrected".into(), pc.clone()),
                ],
            });
        }
    }

    let gap_before = nominal.gap;
    let gap_after = corrected.gap.min(gap_before);
    let verdict = if !found.is_empty() {
        Verdict::MissingEffect
    } else if reidentified.gap < 0.5 * gap_before && gap_before > opts.min_abs_shrink * 2.0 {
        if reidentified.gap < 5.0 {
            Verdict::MistunedParameters
        } else {
            Verdict::Unexplained
        }
    } else if reidentified.gap.min(gap_before) < 5.0 {
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
        gap_after: if found.is_empty() {
            reidentified.gap.min(gap_before)
        } else {
            gap_after
        },
        shrink: if gap_before > 0.0 {
            1.0 - (if found.is_empty() {
                reidentified.gap.min(gap_before)
            } else {
                gap_after
            }) / gap_before
        } else {
            0.0
        },
        nominal,
        reidentified,
        corrected,
        equations,
        drift,
        moved,
        found,
        ranking,
        residual_ranking,
        notes,
        fixed_source: fixed,
        spectra,
    })
}
