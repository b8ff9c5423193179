//! `dynid diagnose` end to end: outputs written all or nothing, bad input refused before
//! the work starts.

mod common;
mod figures;

use common::{dynid, model_path as model, stderr, two_mass_levels as simulate};

use std::path::{Path, PathBuf};
use std::process::Output;

/// Files directly in `dir` (not the data folder).
fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `dynid diagnose two_mass_linear.dyn LEVELS... FLAGS...` (each flag followed by its path).
fn diagnose(levels: &[PathBuf], flags: &[(&str, &Path)]) -> Output {
    let mut cmd = dynid();
    cmd.arg("diagnose")
        .arg(model("two_mass_linear.dyn"))
        .args(levels)
        .arg("--quiet");
    for (flag, path) in flags {
        cmd.arg(flag).arg(path);
    }
    cmd.output().unwrap()
}

#[test]
fn diagnosis_writes_report_json_and_a_model_that_compiles() {
    let dir = tempfile::tempdir().unwrap();
    let levels = simulate(dir.path());
    let (report, json, fixed) = (
        dir.path().join("gap.html"),
        dir.path().join("gap.json"),
        dir.path().join("fixed.dyn"),
    );
    let out = diagnose(
        &levels,
        &[
            ("--report", &report),
            ("--json", &json),
            ("--write-model", &fixed),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("Most likely missing effect:"), "{stdout}");
    assert_eq!(files_in(dir.path()), ["fixed.dyn", "gap.html", "gap.json"]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v.is_object());
    // `parameters` is the corrected model (every found effect added), not the model as
    // given re-fitted (`moved`): each value is the one the written model holds (rounded
    // there to five significant digits), and each found effect's coefficient is there.
    let ir = dynid()
        .arg("compile")
        .arg(&fixed)
        .args(["--emit", "json"])
        .output()
        .unwrap();
    assert!(ir.status.success(), "{}", stderr(&ir));
    let ir: serde_json::Value = serde_json::from_slice(&ir.stdout).unwrap();
    let params = v["parameters"].as_array().expect("parameters");
    assert!(!params.is_empty(), "{v}");
    for p in params {
        let (name, value) = (p["name"].as_str().unwrap(), p["value"].as_f64().unwrap());
        let written = ir["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|q| q["name"] == name)
            .and_then(|q| q["kind"]["Unknown"]["nominal"].as_f64())
            .unwrap_or_else(|| panic!("{name} not an unknown of the corrected model"));
        assert!(
            (written - value).abs() <= 1e-4 * value.abs(),
            "{name}: {value} in parameters, {written} in the model"
        );
        assert!(p["stderr"].as_f64().is_some_and(|e| e > 0.0), "{p}");
    }
    for f in v["found"].as_array().unwrap() {
        let p = params
            .iter()
            .find(|p| p["name"] == f["param"])
            .unwrap_or_else(|| panic!("found {f} not in parameters"));
        assert_eq!(p["kind"], "found effect");
        assert_eq!(p["value"], f["value"]);
    }
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(html.contains("<html"));
    // Figures say what they show and in which unit; the summary wraps instead of being cut.
    for label in [
        "Parameters of the corrected model",
        "statistical gap (%)",
        "value / value on level 1 (± 1 SE)",
        "frequency (Hz)",
        "log10 PSD (m²/Hz)",
        "log10 PSD ((m/s)²/Hz)",
        "time (s)",
        "white-space:pre-wrap",
    ] {
        assert!(html.contains(label), "the report lacks `{label}`");
    }
    let compiled = dynid().arg("compile").arg(&fixed).output().unwrap();
    assert!(compiled.status.success(), "{}", stderr(&compiled));
}

#[test]
fn an_unwritable_output_is_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let levels = simulate(dir.path());
    let json = dir.path().join("gap.json");
    let missing = dir.path().join("no_such_dir").join("gap.html");
    let out = diagnose(&levels, &[("--json", &json), ("--report", &missing)]);
    assert!(!out.status.success());
    let err = stderr(&out);
    // The code, and the path the user gave (the message's job is to name it).
    assert!(
        err.contains("dynid::output::no_directory") && err.contains("gap.html"),
        "{err}"
    );
    // Nothing was computed, nothing written.
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(files_in(dir.path()).is_empty());
}

#[test]
fn a_bad_level_file_names_file_and_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut levels = simulate(dir.path());
    let text = std::fs::read_to_string(&levels[2]).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines[10] = "0.09,1.0,2.0";
    let bad = dir.path().join("data").join("ragged.csv");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    levels[2] = bad;
    let json = dir.path().join("gap.json");
    let out = diagnose(&levels, &[("--json", &json)]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("ragged.csv") && err.contains("line 11"),
        "{err}"
    );
    assert!(files_in(dir.path()).is_empty());
}

