//! One record of a repeated trajectory cut at its cycles (`--segments`, `--cut`), and the
//! flag names of `identify` that do not collide with them.

mod common;
mod figures;

use common::{dynid, stderr};
use std::path::{Path, PathBuf};

fn model(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(name)
}

/// `dynid simulate MODEL --duration 25` at 1 kHz with a 1 µm encoder into `dir/data`: the
/// record of level 2 (`models/servo_axis_planned.dyn` at level 1: four cycles of 6.18 s).
fn simulate(dir: &Path, name: &str) -> PathBuf {
    let data = dir.join("data");
    let st = dynid()
        .arg("simulate")
        .arg(model(name))
        .args([
            "--duration",
            "25",
            "--sample",
            "0.001",
            "--quantise",
            "1e-6",
            "--seed",
            "3",
            "--out",
        ])
        .arg(&data)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", stderr(&st));
    data.join("level_2.csv")
}

/// One diagnosis of the closed-loop axis without its Coulomb friction on one planned record
/// cut at its four cycles (run once for the tests that read its outputs): the temporary
/// directory, the record, the command's output, its JSON and its report.
struct Planned {
    _dir: tempfile::TempDir,
    one: PathBuf,
    out: std::process::Output,
    json: serde_json::Value,
    report: String,
}

fn planned() -> &'static Planned {
    static ONCE: std::sync::OnceLock<Planned> = std::sync::OnceLock::new();
    ONCE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let one = simulate(dir.path(), "servo_axis_planned.dyn");
        let (json, report) = (dir.path().join("gap.json"), dir.path().join("gap.html"));
        let out = dynid()
            .arg("diagnose")
            .arg(model("servo_axis_linear.dyn"))
            .arg(&one)
            .args(["--segments", "4", "--quiet", "--json"])
            .arg(&json)
            .arg("--report")
            .arg(&report)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        Planned {
            json: serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap(),
            report: std::fs::read_to_string(&report).unwrap(),
            _dir: dir,
            one,
            out,
        }
    })
}

