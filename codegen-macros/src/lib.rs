//! `include_model!` and `model!`: a thin shim over `dsl_parser`'s code generator.
