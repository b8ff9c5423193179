//! The frequency response per level that `detect --plot` and `diagnose --report` draw.

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

pub use dynid::schema::{diagnosis_frfs, level_frfs};
