//! The frequency response per level that `detect --plot` and `diagnose --report` draw.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::LevelSource;
use dynid_runtime::detect::Detection;
use dynid_runtime::frf::{self, LevelFrf};
use dynid_runtime::ident::Identification;
use std::path::{Path, PathBuf};

/// The FRF options.
#[derive(clap::Args, Debug, Clone)]
pub struct FrfArgs {
    /// Each record holds this many whole periods of a periodic excitation (a multisine of
    /// `dynid simulate --signal multisine --periods N`): the FRF is then averaged over the
    /// periods at the excited lines instead of Welch's H1 over Hann-windowed segments.
    #[arg(long, value_name = "N")]
    pub frf_periods: Option<usize>,
}

/// `curves.png` → `curves-frf.png`.
pub fn frf_plot_path(plot: &Path) -> PathBuf {
    let stem = plot
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match plot.extension() {
        Some(e) => format!("{stem}-frf.{}", e.to_string_lossy()),
        None => format!("{stem}-frf"),
    };
    plot.with_file_name(name)
}

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
    records: &[dynid_runtime::record::Record],
    d: &dynid_runtime::diagnose::Diagnosis,
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
