//! Identification and detection from the excitations of structural testing: multisines
//! (whole periods) and sine sweeps, against the same tolerances as random data.
//!
//! Tolerances are 3x the largest error over seeds 1–5 of *random* data (three levels of
//! 2000 s at Ts = 0.01 s, 5 % noise on every channel), measured by
//! `DYNID_SIGNAL_SPREAD=1 cargo test --test test_signals spread -- --nocapture`, which
//! prints the errors of every case over the five seeds. Measured (largest |error|, %) with
//! the same cases through the CLI (`dynid simulate … --signal multisine --band-hz 0.01,1.6
//! --levels 1.34,3.35,8.94` / `--signal sweep --band-hz 0.02,1.6 --levels 1.9,4.74,12.6`,
//! `--duration 2000 --noise 0.05 --seed 1…5`, then `dynid identify`):
//!
//! | model        | data      | d     | k     | k3   |       |       |       |       |
//! |--------------|-----------|-------|-------|------|-------|-------|-------|-------|
//! | sdof_duffing | random    | 0.30  | 0.08  | 0.16 |       |       |       |       |
//! | sdof_duffing | multisine | 0.19  | 0.06  | 0.12 |       |       |       |       |
//! | sdof_duffing | log sweep | 0.70  | 0.12  | 0.14 |       |       |       |       |
//!
//! | two_mass     | data      | d1   | d2   | k1   | k2   | k3   | m2   | r    |
//! |--------------|-----------|------|------|------|------|------|------|------|
//! | two_mass     | random    | 0.66 | 2.27 | 0.03 | 0.15 | 0.32 | 0.07 | 1.94 |
//! | two_mass     | multisine | 0.31 | 1.87 | 0.03 | 0.12 | 0.20 | 0.07 | 1.98 |
//! | two_mass     | log sweep | 0.71 | 17.5 | 2.09 | 2.56 | 3.44 | 3.24 | 26.7 |
//!
//! The noisy log sweep of `two_mass` is biased (k1, k2, m2 about −2 %, every seed): it is
//! not the sweep's non-stationarity as such — noise-free, or on `two_mass_linear` with the
//! same noise, the sweep is as good as random data — and not the noise correction alone
//! (without it the bias stays): the noisy nonlinear columns of a joint that a sweep's slow
//! start holds near zero relative velocity for
//! long stretches. The sweep cases below are therefore `two_mass_linear` with 5 % noise and
//! `two_mass` noise-free, the limitation stated in docs/method.md.

mod common;
mod figures;

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::ident::Identification;
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, Grid, Phases, SweepLaw, TestSignal};

fn model(name: &str) -> ModelIr {
    let path = common::model_path(name);
    let src = std::fs::read_to_string(&path).unwrap();
    dynid::dsl_parser::compile_str(name, &src).unwrap()
}

/// Random (the model's form filter, levels 6/15/40: input RMS 1.34/3.35/8.94), a
/// multisine of the same RMS over 0.01–1.6 Hz (4 periods of 500 s, random phases), or a
/// log sweep 0.02–1.6 Hz of the same RMS (4 sweeps of 500 s).
#[derive(Clone, Copy, Debug)]
enum Data {
    Random,
    Multisine,
    Sweep,
    LinearSweep,
}

fn records(ir: &ModelIr, data: Data, noise: f64, seed: u64) -> Vec<Record> {
    let rms = [1.34, 3.35, 8.94];
    let cfg = |levels: Option<Vec<f64>>| sim::SimConfig {
        duration: 2000.0,
        sample: 0.01,
        seed: common::seed(seed),
        noise,
        levels,
        ..Default::default()
    };
    let out = match data {
        Data::Random => sim::simulate(ir, &cfg(None)),
        Data::Multisine => sim::simulate_signal(
            ir,
            &cfg(Some(rms.to_vec())),
            &TestSignal::Multisine {
                f_min_hz: 0.01,
                f_max_hz: 1.6,
                periods: 4,
                grid: Grid::Full,
                phases: Phases::Random,
            },
        ),
        Data::Sweep | Data::LinearSweep => sim::simulate_signal(
            ir,
            &cfg(Some(rms.iter().map(|r| r * 2f64.sqrt()).collect())),
            &TestSignal::Sweep {
                f_start_hz: if matches!(data, Data::Sweep) {
                    0.02
                } else {
                    0.05
                },
                f_end_hz: 1.6,
                law: if matches!(data, Data::Sweep) {
                    SweepLaw::Log
                } else {
                    SweepLaw::Linear
                },
                sweeps: 4,
            },
        ),
    };
    out.expect("simulation").records
}