#[test]
fn demo_names_the_friction_and_reports_the_three_gaps() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("demo.html");
    let out = dynid()
        .args(["demo", "--quiet", "--report"])
        .arg(&report)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("Most likely missing effect: Coulomb friction sign(v) at (m1, m2)"),
        "{stdout}"
    );
    for line in [
        "nominal model",
        "re-identified (withheld level)",
        "corrected model (withheld level)",
        "Re-identification alone:",
        "Overall (nominal → corrected):",
    ] {
        assert!(stdout.contains(line), "`{line}` missing:\n{stdout}");
    }
    assert!(!stdout.contains("Also missing effect"), "{stdout}");
    assert!(
        !stdout.contains("NaN") && !stdout.contains("inf "),
        "{stdout}"
    );
    // The number that follows `before` (after `skip` more words) on the line that holds it.
    let after = |before: &str, skip: usize| -> f64 {
        stdout
            .split(before)
            .nth(1)
            .and_then(|s| s.split_whitespace().nth(skip))
            .and_then(|s| s.trim_start_matches('(').parse().ok())
            .unwrap_or_else(|| panic!("no number after `{before}` in:\n{stdout}"))
    };
    // r = 0.3 within three of its standard errors; the demo's seed is fixed, so r, its
    // standard error and the gaps are docs/diagnosis.md's figures to their last digit.
    let (r, se) = (
        after("identified r_fix = ", 0),
        after("identified r_fix = ", 2),
    );
    assert!((r - 0.3).abs() < 3.0 * se, "{stdout}");
    const DOC: &str = "docs/diagnosis.md";
    figures::check(DOC, "demo.r", r);
    figures::check(DOC, "demo.r_stderr", se);
    figures::check(DOC, "demo.gap_before", after("nominal model", 0));
    figures::check(DOC, "demo.pathwise_before", after("nominal model", 2));
    figures::check(
        DOC,
        "demo.gap_reidentified",
        after("re-identified (withheld level)", 0),
    );
    figures::check(
        DOC,
        "demo.gap_after",
        after("corrected model (withheld level)", 0),
    );
    figures::check(
        DOC,
        "demo.pathwise_after",
        after("corrected model (withheld level)", 2),
    );
    let removed = after("Overall (nominal → corrected): ", 5);
    figures::check(DOC, "demo.shrink", removed);
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(
        html.contains("corrected (level withheld)"),
        "report spectra"
    );
}

/// `--refine`: the corrected model's values refined on the free-run error, written to the
/// model and the JSON; in-sample the refined free run is no worse than the covariance one.
#[test]
fn refine_writes_the_refined_model_and_both_free_run_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let st = dynid()
        .arg("simulate")
        .arg(model("two_mass_friction.dyn"))
        .args([
            "--duration",
            "100",
            "--seed",
            &common::seed(5).to_string(),
            "--out",
        ])
        .arg(&data)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", stderr(&st));
    let levels: Vec<PathBuf> = (1..=3)
        .map(|i| data.join(format!("level_{i}.csv")))
        .collect();
    let (json, fixed) = (dir.path().join("d.json"), dir.path().join("fixed.dyn"));
    let mut cmd = dynid();
    cmd.arg("diagnose")
        .arg(model("two_mass_linear.dyn"))
        .args(&levels)
        .args(["--quiet", "--refine", "--json"])
        .arg(&json)
        .arg("--write-model")
        .arg(&fixed);
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("output-error refinement"), "{text}");
    let d: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let r = &d["refined"];
    let params = r["refinement"]["params"].as_array().unwrap();
    let r_fix = params
        .iter()
        .find(|p| p["name"] == "r_fix")
        .expect("r_fix refined");
    let v = r_fix["value"].as_f64().unwrap();
    eprintln!("r_fix refined {v}, start {}", r_fix["start"]);
    // Noise-free data whose input is linear between samples (the simulator's own: friendly
    // to the refinement, see docs/method.md): DYNID_SEED_OFFSET=0..3 gave r_fix within
    // 1.8e-5 of the truth refined, 1.6e-3 from the covariance method.
    assert!((v / 0.3 - 1.0).abs() < 5e-5, "r_fix {v}");
    for (cov, refd) in r["estimation"][0]
        .as_array()
        .unwrap()
        .iter()
        .zip(r["estimation"][1].as_array().unwrap())
    {
        let (c, f) = (cov["rms"].as_f64().unwrap(), refd["rms"].as_f64().unwrap());
        assert!(f <= c, "{}: refined {f} vs covariance {c}", cov["signal"]);
    }
    // The written model carries the refined values and compiles.
    let src = std::fs::read_to_string(&fixed).unwrap();
    let ir = dynid::dsl_parser::compile_str("fixed", &src).unwrap();
    let r_written = ir
        .params
        .iter()
        .find(|p| p.name == "r_fix")
        .and_then(|p| p.nominal())
        .unwrap();
    assert!((r_written / v - 1.0).abs() < 1e-4, "{r_written} vs {v}");
}
