//! `dynid compile` end to end: exit codes, diagnostics on stderr, JSON outputs.

use std::process::Command;

fn dynid(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dynid"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the dynid binary runs")
}

#[test]
fn bad_model_fails_with_all_diagnostics() {
    let out = dynid(&["compile", "dsl-parser/tests/bad_models/many_errors.dyn"]);
    assert!(!out.status.success());
    assert!(out.stdout.is_empty(), "no partial output on error");
    let err = String::from_utf8_lossy(&out.stderr);
    for code in [
        "dyn::missing_mass",
        "dyn::undefined_name",
        "dyn::nonlinear_parameter",
        "dyn::unused_parameter",
    ] {
        assert!(err.contains(code), "{code} missing from\n{err}");
    }
    assert!(
        err.contains("many_errors.dyn:5:10"),
        "line:column of `m3`:\n{err}"
    );
}

#[test]
fn missing_file_fails() {
    let out = dynid(&["compile", "no/such/model.dyn"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("dyn::io"));
}

#[test]
fn good_model_prints_equations_and_tables() {
    let out = dynid(&["compile", "models/two_mass.dyn"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("m1: 1 m1.x'' + k1 m1.x + d1 m1.x'"), "{text}");
    assert!(text.contains("least-squares columns:"));
}

#[test]
fn json_report_and_ir() {
    let out = dynid(&["compile", "models/silverbox_cubic.dyn", "--format", "json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["params"].as_array().unwrap().len(), 4);
    let kinds: Vec<&str> = v["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["kind"].as_str().unwrap())
        .collect();
    assert!(kinds.contains(&"derivative (moved onto the filter)"));

    let out = dynid(&["compile", "models/two_mass.dyn", "--emit", "json"]);
    assert!(out.status.success());
    let ir: dynid::dsl_parser::ir::ModelIr = serde_json::from_slice(&out.stdout).unwrap();
    let direct =
        dynid::dsl_parser::compile_file(std::path::Path::new("models/two_mass.dyn")).unwrap();
    assert_eq!(ir.equations, direct.equations);
}

#[test]
fn emit_rust_is_not_available_yet() {
    let out = dynid(&["compile", "models/two_mass.dyn", "--emit", "rust"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not available yet"));
}
