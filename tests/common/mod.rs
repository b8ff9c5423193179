//! Helpers shared by the integration tests: run the binary, identify simulated records and
//! compare the estimates with the values the simulation used.
#![allow(dead_code)] // each test binary uses a subset

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::ident::{Identification, IdentifyError};
use dynid::runtime::record::Record;
use dynid::runtime::sim;
use dynid::runtime::{identify, IdentifyOptions};

/// One source per record, named `level 1`, `level 2`, ….
pub fn sources<'r>(ir: &ModelIr, recs: &'r [Record]) -> Vec<RecordSource<'r>> {
    recs.iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect()
}

/// Identify `ir` from one record per level.
pub fn identify_with(
    ir: &ModelIr,
    recs: &[Record],
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let srcs = sources(ir, recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    identify(ir, &levels, opts)
}

/// [`identify_with`] with the default options; panics on an error.
pub fn identify_records(ir: &ModelIr, recs: &[Record]) -> Identification {
    identify_with(ir, recs, &IdentifyOptions::default()).expect("identification")
}

/// Relative error of every unknown parameter against the value the simulator used (its
/// nominal value); panics, naming `case`, when one has no estimate.
pub fn relative_errors(case: &str, ir: &ModelIr, id: &Identification) -> Vec<(String, f64)> {
    let values = sim::parameter_values(ir).unwrap();
    ir.unknowns()
        .iter()
        .map(|&p| {
            let name = ir.params[p.index()].name.clone();
            let t = values[p.index()];
            let est = id
                .param(&name)
                .unwrap_or_else(|| panic!("{case}: `{name}` not identified: {id:#?}"));
            (name, (est.value - t) / t)
        })
        .collect()
}

/// The model's levels, `duration` seconds at Ts = 0.01 s, with `noise` (a fraction of each
/// signal's std) on every channel, inputs included; `seed` goes through [`seed`].
pub fn simulate(ir: &ModelIr, duration: f64, noise: f64, seed: u64) -> Vec<Record> {
    let cfg = sim::SimConfig {
        duration,
        sample: 0.01,
        seed: self::seed(seed),
        noise,
        noise_on_inputs: true,
        ..Default::default()
    };
    sim::simulate(ir, &cfg).expect("simulation").records
}

/// [`relative_errors`], printed as one table row `| case | k +0.012% (±0.034%), … | cond |`
/// (the standard error relative to the estimate in brackets).
pub fn error_row(case: &str, ir: &ModelIr, id: &Identification) -> Vec<(String, f64)> {
    let errs = relative_errors(case, ir, id);
    let row: Vec<String> = errs
        .iter()
        .map(|(n, e)| {
            let se = id.param(n).map_or(0.0, |p| p.stderr / p.value.abs());
            format!("{n} {:+.3}% (±{:.3}%)", 100.0 * e, 100.0 * se)
        })
        .collect();
    println!(
        "| {case:<34} | {} | cond {:.1e} |",
        row.join(", "),
        id.condition
    );
    errs
}

/// `models/NAME` as an absolute path (the CLI tests run in temporary folders).
pub fn model_path(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(name)
}

/// `models/NAME.dyn` compiled, with its source.
pub fn model_and_source(name: &str) -> (ModelIr, String) {
    let src = std::fs::read_to_string(model_path(&format!("{name}.dyn"))).unwrap();
    let ir = dynid::dsl_parser::compile_str(&format!("{name}.dyn"), &src)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    (ir, src)
}

/// The model of `src` with its measure line `from` replaced by `to` (the same model
/// measured by positions instead of accelerations, say).
pub fn measured_otherwise(src: &str, from: &str, to: &str) -> ModelIr {
    let text = src.replace(from, to);
    assert_ne!(text, src, "the measure line `{from}` is in the model");
    dynid::dsl_parser::compile_str("positions.dyn", &text).unwrap_or_else(|e| panic!("{e:?}"))
}

/// The seeds of a case: `first` in the suite, `first`… with `DYNID_SEEDS=N` (the long form).
pub fn seeds_from(first: u64) -> Vec<u64> {
    (first..first + seed_count(1) as u64).collect()
}

/// Assert every relative error of `errs` below its parameter's bound in `tol` (a parameter
/// without a bound fails: each test states all of its bounds).
pub fn assert_within(case: &str, errs: &[(String, f64)], tol: &[(&str, f64)]) {
    for (n, e) in errs {
        let bound = tol
            .iter()
            .find(|(p, _)| p == n)
            .map(|&(_, b)| b)
            .unwrap_or_else(|| panic!("{case}: no bound for `{n}`"));
        assert!(
            e.abs() < bound,
            "{case}: `{n}` off by {:+.3}% (bound {}%)",
            100.0 * e,
            100.0 * bound
        );
    }
}

/// A servo rig's record for `dynid simulate`: 25 s at 1 kHz, the drive's force updated
/// ten times per sample.
pub const RIG: [&str; 6] = [
    "--duration",
    "25",
    "--sample",
    "0.001",
    "--input-oversample",
    "10",
];

/// The `dynid` binary of this build.
pub fn dynid() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_dynid"))
}

