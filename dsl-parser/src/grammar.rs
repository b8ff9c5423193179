//! The grammar of `.dyn` files (`dyn.pest`) and the parser pest derives from it; its
//! [`Rule`]s are private to this crate.

#[derive(pest_derive::Parser)]
#[grammar = "dyn.pest"]
pub(crate) struct DynParser;
