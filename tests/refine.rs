//! The output-error refinement started from the covariance estimate: recovery on simulated
//! data with noise on the measured position, and the CLI's refusals.
//!
//! The input is linear between samples in the recovery test. With content between samples
//! (input simulated 10× finer) the free run, which interpolates the measured input
//! linearly, is itself wrong, and the refinement absorbs that into the parameters
//! (`input_between_samples_goes_into_the_refined_parameters`, docs/method.md, section 9).

mod common;
mod figures;

use dynid::dsl_parser::{self, ir::ModelIr};
use dynid::runtime::record::Record;
use dynid::runtime::refine::{self, RefineOptions};
use dynid::runtime::sim::{self, SimConfig};

fn model(name: &str) -> ModelIr {
    dsl_parser::compile_file(&common::model_path(name)).expect("model compiles")
}

/// The Duffing levels, `duration` s at Ts = 0.01 s, 2 % noise on the position.
fn records(ir: &ModelIr, duration: f64, seed: u64) -> Vec<Record> {
    records_oversampled(ir, duration, seed, 1)
}

/// [`records`] with the input simulated `oversample` times finer than the samples.
fn records_oversampled(ir: &ModelIr, duration: f64, seed: u64, oversample: usize) -> Vec<Record> {
    let cfg = SimConfig {
        duration,
        seed: common::seed(seed),
        noise: 0.02,
        noise_on_inputs: false,
        burn_in: 20.0,
        input_oversample: oversample,
        ..Default::default()
    };
    sim::simulate(ir, &cfg).expect("simulation").records
}

fn rel_errors(ir: &ModelIr, values: &[f64]) -> Vec<f64> {
    let truth = sim::parameter_values(ir).unwrap();
    ir.unknowns()
        .iter()
        .zip(values)
        .map(|(p, v)| v / truth[p.index()] - 1.0)
        .collect()
}

fn worst(e: &[f64]) -> f64 {
    e.iter().fold(0.0, |a, b| a.max(b.abs()))
}

