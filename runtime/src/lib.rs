//! Numerics of dynid: it runs a [`dynid_ir::ir::ModelIr`] directly.
//!
//! Architecture invariant: no parsing and no terminal output here; every public function
//! takes the IR (or a [`BasisEval`] compiled from it) and plain data, and returns typed
//! results or typed errors. Long records are streamed in chunks: memory use of
//! identification does not grow with the record length.
//!
//! API boundary: [`ident`] (identification: [`identify`], [`identify_per_level`],
//! [`ident::measure`] for repeated solves), [`data`] (level sources: CSV files and in-memory
//! [`record::Record`]s), [`basis::BasisEval`] (the evaluator plug-in shared by the tape
//! interpreter and macro-generated code), [`sim`] (simulation), [`detect`] (nonlinearity
//! detection from per-level linear fits), [`silverbox`] (the Silverbox benchmark on real data).

pub mod basis;
pub mod data;
pub mod describe;
pub mod detect;
pub mod diagnose;
mod fft;
pub mod ident;
pub mod record;
pub mod silverbox;
pub mod sim;
pub mod tape;

pub use basis::BasisEval;
pub use ident::{identify, identify_per_level, identify_with, IdentifyError, IdentifyOptions};
