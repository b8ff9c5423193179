//! Detection end to end: each nonlinear model is simulated with the project simulator at
//! its three excitation levels, its linear counterpart is identified per level, and the
//! verdict and the implied nonlinear parameter are checked against the truth.

use dynid::dsl_parser::{compile_file, compile_str, ir::ModelIr};
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::detect::{
    detect_from_data, DetectOptions, Detection, ElementFinding, LevelFits, Verdict,
};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{simulate, SimConfig};
use dynid::runtime::IdentifyOptions;
use std::path::Path;

fn model(name: &str) -> ModelIr {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(format!("{name}.dyn"));
    compile_file(&p).unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

fn sim(truth: &str, duration: f64, seed: u64) -> Vec<Record> {
    sim_ir(&model(truth), duration, seed)
}

fn sim_ir(ir: &ModelIr, duration: f64, seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration,
        seed,
        burn_in: 20.0,
        ..Default::default()
    };
    simulate(ir, &cfg).expect("simulate").records
}

fn run(linear: &str, records: &[Record], balance: bool) -> (Detection, LevelFits) {
    run_ir(&model(linear), records, balance)
}

fn run_ir(ir: &ModelIr, records: &[Record], balance: bool) -> (Detection, LevelFits) {
    let srcs: Vec<RecordSource> = records
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = IdentifyOptions {
        balance: Some(balance),
        ..Default::default()
    };
    detect_from_data(ir, &levels, &opts, &DetectOptions::default(), &[]).expect("detect")
}

fn finding<'a>(d: &'a Detection, element: &str) -> &'a ElementFinding {
    d.elements
        .iter()
        .find(|e| e.element == element)
        .unwrap_or_else(|| panic!("no element {element}"))
}

/// The verdict's template and its implied effect parameters by name.
fn best(d: &Detection, element: &str) -> (String, Vec<(String, f64)>) {
    let f = finding(d, element);
    let name = match &f.verdict {
        Verdict::Nonlinear { best, .. } => best.clone(),
        v => panic!(
            "{element}: expected a nonlinear verdict, got {v}\n{}",
            d.render_table()
        ),
    };
    let est = f.ranking[0]
        .effect_estimates()
        .iter()
        .map(|e| (e.name.clone(), e.value))
        .collect();
    (name, est)
}

fn implied(est: &[(String, f64)], name: &str) -> f64 {
    est.iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no estimate {name} in {est:?}"))
        .1
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b) / b
}

/// Simulate `truth`, detect on `linear`, check the verdict at `element` and the implied
/// parameters against the truth within `tol` (relative).
fn check(
    truth: &str,
    linear: &str,
    element: &str,
    template: &str,
    expect: &[(&str, f64)],
    tol: f64,
) {
    let recs = sim(truth, DURATION, 7);
    let (d, _) = run(linear, &recs, false);
    println!("{truth}:\n{}", d.render_table());
    let (name, est) = best(&d, element);
    assert_eq!(name, template, "{truth}\n{}", d.render_table());
    for (p, t) in expect {
        let e = rel(implied(&est, p), *t);
        println!(
            "{truth}: {p} = {:.4} (truth {t}, {:+.1} %)",
            implied(&est, p),
            100.0 * e
        );
        assert!(e.abs() < tol, "{truth}: {p} off by {:.1} %", 100.0 * e);
    }
}

/// Seconds per level: long enough that every verdict below held on the seeds tried.
const DURATION: f64 = 400.0;

#[test]
fn duffing_is_cubic_at_the_spring() {
    // Statistical linearisation assumes a Gaussian s; the hardening spring at the loudest
    // level makes s markedly sub-Gaussian, so the implied k3 comes out low (see docs).
    check(
        "sdof_duffing",
        "sdof_linear",
        "k/d (ground, m)",
        "cubic stiffness",
        &[("k3", 2.0)],
        0.35,
    );
}

#[test]
fn coulomb_is_friction_at_the_damper() {
    check(
        "sdof_coulomb",
        "sdof_linear",
        "k/d (ground, m)",
        "Coulomb friction",
        &[("r", 0.3)],
        0.10,
    );
}

#[test]
fn quadratic_damping_is_found() {
    check(
        "quadratic_damping",
        "quadratic_damping_linear",
        "k/d (ground, m)",
        "quadratic damping",
        &[("c", 0.2)],
        0.25,
    );
}

#[test]
fn prestress_is_found() {
    check(
        "prestress",
        "prestress_linear",
        "d/k (ground, m)",
        "prestress",
        &[("f0", 0.5)],
        0.25,
    );
}

#[test]
fn backlash_is_found() {
    // The gap and the stiffness trade off along three points: the template is named
    // reliably, its two parameters only roughly (measured: kb −36 %, g +63 %).
    check(
        "backlash",
        "backlash_linear",
        "k/d (ground, m)",
        "backlash",
        &[("kb", 4.0), ("g", 0.1)],
        0.7,
    );
}

/// Both effects in one element: at 400 s per level the cubic spring dominates the verdict
/// and the pair template ranks second with the friction visible (r ≈ 0.2 of 0.3).
#[test]
fn cubic_and_coulomb_in_one_element() {
    let recs = sim("sdof_cubic_coulomb", DURATION, 7);
    let (d, _) = run("sdof_linear", &recs, false);
    println!("{}", d.render_table());
    let (name, _) = best(&d, "k/d (ground, m)");
    assert!(name.contains("cubic stiffness"), "{name}");
    let f = finding(&d, "k/d (ground, m)");
    let pair = f.ranking[..2]
        .iter()
        .find(|t| t.name == "cubic stiffness + Coulomb friction")
        .expect("the pair template ranks in the top two");
    let r = pair
        .effect_estimates()
        .iter()
        .find(|e| e.name == "r")
        .unwrap()
        .value;
    println!("pair: r = {r:.3} (truth 0.3)");
    assert!(r > 0.1, "the friction shows in the pair fit");
}