/// The doc that quotes these tests' figures (seed 1), checked only on the tests' own seeds.
fn doc_figure(name: &str, measured: f64) {
    if common::seeds_as_documented() {
        figures::check("docs/method.md", name, measured);
    }
}

/// The relative error of `name` in `errs`, in %.
fn pct(errs: &[(String, f64)], name: &str) -> f64 {
    100.0 * errs.iter().find(|(n, _)| n == name).expect("estimated").1
}

/// The largest |relative error| in `errs` over the names not in `except`, in %.
fn largest_pct(errs: &[(String, f64)], except: &[&str]) -> f64 {
    errs.iter()
        .filter(|(n, _)| !except.contains(&n.as_str()))
        .fold(0.0f64, |a, (_, e)| a.max(100.0 * e.abs()))
}

/// The standard error of `name` relative to its value, in %.
fn se_pct(id: &Identification, name: &str) -> f64 {
    let p = id.param(name).expect("estimated");
    100.0 * p.stderr / p.value.abs()
}

/// Identify `ir` from `data` and check every unknown within `tol` (relative, by name);
/// returns the identification and the relative errors.
fn check(
    name: &str,
    data: Data,
    noise: f64,
    seed: u64,
    tol: &[(&str, f64)],
) -> (Identification, Vec<(String, f64)>) {
    let ir = model(name);
    let recs = records(&ir, data, noise, seed);
    let id = common::identify_records(&ir, &recs);
    let errs = common::error_row(&format!("{name} {data:?} seed {seed}"), &ir, &id);
    for (n, e) in &errs {
        let t = tol
            .iter()
            .find(|(p, _)| p == n)
            .unwrap_or_else(|| panic!("no tolerance for {n}"))
            .1;
        assert!(
            e.abs() < t,
            "{name} {data:?}: {n} off by {:+.3}% (tolerance {:.2}%)",
            100.0 * e,
            100.0 * t
        );
    }
    (id, errs)
}

/// 3x the largest error over five seeds of random data (module doc).
const SDOF_TOL: [(&str, f64); 3] = [("d", 0.009), ("k", 0.0025), ("k3", 0.005)];
const TWO_MASS_TOL: [(&str, f64); 7] = [
    ("d1", 0.02),
    ("d2", 0.07),
    ("k1", 0.001),
    ("k2", 0.005),
    ("k3", 0.01),
    ("m2", 0.0025),
    ("r", 0.06),
];
/// `two_mass_linear`, random data, seeds 1–3: d1 0.27, d2 0.34, k1 0.03, k2 0.03, m2 0.02 %.
const TWO_MASS_LINEAR_TOL: [(&str, f64); 5] = [
    ("d1", 0.008),
    ("d2", 0.01),
    ("k1", 0.001),
    ("k2", 0.001),
    ("m2", 0.001),
];

#[test]
fn sdof_duffing_from_multisine_and_sweep_within_the_random_tolerances() {
    let (random, _) = check("sdof_duffing.dyn", Data::Random, 0.05, 1, &SDOF_TOL);
    let (_, e) = check("sdof_duffing.dyn", Data::Multisine, 0.05, 1, &SDOF_TOL);
    doc_figure("signals.multisine.sdof.d", pct(&e, "d"));
    doc_figure("signals.multisine.sdof.k", pct(&e, "k"));
    doc_figure("signals.multisine.sdof.k3", pct(&e, "k3"));
    // A sweep's batch-means standard errors hold the spread between its windows, which
    // see different bands: larger than random data's, and they cover the sweep's errors.
    let (sweep, e) = check("sdof_duffing.dyn", Data::Sweep, 0.05, 1, &SDOF_TOL);
    doc_figure("signals.sweep.sdof.d_se", se_pct(&sweep, "d"));
    doc_figure("signals.random.sdof.d_se", se_pct(&random, "d"));
    let z = e
        .iter()
        .map(|(n, e)| 100.0 * e.abs() / se_pct(&sweep, n))
        .fold(0.0f64, f64::max);
    println!("sweep: largest error {z:.2} standard errors");
    doc_figure("signals.sweep.sdof.z", z);
}

