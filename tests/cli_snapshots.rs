//! The CLI's human output, snapshot-tested with insta so that a change of wording or layout
//! is reviewed as a diff of `tests/snapshots/`. The data are simulated with a fixed seed into
//! a temporary folder and named by relative paths, and the commands run with one thread,
//! so the output does not depend on the machine. Accept a change
//! with `INSTA_UPDATE=always cargo test --test cli_snapshots` (or `cargo insta review`).

use std::path::Path;
use std::process::{Command, Output};

/// `dynid ARGS` run in `dir`, with colours and terminal links off and one thread, so that
/// the output is the same in every terminal, on every machine and in CI.
fn dynid_in<S: AsRef<std::ffi::OsStr>>(dir: &Path, args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dynid"))
        .args(args)
        .current_dir(dir)
        .env("NO_COLOR", "1")
        .env("RAYON_NUM_THREADS", "1")
        .env_remove("CLICOLOR_FORCE")
        .env_remove("FORCE_COLOR")
        .env_remove("FORCE_HYPERLINK")
        .env_remove("NO_GRAPHICS")
        .output()
        .expect("the dynid binary runs")
}

/// `dynid ARGS` from the repository root.
fn dynid<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    dynid_in(Path::new(env!("CARGO_MANIFEST_DIR")), args)
}

fn stdout(o: &Output) -> String {
    assert!(
        o.status.success(),
        "dynid failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout.clone()).expect("UTF-8 output")
}

/// `models/NAME` as an absolute path (the data commands run in a temporary folder).
fn model(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(name)
        .display()
        .to_string()
}

/// Three levels of `model` (100 s each, seed 1) in `dir/data`; their paths relative to
/// `dir`, so that the output (which names the files) does not depend on where `dir` is.
fn simulate(dir: &Path, model: &str) -> Vec<String> {
    let o = dynid_in(
        dir,
        &[
            "simulate",
            model,
            "--duration",
            "100",
            "--seed",
            "1",
            "--out",
            "data",
        ],
    );
    stdout(&o);
    (1..=3).map(|i| format!("data/level_{i}.csv")).collect()
}

/// `text` with the repository's path written as `[REPO]` (in case a model path shows).
fn redact(text: &str) -> String {
    text.replace(env!("CARGO_MANIFEST_DIR"), "[REPO]")
}

#[test]
fn compile_prints_equations_and_columns() {
    let o = dynid(&["compile", "models/sdof_cubic_coulomb.dyn"]);
    insta::assert_snapshot!(stdout(&o));
}

#[test]
fn identify_prints_equations_and_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let model = model("sdof_cubic_coulomb.dyn");
    let mut args = vec!["identify".to_string(), model.clone()];
    args.extend(simulate(dir.path(), &model));
    let o = dynid_in(dir.path(), &args);
    insta::assert_snapshot!(redact(&stdout(&o)));
}

#[test]
fn detect_prints_the_element_table() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec!["detect".to_string(), model("sdof_linear.dyn")];
    args.extend(simulate(dir.path(), &model("sdof_coulomb.dyn")));
    let o = dynid_in(dir.path(), &args);
    insta::assert_snapshot!(redact(&stdout(&o)));
}

#[test]
fn malformed_model_error_points_at_the_source() {
    let o = dynid(&["compile", "dsl-parser/tests/bad_models/undefined_name.dyn"]);
    assert!(!o.status.success());
    assert!(o.stdout.is_empty(), "no partial output on error");
    insta::assert_snapshot!(String::from_utf8(o.stderr).expect("UTF-8 output"));
}
