//! A constant force (`force off (ground, m) = f0 ~ -0.5`) end to end on simulated data
//! (fixed seeds): the simulator applies it, identification recovers it from the mean it
//! puts into the data, data without a mean name it unidentifiable, and detection and
//! diagnosis take an offset for what it is, not for a nonlinearity.
//!
//! The bounds are about 2–3 times what the method achieves over five seeds, the test's own
//! and the four after it: `for o in 0 1 2 3 4; do DYNID_SEED_OFFSET=$o cargo test --test
//! constant_force -- --nocapture; done` prints the errors.

mod common;
mod figures;

use dynid::dsl_parser::{self, ir::ModelIr};
use dynid::runtime::data::LevelSource;
use dynid::runtime::detect::{self, DetectOptions, Verdict};
use dynid::runtime::diagnose::{self, DiagnoseOptions};
use dynid::runtime::IdentifyOptions;
use std::path::Path;

fn model(name: &str) -> ModelIr {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("models/{name}.dyn"));
    dsl_parser::compile_file(&path).unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

/// `models/sdof_linear.dyn` with a constant force `f0 ~ -0.5`.
fn linear_offset() -> ModelIr {
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/sdof_linear.dyn"),
    )
    .unwrap();
    let src = src.replace(
        "    excite",
        "    force off (ground, m) = f0 ~ -0.5\n    excite",
    );
    dsl_parser::compile_str("sdof_linear_offset", &src).expect("valid model")
}

/// Every error within `default`, or the bound `tol` names for the parameter.
fn assert_within(case: &str, errs: &[(String, f64)], default: f64, tol: &[(&str, f64)]) {
    for (n, e) in errs {
        let bound = tol.iter().find(|(m, _)| m == n).map_or(default, |t| t.1);
        assert!(
            e.abs() < bound,
            "{case}: `{n}` off by {:+.3}% (bound {}%)",
            100.0 * e,
            100.0 * bound
        );
    }
}

#[test]
fn simulated_offset_shifts_the_mean_position() {
    // m ẍ + d ẋ + k x + r sign(ẋ) + f0 = u with zero-mean u: ⟨x⟩ = −f0 / k = 0.125.
    let ir = model("sdof_offset");
    let recs = common::simulate(&ir, 500.0, 0.0, 21);
    for (i, r) in recs.iter().enumerate() {
        // The louder the level, the more the mean of 500 s wanders (seeds 21–25: 0.12–0.14
        // at level 1, 0.04–0.13 at level 3), so the mean is compared with its own standard
        // error from ten batches of 50 s, each far longer than the 5 s decay time 2m/d.
        let x = r.column("m.x").unwrap();
        let batch: Vec<f64> = x
            .chunks(x.len() / 10)
            .take(10)
            .map(|c| c.iter().sum::<f64>() / c.len() as f64)
            .collect();
        let mean = batch.iter().sum::<f64>() / 10.0;
        let se = (batch.iter().map(|b| (b - mean).powi(2)).sum::<f64>() / 90.0).sqrt();
        let z = (mean - 0.125) / se;
        println!(
            "level {}: mean m.x = {mean:.4} ± {se:.4} ({z:+.2} errors)",
            i + 1
        );
        // Seeds 21–25 (`DYNID_SEED_OFFSET=0…4`): |z| at most 2.4 (t with 9 degrees of freedom).
        assert!(z.abs() < 4.0, "level {}: {mean} ± {se}", i + 1);
    }
}

#[test]
fn sdof_offset_noise_free() {
    let ir = model("sdof_offset");
    let recs = common::simulate(&ir, 2000.0, 0.0, 22);
    let id = common::identify_records(&ir, &recs);
    assert!(id.unidentifiable.is_empty(), "{:?}", id.unidentifiable);
    let e = common::error_row("sdof_offset, noise 0 %", &ir, &id);
    // Seeds 22–26 (`DYNID_SEED_OFFSET=0…4`): d, r up to −0.18, −0.21 %; k −0.03 %, f0 +0.03 %.
    // The bound of f0 is the one docs/language.md states.
    let f0 = f0_bound("constant_force.f0.noise_free");
    assert_within(
        "sdof_offset noise-free",
        &e,
        0.005,
        &[("k", 0.001), ("f0", f0)],
    );
    // The identified equation writes the offset as its value alone.
    let eq = dynid::runtime::ident::print::format_equations(&ir, &id);
    assert!(
        eq.contains("sign(m.v) - 0.5") && eq.trim_end().ends_with(") = u"),
        "{eq}"
    );
}