/// `dynid simulate MODEL ARGS… --out OUT`, which must succeed; the first `levels` level
/// files it wrote (`OUT/level_1.csv` …).
pub fn simulate_levels<S: AsRef<std::ffi::OsStr>>(
    model: &std::path::Path,
    args: impl IntoIterator<Item = S>,
    out: &std::path::Path,
    levels: usize,
) -> Vec<std::path::PathBuf> {
    let st = dynid()
        .arg("simulate")
        .arg(model)
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", stderr(&st));
    (1..=levels)
        .map(|i| out.join(format!("level_{i}.csv")))
        .collect()
}

/// Three levels of two_mass (cubic coupling spring and Coulomb friction; 200 s, seed 5)
/// written by `dynid simulate` into `dir/data`: the data of the CLI's diagnosis tests.
pub fn two_mass_levels(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    simulate_levels(
        &model_path("two_mass.dyn"),
        ["--duration", "200", "--seed", "5"],
        &dir.join("data"),
        3,
    )
}

/// The value of parameter `name` in the parameter table of `dynid identify`'s text output
/// (the number after the name at the start of a line); panics, showing `stdout`, where no
/// row has it.
pub fn table_value(stdout: &str, name: &str) -> f64 {
    stdout
        .lines()
        .find_map(|l| {
            let mut w = l.split_whitespace();
            (w.next() == Some(name)).then(|| w.next()?.parse().ok())?
        })
        .unwrap_or_else(|| panic!("no row `{name}` in:\n{stdout}"))
}

/// A command's standard error with miette's line wrapping undone.
pub fn stderr(o: &std::process::Output) -> String {
    // The report wraps lines at the terminal width and may break a word after a hyphen
    // (`--allow-` / `large`): a line ending in a letter and a hyphen continues its word on
    // the next line.
    let mut out = String::new();
    let mut glue = false;
    for line in String::from_utf8_lossy(&o.stderr).lines() {
        for (k, w) in line.split_whitespace().filter(|w| *w != "│").enumerate() {
            let continues_word = k == 0 && glue;
            if !(out.is_empty() || continues_word) {
                out.push(' ');
            }
            out.push_str(w);
        }
        let b = out.as_bytes();
        glue = b.len() >= 2 && b[b.len() - 1] == b'-' && b[b.len() - 2].is_ascii_alphabetic();
    }
    out
}

