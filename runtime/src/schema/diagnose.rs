//! The document of a diagnosis.

use super::{NoRefinement, SCHEMA_VERSION};
use crate::data::Split;
use crate::diagnose::Diagnosis;
use crate::frf::LevelFrf;
use crate::sim::FREE_RUN_START;
use serde::Serialize;

/// `dynid diagnose --json` and `Diagnosis.to_dict()`: the diagnosis' fields, with the
/// extras next to them.
#[derive(Debug, Serialize)]
pub struct DiagnoseDoc<'a, R: Serialize = NoRefinement> {
    pub schema_version: u32,
    #[serde(flatten)]
    pub diagnosis: &'a Diagnosis,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<&'a Split>,
    /// The output-error refinement of the corrected model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined: Option<&'a R>,
    /// How every free run of the diagnosis starts.
    pub free_run_start: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closed_loop_hint: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frf: Option<&'a [LevelFrf]>,
}

impl<'a, R: Serialize> DiagnoseDoc<'a, R> {
    /// The document of `d` alone; the extras are set with struct update syntax.
    pub fn new(d: &'a Diagnosis) -> Self {
        DiagnoseDoc {
            schema_version: SCHEMA_VERSION,
            diagnosis: d,
            segments: None,
            refined: None,
            free_run_start: FREE_RUN_START,
            closed_loop_hint: None,
            frf: None,
        }
    }
}
