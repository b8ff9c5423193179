//! The results' JSON and what the front ends build around it, shared by the command line
//! (`--json`) and the Python package (`to_dict()`).
//!
//! The documents themselves are the runtime's ([`dynid_runtime::schema`], one schema for
//! both front ends; docs/json.md): [`IdentifyDoc`], [`DetectDoc`], [`DiagnosisJson`].
//! The refinement report that `refined` carries ([`RefineReport`]) is the runtime's too.
//! Built here: [`level_frfs`] and [`diagnosis_frfs`], the frequency responses per level that the
//! detection and diagnosis JSON (`frf`) carry.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::LevelSource;
use dynid_runtime::detect::Detection;
use dynid_runtime::diagnose::Diagnosis;
use dynid_runtime::frf::{self, LevelFrf};
use dynid_runtime::ident::Identification;
use dynid_runtime::record::Record;
pub use dynid_runtime::schema::{
    detection_warnings, DetectDoc, DiagnoseDoc, IdentifyDoc, SCHEMA_VERSION,
};

/// The JSON of a diagnosis, with the refinement of its corrected model.
pub type DiagnosisJson<'a> = DiagnoseDoc<'a, RefineReport>;

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
