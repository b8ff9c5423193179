//! The diagnosis assembled from the phases: the corrected model (identified on all levels
//! with the found effects, written as `.dyn` text), the spectra and time series of the
//! level the nominal model misses most, and the force channel of each recorded force.

use super::baseline::Baseline;
use super::force::{self, Channel};
use super::format::{fmt_num, shrink};
use super::levels::{unit_of, with_values, Data};
use super::score::level_gap;
use super::search::{Outcome, Reached};
use super::types::{
    CorrectedParam, DiagnoseOptions, Diagnosis, ForceGap, ForceGapValue, FoundEffect, ModelGap,
    Spectrum, Trace, Verdict,
};
use crate::ident::Identification;
use dynid_ir::ir::ModelIr;
use dynid_ir::num;
use rayon::prelude::*;

/// A note for each found effect that the corrected model leaves within `t_min` standard
/// errors of zero: the greedy search keeps an effect it found first even where the one
/// found after it takes its part (a cubic stiffness found before the backlash of a
/// clearance between two accelerometers, −0.045 ± 0.023 once the backlash joined it;
/// docs/diagnosis.md, "Limits").
fn left_insignificant(found: &[FoundEffect], t_min: f64) -> Vec<String> {
    if found.len() < 2 {
        return Vec::new();
    }
    found
        .iter()
        .enumerate()
        .filter(|(_, f)| f.stderr > 0.0 && f.value.abs() <= t_min * f.stderr)
        .map(|(k, f)| {
            let others: Vec<String> = found
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .map(|(_, o)| format!("{} at {}", o.effect.name(), o.location.label()))
                .collect();
            format!(
                "{} at {} is not significant in the corrected model ({} ± {}, |p|/σ = {:.1}) \
                 once {} is in it: the search found it first, and {} alone may explain its part",
                f.effect.name(),
                f.location.label(),
                fmt_num(f.value),
                fmt_num(f.stderr),
                f.value.abs() / f.stderr,
                others.join(" and "),
                if others.len() > 1 { "those" } else { "that" }
            )
        })
        .collect()
}

/// The diagnosis of `ir` on the levels from its `base`line, the search's `outcome` and the
/// `verdict`.
pub(super) fn assemble(
    ir: &ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
    base: Baseline,
    mut outcome: Outcome,
    verdict: Verdict,
    mut notes: Vec<String>,
) -> Diagnosis {
    let reached = &outcome.reached;
    // Each found effect's value as the corrected model has it (identified on all levels
    // with every found effect): a constant force found before a friction carries part of
    // the friction's bias until the friction is added.
    for f in &mut outcome.found {
        if let Some(e) = reached.fit.param(&f.param) {
            (f.value, f.stderr) = (e.value, e.stderr);
        }
    }
    notes.extend(left_insignificant(&outcome.found, opts.t_min));
    let found_any = !outcome.found.is_empty();
    let (parameters, fixed_source) = corrected_model(ir, reached);
    let corrected = ModelGap {
        label: "corrected".into(),
        ..reached.gap.clone()
    };
    let (spectra, traces) = spectra_and_traces(ir, data, opts, &base, reached, found_any);
    let force_gaps = force_gaps(ir, data, &base.reid_fits, reached, found_any);
    let nominal = base.nominal;
    let reidentified = base.reidentified;
    let (gap_before, gap_after) = (nominal.gap, corrected.gap);
    Diagnosis {
        model: ir.name.clone(),
        levels: data.origins.to_vec(),
        response_signals: data.response.clone(),
        verdict,
        gap_before,
        gap_reidentified: reidentified.gap,
        gap_after,
        shrink: shrink(gap_before, gap_after),
        effect_shrink: if found_any {
            shrink(reidentified.gap, gap_after)
        } else {
            Some(0.0)
        },
        pathwise_gap_before: nominal.pathwise,
        pathwise_gap_reidentified: reidentified.pathwise,
        pathwise_gap_after: corrected.pathwise,
        nominal,
        reidentified,
        corrected,
        equations: base.equations,
        force_gaps,
        drift: base.drift,
        moved: base.moved,
        parameters,
        found: outcome.found,
        ranking: outcome.ranking,
        residual_ranking: outcome.residual_ranking,
        notes,
        fixed_source,
        spectra,
        traces,
    }
}

/// The corrected model's parameters and its text: identified on all levels, values
/// written as nominals. Five significant digits: the standard errors are far larger than
/// the rounding.
fn corrected_model(ir: &ModelIr, reached: &Reached) -> (Vec<CorrectedParam>, String) {
    let parameters = reached
        .fit
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
    let mut fixed_ir = reached.variant.ir.clone();
    for e in &reached.fit.params {
        // An unknown of the model by construction; a non-finite value keeps the nominal.
        let _ = fixed_ir.set_nominal(&e.name, num::round_sig(e.value, 5));
    }
    let shapes: Vec<f64> = fixed_ir
        .shapes
        .iter()
        .map(|sh| num::round_sig(sh.nominal, 5))
        .collect();
    let fixed_ir = fixed_ir.with_shapes(&shapes);
    (parameters, dynid_ir::print::to_source(&fixed_ir))
}

/// Spectra and time series on the level where the nominal model misses most: the nominal
/// model, and the re-identified and corrected models fitted without that level (as
/// scored); the corrected one only when an effect was found.
fn spectra_and_traces(
    ir: &ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
    base: &Baseline,
    reached: &Reached,
    found_any: bool,
) -> (Vec<Spectrum>, Vec<Trace>) {
    let n = data.records.len();
    let big = (0..n)
        .max_by(|&a, &b| {
            let g = |w: usize| base.nominal.levels[w].gap.unwrap_or(f64::NEG_INFINITY);
            g(a).total_cmp(&g(b))
        })
        .unwrap_or(0);
    let reid_runs = level_gap(
        &with_values(ir, &base.reid_fits[big]),
        data,
        big,
        opts,
        true,
    );
    let corrected_runs = found_any.then(|| {
        level_gap(
            &with_values(&reached.variant.ir, &reached.fits[big]),
            data,
            big,
            opts,
            true,
        )
    });
    let nominal_run = level_gap(ir, data, big, opts, true).1;
    let mut spectra = Vec::new();
    let mut traces = Vec::new();
    let (Some(nom), Some(re)) = (&nominal_run, &reid_runs.1) else {
        return (spectra, traces);
    };
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
            unit: unit_of(ir, &n.signal).into(),
            level: big,
            t0: n.t0,
            ts: data.records[big].ts,
            measured: n.measured.clone(),
            models: runs,
        });
    }
    (spectra, traces)
}

/// The force channel of each recorded force (open loop): the nominal model, and the
/// re-identified and corrected models fitted without each level, on that level.
fn force_gaps(
    ir: &ModelIr,
    data: &Data,
    reid_fits: &[Identification],
    reached: &Reached,
    found_any: bool,
) -> Vec<ForceGap> {
    let levels = data.records;
    let n = levels.len();
    force::channels(ir)
        .into_iter()
        .map(|(input, body)| {
            let channels: Vec<Option<Channel>> =
                levels.par_iter().map(|r| force::channel(ir, r)).collect();
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
                reidentified: per_model(&|w| with_values(ir, &reid_fits[w])),
                corrected: found_any
                    .then(|| per_model(&|w| with_values(&reached.variant.ir, &reached.fits[w])))
                    .flatten(),
                unit: "N".into(),
                input,
                equation: body,
            }
        })
        .collect()
}
