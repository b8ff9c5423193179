//! The JSON documents of the results: one schema for the command line (`--json`) and the
//! Python package (`to_dict()`), both of which serialise these types (docs/json.md
//! describes every key).
//!
//! - [`IdentifyDoc`]: `dynid identify --json`, `Identification.to_dict()`;
//! - [`DetectDoc`]: `dynid detect --json`, `Detection.to_dict()`;
//! - [`DiagnoseDoc`]: `dynid diagnose --json`, `Diagnosis.to_dict()`;
//! - [`FleetDoc`]: `dynid fleet --json`.
//!
//! Every document carries `schema_version` ([`SCHEMA_VERSION`]): it grows when a key is
//! renamed or removed or its meaning changes; added keys leave it as it is. A renamed key
//! keeps its old name beside the new one for one release (docs/json.md lists them).
//!
//! The documents borrow the results they describe; a refinement's report (`refined`) is a
//! type parameter `R`, serialised as it is, since the report is built by the front ends.

mod detect;
mod diagnose;
mod fleet;
mod identify;

pub use detect::{detection_warnings, DetectDoc};
pub use diagnose::DiagnoseDoc;
pub use fleet::{Between, FleetDoc};
pub use identify::{Covariance, IdentifyDoc};

/// The version of the JSON documents (key `schema_version`).
pub const SCHEMA_VERSION: u32 = 2;

/// The type parameter of a document without a refinement (`refined` is then absent).
#[derive(Debug, serde::Serialize)]
pub enum NoRefinement {}

#[cfg(test)]
mod tests;
