//! The model as given, before any effect is added: its gap with the nominal values, the
//! covariance residual of each equation, what the identification's guard and detection
//! say of the data, the parameters re-identified on all levels and per level (their
//! drift), and the gap of the re-identified model — the start of the search.

use super::fit::{cross_validate, measure_all};
use super::levels::{sources, Data};
use super::score::{cov_residual, cv_gap, level_gap, model_gap};
use super::types::{DiagnoseError, DiagnoseOptions, EquationGap, LevelGap, ModelGap};
use super::types::{MovedParam, ParamDrift};
use crate::data::LevelSource;
use crate::ident::{Identification, LikelyCause, Measurement};
use dynid_ir::ir::{ModelIr, ParamId};
use rayon::prelude::*;

/// What the diagnosis knows of the model as given.
pub(super) struct Baseline {
    /// The free-run gap with the nominal values.
    pub(super) nominal: ModelGap,
    pub(super) equations: Vec<EquationGap>,
    /// The covariance estimate on all levels.
    pub(super) pooled: Identification,
    pub(super) drift: Vec<ParamDrift>,
    pub(super) moved: Vec<MovedParam>,
    /// The withheld free-run gap of the re-identified model, and its training fits.
    pub(super) reidentified: ModelGap,
    pub(super) reid_fits: Vec<Identification>,
}

/// Examine the model `ir` on the levels; notes on the data go to `notes`.
pub(super) fn examine(
    ir: &ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
    notes: &mut Vec<String>,
) -> Result<Baseline, DiagnoseError> {
    let n = data.records.len();
    let nominal = nominal_gap(ir, data, opts, notes)?;
    // Where: covariance residual per equation with the nominal values; drift per level.
    let m = measure_all(ir, data, opts)?;
    let equations = equation_gaps(ir, &m, n);
    let pooled = m.identify_pooled();
    data_notes(ir, data, &m, &pooled, opts, notes)?;
    let drift = drift(ir, &m, &pooled, n);
    let moved = moved(ir, &pooled);
    let (_, reid_fits) = cross_validate(&m, ir, n);
    let reidentified = cv_gap(ir, &reid_fits, data, opts, "re-identified");
    Ok(Baseline {
        nominal,
        equations,
        pooled,
        drift,
        moved,
        reidentified,
        reid_fits,
    })
}

/// The nominal model's free-run gap on every level; an error when no level has one.
fn nominal_gap(
    ir: &ModelIr,
    data: &Data,
    opts: &DiagnoseOptions,
    notes: &mut Vec<String>,
) -> Result<ModelGap, DiagnoseError> {
    let levels: Vec<LevelGap> = (0..data.records.len())
        .into_par_iter()
        .map(|w| level_gap(ir, data, w, opts, false).0)
        .collect();
    if levels.iter().all(|l| l.gap.is_none()) {
        return Err(DiagnoseError::NoVariance);
    }
    for l in levels.iter().filter(|l| l.gap.is_none()) {
        notes.push(format!(
            "{}: no response signal varies, so its gap is unavailable and left out of the means",
            l.origin
        ));
    }
    Ok(model_gap("nominal", levels))
}

/// The covariance residual of each equation on each level with the nominal values.
fn equation_gaps(ir: &ModelIr, m: &Measurement, n: usize) -> Vec<EquationGap> {
    let p_nom: Vec<f64> = ir
        .unknowns()
        .iter()
        .map(|p| ir.params[p.index()].nominal().unwrap_or(0.0))
        .collect();
    ir.bodies
        .iter()
        .map(|b| EquationGap {
            equation: b.name.clone(),
            per_level: (0..n)
                .map(|w| cov_residual(m, &p_nom, w, Some(&b.name)))
                .collect(),
        })
        .collect()
}

/// What the identification's guard says of the data (a sensor offset, a wrong fixed
/// mass, a record given twice) holds for every fit of the diagnosis. A missing force (a
/// constant one included) is what the diagnosis itself looks for, so that warning is left
/// to the search. Levels too alike to show a drift (the warning of `dynid detect`, with
/// its settings): an effect the search does not find may be one the levels cannot
/// resolve. A model that detection cannot fit per level gets no such warning.
fn data_notes(
    ir: &ModelIr,
    data: &Data,
    m: &Measurement,
    pooled: &Identification,
    opts: &DiagnoseOptions,
    notes: &mut Vec<String>,
) -> Result<(), DiagnoseError> {
    let srcs = sources(ir, data)?;
    let refs: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    for w in crate::ident::guard::check(m, pooled, &refs, &opts.ident)
        .into_iter()
        .filter(|w| {
            matches!(
                w.cause,
                LikelyCause::SensorOffset | LikelyCause::WrongMass | LikelyCause::SameRecordTwice
            )
        })
    {
        notes.push(format!("identification warning: {w}"));
    }
    let detect_opts = crate::ident::IdentifyOptions {
        n_blocks: crate::ident::IdentifyOptions::default().n_blocks,
        ..opts.ident.clone()
    };
    if let Ok(alike) = crate::detect::levels_too_alike_in(ir, &refs, &detect_opts) {
        for w in alike {
            notes.push(format!("detection warning: {}", w.message));
        }
    }
    Ok(())
}

/// Each unknown's estimate per level and how far it drifts. Masses are held at one value,
/// as detection does: a mass fitted freely per level trades off against the stiffness and
/// hides its drift (Silverbox: m and a each scatter by 10 % while their ratio rises 8 %).
fn drift(ir: &ModelIr, m: &Measurement, pooled: &Identification, n: usize) -> Vec<ParamDrift> {
    let held: Vec<(String, f64)> = crate::detect::held_inertia(ir, m)
        .into_iter()
        .map(|h| (h.param, h.value))
        .collect();
    let per_level: Vec<Identification> =
        (0..n).map(|i| m.identify_level_holding(i, &held)).collect();
    ir.unknowns()
        .iter()
        .filter(|p| !held.iter().any(|(h, _)| *h == ir.params[p.index()].name))
        .map(|p| param_drift(ir, *p, &per_level, pooled))
        .collect()
}

/// The drift of the unknown `p` over the levels' estimates `per_level`: the spread of the
/// estimates relative to their mean, significant when above 4 combined standard errors.
fn param_drift(
    ir: &ModelIr,
    p: ParamId,
    per_level: &[Identification],
    pooled: &Identification,
) -> ParamDrift {
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
}

/// The unknowns whose estimate on all levels differs from their nominal value.
fn moved(ir: &ModelIr, pooled: &Identification) -> Vec<MovedParam> {
    ir.unknowns()
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
        .collect()
}
