//! dynid: detect, identify and diagnose nonlinear force elements of mechanical models
//! from random-excitation data by the covariance method.

pub use codegen_macros::{include_model, model};
pub use dsl_parser;
pub use dynid_runtime as runtime;

pub mod output;
pub mod plot;
pub mod schema;
