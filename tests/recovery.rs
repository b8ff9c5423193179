//! Recovery of known parameters from data of the project's own simulator (fixed seeds).
//!
//! Each case parses a model from `models/`, simulates its excitation levels in memory with
//! `runtime::sim`, identifies the unknown parameters from the records and compares them with
//! the nominal values the simulation used. The bounds are what the covariance method achieves
//! on these records, not aspirations: about 2–3 times the largest error over five seeds, the
//! test's own and the four after it (`for o in 0 1 2 3 4; do DYNID_SEED_OFFSET=$o cargo test
//! --test recovery -- --nocapture; done` prints the table).

mod common;

use dynid::dsl_parser::{self, ir::ModelIr};
use std::path::Path;

fn model(name: &str) -> ModelIr {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("models/{name}.dyn"));
    dsl_parser::compile_file(&path).unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

fn model_str(name: &str, text: &str) -> ModelIr {
    dsl_parser::compile_str(name, text).unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

fn assert_within(case: &str, errs: &[(String, f64)], tol: f64) {
    for (n, e) in errs {
        assert!(
            e.abs() < tol,
            "{case}: `{n}` off by {:+.3}% (bound {}%)",
            100.0 * e,
            100.0 * tol
        );
    }
}

#[test]
fn sdof_cubic_coulomb_noise_free_within_one_percent() {
    let ir = model("sdof_cubic_coulomb");
    let recs = common::simulate(&ir, 2000.0, 0.0, 11);
    let id = common::identify_records(&ir, &recs);
    assert!(id.unidentifiable.is_empty(), "{:?}", id.unidentifiable);
    let e = common::error_row("sdof_cubic_coulomb, noise 0 %", &ir, &id);
    // Seeds 11–15 (`DYNID_SEED_OFFSET=0…4`): largest errors d −0.13 %, r −0.14 %, the
    // simulated input's path between samples (docs/method.md §3), not noise: with a smooth
    // input drawn on a finer grid every error is within its standard errors
    // (`sim::input_path_tests` in the runtime).
    assert_within("sdof_cubic_coulomb noise-free", &e, 0.004);
}

#[test]
fn sdof_cubic_coulomb_five_percent_noise_within_two_percent() {
    // Noise of 5 % of each signal's std on position, velocity and input alike.
    let ir = model("sdof_cubic_coulomb");
    let recs = common::simulate(&ir, 2000.0, 0.05, 12);
    let id = common::identify_records(&ir, &recs);
    let e = common::error_row("sdof_cubic_coulomb, noise 5 %", &ir, &id);
    // Seeds 12–16 (`DYNID_SEED_OFFSET=0…4`): largest errors r +0.77 %, d −0.46 %.
    assert_within("sdof_cubic_coulomb 5 % noise", &e, 0.02);
}

#[test]
fn two_mass_within_two_percent() {
    let ir = model("two_mass");
    let recs = common::simulate(&ir, 2000.0, 0.0, 13);
    let id = common::identify_records(&ir, &recs);
    let e = common::error_row("two_mass, noise 0 %", &ir, &id);
    // Seeds 13–17 (`DYNID_SEED_OFFSET=0…4`): largest error r −0.11 %.
    assert_within("two_mass", &e, 0.003);
}

/// Parameters of the backlash-with-preload element `n4` of chain4: `k4 s + b4 dz(s, g) +
/// f4 sign(s)` is nearly collinear (beyond the gap `dz(s, g) = s − g sign(s)`), so the three
/// are determined only as well as the displacement spends time inside the 0.05 gap. The
/// identification reports this through large standard errors (2000 s per level, seeds 14–18,
/// `DYNID_SEED_OFFSET=0…4`: errors up to +8.2 / −12.4 / −12.1 % with standard errors of
/// 2.5–10 / 4–16 / 4–15 %; 6000 s per level did not tighten them), so their errors are
/// bounded by the reported standard errors.
const CHAIN4_WEAK: [&str; 3] = ["k4", "b4", "f4"];

/// The dampers and frictions of chain4: over seeds 14–18 errors up to 2.1 % (r1), 2.0 %
/// (d1), 1.8 % (d2, q2), 1.3 % (r3); the other dampers (d3, d4), the springs and the cubic
/// terms stay within 0.25 %.
const CHAIN4_DISSIPATIVE: [&str; 5] = ["d1", "d2", "r1", "q2", "r3"];

/// Seconds per level for chain4.
const CHAIN4_DURATION: f64 = 2000.0;

#[test]
fn chain4_within_measured_bounds() {
    let ir = model("chain4");
    let recs = common::simulate(&ir, CHAIN4_DURATION, 0.0, 14);
    let id = common::identify_records(&ir, &recs);
    let e = common::error_row("chain4, noise 0 %", &ir, &id);
    let (weak, strong): (Vec<_>, Vec<_>) = e
        .into_iter()
        .partition(|(n, _)| CHAIN4_WEAK.contains(&n.as_str()));
    let (dissipative, stiff): (Vec<_>, Vec<_>) = strong
        .into_iter()
        .partition(|(n, _)| CHAIN4_DISSIPATIVE.contains(&n.as_str()));
    assert_within("chain4", &dissipative, 0.05);
    assert_within("chain4", &stiff, 0.005);
    for (n, err) in weak {
        let p = id.param(&n).unwrap();
        let rel_se = p.stderr / p.value.abs();
        assert!(
            err.abs() < 3.0 * rel_se && err.abs() < 0.25,
            "chain4: `{n}` off by {:+.2}% with a standard error of {:.2}%",
            100.0 * err,
            100.0 * rel_se
        );
    }
}

#[test]
fn duffing_from_positions_and_input_only_within_one_percent() {
    // The velocity is declared unmeasured, so it is absent from the records: the damping
    // moves onto the filters and accelerations come from positions alone.
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_duffing.dyn"),
    )
    .unwrap();
    let src = src.replace("input u on m\n", "input u on m\n    measure m.x, u\n");
    let ir = model_str("sdof_duffing_positions", &src);
    let recs = common::simulate(&ir, 2000.0, 0.0, 15);
    assert!(recs.iter().all(|r| r.column("m.v").is_none()));
    let id = common::identify_records(&ir, &recs);
    let e = common::error_row("sdof_duffing, x and u only, noise 0 %", &ir, &id);
    // Seeds 15–19 (`DYNID_SEED_OFFSET=0…4`): largest errors k3 −0.11 %, d −0.10 %.
    assert_within("sdof_duffing from positions", &e, 0.003);
}

#[test]
fn unexcited_term_is_named_and_gets_no_value() {
    // A dead-zone gap far larger than any displacement: the term is identically zero.
    let ir = model_str(
        "sdof_gap",
        "model sdof_gap {
            body m = 1.0
            input u on m
            spring k (ground, m) ~ 4.0
            damper d (ground, m) ~ 0.4
            force nl (ground, m) = k3 ~ 2.0 * s^3 + kgap ~ 1.0 * deadzone(s, 1000)
            excite u: lowpass(corner = 10) levels [6, 15, 40]
        }",
    );
    let recs = common::simulate(&ir, 500.0, 0.0, 16);
    let id = common::identify_records(&ir, &recs);
    assert!(id.param("kgap").is_none(), "{:?}", id.params);
    let u = id
        .unidentifiable
        .iter()
        .find(|u| u.name == "kgap")
        .unwrap_or_else(|| panic!("kgap not reported: {:?}", id.unidentifiable));
    assert!(u.reason.contains("never excited"), "{}", u.reason);
    for name in ["d", "k", "k3"] {
        assert!(id.param(name).is_some(), "{name} missing");
    }
}
