//! Numerics of dynid: it runs a [`dynid_ir::ir::ModelIr`] directly.
//!
//! Architecture invariant: no parsing, no terminal output and no output files here (this
//! crate depends on the IR crate, not on the language front end); every public function
//! takes the IR (or a [`BasisEval`] compiled from it) and plain data, and returns typed
//! results or typed errors. Long records are streamed in chunks: memory use of
//! identification and detection does not grow with the record length (diagnosis and the
//! Silverbox procedure hold whole records for their free-run simulations, and the reference
//! regressions of [`baseline`] take an in-memory [`record::Record`]).
//!
//! API boundary: [`ident`] (identification: [`identify`], [`identify_per_level`],
//! [`ident::measure`] for repeated solves), [`data`] (level sources: CSV files and in-memory
//! [`record::Record`]s), [`basis::BasisEval`] (the evaluator plug-in shared by the tape
//! interpreter and macro-generated code), [`sim`] (simulation), [`detect`] (nonlinearity
//! detection from per-level linear fits), [`diagnose`] (the sim-to-real gap and the
//! unmodelled effect behind it), [`fleet`] (machines of one model, identified one by one,
//! tested against their fleet), [`silverbox`] (the Silverbox benchmark on real data),
//! [`describe`] (mean and standard deviation of a column), [`baseline`] (two classical
//! regressions, IDIM-LS and SVF-LS: references for benches and tests, not the method).

pub mod baseline;
pub mod basis;
pub mod data;
pub mod describe;
pub mod detect;
pub mod diagnose;
mod fft;
pub mod fleet;
pub mod frf;
#[doc(hidden)]
pub mod fuzz;
pub mod ident;
pub mod limits;
pub(crate) mod prefetch;
pub mod record;
pub mod refine;
pub mod schema;
pub mod set_point;
pub mod settle;
pub mod silverbox;
pub mod sim;
pub mod tape;

/// Collect the results of parallel per-level work; on failure, the error of the first
/// failing item in the iterator's order (rayon's own `Result` collection returns whichever
/// error a thread meets first, so the message would change from run to run).
pub(crate) fn first_error_in_order<T: Send, E: Send>(
    results: impl rayon::iter::IndexedParallelIterator<Item = Result<T, E>>,
) -> Result<Vec<T>, E> {
    results.collect::<Vec<_>>().into_iter().collect()
}

pub use basis::BasisEval;
pub use ident::{identify, identify_per_level, identify_with, IdentifyError, IdentifyOptions};