#[test]
fn refined_estimate_is_at_least_as_accurate_as_the_covariance_one() {
    let ir = model("sdof_duffing.dyn");
    let est = records(&ir, 150.0, 31);
    let test = records(&ir, 50.0, 131);
    let id = common::identify_records(&ir, &est);
    let start = refine::start_from(&ir, &id);
    let r = refine::refine(&ir, &est, &start, &RefineOptions::default()).expect("refines");
    let (ec, er) = (rel_errors(&ir, &start), rel_errors(&ir, &r.values()));
    let fr = |v: &[f64], recs: &[Record]| {
        refine::free_run_errors(&ir, v, recs, sim::DEFAULT_SUBSTEPS).unwrap()[0].relative
    };
    let (tc, tr) = (fr(&start, &test), fr(&r.values(), &test));
    println!(
        "| seed offset | covariance k, d, k3 | refined k, d, k3 | test free-run covariance / refined | iterations |"
    );
    let pct = |e: &[f64]| {
        e.iter()
            .map(|x| format!("{:+.3}%", 100.0 * x))
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!(
        "| {} | {} | {} | {:.4} / {:.4} | {} |",
        common::seed(0),
        pct(&ec),
        pct(&er),
        tc,
        tr,
        r.iterations
    );
    assert!(r.converged, "{r:?}");
    // The refinement lowers the fitted error and is not worse on parameters or test data.
    assert!(r.cost_end < r.cost_start, "{r:?}");
    assert!(
        worst(&er) <= worst(&ec),
        "refined {er:?} vs covariance {ec:?}"
    );
    // Seed offsets 0–3 (`DYNID_SEED_OFFSET=k cargo test --test refine -- --nocapture`):
    // worst refined error 0.045 %, 0.055 %, 0.38 %, 0.024 % (covariance 0.18 %, 0.19 %,
    // 0.53 %, 0.60 %); the bound is 3× the largest. Every record starts from its measured
    // state, the velocity from a difference of three positions with 2 % noise: that start
    // error goes into the parameters (fitting the initial states instead gave 0.006–0.013 %,
    // but a score the printed free run did not share). The test records' free-run error is
    // printed, not asserted: at this noise it moves either way by up to 45 % (0.048 → 0.070
    // at offset 3) although the refined parameters are closer.
    assert!(worst(&er) < 1.2e-2, "{er:?}");
    // docs/method.md (section 9) quotes this seed's worst errors.
    if common::seeds_as_documented() {
        figures::check("docs/method.md", "refine.worst", 100.0 * worst(&er));
        figures::check(
            "docs/method.md",
            "refine.covariance_worst",
            100.0 * worst(&ec),
        );
    }
    // Standard errors are finite and positive.
    assert!(r
        .params
        .iter()
        .all(|p| p.stderr > 0.0 && p.stderr.is_finite()));
}

/// The input simulated 10× finer than the samples: the free run's linear interpolation of
/// the input is wrong between samples, and the refinement puts that error into k3, while
/// the covariance moments average it out. Seed offsets 0–3 (`DYNID_SEED_OFFSET=k cargo
/// test --test refine input_between -- --nocapture`): k3 −1.53, +1.84, −1.79, −1.49 %
/// refined against −0.16, −0.38, −0.62, +0.02 % from the covariance method. Asserted: the
/// refined error at least half the smallest of those (0.75 %) and twice the covariance
/// one (the ratio was 2.9 at least); offset 0's figures are docs/method.md's.
#[test]
fn input_between_samples_goes_into_the_refined_parameters() {
    let ir = model("sdof_duffing.dyn");
    let est = records_oversampled(&ir, 150.0, 31, 10);
    let id = common::identify_records(&ir, &est);
    let start = refine::start_from(&ir, &id);
    let r = refine::refine(&ir, &est, &start, &RefineOptions::default()).expect("refines");
    let k3 = ir
        .unknowns()
        .iter()
        .position(|p| ir.params[p.index()].name == "k3")
        .expect("k3 is unknown");
    let (ec, er) = (
        rel_errors(&ir, &start)[k3],
        rel_errors(&ir, &r.values())[k3],
    );
    println!(
        "input ×10: k3 {:+.3} % refined, {:+.3} % covariance",
        100.0 * er,
        100.0 * ec
    );
    assert!(
        er.abs() > 0.0075 && er.abs() > 2.0 * ec.abs(),
        "refined {er}, covariance {ec}"
    );
    if common::seeds_as_documented() {
        figures::check("docs/method.md", "refine.fine_input.k3", 100.0 * er);
        figures::check(
            "docs/method.md",
            "refine.fine_input.covariance_k3",
            100.0 * ec,
        );
    }
}

#[test]
fn refine_flags_need_refine_and_bad_weights_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let model = common::model_path("sdof_duffing.dyn");
    let out = dir.path().join("data");
    let o = common::dynid()
        .args(["simulate", model.to_str().unwrap(), "--duration", "20"])
        .args(["--levels", "6,15", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", common::stderr(&o));
    let level = out.join("level_1.csv");
    // A refinement flag without --refine: refused by the argument parser (exit 2).
    let o = common::dynid()
        .args(["identify", model.to_str().unwrap(), level.to_str().unwrap()])
        .args(["--weight", "m.x=2"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
    assert!(
        common::stderr(&o).contains("--refine"),
        "{}",
        common::stderr(&o)
    );
    // A weight on a signal the refinement does not compare: named, with the choices.
    let o = common::dynid()
        .args(["identify", model.to_str().unwrap(), level.to_str().unwrap()])
        .args(["--refine", "--weight", "u=2"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    let e = common::stderr(&o);
    assert!(e.contains("weight of `u`") && e.contains("m.x"), "{e}");
    // A well-formed refinement prints both estimates side by side.
    let o = common::dynid()
        .args(["identify", model.to_str().unwrap(), level.to_str().unwrap()])
        .args([
            "--refine",
            "--test",
            out.join("level_2.csv").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", common::stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("output-error refinement"), "{s}");
    assert!(s.contains("covariance") && s.contains("refined"), "{s}");
    assert!(
        s.contains("estimation m.x") && s.contains("test m.x"),
        "{s}"
    );
}
