//! Numerics of dynid: it runs a [`dsl_parser::ir::ModelIr`] directly.
//!
//! Architecture invariant: no parsing and no terminal output here; every public function
//! takes the IR (or a [`BasisEval`] compiled from it) and plain data, and returns typed
//! results or typed errors.

pub mod detect;
pub mod record;
pub mod sim;
pub mod tape;
