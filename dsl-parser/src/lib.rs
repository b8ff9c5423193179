//! The `.dyn` modelling language front end.
//!
//! Architecture invariant: stages only call forward, `parse → lower → validate → emit`;
//! the only thing that leaves this crate for the back ends is [`ir::ModelIr`], which is
//! plain data (no pest or syn types, no I/O).
//!
//! API boundary: [`ir`] (the IR) and the functions re-exported below.

pub mod codegen;
pub mod ir;