/// `o` is a refusal, not a crash: a non-zero exit other than a panic's, stderr naming
/// `code` and every text of `also`.
pub fn assert_refused(o: &std::process::Output, code: &str, also: &[&str]) {
    let err = stderr(o);
    assert!(!o.status.success(), "accepted: {err}");
    assert_ne!(o.status.code(), Some(101), "panicked: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(code), "no `{code}` in: {err}");
    for a in also {
        assert!(err.contains(a), "no `{a}` in: {err}");
    }
}

/// `seed` shifted by the environment variable `DYNID_SEED_OFFSET` (default 0). The tests
/// run on fixed seeds; `DYNID_SEED_OFFSET=1 cargo test --test NAME -- --nocapture` reruns
/// them on other seeds to measure the spread their bounds are set from.
pub fn seed(seed: u64) -> u64 {
    match std::env::var("DYNID_SEED_OFFSET") {
        Ok(o) => {
            seed + o
                .parse::<u64>()
                .expect("DYNID_SEED_OFFSET is a whole number")
        }
        Err(_) => seed,
    }
}

/// `dynid COMMAND MODEL LEVELS… --json FILE --quiet`, which must succeed: the JSON it
/// wrote and its standard output.
pub fn run_json(
    command: &str,
    model: &std::path::Path,
    levels: &[std::path::PathBuf],
) -> (serde_json::Value, String) {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join(format!("{command}.json"));
    let out = dynid()
        .arg(command)
        .arg(model)
        .args(levels)
        .arg("--json")
        .arg(&json)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let v = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (v, String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The coefficient and standard error of an element's verdict from `detect --json` (an
/// element of `detection.elements`): the estimator's template fit of `effect`.
pub fn verdict_coefficient(element: &serde_json::Value, effect: &str) -> (f64, f64) {
    let fit = element["estimator"]
        .as_array()
        .and_then(|a| a.iter().find(|f| f["effect"] == effect))
        .unwrap_or_else(|| panic!("no estimator fit of {effect} in {element}"));
    (
        fit["value"].as_f64().expect("a value"),
        fit["stderr"].as_f64().expect("a standard error"),
    )
}

/// The drift (NRMSE, %) that a closed-loop hint (`closed_loop_hint` of `identify --json` or
/// `diagnose --json`) quotes.
pub fn hint_nrmse(hint: &str) -> f64 {
    hint.split("(NRMSE ")
        .nth(1)
        .and_then(|r| r.split(" %").next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no NRMSE in the hint: {hint}"))
}

/// Whether the tests run on their own seeds (no `DYNID_SEED_OFFSET`, or 0): figures the docs
/// quote for a seed are checked only then.
pub fn seeds_as_documented() -> bool {
    seed(0) == 0
}

/// The seeds of a verdict asserted as a rate: `count` seeds from `first` (shifted by
/// `DYNID_SEED_OFFSET`). `DYNID_SEEDS=N` runs N seeds instead: the long form, which
/// measures the rate the suite's short form asserts (`DYNID_SEEDS=20 cargo test --release
/// --test NAME -- --nocapture`).
pub fn rate_seeds(first: u64, count: usize) -> Vec<u64> {
    let first = seed(first);
    (first..first + seed_count(count) as u64).collect()
}

/// `count`, or the number `DYNID_SEEDS` gives (the long form of a rate over seeds).
pub fn seed_count(count: usize) -> usize {
    std::env::var("DYNID_SEEDS").map_or(count, |n| {
        n.parse::<usize>().expect("DYNID_SEEDS is a whole number")
    })
}

/// A copy of the linear SDOF model and three short levels of it in `dir`.
pub fn setup_linear_levels(dir: &std::path::Path) -> (std::path::PathBuf, Vec<std::path::PathBuf>) {
    let model = dir.join("sdof_linear.dyn");
    std::fs::copy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_linear.dyn"),
        &model,
    )
    .unwrap();
    let levels = simulate_levels(&model, ["--duration", "50", "--seed", "3"], dir, 3);
    (model, levels)
}

/// Every column minus its mean: data without a mean, as a logger that removes the DC
/// part records it.
pub fn centred(recs: &[Record]) -> Vec<Record> {
    recs.iter()
        .map(|r| {
            let mut r = r.clone();
            for c in &mut r.columns {
                let m = c.iter().sum::<f64>() / c.len() as f64;
                c.iter_mut().for_each(|v| *v -= m);
            }
            r
        })
        .collect()
}