/// two_mass hides cubic stiffness and Coulomb friction in the coupling: the coupling must
/// be flagged (the best template is the cubic spring; the verdict is not always a clean
/// `nonlinear`) and the ground element must stay linear.
#[test]
fn two_mass_nonlinear_coupling_linear_ground() {
    let recs = sim("two_mass", DURATION, 7);
    let (d, _) = run("two_mass_linear", &recs, false);
    println!("{}", d.render_table());
    assert_eq!(finding(&d, "k1/d1 (ground, m1)").verdict, Verdict::Linear);
    let f = finding(&d, "k2/d2 (m1, m2)");
    assert_ne!(f.verdict, Verdict::Linear);
    assert!(
        f.ranking[0].name.contains("cubic stiffness"),
        "{}",
        f.ranking[0].name
    );
    assert!(f.ranking[..2]
        .iter()
        .any(|t| t.name == "cubic stiffness + Coulomb friction"));
}

const FRICTION_AT_GROUND: &str = "
model two_mass_friction {
    body m1 = 1.0
    body m2 ~ 2.0
    input u on m1
    spring k1 (ground, m1) ~ 4.0
    damper d1 (ground, m1) ~ 0.4
    force fr (ground, m1) = r ~ 0.3 * sign(v)
    spring k2 (m1, m2) ~ 3.0
    damper d2 (m1, m2) ~ 0.2
    excite u: lowpass(corner = 10) levels [6, 15, 40]
    filter corners [0.5, 1, 2, 4, 8, 16] order 2
}";

#[test]
fn two_mass_friction_at_ground_only() {
    let truth = compile_str("two_mass_friction", FRICTION_AT_GROUND).unwrap();
    let recs = sim_ir(&truth, DURATION, 7);
    let (d, _) = run("two_mass_linear", &recs, false);
    println!("{}", d.render_table());
    assert_eq!(finding(&d, "k2/d2 (m1, m2)").verdict, Verdict::Linear);
    let (name, est) = best(&d, "k1/d1 (ground, m1)");
    assert_eq!(name, "Coulomb friction");
    let r = implied(&est, "r");
    println!(
        "two_mass_friction: r = {r:.4} (truth 0.3, {:+.1} %)",
        100.0 * rel(r, 0.3)
    );
    assert!(rel(r, 0.3).abs() < 0.15);
}

fn linear_detections(seeds: std::ops::Range<u64>) -> (usize, usize) {
    let two = model("two_mass_linear");
    let sdof = model("sdof_linear");
    let (mut alarms, mut total) = (0, 0);
    for seed in seeds {
        for ir in [&sdof, &two] {
            let recs = sim_ir(ir, DURATION, 1000 + seed);
            let (d, _) = run_ir(ir, &recs, false);
            for e in &d.elements {
                total += 1;
                if e.verdict != Verdict::Linear {
                    alarms += 1;
                    println!("seed {seed} {}: {}", ir.name, e.verdict);
                }
            }
        }
    }
    (alarms, total)
}

#[test]
fn linear_systems_give_no_detection() {
    let (alarms, total) = linear_detections(0..3);
    assert_eq!(alarms, 0, "{alarms} of {total} linear elements flagged");
}

/// `cargo test --test detect_models -- --ignored --nocapture false_positive_rate`
#[test]
#[ignore = "measurement: false-positive rate over 25 seeds"]
fn false_positive_rate() {
    let (alarms, total) = linear_detections(0..25);
    println!("false positives: {alarms} of {total} linear elements");
    assert!(alarms * 20 <= total, "more than 5 % false positives");
}

const SDOF_POSITIONS_ONLY: &str = "
model sdof_linear_x {
    body m = 1.0
    input u on m
    spring k (ground, m) ~ 4.0
    damper d (ground, m) ~ 0.4
    measure m.x, u
}";

/// σ_v from positions (Rice's zero-crossing rate) against the measured velocity, on a
/// linear and on a friction-damped oscillator; and friction is still detected without
/// velocities.
#[test]
fn sigma_v_from_zero_crossings() {
    let x_only = compile_str("sdof_linear_x", SDOF_POSITIONS_ONLY).unwrap();
    for truth in ["sdof_linear", "sdof_coulomb", "sdof_duffing"] {
        let recs = sim(truth, DURATION, 7);
        let (_, with_v) = run("sdof_linear", &recs, false);
        let (d, no_v) = run_ir(&x_only, &recs, false);
        let (a, b) = (&with_v.input.elements[0], &no_v.input.elements[0]);
        let errs: Vec<f64> = a
            .sigma_v
            .iter()
            .zip(&b.sigma_v)
            .map(|(m, z)| rel(*z, *m))
            .collect();
        println!("{truth}: σ_v zero-crossing error per level {errs:+.4?}");
        for e in &errs {
            assert!(e.abs() < 0.2, "{truth}: {errs:?}");
        }
        if truth == "sdof_coulomb" {
            let (name, est) = best(&d, "k/d (ground, m)");
            assert_eq!(name, "Coulomb friction");
            println!("positions only: r = {:.4} (truth 0.3)", implied(&est, "r"));
        }
    }
}
