//! `ModelIr`, the one contract between the `.dyn` language and every back end.
//!
//! This crate is plain data and plain functions over it: the IR ([`ir`]), its readable
//! views and the inverse of compilation ([`print`]), the edits a back end may make to a
//! model ([`edit`]: add a force element, set a nominal value), the number formats
//! ([`num`]) and the quoting of user text in messages ([`text`]: invisible and control
//! characters escaped and named). It depends on serde and serde_json alone — no grammar, no code generator, no I/O — so the
//! numerics (`dynid-runtime`) link it without the language front end (`dsl-parser`), which
//! re-exports it as `dsl_parser::{ir, print, edit, num, text}`.

pub mod edit;
pub mod ir;
pub mod num;
pub mod print;
pub mod text;