#[test]
fn two_mass_from_multisine_within_the_random_tolerances() {
    check("two_mass.dyn", Data::Random, 0.05, 1, &TWO_MASS_TOL);
    let (_, e) = check("two_mass.dyn", Data::Multisine, 0.05, 1, &TWO_MASS_TOL);
    doc_figure("signals.multisine.two_mass.d2", pct(&e, "d2"));
    doc_figure("signals.multisine.two_mass.r", pct(&e, "r"));
    doc_figure(
        "signals.multisine.two_mass.rest",
        largest_pct(&e, &["d2", "r"]),
    );
}

#[test]
fn two_mass_from_sweeps_within_the_random_tolerances() {
    // The linear structure with noise, from a log sweep.
    check(
        "two_mass_linear.dyn",
        Data::Sweep,
        0.05,
        1,
        &TWO_MASS_LINEAR_TOL,
    );
    // The friction joint, noise-free, from a linear sweep 0.05–1.6 Hz (seed 1: d2 −0.09 %,
    // r +0.08 %, the rest within 0.05 %; docs/method.md quotes d2 and r).
    let (_, e) = check("two_mass.dyn", Data::LinearSweep, 0.0, 1, &TWO_MASS_TOL);
    doc_figure("signals.linear_sweep.two_mass.d2", pct(&e, "d2"));
    doc_figure("signals.linear_sweep.two_mass.r", pct(&e, "r"));
}

/// The limitation docs/method.md states, measured on seed 1: with 5 % noise a log sweep
/// from 0.02 Hz biases `two_mass`'s stiffnesses and mass low (seeds 1–5 by the long
/// form: k1, k2, m2 about −2 % and k3 −3.4 % on every seed), and noise-free the slow start
/// costs the friction joint d2 and r tens of percent.
#[test]
fn two_mass_from_a_log_sweep_is_biased() {
    let ir = model("two_mass.dyn");
    let id = common::identify_records(&ir, &records(&ir, Data::Sweep, 0.05, 1));
    let e = common::error_row("two_mass.dyn Sweep seed 1", &ir, &id);
    // A bias, not spread: each of k1, k2, m2, k3 at least 1 % low (seed 1: −2.0, −2.4,
    // −3.2, −3.4 % against standard errors of 0.4–1.0 %).
    for n in ["k1", "k2", "m2", "k3"] {
        assert!(pct(&e, n) < -1.0, "{n}: {:+.2} %", pct(&e, n));
    }
    for (n, figure) in [
        ("k1", "signals.log_sweep.two_mass.k1"),
        ("k2", "signals.log_sweep.two_mass.k2"),
        ("m2", "signals.log_sweep.two_mass.m2"),
        ("k3", "signals.log_sweep.two_mass.k3"),
    ] {
        doc_figure(figure, pct(&e, n));
    }
    let id = common::identify_records(&ir, &records(&ir, Data::Sweep, 0.0, 1));
    let e = common::error_row("two_mass.dyn Sweep noise-free seed 1", &ir, &id);
    doc_figure("signals.log_sweep.noise_free.two_mass.d2", pct(&e, "d2"));
    doc_figure("signals.log_sweep.noise_free.two_mass.r", pct(&e, "r"));
}

/// The long form: every case over seeds 1–5, printed (the table of the module doc).
#[test]
fn spread_over_seeds() {
    if std::env::var("DYNID_SIGNAL_SPREAD").is_err() {
        return;
    }
    for name in ["sdof_duffing.dyn", "two_mass.dyn", "two_mass_linear.dyn"] {
        let ir = model(name);
        for data in [Data::Random, Data::Multisine, Data::Sweep] {
            for seed in 1..=5 {
                let recs = records(&ir, data, 0.05, seed);
                let id = common::identify_records(&ir, &recs);
                common::error_row(&format!("{name} {data:?} seed {seed}"), &ir, &id);
            }
        }
    }
}

