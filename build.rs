//! Writes `$OUT_DIR/models.rs`: one `include_model!` per `models/*.dyn`, and the list of
//! them, so that the code-generation parity test covers every example model, including
//! ones added later, without a hand-kept list.

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    println!("cargo:rerun-if-changed=models");
    println!("cargo:rerun-if-changed=build.rs");
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
        let Some(model) = model_name(&source) else {
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
    let path = Path::new(&std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("models.rs");
    std::fs::write(path, out).expect("OUT_DIR is writable");
}

/// The word after the first `model` outside comments (as `dsl_parser::codegen`'s
/// `model_name_hint`; a mismatch shows up as a compile error of the parity test).
fn model_name(source: &str) -> Option<String> {
    let mut words = source
        .lines()
        .map(|l| {
            l.split("//")
                .next()
                .unwrap_or("")
                .split('#')
                .next()
                .unwrap_or("")
        })
        .flat_map(|l| l.split(|c: char| !(c.is_alphanumeric() || c == '_')))
        .filter(|w| !w.is_empty());
    while let Some(w) = words.next() {
        if w == "model" {
            return words.next().map(str::to_string);
        }
    }
    None
}

/// `dsl_parser::codegen::type_name`: `two_mass` → `TwoMass`.
fn type_name(model: &str) -> String {
    let mut out = String::new();
    for part in model.split(|c: char| !c.is_ascii_alphanumeric()) {
        let mut chars = part.chars();
        if let Some(first) = chars.next() {
            out.push(first.to_ascii_uppercase());
            out.extend(chars);
        }
    }
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert_str(0, "Model");
    }
    out
}
