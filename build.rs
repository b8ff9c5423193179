//! Writes `$OUT_DIR/models.rs`: one `include_model!` per `models/*.dyn`, and the list of
//! them, so that the code-generation parity test covers every example model, including
//! ones added later, without a hand-kept list.

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    println!("cargo:rerun-if-changed=models");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=dsl-parser/src/codegen/naming.rs");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".dyn"))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    let mut modules = String::new();
    let mut cases = String::new();
    for file in &files {
        let source = std::fs::read_to_string(dir.join(file)).unwrap_or_default();
        let stem = file.trim_end_matches(".dyn");
        let module = format!(
            "m_{}",
            stem.replace(|c: char| !c.is_ascii_alphanumeric(), "_")
        );
        // A model whose name cannot be found is still included, so the macro reports why.
        let Some(model) = model_name_hint(&source) else {
            let _ = writeln!(modules, "::dynid::include_model!(\"models/{file}\");");
            continue;
        };
        let ty = type_name(&model);
        let _ = writeln!(
            modules,
            "pub mod {module} {{ ::dynid::include_model!(\"models/{file}\"); }}"
        );
        let _ = writeln!(
            cases,
            "    Case {{ file: \"models/{file}\", eval: &{module}::{ty}, ir: || {module}::{ty}.ir(), \
             simulate: |cfg| {module}::{ty}.simulate(&{module}::{ty}Params::default(), cfg), \
             identify: |levels, opts| {module}::{ty}.identify_with_options(levels, opts), \
             typed: |id| {module}::{ty}Params::from_identification(id).map(|p| p.to_vec()) }},"
        );
    }
    let out = format!("{modules}\npub const CASES: &[Case] = &[\n{cases}];\n");
    let path = Path::new(&std::env::var("OUT_DIR").expect("invariant: cargo sets OUT_DIR"))
        .join("models.rs");
    std::fs::write(path, out).expect("invariant: OUT_DIR is writable");
}

// `model_name_hint` and `type_name`, exactly as the macros use them.
include!("dsl-parser/src/codegen/naming.rs");