#[test]
fn sdof_offset_five_percent_noise() {
    let ir = model("sdof_offset");
    let recs = common::simulate(&ir, 2000.0, 0.05, 23);
    let id = common::identify_records(&ir, &recs);
    let e = common::error_row("sdof_offset, noise 5 %", &ir, &id);
    // Seeds 23–27 (`DYNID_SEED_OFFSET=0…4`): r up to +0.76 %, d −0.40 %, f0 −0.14 %.
    // The bound of f0 is the one docs/language.md states.
    let f0 = f0_bound("constant_force.f0.noise_5");
    assert_within("sdof_offset 5 % noise", &e, 0.015, &[("f0", f0)]);
}

/// The relative bound on f0 that docs/language.md states (a percentage there), checked to
/// be the one this test was measured for.
fn f0_bound(name: &str) -> f64 {
    let want = match name {
        "constant_force.f0.noise_free" => 0.1,
        _ => 0.4,
    };
    figures::check("docs/language.md", name, want);
    want / 100.0
}

#[test]
fn data_without_a_mean_name_the_offset_unidentifiable() {
    let ir = model("sdof_offset");
    let recs = common::centred(&common::simulate(&ir, 2000.0, 0.0, 22));
    let id = common::identify_records(&ir, &recs);
    assert!(id.param("f0").is_none(), "{:?}", id.params);
    let u = id
        .unidentifiable
        .iter()
        .find(|u| u.name == "f0")
        .unwrap_or_else(|| panic!("f0 not reported: {:?}", id.unidentifiable));
    assert!(
        u.reason
            .contains("a constant force needs data whose mean is not zero"),
        "{}",
        u.reason
    );
    for name in ["k", "d", "r"] {
        assert!(id.param(name).is_some(), "{name} missing: {id:#?}");
    }
}

#[test]
fn zero_offset_in_the_data_is_estimated_near_zero_not_removed() {
    // The model has an offset, the simulated system none: the data still have means (of
    // x and u, over a finite record), so f0 is estimated — close to zero, flagged as not
    // significant or within a few standard errors of zero — and never dropped: "not
    // significant" is not "unidentifiable".
    let ir = model("sdof_offset");
    let truth = ir.with_nominals(&[4.0, 0.4, 0.3, 0.0]);
    let recs = common::simulate(&truth, 2000.0, 0.0, 24);
    let id = common::identify_records(&ir, &recs);
    println!("{:?}\n{:?}", id.params, id.unidentifiable);
    assert!(id.unidentifiable.is_empty(), "{:?}", id.unidentifiable);
    let f0 = id.param("f0").expect("f0 estimated");
    assert!(
        f0.value.abs() < 3.0 * f0.stderr.max(1e-3),
        "f0 = {} ± {}",
        f0.value,
        f0.stderr
    );
}

#[test]
fn detection_takes_an_offset_for_linear() {
    let ir = linear_offset();
    let recs = common::simulate(&ir, 1000.0, 0.0, 25);
    let srcs = common::sources(&ir, &recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let (d, _) = detect::detect_from_data(
        &ir,
        &levels,
        &IdentifyOptions::default(),
        &DetectOptions::default(),
        &[],
    )
    .expect("detect");
    println!("{}", d.render_table());
    assert!(!d.elements.is_empty());
    for e in &d.elements {
        assert_eq!(e.verdict, Verdict::Linear, "{}: {}", e.element, e.verdict);
    }
    // The offset is held at its pooled estimate in the per-level fits, not given a curve.
    assert!(d.params.iter().all(|p| p.curve.param != "f0"));
    let f0 = d.held.iter().find(|h| h.param == "f0").expect("f0 held");
    // Seeds 25–29 (`DYNID_SEED_OFFSET=0…4`): f0 = −0.50010 … −0.50040.
    assert!((f0.value + 0.5).abs() < 0.001, "{f0:?}");
}

#[test]
fn diagnosis_of_a_matching_offset_model_adds_nothing() {
    let ir = linear_offset();
    let recs = common::simulate(&ir, 300.0, 0.0, 26);
    let origins: Vec<String> = (1..=recs.len()).map(|k| format!("level{k}")).collect();
    let d = diagnose::diagnose(
        &ir,
        &recs,
        &origins,
        &DiagnoseOptions::default(),
        &|_, _| {},
    )
    .expect("diagnoses");
    println!("{}", d.summary());
    assert!(d.found.is_empty(), "{}", d.summary());
    assert_eq!(d.verdict, diagnose::Verdict::Consistent, "{}", d.summary());
}
