//! The document of a detection.

use super::SCHEMA_VERSION;
use crate::data::Split;
use crate::detect::{
    levels_too_alike, DetectOptions, Detection, ElementIntensity, LevelFits, LevelsTooAlike,
    SigmaVSource,
};
use crate::frf::LevelFrf;
use serde::Serialize;

/// `dynid detect --json` and `Detection.to_dict()`: the detection, the element
/// intensities, where each σ_v came from, the time blocks of the standard errors, the
/// segments of a split record, the warnings and the frequency response per level.
#[derive(Debug, Serialize)]
pub struct DetectDoc<'a> {
    pub schema_version: u32,
    pub detection: &'a Detection,
    pub intensities: &'a [ElementIntensity],
    pub sigma_v_source: &'a [SigmaVSource],
    /// The time blocks of the batch-means standard errors (fewest over the levels).
    pub batch_blocks: usize,
    /// `batch_blocks` under its name before schema version 2 (removed in version 3).
    pub jackknife_blocks: usize,
    /// The segments, where one record was cut into the levels (else `null`).
    pub segments: Option<&'a Split>,
    pub warnings: &'a [LevelsTooAlike],
    /// Cycles of one amplitude, which cannot show a drift (else `null`).
    pub cycles_note: Option<String>,
    pub frf: &'a [LevelFrf],
}

impl<'a> DetectDoc<'a> {
    /// The document of the detection `det` from the per-level fits `fits`, with the
    /// warnings of [`detection_warnings`], the split (where one record was cut) and the
    /// frequency responses.
    pub fn new(
        det: &'a Detection,
        fits: &'a LevelFits,
        warnings: &'a [LevelsTooAlike],
        segments: Option<&'a Split>,
        frf: &'a [LevelFrf],
    ) -> Self {
        DetectDoc {
            schema_version: SCHEMA_VERSION,
            detection: det,
            intensities: &fits.input.elements,
            sigma_v_source: &fits.sigma_v_source,
            batch_blocks: fits.n_blocks,
            jackknife_blocks: fits.n_blocks,
            segments,
            warnings,
            cycles_note: segments.and_then(Split::cycles_note),
            frf,
        }
    }
}

/// The levels-too-alike warnings of a detection run with `opts`: the test's degrees of
/// freedom are those the detection used (the time blocks of `fits` minus one, unless
/// `opts` set them).
pub fn detection_warnings(
    det: &Detection,
    fits: &LevelFits,
    opts: &DetectOptions,
) -> Vec<LevelsTooAlike> {
    let mut opts = opts.clone();
    opts.se_dof.get_or_insert(fits.n_blocks as f64 - 1.0);
    levels_too_alike(det, &opts)
}
