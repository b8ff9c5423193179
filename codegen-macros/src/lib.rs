//! `include_model!` and `model!`: a thin shim over `dsl_parser`'s code generator.
//!
//! Architecture invariant: no logic lives here. Reading the file, parsing, rendering
//! diagnostics and generating code are `dsl_parser::codegen` functions (unit-tested there);
//! this crate only converts between `proc_macro` and `proc_macro2` and calls them.
//!
//! API boundary: the two macros, re-exported by the `dynid` facade. The generated code
//! refers to `::dynid::dsl_parser` and `::dynid::runtime`, so callers depend on `dynid`.

use dsl_parser::codegen::{macro_support, CodegenOptions};
use dsl_parser::ir::ModelIr;
use proc_macro::TokenStream;
use std::path::PathBuf;

/// Compile a `.dyn` file into Rust items: `include_model!("models/two_mass.dyn")`.
///
/// The path is relative to the directory of the calling crate's `Cargo.toml`. The crate is
/// rebuilt when the file changes. Errors in the model are reported at the path literal,
/// with the `.dyn` file's line and column.
#[proc_macro]
pub fn include_model(input: TokenStream) -> TokenStream {
    let path = syn::parse_macro_input!(input as syn::LitStr);
    let dir = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .unwrap_or_default();
    macro_support::expand_include_model(&path, &dir, parse, &CodegenOptions::default()).into()
}

/// Compile a model written inline: `model! { model two_mass { ... } }`.
///
/// Errors are reported on the offending token.
#[proc_macro]
pub fn model(input: TokenStream) -> TokenStream {
    macro_support::expand_model(input.into(), parse, &CodegenOptions::default()).into()
}

/// The `.dyn` front end; every diagnostic of the file is passed on.
fn parse(name: &str, source: &str) -> Result<ModelIr, Vec<impl miette::Diagnostic>> {
    dsl_parser::compile_str(name, source).map_err(|e| e.errors)
}
