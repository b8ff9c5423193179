//! Detection and diagnosis from ONE record whose amplitude varies: the model is driven by
//! a measured input whose envelope rises over the record, the record is written as one
//! CSV, and `dynid detect` / `dynid diagnose` split it into levels by amplitude.
//!
//! Run with `-- --nocapture` to see the figures the bounds are set from;
//! `DYNID_SEED_OFFSET` shifts the seeds.

mod common;
mod figures;

use common::{dynid, model_path, stderr};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{simulate_driven, write_csv};
use std::path::{Path, PathBuf};

/// SplitMix64 with Box–Muller: standard normal draws from a fixed seed.
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn draw(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

const TS: f64 = 0.01;
/// Settling before the record starts (dropped), seconds.
const BURN_IN: f64 = 50.0;

/// The input `u`: the models' form filter (white noise through a low-pass with corner
/// 10 rad/s, exactly discretised) whose intensity follows `level(t)` over `duration`
/// seconds, preceded by [`BURN_IN`] seconds at `level(0)`.
fn input(duration: f64, seed: u64, level: impl Fn(f64) -> f64) -> Record {
    let corner: f64 = 10.0;
    let phi = (-corner * TS).exp();
    let q = ((1.0 - phi * phi) / (2.0 * corner)).sqrt();
    let n = ((duration + BURN_IN) / TS).round() as usize;
    let mut rng = Normal(common::seed(seed));
    let mut z = level(0.0) / (2.0 * corner).sqrt() * rng.draw();
    let u = (0..n)
        .map(|k| {
            let t = (k as f64 * TS - BURN_IN).max(0.0);
            z = phi * z + level(t) * q * rng.draw();
            z
        })
        .collect();
    Record {
        names: vec!["u".into()],
        columns: vec![u],
        ts: TS,
        t0: -BURN_IN,
    }
}

/// Drive `truth` with [`input`], drop the burn-in, add white noise of `noise` times each
/// column's std to every column (the input included) and write `dir/one.csv`.
fn one_record(
    dir: &Path,
    truth: &str,
    duration: f64,
    seed: u64,
    noise: f64,
    level: impl Fn(f64) -> f64,
) -> PathBuf {
    let ir = dynid::dsl_parser::compile_file(&model_path(truth)).expect("model compiles");
    let u = input(duration, seed, level);
    let mut rec = simulate_driven(&ir, &u, 4).expect("driven run");
    let skip = (BURN_IN / TS).round() as usize;
    let mut rng = Normal(common::seed(seed) ^ 0xABCD);
    for c in &mut rec.columns {
        c.drain(..skip);
        let m = c.iter().sum::<f64>() / c.len() as f64;
        let sd = (c.iter().map(|v| (v - m).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
        for v in c.iter_mut() {
            *v += noise * sd * rng.draw();
        }
    }
    rec.t0 = 0.0;
    let path = dir.join("one.csv");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    write_csv(&mut f, &rec).unwrap();
    path
}

/// The levels of the models' `excite` line, 6 → 40, swept geometrically over `duration`.
fn sweep(duration: f64) -> impl Fn(f64) -> f64 {
    move |t| 6.0 * (40.0f64 / 6.0).powf(t / duration)
}

fn run(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let out = dynid().args(args).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    out
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The σ of the segments in a JSON output, checked to be 3 and sorted.
fn segment_sigmas(v: &serde_json::Value) -> Vec<f64> {
    let s: Vec<f64> = v["segments"]["segments"]
        .as_array()
        .expect("segments in the JSON")
        .iter()
        .map(|g| g["sigma"].as_f64().unwrap())
        .collect();
    assert_eq!(s.len(), 3, "{v}");
    assert!(s.windows(2).all(|p| p[0] < p[1]), "{s:?}");
    s
}

#[test]
fn detect_names_the_cubic_spring_from_one_noisy_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let one = one_record(
        dir.path(),
        "sdof_duffing.dyn",
        600.0,
        21,
        0.02,
        sweep(600.0),
    );
    let out_json = dir.path().join("detect.json");
    let out = run(&[
        "detect".as_ref(),
        model_path("sdof_linear.dyn").as_os_str(),
        one.as_os_str(),
        "--json".as_ref(),
        out_json.as_os_str(),
    ]);
    let (so, se) = (String::from_utf8_lossy(&out.stdout), stderr(&out));
    eprintln!("{se}\n{so}");
    assert!(se.contains("segments by the amplitude of `m.x`"), "{se}");
    assert!(
        so.contains("Element k/d (ground, m): nonlinear: cubic stiffness"),
        "{so}"
    );
    let v = json(&out_json);
    let s = segment_sigmas(&v);
    eprintln!("σ ratio {:.2}", s[2] / s[0]);
    assert!(v["warnings"].as_array().unwrap().is_empty(), "{v}");
    let el = &v["detection"]["elements"][0];
    let k3 = el["ranking"][0]["estimates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == "k3")
        .expect("k3 estimate");
    let (k3, k3_se) = (
        k3["value"].as_f64().unwrap(),
        k3["stderr"].as_f64().unwrap(),
    );
    eprintln!("k3 = {k3} ± {k3_se} (truth 2)");
    assert!((k3 - 2.0).abs() < 0.3, "k3 = {k3} ± {k3_se}");
    // The verdict's k3 (the estimator's template, docs/detection.md quotes it).
    let (k3, k3_se) = common::verdict_coefficient(el, "cubic stiffness");
    eprintln!("verdict: k3 = {k3} ± {k3_se}");
    assert!((k3 - 2.0).abs() < 3.0 * k3_se, "k3 = {k3} ± {k3_se}");
    if common::seeds_as_documented() {
        figures::check("docs/detection.md", "detect.sweep.k3", k3);
        figures::check("docs/detection.md", "detect.sweep.k3_stderr", k3_se);
        figures::check("docs/detection.md", "detect.sweep.sigma_ratio", s[2] / s[0]);
    }
}

#[test]
fn a_linear_record_is_not_flagged_swept_or_steady() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_path("sdof_linear.dyn");
    let one = one_record(dir.path(), "sdof_linear.dyn", 600.0, 22, 0.02, sweep(600.0));
    let out_json = dir.path().join("detect.json");
    let out = run(&[
        "detect".as_ref(),
        model.as_os_str(),
        one.as_os_str(),
        "--json".as_ref(),
        out_json.as_os_str(),
    ]);
    let so = String::from_utf8_lossy(&out.stdout);
    assert!(so.contains("Element k/d (ground, m): linear"), "{so}");
    let v = json(&out_json);
    segment_sigmas(&v);
    assert!(v["warnings"].as_array().unwrap().is_empty(), "{v}");

    // The same system at one steady level: the segments' σ differ only by the random
    // wander of the envelope; still linear. (Whether the drift test can resolve an effect
    // of a quarter of `k` there depends on that wander; the warning itself is tested in
    // `dynid_runtime::detect::resolution`.)
    let one = one_record(dir.path(), "sdof_linear.dyn", 600.0, 23, 0.02, |_| 15.0);
    let out = run(&[
        "detect".as_ref(),
        model.as_os_str(),
        one.as_os_str(),
        "--json".as_ref(),
        out_json.as_os_str(),
    ]);
    let (so, se) = (String::from_utf8_lossy(&out.stdout), stderr(&out));
    eprintln!("{se}");
    assert!(so.contains("Element k/d (ground, m): linear"), "{so}");
}

#[test]
fn diagnose_finds_the_withheld_cubic_spring_in_one_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let one = one_record(dir.path(), "sdof_duffing.dyn", 600.0, 24, 0.0, sweep(600.0));
    let out_json = dir.path().join("gap.json");
    let out = run(&[
        "diagnose".as_ref(),
        model_path("sdof_linear.dyn").as_os_str(),
        one.as_os_str(),
        "--quiet".as_ref(),
        "--json".as_ref(),
        out_json.as_os_str(),
    ]);
    let so = String::from_utf8_lossy(&out.stdout);
    eprintln!("{so}");
    let v = json(&out_json);
    segment_sigmas(&v);
    let found = v["found"].as_array().expect("found effects");
    assert_eq!(found.len(), 1, "{so}");
    let loc = &found[0]["location"];
    assert_eq!(
        (loc["a"].as_str(), loc["b"].as_str()),
        (Some("ground"), Some("m")),
        "{so}"
    );
    assert!(so.contains("cubic"), "{so}");
    let (before, after) = (
        v["gap_before"].as_f64().unwrap(),
        v["gap_after"].as_f64().unwrap(),
    );
    eprintln!("headline gap {before:.2} % → {after:.2} %");
    // Measured 46.8 % → 0.06 % (seed 24); the bound leaves room for other seeds.
    assert!(before > 20.0 && after < 1.0, "{before} → {after}");
    // docs/diagnosis.md quotes the seed's figures, to their last digit.
    if common::seeds_as_documented() {
        let doc = "docs/diagnosis.md";
        let k3 = found[0]["value"].as_f64().expect("the found coefficient");
        figures::check(doc, "diagnose.sweep.k3", k3);
        figures::check(doc, "diagnose.sweep.gap_before", before);
        figures::check(doc, "diagnose.sweep.gap_after", after);
    }
}

#[test]
fn several_files_with_segments_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let one = one_record(dir.path(), "sdof_linear.dyn", 100.0, 25, 0.0, |_| 15.0);
    let out = dynid()
        .arg("detect")
        .arg(model_path("sdof_linear.dyn"))
        .args([&one, &one])
        .args(["--segments", "4"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("dynid::split::several_files") && e.contains("--segments splits a single"),
        "{e}"
    );
    // 100 s at ω₀ ≈ 2 rad/s holds two segments of ≥ 40 s but not four.
    let out = dynid()
        .arg("diagnose")
        .arg(model_path("sdof_linear.dyn"))
        .arg(&one)
        .args(["--segments", "4", "--quiet"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("dynid::split::too_short") && e.contains("--segments 2"),
        "{e}"
    );
}
