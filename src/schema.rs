//! The JSON of the results: one schema for the command line (`--json`) and the Python
//! package (`to_dict()`), built here for both.
//!
//! - [`identification`]: `dynid identify --json` (with `refined` from [`RefineReport`]);
//! - [`detection`]: `dynid detect --json`;
//! - [`DiagnosisJson`]: `dynid diagnose --json`;
//! - [`level_frfs`] and [`diagnosis_frfs`]: the frequency responses per level that the
//!   detection and diagnosis JSON (`frf`) carry.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::{LevelSource, Split};
use dynid_runtime::detect::{Detection, LevelFits, LevelsTooAlike};
use dynid_runtime::diagnose::Diagnosis;
use dynid_runtime::frf::{self, LevelFrf};
use dynid_runtime::ident::Identification;
use dynid_runtime::record::Record;
use serde::Serialize;

/// `{"parameters": {name: {value, stderr, significant}}, "condition", "rows", "residual",
/// "levels", "unidentifiable", "warnings", "fit_warnings", "filter", "estimated", "shapes"}`.
pub fn identification(id: &Identification) -> serde_json::Value {
    let params: serde_json::Map<String, serde_json::Value> = id
        .params
        .iter()
        .map(|p| {
            (
                p.name.clone(),
                serde_json::json!({
                    "value": p.value,
                    "stderr": p.stderr,
                    "significant": p.significant,
                }),
            )
        })
        .collect();
    let residual: serde_json::Map<String, serde_json::Value> = id
        .residual
        .iter()
        .map(|r| (r.equation.clone(), serde_json::json!(r.per_level)))
        .collect();
    serde_json::json!({
        "parameters": params,
        "condition": id.condition,
        "rows": id.rows,
        "residual": residual,
        "levels": id.levels,
        "unidentifiable": id.unidentifiable,
        "warnings": id.warnings,
        "fit_warnings": id.fit_warnings,
        "filter": id.filter,
        "estimated": id.estimated,
        "shapes": id.shapes,
    })
}

/// The JSON of a detection: the detection, the element intensities, where each σ_v came
/// from, the jackknife's blocks, the segments of a split record, the warnings and the
/// frequency response per level.
pub fn detection(
    det: &Detection,
    fits: &LevelFits,
    warnings: &[LevelsTooAlike],
    segments: Option<&Split>,
    cycles_note: Option<&str>,
    frf: &[LevelFrf],
) -> serde_json::Value {
    serde_json::json!({
        "detection": det,
        "intensities": fits.input.elements,
        "sigma_v_source": fits.sigma_v_source,
        "jackknife_blocks": fits.n_blocks,
        "segments": segments,
        "warnings": warnings,
        "cycles_note": cycles_note,
        "frf": frf,
    })
}

/// The JSON of a diagnosis: its fields, with the extras next to them.
#[derive(Serialize)]
pub struct DiagnosisJson<'a> {
    #[serde(flatten)]
    pub diagnosis: &'a Diagnosis,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<&'a Split>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined: Option<&'a RefineReport>,
    /// How every free run of the diagnosis starts.
    pub free_run_start: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closed_loop_hint: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frf: Option<&'a [LevelFrf]>,
}

/// The refinement and the free-run errors of both estimates (JSON `refined`).
pub use dynid_runtime::refine::RefineReport;

/// The measured FRF of every level with the FRF of the linear model fitted at it
/// (`fits[l]`; a parameter held over the levels, e.g. a mass, from `det.held`).
pub fn level_frfs(
    ir: &ModelIr,
    levels: &[&dyn LevelSource],
    det: &Detection,
    fits: &[Identification],
    periods: Option<usize>,
) -> miette::Result<Vec<LevelFrf>> {
    let values: Vec<Option<Vec<f64>>> = fits
        .iter()
        .map(|id| {
            frf::parameter_values(ir, |name| {
                id.param(name)
                    .map(|p| p.value)
                    .or_else(|| det.held.iter().find(|h| h.param == name).map(|h| h.value))
            })
        })
        .collect();
    let labels: Vec<String> = (0..levels.len())
        .map(|l| {
            det.level_labels
                .get(l)
                .cloned()
                .unwrap_or_else(|| format!("level {}", l + 1))
        })
        .collect();
    Ok(frf::level_frfs(ir, levels, &labels, &values, periods)?)
}

/// The measured FRF of every record of a diagnosis with the FRF of the diagnosed model at
/// the parameter values identified at each level (`d.drift`; nominal values where a level
/// has none).
pub fn diagnosis_frfs(
    ir: &ModelIr,
    records: &[Record],
    d: &Diagnosis,
    periods: Option<usize>,
) -> miette::Result<Vec<LevelFrf>> {
    let sources = records
        .iter()
        .zip(&d.levels)
        .map(|(r, o)| dynid_runtime::data::RecordSource::new(r, ir, o.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let levels: Vec<&dyn LevelSource> = sources.iter().map(|s| s as &dyn LevelSource).collect();
    let values: Vec<Option<Vec<f64>>> = (0..records.len())
        .map(|l| {
            frf::parameter_values(ir, |name| {
                d.drift
                    .iter()
                    .find(|p| p.name == name)
                    .and_then(|p| p.per_level.get(l).copied().flatten())
            })
        })
        .collect();
    Ok(frf::level_frfs(ir, &levels, &d.levels, &values, periods)?)
}
