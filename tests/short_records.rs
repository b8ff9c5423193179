//! Short records: 25 s per level at 1 kHz identify with the default filter design, which
//! lifts the slowest corner until its chains settle within the record; a record that is too
//! short for given corners is refused with corners that fit it.
//!
//! Run with `--nocapture` for the errors and the corners chosen. Bounds are about 2–3 times
//! the largest error over five seeds, the test's own and the four after it: `for o in 0 1 2
//! 3 4; do DYNID_SEED_OFFSET=$o cargo test --test short_records -- --nocapture; done`.

mod common;
mod figures;

use dynid::dsl_parser::{self, ir::ModelIr};
use dynid::runtime::ident::{Identification, IdentifyError};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, SimConfig};
use dynid::runtime::IdentifyOptions;
use std::path::Path;

fn simulate(ir: &ModelIr, duration: f64, noise: f64, seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration,
        sample: 0.001,
        seed: common::seed(seed),
        noise,
        noise_on_inputs: true,
        substeps: 1,
        burn_in: 20.0,
        ..Default::default()
    };
    sim::simulate(ir, &cfg).expect("simulation").records
}

/// Every unknown within `tol` of its nominal value; prints the errors and the corners.
fn check(case: &str, ir: &ModelIr, id: &Identification, tol: f64) -> f64 {
    within(case, ir, id, tol).unwrap_or_else(|e| panic!("{e}"))
}

/// The largest relative residual of `id` over its equations and levels.
fn largest_residual(id: &Identification) -> f64 {
    id.residual
        .iter()
        .flat_map(|r| r.per_level.iter().copied())
        .fold(0.0, f64::max)
}

/// [`check`], telling instead of failing; `Ok` holds the largest relative error (signed).
fn within(case: &str, ir: &ModelIr, id: &Identification, tol: f64) -> Result<f64, String> {
    let mut row = Vec::new();
    let mut worst = (String::new(), 0.0f64);
    for (name, e) in common::relative_errors(case, ir, id) {
        row.push(format!("{name} {:+.2}%", 100.0 * e));
        if e.abs() > worst.1.abs() {
            worst = (name, e);
        }
    }
    let corners: Vec<String> = id
        .filter
        .corners
        .iter()
        .map(|c| format!("{c:.3}"))
        .collect();
    println!(
        "| {case:<40} | {} | corners {} rad/s |",
        row.join(", "),
        corners.join(", ")
    );
    if worst.1.abs() < tol {
        Ok(worst.1)
    } else {
        Err(format!(
            "{case}: `{}` off by {:+.2}% (bound {}%)",
            worst.0,
            100.0 * worst.1,
            100.0 * tol
        ))
    }
}

#[test]
fn cubic_coulomb_25_s_at_1_khz_within_five_percent() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_cubic_coulomb.dyn");
    let ir = dsl_parser::compile_file(&path).unwrap();
    // The bound is the one docs/method.md states; the doc also quotes the largest error
    // measured here over seeds 31–35 (`simulate` shifts them by `DYNID_SEED_OFFSET`).
    figures::check("docs/method.md", "short_records.cubic_coulomb", 0.2);
    let mut largest = 0.0f64;
    for seed in 31..36 {
        let recs = simulate(&ir, 25.0, 0.0, seed);
        assert_eq!(recs[0].len(), 25_000);
        let id = common::identify_with(&ir, &recs, &IdentifyOptions::instrument_rows())
            .expect("25 s records identify");
        let case = format!("sdof_cubic_coulomb, 3 × 25 s at 1 kHz, seed {seed}");
        largest = largest.max(check(&case, &ir, &id, 0.002).abs());
    }
    if common::seeds_as_documented() {
        figures::check(
            "docs/method.md",
            "short_records.cubic_coulomb.measured",
            100.0 * largest,
        );
    }
}

/// A rig in SI units: 50 kg, 120 N s/m, a 20 kN/m spring and 30 N of dry friction, position
/// and force measured (the velocity is estimated for the friction term).
const RIG: &str = "model rig {
    body m ~ 50.0
    input u on m
    measure m.x, u
    spring k (ground, m) ~ 20000.0
    damper d (ground, m) ~ 120.0
    force friction (ground, m) = r ~ 30.0 * sign(v)
    excite u: lowpass(corner = 200) levels [2000, 8000, 32000]
}";