/// Detection names the Duffing spring from multisine levels, and writes the frequency
/// response per level (periodic average at the excited lines) beside the curves, and into
/// the JSON.
#[test]
fn detect_names_the_duffing_spring_from_multisine_levels_and_draws_the_frf() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let o = common::dynid()
        .args([
            "simulate",
            common::model_path("sdof_duffing.dyn").to_str().unwrap(),
            "--signal",
            "multisine",
            "--band-hz",
            "0.01,1.6",
            "--periods",
            "4",
            "--levels",
            "1.34,3.35,8.94",
            "--duration",
            "1000",
            "--noise",
            "0.05",
            "--seed",
            &common::seed(3).to_string(),
            "--out",
            data.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", common::stderr(&o));
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["signal"]["kind"], "multisine");
    let plot = dir.path().join("curves.png");
    let json = dir.path().join("detect.json");
    let o = common::dynid()
        .args([
            "detect",
            common::model_path("sdof_linear.dyn").to_str().unwrap(),
            data.join("level_1.csv").to_str().unwrap(),
            data.join("level_2.csv").to_str().unwrap(),
            data.join("level_3.csv").to_str().unwrap(),
            "--frf-periods",
            "4",
            "--plot",
            plot.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", common::stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.starts_with("Element") && l.contains("(ground, m)"))
        .unwrap_or_else(|| panic!("no element line:\n{out}"));
    assert!(line.contains("cubic stiffness"), "{out}");
    let frf_png = dir.path().join("curves-frf.png");
    assert_eq!(&std::fs::read(&frf_png).unwrap()[1..4], b"PNG");
    if let Ok(keep) = std::env::var("DYNID_KEEP_PLOTS") {
        std::fs::copy(&frf_png, format!("{keep}-frf.png")).unwrap();
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let frf = v["frf"].as_array().unwrap();
    assert_eq!(frf.len(), 3);
    // The lines k/250 Hz, k = 3 … 400 (0.012–1.6 Hz): 398 of them, every level.
    for l in frf {
        assert_eq!(l["measured"]["method"]["kind"], "periodic");
        assert_eq!(l["measured"]["freq_hz"].as_array().unwrap().len(), 398);
    }
    // The model fitted at the lowest level (the most linear) follows the measured FRF of
    // the position over the resonance band 0.2–0.5 Hz: the median of log(|model| /
    // |measured|) over its lines was −0.9 % (line by line the nonlinear distortion
    // scatters them by 16 % on average); 3 % allows 3x.
    let low = &frf[0];
    let f = low["measured"]["freq_hz"].as_array().unwrap();
    let mag = |h: &serde_json::Value| h[0].as_f64().unwrap().hypot(h[1].as_f64().unwrap());
    let mut r: Vec<f64> = (0..f.len())
        .filter(|&k| (0.2..=0.5).contains(&f[k].as_f64().unwrap()))
        .map(|k| (mag(&low["model"][0][k]) / mag(&low["measured"]["h"][0][k])).ln())
        .collect();
    r.sort_by(f64::total_cmp);
    let median = r[r.len() / 2];
    assert!(median.abs() < 0.03, "median log ratio {median}");
}

/// A test signal without its band, or with periods that do not split the record, is
/// refused before any file is written, with the flag to fix.
#[test]
fn bad_test_signals_are_refused_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "simulate".to_string(),
            common::model_path("sdof_duffing.dyn").display().to_string(),
            "--duration".into(),
            "10.01".into(),
            "--out".into(),
            out.display().to_string(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        common::dynid().args(&args).output().unwrap()
    };
    let o = run(&["--signal", "multisine"]);
    assert!(!o.status.success());
    let e = common::stderr(&o);
    assert!(e.contains("--band-hz"), "{e}");
    // 1001 samples do not split into 4 periods; 7 or 11 would.
    let o = run(&["--signal", "multisine", "--band-hz", "0.5,3"]);
    assert!(!o.status.success());
    let e = common::stderr(&o);
    assert!(
        e.contains("1001 samples in 4 periods") && e.contains("--periods"),
        "{e}"
    );
    // A band above the Nyquist frequency (50 Hz).
    let o = run(&["--signal", "sweep", "--band-hz", "1,80", "--periods", "1"]);
    assert!(!o.status.success());
    assert!(
        common::stderr(&o).contains("Nyquist"),
        "{}",
        common::stderr(&o)
    );
    assert!(!out.join("level_1.csv").exists());
}