#[test]
fn a_planned_record_is_cut_at_its_cycles_for_diagnose_and_detect() {
    let p = planned();
    let (one, err, v) = (&p.one, stderr(&p.out), &p.json);
    // What was cut and why: the repeating signal, its period, the count and where.
    assert!(err.contains("segments at the cycles"), "{err}");
    assert!(err.contains("`xr` repeats every 6.18 s"), "{err}");
    assert!(
        err.contains("4 whole cycles from t = 0.063 s, where it rests"),
        "{err}"
    );
    let c = &v["segments"]["cycles"];
    assert_eq!(c["signal"], "xr");
    assert_eq!(c["cycles"], 4);
    assert_eq!(c["per_segment"], serde_json::json!([1, 1, 1, 1]));
    // The planned cycle is padded to whole samples: 6.18 s at 1 kHz.
    assert!((c["period"].as_f64().unwrap() - 6.18).abs() < 1e-3, "{c}");
    assert!(c["correlation"].as_f64().unwrap() > 0.999, "{c}");
    // docs/diagnosis.md quotes the cut, to its last digit (fixed seed).
    let doc = "docs/diagnosis.md";
    figures::check(doc, "cycles.period", c["period"].as_f64().unwrap());
    figures::check(
        doc,
        "cycles.correlation",
        c["correlation"].as_f64().unwrap(),
    );
    figures::check(doc, "cycles.count", c["cycles"].as_f64().unwrap());
    figures::check(doc, "cycles.first_cut", c["first_cut"].as_f64().unwrap());
    let segs = v["segments"]["segments"].as_array().unwrap();
    assert_eq!(segs.len(), 4);
    // In time order, every sample kept.
    let n: u64 = segs.iter().map(|s| s["len"].as_u64().unwrap()).sum();
    assert_eq!(n, 25_000);
    assert_eq!(v["levels"].as_array().unwrap().len(), 4);

    // Two segments of two cycles each; more segments than cycles are refused.
    let out = dynid()
        .arg("diagnose")
        .arg(model("servo_axis_linear.dyn"))
        .arg(one)
        .args(["--segments", "5", "--quiet"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(err.contains("dynid::split::few_cycles"), "{err}");
    assert!(err.contains("--segments 4"), "{err}");

    // Detection: the cycles are cut, and the warning says they cannot show an effect.
    let dir = tempfile::tempdir().unwrap();
    let dj = dir.path().join("detect.json");
    let out = dynid()
        .arg("detect")
        .arg(model("servo_axis_linear.dyn"))
        .arg(one)
        .arg("--json")
        .arg(&dj)
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("cycles of one repeated trajectory"), "{err}");
    assert!(err.contains("cannot show one"), "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&dj).unwrap()).unwrap();
    assert!(v["cycles_note"].as_str().unwrap().contains("one amplitude"));
    assert_eq!(v["segments"]["cycles"]["cycles"], 4);
}

#[test]
fn a_record_that_does_not_repeat_is_cut_by_amplitude_or_refused_at_cycles() {
    let dir = tempfile::tempdir().unwrap();
    // A random set point: nothing repeats.
    let one = simulate(dir.path(), "servo_axis.dyn");
    let out = dynid()
        .arg("diagnose")
        .arg(model("servo_axis_linear.dyn"))
        .arg(&one)
        .args(["--cut", "cycles", "--quiet"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(err.contains("dynid::split::no_cycles"), "{err}");
    assert!(err.contains("xr, m.x, u checked"), "{err}");
    assert!(err.contains("--cut amplitude"), "{err}");
}

#[test]
fn identify_names_its_flags_apart_from_the_segments_of_diagnose() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("one.csv");
    std::fs::write(&csv, "t,m.x,u\n0,0,0\n0.001,0,0\n").unwrap();
    let run = |args: &[&str]| {
        dynid()
            .arg("identify")
            .arg(model("servo_axis.dyn"))
            .arg(&csv)
            .args(args)
            .output()
            .unwrap()
    };
    // No clap suggestion of the unrelated multiple-shooting flag: an explanation.
    let out = run(&["--segments", "4"]);
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(err.contains("dynid::identify::segments"), "{err}");
    assert!(err.contains("diagnose"), "{err}");
    assert!(!err.contains("similar argument"), "{err}");
    // The multiple-shooting length is `--shooting`; its old name still works.
    for flag in ["--shooting", "--segment"] {
        let out = run(&["--refine", flag, "0"]);
        let err = stderr(&out);
        assert!(!out.status.success());
        assert!(
            err.contains("--shooting 0 is not a positive duration"),
            "{flag}: {err}"
        );
    }
    let help = dynid().args(["identify", "--help"]).output().unwrap();
    let text = String::from_utf8_lossy(&help.stdout);
    assert!(text.contains("--shooting <SECONDS>"), "{text}");
    assert!(!text.contains("--segment "), "{text}");
    assert!(!text.contains("--segments"), "{text}");
}

#[test]
fn gaps_are_printed_in_the_signals_units_beside_the_percentages() {
    let p = planned();
    let stdout = String::from_utf8_lossy(&p.out.stdout);
    // The closed loop holds the position: its gap is micrometres, the force carries the
    // information in newtons.
    assert!(stdout.contains("Per signal (mean over levels"), "{stdout}");
    let line = |name: &str| {
        stdout
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{name} ")) && l.contains("nominal"))
            .unwrap_or_else(|| panic!("no line for {name} in\n{stdout}"))
            .to_string()
    };
    let (x, u) = (line("m.x"), line("u"));
    assert!(x.contains("µm)") || x.contains("mm)"), "{x}");
    assert!(
        u.contains(" N)") || u.contains(" mN)") || u.contains(" kN)"),
        "{u}"
    );
    assert!(
        stdout.contains("Where: worst signals (nominal): "),
        "{stdout}"
    );
    assert!(stdout.contains("(RMS "), "{stdout}");
    for level in p.json["nominal"]["levels"].as_array().unwrap() {
        for s in level["signals"].as_array().unwrap() {
            let unit = s["unit"].as_str().unwrap();
            match s["signal"].as_str().unwrap() {
                "m.x" => assert_eq!(unit, "m"),
                "u" => assert_eq!(unit, "N"),
                other => panic!("unexpected signal {other}"),
            }
            let rms = s["rms_error"].as_f64().unwrap();
            assert!(rms.is_finite() && rms > 0.0, "{s}");
            assert!(s["std_diff"].as_f64().unwrap().is_finite(), "{s}");
        }
    }
    // The figures of docs/diagnosis.md (nominal, mean over the cycles), to their last digit
    // (fixed seed).
    let mean = |name: &str, field: &str| {
        let v: Vec<f64> = p.json["nominal"]["levels"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|l| l["signals"].as_array().unwrap().iter())
            .filter(|s| s["signal"] == name)
            .map(|s| s[field].as_f64().unwrap())
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (x_rms, u_rms) = (mean("m.x", "rms_error"), mean("u", "rms_error"));
    assert!((90e-6..360e-6).contains(&x_rms), "m.x RMS {x_rms}");
    assert!((7.0..30.0).contains(&u_rms), "u RMS {u_rms}");
    let doc = "docs/diagnosis.md";
    figures::check(doc, "cycles.gap.x", mean("m.x", "statistical"));
    figures::check(doc, "cycles.gap.x_um", 1e6 * x_rms);
    figures::check(doc, "cycles.gap.u", mean("u", "statistical"));
    figures::check(doc, "cycles.gap.u_n", u_rms);
    // The report's table has the same figures in units.
    assert!(p.report.contains("free-run RMS error"), "report table");
}

#[test]
fn the_report_shows_time_traces_and_fine_spectra() {
    let r = &planned().report;
    assert!(r.contains("<h2>Time traces</h2>"));
    for what in [
        "whole record",
        "zoomed",
        "Free-run error of u",
        "Free-run error of m.x",
    ] {
        assert!(r.contains(what), "no {what:?} in the report");
    }
    assert!(r.contains("time (s)") && r.contains("frequency (Hz)"));
    // Every figure drew (no "figure not drawn").
    assert!(!r.contains("figure not drawn"), "a figure failed");
}