/// Over seeds: one seed of five (33) is off by −12 % in all four parameters alike (m, k, d,
/// r), a failure of the method on that record rather than spread, so the bound is asserted
/// as a rate. Seeds 32–36 (`DYNID_SEEDS=5`, the suite's form): largest error d −0.89 % on
/// the four that hold; RATE_LONG.
#[test]
fn si_rig_25_s_at_1_khz_within_five_percent() {
    let ir = dsl_parser::compile_str("rig", RIG).unwrap();
    // The bound is the one docs/method.md states (with the failing seed).
    figures::check("docs/method.md", "short_records.si_rig", 2.0);
    // `simulate` shifts each seed by `DYNID_SEED_OFFSET`.
    let n = common::seed_count(5);
    let mut pass = 0;
    // The largest error of the seeds that hold, and the smallest of those that fail.
    let (mut held, mut failed) = (0.0f64, f64::INFINITY);
    for seed in (32..).take(n) {
        let recs = simulate(&ir, 25.0, 0.0, seed);
        let id = common::identify_with(&ir, &recs, &IdentifyOptions::instrument_rows())
            .expect("25 s records identify");
        let case = format!("SI rig, 3 × 25 s at 1 kHz, seed {}", common::seed(seed));
        match within(&case, &ir, &id, 0.02) {
            Ok(e) => {
                pass += 1;
                held = held.max(e.abs());
            }
            Err(e) => {
                println!("FAILS: {e}");
                let worst = common::relative_errors(&case, &ir, &id)
                    .iter()
                    .fold(0.0f64, |a, (_, e)| a.max(e.abs()));
                failed = failed.min(worst);
            }
        }
    }
    println!("SI rig: within 2 % on {pass} of {n} seeds");
    assert!(5 * pass >= 4 * n, "{pass} of {n} seeds");
    if common::seeds_as_documented() && n == 5 {
        let doc = "docs/method.md";
        figures::check(doc, "short_records.si_rig.held", 100.0 * held);
        figures::check(doc, "short_records.si_rig.pass", pass as f64);
        figures::check(doc, "short_records.si_rig.failed", 100.0 * failed);
    }
}

#[test]
fn free_mass_25_s_at_1_khz_within_five_percent() {
    // No spring: the position wanders and rarely crosses its mean, so 25 s hold little
    // information on the slow end; the spread over seeds is wide (one of these three seeds
    // is off by 5–6 % with a standard error of 37 %). Each estimate is checked against its
    // own standard error, the median over the seeds against 5 %.
    let ir = dsl_parser::compile_str(
        "free",
        "model free {
            body m ~ 50.0
            input u on m
            measure m.x, u
            damper d (ground, m) ~ 120.0
            excite u: lowpass(corner = 200) levels [2000, 8000, 32000]
        }",
    )
    .unwrap();
    let values = sim::parameter_values(&ir).unwrap();
    let mut errs: Vec<Vec<f64>> = vec![Vec::new(); 2];
    let mut residual = 0.0f64;
    for seed in [33, 34, 35] {
        let recs = simulate(&ir, 25.0, 0.0, seed);
        let id = common::identify_with(&ir, &recs, &IdentifyOptions::instrument_rows())
            .expect("25 s records identify");
        println!("seed {seed}: largest residual {:.3}", largest_residual(&id));
        residual = residual.max(largest_residual(&id));
        check(
            &format!("free mass, 3 × 25 s at 1 kHz, seed {}", common::seed(seed)),
            &ir,
            &id,
            1.0,
        );
        for (k, &p) in ir.unknowns().iter().enumerate() {
            let est = id.param(&ir.params[p.index()].name).unwrap();
            let truth = values[p.index()];
            assert!(
                (est.value - truth).abs() < 3.0 * est.stderr,
                "seed {seed}: {} = {} ± {}",
                est.name,
                est.value,
                est.stderr
            );
            errs[k].push(((est.value - truth) / truth).abs());
        }
    }
    for e in &mut errs {
        e.sort_by(f64::total_cmp);
        // Seeds 33–39 (`DYNID_SEED_OFFSET=0…4`): m −5.4, −0.8, +0.2, −1.8, +0.3, −1.5, −0.3 %
        // (d alike); the median of each three consecutive seeds at most 1.5 %.
        assert!(e[1] < 0.04, "median error {:.2}%", 100.0 * e[1]);
    }
    // A record that holds little information leaves a large residual at one level without
    // any defect of the model (docs/method.md quotes the largest, section 7).
    if common::seeds_as_documented() {
        figures::check("docs/method.md", "short_records.largest_residual", residual);
    }
}

#[test]
fn too_short_for_the_given_corners_names_corners_that_fit() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_cubic_coulomb.dyn");
    let ir = dsl_parser::compile_file(&path).unwrap();
    let recs = simulate(&ir, 25.0, 0.0, 34);
    let slow = IdentifyOptions {
        corners: Some(vec![0.2, 0.5, 1.0, 2.0, 5.0, 10.0]),
        ..Default::default()
    };
    let err = common::identify_with(&ir, &recs, &slow).unwrap_err();
    let IdentifyError::TooShort { advice, .. } = &err else {
        panic!("expected TooShort, got {err:?}");
    };
    // The advice names corners; they work on this record.
    let list = advice
        .split("--filter-corners ")
        .nth(1)
        .unwrap_or_else(|| panic!("no corners in: {advice}"))
        .trim_end_matches('`');
    let corners: Vec<f64> = list.split(',').map(|c| c.parse().unwrap()).collect();
    let id = common::identify_with(
        &ir,
        &recs,
        &IdentifyOptions {
            corners: Some(corners),
            ..Default::default()
        },
    )
    .expect("the suggested corners fit");
    assert!(id.params.len() >= 3);
}

#[test]
fn a_record_too_short_for_any_corner_says_how_long_it_must_be() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_cubic_coulomb.dyn");
    let ir = dsl_parser::compile_file(&path).unwrap();
    let recs = simulate(&ir, 0.15, 0.0, 35);
    let err = common::identify_with(&ir, &recs, &IdentifyOptions::instrument_rows()).unwrap_err();
    let IdentifyError::TooShort { advice, need, .. } = &err else {
        panic!("expected TooShort, got {err:?}");
    };
    assert!(*need > recs[0].len(), "{need}");
    assert!(advice.contains("record at least"), "{advice}");
}
