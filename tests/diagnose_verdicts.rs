//! The two verdicts of `diagnose` that name no effect: data of the model's own structure
//! with other parameter values (mis-tuned: re-identification closes the gap), and data of
//! a structure no library effect reaches (unexplained: an unmodelled body, so the gap stays
//! whatever is added).

mod common;

use dynid::runtime::diagnose::{diagnose, DiagnoseOptions, Diagnosis, Verdict};
use dynid::runtime::sim::{simulate, SimConfig};

const TWO_MASS: &str = include_str!("../models/two_mass_linear.dyn");

/// Diagnose data simulated from `truth` with the model `model`.
fn run(model: &str, truth: &str) -> Diagnosis {
    let ir = dynid::dsl_parser::compile_str("truth", truth).expect("truth compiles");
    let cfg = SimConfig {
        duration: 300.0,
        burn_in: 50.0,
        seed: common::seed(11),
        noise: 0.01,
        ..Default::default()
    };
    let out = simulate(&ir, &cfg).expect("simulates");
    let origins: Vec<String> = (1..=out.records.len())
        .map(|k| format!("level{k}"))
        .collect();
    let model = dynid::dsl_parser::compile_str("model", model).expect("model compiles");
    let d = diagnose(
        &model,
        &out.records,
        &origins,
        &DiagnoseOptions::default(),
        &|_, _| {},
    )
    .expect("diagnoses");
    eprintln!("{}", d.summary());
    d
}

/// `src` with one line replaced.
fn replaced(src: &str, from: &str, to: &str) -> String {
    assert!(src.contains(from), "`{from}` is in the model");
    src.replace(from, to)
}

#[test]
fn a_model_with_wrong_values_is_mistuned() {
    // Stiffnesses and dampings off by 25–100 %: the same structure, other values.
    let mut truth = replaced(
        TWO_MASS,
        "spring k1 (ground, m1) ~ 4.0",
        "spring k1 (ground, m1) ~ 5.5",
    );
    truth = replaced(
        &truth,
        "damper d1 (ground, m1) ~ 0.4",
        "damper d1 (ground, m1) ~ 0.8",
    );
    truth = replaced(
        &truth,
        "spring k2 (m1, m2) ~ 3.0",
        "spring k2 (m1, m2) ~ 2.2",
    );
    let d = run(TWO_MASS, &truth);
    assert_eq!(d.verdict, Verdict::MistunedParameters, "{}", d.summary());
    assert!(d.found.is_empty(), "{}", d.summary());
    // Re-identification closes the gap (withheld levels), the nominal model does not:
    // DYNID_SEED_OFFSET=0..4 gave 42.3–46.2 % → 0.1 % each.
    assert!(
        d.gap_before > 20.0 && d.gap_reidentified < 0.3,
        "re-identified {} vs nominal {}",
        d.gap_reidentified,
        d.gap_before
    );
    // The moved parameters are the ones changed, at their true values: over
    // DYNID_SEED_OFFSET=0..4, k1 −0.025 … −0.047 %, k2 −0.015 … −0.059 % (1 % noise on
    // every channel); the bound is 2.5× the worst.
    let moved = |name: &str| {
        d.moved
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("{name} moved:\n{}", d.summary()))
            .identified
    };
    let (e1, e2) = (moved("k1") / 5.5 - 1.0, moved("k2") / 2.2 - 1.0);
    eprintln!("k1 {:+.4} %, k2 {:+.4} %", 100.0 * e1, 100.0 * e2);
    assert!(
        e1.abs() < 0.0015 && e2.abs() < 0.0015,
        "k1 {e1:+.2e}, k2 {e2:+.2e}"
    );
}

#[test]
fn an_unmodelled_body_is_unexplained() {
    // A third mass hangs on m2; the model has two. No force between the model's bodies
    // can stand in for a resonance of its own.
    let k = TWO_MASS.rfind('}').expect("closing brace");
    let truth = format!(
        "{}    body m3 = 0.5\n    spring k3 (m2, m3) ~ 6.0\n    damper d3 (m2, m3) ~ 0.05\n{}",
        &TWO_MASS[..k],
        &TWO_MASS[k..]
    );
    let d = run(TWO_MASS, &truth);
    assert_eq!(d.verdict, Verdict::Unexplained, "{}", d.summary());
    assert!(d.found.is_empty(), "{}", d.summary());
    // The gap re-identification leaves (DYNID_SEED_OFFSET=0..4: 9.5–12.5 %, from 19.7–28.9 %
    // nominal) is above the 5 % of a consistent model.
    assert!(d.gap_reidentified > 5.0, "{}", d.summary());
}
