//! Diagnosis of the sim-to-real gap: where a simulation model misses measured data, which
//! unmodelled effect explains it, and how far the gap shrinks once that effect is added.
//!
//! The gap is measured by simulation (the model driven by the measured input from the
//! measured initial state, free run, compared with the measured response) and by the
//! covariance-equation residual.
//! Candidate effects from a small library are added as new unknown force elements by editing
//! the model's IR (`dynid_ir::edit`), so that names stay those of the user's model; the
//! corrected model is written as ordinary `.dyn` text by the IR's source printer. Every
//! candidate is fitted on all levels but one and scored on the withheld level, rotating the
//! withheld level, so that an extra term is never rewarded for fitting noise. Definitions
//! and thresholds are documented in `docs/diagnosis.md`.
//!
//! # Phases
//!
//! [`diagnose`] runs them in order; each module calls only the ones below it.
//!
//! | phase | module | entry point |
//! |---|---|---|
//! | the levels: responses, names, sources | `levels` | `prepare` |
//! | the model as given: nominal gap, equations, drift, re-identified gap | `baseline` | `examine` |
//! | greedy search, one step = the four phases below | `search` | `search` |
//! | candidates: effects × sites, backlash grid, pairs | `candidates` | `candidates` |
//! | fit: moments, estimates, cross-validated covariance residual | `fit` | `fit_candidates` |
//! | score: withheld free-run gap, covariance residual | `score` | `cv_gap` |
//! | verdict: acceptance rules (one home for each), the conclusion | `verdict` | `accept`, `verdict` |
//! | the result: corrected model, spectra, force channel | `report` | `assemble` |
//!
//! Beside them: the effect library ([`effects`]), the gap metrics ([`metrics`]), the
//! backlash gap profile (`profile`), the force channel (`force`), the numbers' format
//! (`format`) and the text (`summary`).

mod baseline;
mod candidates;
pub mod effects;
mod fit;
mod force;
mod format;
mod levels;
pub mod metrics;
mod profile;
mod report;
mod score;
mod search;
mod summary;
pub mod types;
mod verdict;

pub use effects::{Effect, Location};
pub use format::{fmt_gap, fmt_num, fmt_opt_gap, fmt_si, shrink, GAP_SHOWN_MAX};
pub use levels::read_record;
pub use summary::{fmt_shrink, signal_means};
pub use types::{
    CandidateScore, CorrectedParam, DiagnoseError, DiagnoseOptions, Diagnosis, EquationGap,
    ForceGap, ForceGapValue, FoundEffect, LevelGap, ModelGap, MovedParam, ParamDrift, SignalGap,
    Spectrum, Trace, Verdict,
};

use crate::record::Record;
use dynid_ir::ir::ModelIr;
use effects::Variant;
use levels::Data;
use search::Reached;

/// Diagnose the gap between the model in `source` and measured `levels` (one record per
/// excitation level, at least 2). `progress(done, total)` reports the candidate search.
pub fn diagnose(
    model: &ModelIr,
    levels: &[Record],
    origins: &[String],
    opts: &DiagnoseOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Diagnosis, DiagnoseError> {
    let ir = model;
    // On records of accelerations, the rows `identify` chooses for them (each weighted by
    // its own estimated error, iterated): with the rows at unit norm the bodies without a
    // force shrink together, and the five-body structure's re-identified model, so shrunk,
    // diverged in its free runs (docs/diagnosis.md, "Accelerations").
    let chosen = crate::ident::accel_rows(ir, &opts.ident).map(|ident| DiagnoseOptions {
        ident,
        ..opts.clone()
    });
    let opts = chosen.as_ref().unwrap_or(opts);
    let (response, origins) = levels::prepare(ir, levels, origins)?;
    let data = Data {
        records: levels,
        origins: &origins,
        response,
        displacements: candidates::displacements(ir, levels, &origins),
    };
    let mut notes: Vec<String> = Vec::new();
    if chosen.is_some() {
        notes.push(
            "rows: every fit weights each row by its own estimated error (iterated), chosen \
             for this record of measured accelerations, as `dynid identify` does"
                .into(),
        );
    }
    // Before: the model as given.
    let base = baseline::examine(ir, &data, opts, &mut notes)?;
    // Which effect: the greedy search from the re-identified model.
    let start = Reached {
        variant: Variant {
            ir: ir.clone(),
            added: vec![],
        },
        gap: base.reidentified.clone(),
        fit: base.pooled.clone(),
        fits: base.reid_fits.clone(),
    };
    let outcome = search::search(start, &base.nominal, &data, opts, &mut notes, progress);
    let verdict = verdict::verdict(
        &base.nominal,
        &base.reidentified,
        !outcome.found.is_empty(),
        opts,
    );
    Ok(report::assemble(
        ir, &data, opts, base, outcome, verdict, notes,
    ))
}
