//! Nonlinear terms of bodies measured only by accelerometers: the Duffing oscillator's
//! `k3·s³` and the two-mass friction `r·sign(v)` read displacement and velocity integrated
//! from the accelerations (`runtime/src/ident/integrate.rs`), beside the same models
//! measured by positions on records of the same seed, 5 % noise on every channel (inputs
//! included), three levels of 1000 s at Ts = 0.01 s.
//!
//! Bounds are about twice the largest error over five seeds, the test's own and the four
//! after it: `DYNID_SEEDS=5 cargo test --test accel_nonlinear -- --nocapture` prints one
//! row per case and seed (the table of docs/method.md, "Accelerations instead of
//! positions", comes from it); the suite runs the first seed of each case. The long form
//! also runs detection of the friction over seeds 1–6
//! (`friction_detection_over_seeds_from_accelerations_and_positions`).

mod common;
mod figures;

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::ident::Identification;
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, Grid, Phases, TestSignal};

/// Random data (the model's form filter and levels) or a multisine of the same input RMS
/// (1.34 / 3.35 / 8.94) over 0.02–1.6 Hz, 4 periods of 250 s, random phases.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Data {
    Random,
    Multisine,
}

fn records(ir: &ModelIr, data: Data, seed: u64) -> Vec<Record> {
    let cfg = |levels: Option<Vec<f64>>| sim::SimConfig {
        duration: 1000.0,
        sample: 0.01,
        seed: common::seed(seed),
        noise: 0.05,
        noise_on_inputs: true,
        levels,
        ..Default::default()
    };
    let out = match data {
        Data::Random => sim::simulate(ir, &cfg(None)),
        Data::Multisine => sim::simulate_signal(
            ir,
            &cfg(Some(vec![1.34, 3.35, 8.94])),
            &TestSignal::Multisine {
                f_min_hz: 0.02,
                f_max_hz: 1.6,
                periods: 4,
                grid: Grid::Full,
                phases: Phases::Random,
            },
        ),
    };
    out.expect("simulation").records
}

/// The report of the integrated signals: `signals` integrated from `from`, every level
/// exactly over whole periods (multisine) or band-limited with a corner below `below`.
fn assert_reported(id: &Identification, signals: &[(&str, &str)], data: Data, below: f64) {
    for (s, from) in signals {
        let e = id
            .estimated
            .iter()
            .find(|e| e.signal == *s)
            .unwrap_or_else(|| panic!("`{s}` not reported as estimated: {:?}", id.estimated));
        assert_eq!(e.from, *from);
        match data {
            Data::Multisine => {
                // The lowest level is periodic; at the highest the hardening spring's
                // response may not repeat exactly (seed 73), and that level falls back to
                // the band-limited integration.
                assert!(e.method.contains("whole periods"), "{}", e.method);
                // The lowest line kept at the lowest level: none below the multisine's
                // lowest (0.02 Hz), and lines below the mode (2 rad/s) where they stand out
                // of the noise (0.377 rad/s on the suite's seed).
                let lowest = 2.0 * std::f64::consts::PI * 0.02;
                assert!(
                    e.cutoff[0] >= lowest * (1.0 - 1e-9) && e.cutoff[0] < 2.0,
                    "{:?}",
                    e.cutoff
                );
            }
            Data::Random => {
                assert!(e.method.contains("band-limited"), "{}", e.method);
                assert!(
                    e.cutoff.iter().all(|&c| c > 0.0 && c < below),
                    "corners {:?} not below {below} rad/s",
                    e.cutoff
                );
            }
        }
    }
}

/// Relative errors by parameter.
type Errors = Vec<(String, f64)>;

/// Keep in `worst` the largest error (by size, with its sign) of each parameter of `errs`.
fn keep_largest(worst: &mut Errors, errs: &Errors) {
    for (n, e) in errs {
        match worst.iter_mut().find(|(m, _)| m == n) {
            Some((_, w)) if e.abs() > w.abs() => *w = *e,
            Some(_) => {}
            None => worst.push((n.clone(), *e)),
        }
    }
}

/// The long form's row of the table of docs/method.md ("Accelerations instead of
/// positions"): run on the five seeds it was measured on (`DYNID_SEEDS=5`), each largest
/// error (%) is the doc's figure to its last digit. `keys`: per parameter, the figures from
/// accelerations and from positions.
fn check_table_row(acc: &Errors, pos: &Errors, keys: &[(&str, &str, &str)]) {
    if common::seed_count(1) != 5 || !common::seeds_as_documented() {
        return;
    }
    for (param, from_acc, from_pos) in keys {
        for (worst, key) in [(acc, from_acc), (pos, from_pos)] {
            let e = worst
                .iter()
                .find(|(n, _)| n == param)
                .unwrap_or_else(|| panic!("no error of {param}"))
                .1;
            figures::check("docs/method.md", key, 100.0 * e);
        }
    }
}

/// Identify the case from accelerations and from positions on the same seed; the rows
/// printed, the errors returned (accelerations, positions).
fn case(
    name: &str,
    data: Data,
    seed: u64,
    measure: (&str, &str),
) -> (Identification, Errors, Errors) {
    let (acc, src) = common::model_and_source(name);
    let pos = common::measured_otherwise(&src, measure.0, measure.1);
    let id_a = common::identify_records(&acc, &records(&acc, data, seed));
    let e_a = common::error_row(&format!("{name}, {data:?}, accelerations"), &acc, &id_a);
    let id_p = common::identify_records(&pos, &records(&pos, data, seed));
    let e_p = common::error_row(&format!("{name}, {data:?}, positions"), &pos, &id_p);
    (id_a, e_a, e_p)
}

#[test]
fn duffing_from_accelerations_random() {
    let (mut worst_a, mut worst_p) = (Errors::new(), Errors::new());
    // k3 from accelerations, every seed's error.
    let mut k3_acc = Vec::new();
    for seed in common::seeds_from(61) {
        let (id, e_a, e_p) = case(
            "sdof_duffing_accel",
            Data::Random,
            seed,
            ("measure m.a, u", "measure m.x, u"),
        );
        // The lowest mode is at 2 rad/s: the corner a quarter of it.
        assert_reported(&id, &[("m.x", "m.a")], Data::Random, 1.0);
        // Seeds 61–65 (the rows weighted, as `identify` chooses for 5 % noise on
        // accelerations), largest errors: accelerations k +0.54 %, d −0.63 %, k3 +4.3 % (k3
        // high on every seed, mean +2.5 %); positions k +1.36 %, d +1.84 %, k3 −2.4 %.
        common::assert_within(
            "duffing accelerations, random",
            &e_a,
            &[("k", 0.012), ("d", 0.015), ("k3", 0.09)],
        );
        common::assert_within(
            "duffing positions, random",
            &e_p,
            &[("k", 0.03), ("d", 0.04), ("k3", 0.05)],
        );
        k3_acc.extend(e_a.iter().filter(|(n, _)| n == "k3").map(|(_, e)| *e));
        keep_largest(&mut worst_a, &e_a);
        keep_largest(&mut worst_p, &e_p);
    }
    check_table_row(
        &worst_a,
        &worst_p,
        &[
            ("k", "accel.table.random.acc.k", "accel.table.random.pos.k"),
            ("d", "accel.table.random.acc.d", "accel.table.random.pos.d"),
            (
                "k3",
                "accel.table.random.acc.k3",
                "accel.table.random.pos.k3",
            ),
        ],
    );
    // The long form: k3 high on every seed, by a mean the doc quotes.
    if common::seed_count(1) == 5 && common::seeds_as_documented() {
        assert!(k3_acc.iter().all(|e| *e > 0.0), "{k3_acc:?}");
        let mean = k3_acc.iter().sum::<f64>() / k3_acc.len() as f64;
        figures::check("docs/method.md", "accel.random.k3_mean", 100.0 * mean);
    }
}

#[test]
fn duffing_from_accelerations_multisine() {
    let (mut worst_a, mut worst_p) = (Errors::new(), Errors::new());
    for seed in common::seeds_from(71) {
        let (id, e_a, e_p) = case(
            "sdof_duffing_accel",
            Data::Multisine,
            seed,
            ("measure m.a, u", "measure m.x, u"),
        );
        assert_reported(&id, &[("m.x", "m.a")], Data::Multisine, 0.0);
        // Seeds 71–75 (rows weighted, the weighting iterated until it settles), largest
        // errors: accelerations k +0.43 %, d +0.71 %, k3 +0.80 % (weights read once:
        // k3 +0.43 %; with unit-norm rows k +1.02 %, d +2.3 %, k3 −2.2 %: the rows freed
        // of the record's ends cost the lowest-corner rows' information, which the weights
        // give back); positions k +0.17 %, d −0.74 %, k3 −0.50 %.
        common::assert_within(
            "duffing accelerations, multisine",
            &e_a,
            &[("k", 0.01), ("d", 0.015), ("k3", 0.016)],
        );
        common::assert_within(
            "duffing positions, multisine",
            &e_p,
            &[("k", 0.005), ("d", 0.02), ("k3", 0.012)],
        );
        keep_largest(&mut worst_a, &e_a);
        keep_largest(&mut worst_p, &e_p);
    }
    check_table_row(
        &worst_a,
        &worst_p,
        &[
            (
                "k",
                "accel.table.multisine.acc.k",
                "accel.table.multisine.pos.k",
            ),
            (
                "d",
                "accel.table.multisine.acc.d",
                "accel.table.multisine.pos.d",
            ),
            (
                "k3",
                "accel.table.multisine.acc.k3",
                "accel.table.multisine.pos.k3",
            ),
        ],
    );
}

#[test]
fn friction_between_two_accelerometers_random() {
    let (mut worst_a, mut worst_p) = (Errors::new(), Errors::new());
    for seed in common::seeds_from(81) {
        let (id, e_a, e_p) = case(
            "two_mass_friction_accel",
            Data::Random,
            seed,
            ("measure m1.a, m2.a, u", "measure m1.x, m2.x, u"),
        );
        // The lowest mode is at 0.88 rad/s.
        assert_reported(
            &id,
            &[("m1.v", "m1.a"), ("m2.v", "m2.a")],
            Data::Random,
            0.5,
        );
        // Seeds 81–85 (rows weighted), largest errors: accelerations m2 +0.37 %, k1
        // −0.44 %, d1 −1.2 %, k2 −0.44 %, d2 −2.5 %, r +1.5 %; positions m2 −0.52 %, k1
        // −0.47 %, d1 −2.3 %, k2 −0.84 %, d2 −3.7 %, r +3.2 %.
        let acc = [
            ("m2", 0.008),
            ("k1", 0.009),
            ("d1", 0.025),
            ("k2", 0.009),
            ("d2", 0.05),
            ("r", 0.03),
        ];
        let pos = [
            ("m2", 0.012),
            ("k1", 0.01),
            ("d1", 0.05),
            ("k2", 0.02),
            ("d2", 0.075),
            ("r", 0.065),
        ];
        common::assert_within("two_mass_friction accelerations", &e_a, &acc);
        common::assert_within("two_mass_friction positions", &e_p, &pos);
        keep_largest(&mut worst_a, &e_a);
        keep_largest(&mut worst_p, &e_p);
    }
    check_table_row(
        &worst_a,
        &worst_p,
        &[
            (
                "m2",
                "accel.table.friction.acc.m2",
                "accel.table.friction.pos.m2",
            ),
            (
                "k1",
                "accel.table.friction.acc.k1",
                "accel.table.friction.pos.k1",
            ),
            (
                "d1",
                "accel.table.friction.acc.d1",
                "accel.table.friction.pos.d1",
            ),
            (
                "k2",
                "accel.table.friction.acc.k2",
                "accel.table.friction.pos.k2",
            ),
            (
                "d2",
                "accel.table.friction.acc.d2",
                "accel.table.friction.pos.d2",
            ),
            (
                "r",
                "accel.table.friction.acc.r",
                "accel.table.friction.pos.r",
            ),
        ],
    );
}

/// Three levels of `truth` (300 s, 5 % noise, `seed`) written by `dynid simulate` into
/// `out`.
fn friction_levels(
    truth: &std::path::Path,
    out: &std::path::Path,
    seed: u64,
) -> Vec<std::path::PathBuf> {
    common::simulate_levels(
        truth,
        [
            "--duration",
            "300",
            "--noise",
            "0.05",
            "--seed",
            &seed.to_string(),
        ],
        out,
        3,
    )
}

/// The standard output of `dynid command model levels…`, which must succeed.
fn run_ok(command: &str, model: &std::path::Path, levels: &[std::path::PathBuf]) -> String {
    let out = common::dynid()
        .arg(command)
        .arg(model)
        .args(levels)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    String::from_utf8_lossy(&out.stdout).to_string()
}

/// Detection from accelerometers alone: the two-mass structure with friction at its
/// coupling, measured by `m1.a`, `m2.a` and the force (5 % noise, three levels of 300 s,
/// seed 3), checked against the linear model: the coupling is named Coulomb friction, the
/// ground element linear; diagnosis names the friction at (m1, m2) as the most likely
/// missing effect (on these records r_fix = 0.298 ± 0.003, the withheld gap 159 % → 1.6 %,
/// the figures of docs/method.md).
#[test]
fn detect_and_diagnose_name_the_friction_between_two_accelerometers() {
    let dir = tempfile::tempdir().unwrap();
    let levels = friction_levels(
        &common::model_path("two_mass_friction_accel.dyn"),
        &dir.path().join("data"),
        3,
    );
    let stdout = run_ok(
        "detect",
        &common::model_path("two_mass_linear_accel.dyn"),
        &levels,
    );
    assert!(
        stdout.contains("Element k2/d2 (m1, m2): nonlinear: Coulomb friction"),
        "{stdout}"
    );
    assert!(
        stdout.contains("Element k1/d1 (ground, m1): linear"),
        "{stdout}"
    );
    let json = dir.path().join("diagnose.json");
    let out = common::dynid()
        .arg("diagnose")
        .arg(common::model_path("two_mass_linear_accel.dyn"))
        .args(&levels)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("Most likely missing effect: Coulomb friction sign(v) at (m1, m2)"),
        "{stdout}"
    );
    // docs/method.md ("Accelerations instead of positions") quotes the friction found and
    // the withheld gaps, to their last digit (fixed seed).
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let found = &v["found"][0];
    let doc = "docs/method.md";
    figures::check(doc, "accel.diagnose.r", found["value"].as_f64().unwrap());
    figures::check(
        doc,
        "accel.diagnose.r_stderr",
        found["stderr"].as_f64().unwrap(),
    );
    figures::check(
        doc,
        "accel.diagnose.gap_before",
        v["gap_before"].as_f64().unwrap(),
    );
    figures::check(
        doc,
        "accel.diagnose.gap_after",
        v["gap_after"].as_f64().unwrap(),
    );
}

/// The linear model fitted to the friction records (`identify`, the model lacks the
/// friction the data show; 300 s, 5 % noise, seed 2): the rows chosen for accelerations
/// re-estimate their weights at each new estimate, and on these records that drove the
/// unforced body's equation onto its trivial solution — m2, k2 and d2 at 1e-11, the
/// iteration "settled" there (seeds 1–6 all did, measured with the CLI). The iteration now
/// stops where an estimate loses nine tenths of a mass the unit-norm rows found
/// significant and keeps the two-step estimate (m2 0.77–1.13 over seeds 1–6, truth 2: a
/// model without the friction, which the guard's warnings say), and the report says why.
#[test]
fn weighting_does_not_collapse_a_model_without_the_friction() {
    let dir = tempfile::tempdir().unwrap();
    let levels = friction_levels(
        &common::model_path("two_mass_friction_accel.dyn"),
        &dir.path().join("data"),
        2,
    );
    let stdout = run_ok(
        "identify",
        &common::model_path("two_mass_linear_accel.dyn"),
        &levels,
    );
    assert!(
        stdout.contains("re-estimated, they drove a parameter to zero"),
        "{stdout}"
    );
    for (name, floor) in [("m2", 0.5), ("k2", 0.5), ("d2", 0.05)] {
        assert!(
            common::table_value(&stdout, name) > floor,
            "{name} collapsed:\n{stdout}"
        );
    }
    assert!(
        stdout.contains("the model lacks a force the data show"),
        "{stdout}"
    );
}

/// Detection from accelerometers on seed 2 of those records (5 % noise, three levels of
/// 300 s), where each level's linear fit holds m2 at 1.03 (truth 2; rows weighted, the
/// default for accelerations) and makes the ground element drift: the coupling's friction,
/// run through the estimator from the model identified with it, predicts that drift, so
/// the coupling is named Coulomb friction and the ground element reported linear as the
/// friction's leak. Before the runs started from the identified model, the coupling
/// drifted unexplained here and the ground element was flagged. r = 0.313 ± 0.002 (truth
/// 0.3; a screening value whose standard error does not cover its error); over seeds 1–6
/// r = 0.298–0.313 (measured once with the CLI), so the bound is ±10 %.
#[test]
fn the_ground_element_drift_is_the_friction_leak() {
    let dir = tempfile::tempdir().unwrap();
    let levels = friction_levels(
        &common::model_path("two_mass_friction_accel.dyn"),
        &dir.path().join("data"),
        common::seed(2),
    );
    let (v, _) = common::run_json(
        "detect",
        &common::model_path("two_mass_linear_accel.dyn"),
        &levels,
    );
    let element = |name: &str| {
        v["detection"]["elements"]
            .as_array()
            .and_then(|a| a.iter().find(|e| e["element"] == name))
            .unwrap_or_else(|| panic!("no element {name} in {v}"))
            .clone()
    };
    let (coupling, ground) = (element("k2/d2 (m1, m2)"), element("k1/d1 (ground, m1)"));
    assert_eq!(
        coupling["verdict"]["Nonlinear"]["best"], "Coulomb friction",
        "{coupling}"
    );
    let (r, _) = common::verdict_coefficient(&coupling, "Coulomb friction");
    assert!((r / 0.3 - 1.0).abs() < 0.1, "r = {r}");
    assert_eq!(ground["verdict"], "Linear", "{ground}");
    let why = ground["explained_by"].as_str().unwrap_or_default();
    assert!(
        why.contains("the leak that Coulomb friction at k2/d2 (m1, m2) predicts"),
        "{ground}"
    );
}

/// Diagnosis of a clearance between two accelerometers (`models/two_mass_backlash_accel.dyn`:
/// a contact stiffness kb = 6 beyond ±0.5 of relative travel; 5 % noise, three levels of
/// 100 s, seed 1) against the linear model. The backlash's gaps are searched on multiples
/// of the spread of the relative displacement, here integrated from the two accelerations;
/// before, a body measured by its acceleration alone had no backlash candidate, and a cubic
/// stiffness stood in for the clearance (withheld gap 27.9 % → 13.1 % on the 300 s records
/// of seed 1, against 2.9 % with the backlash; measured once with the CLI). Seeds 1–5
/// (CLI, measured once): the backlash named at (m1, m2) on all five, kb −3.8 … +4.9 %,
/// the gap +3 … +23 % (the integration's high-pass takes the slowest part of the
/// relative motion), the withheld gap 13–31 % of the nominal one; on seed 2 a cubic
/// stiffness came first, insignificant once the backlash joined it. Seed 1: kb = 6.01, gap
/// 0.518, withheld gap 44.2 % → 7.9 %. Bounds about twice the seeds' spread.
#[test]
fn diagnose_names_a_clearance_between_two_accelerometers() {
    let (v, stdout) = clearance_diagnosis(1);
    let found = v["found"].as_array().unwrap_or_else(|| panic!("{v}"));
    let backlash = found
        .iter()
        .find(|f| f["effect"]["kind"] == "backlash")
        .unwrap_or_else(|| panic!("no backlash found:\n{stdout}"));
    assert_eq!(backlash["location"]["a"], "m1", "{stdout}");
    assert_eq!(backlash["location"]["b"], "m2", "{stdout}");
    let kb = backlash["value"].as_f64().unwrap();
    let gap = backlash["effect"]["gap"].as_f64().unwrap();
    assert!((kb / 6.0 - 1.0).abs() < 0.1, "kb = {kb}\n{stdout}");
    assert!(gap > 0.45 && gap < 0.75, "gap = {gap}\n{stdout}");
    let (before, after) = (
        v["gap_before"].as_f64().unwrap(),
        v["gap_after"].as_f64().unwrap(),
    );
    assert!(after < 0.4 * before, "{before} → {after}\n{stdout}");
}

/// `dynid diagnose` of the linear two-mass model on records of
/// `models/two_mass_backlash_accel.dyn` (5 % noise, three levels of 100 s, `seed`): the
/// JSON and the standard output.
fn clearance_diagnosis(seed: u64) -> (serde_json::Value, String) {
    let dir = tempfile::tempdir().unwrap();
    let seed = common::seed(seed).to_string();
    let levels = common::simulate_levels(
        &common::model_path("two_mass_backlash_accel.dyn"),
        [
            "--duration",
            "100",
            "--noise",
            "0.05",
            "--seed",
            seed.as_str(),
        ],
        &dir.path().join("data"),
        3,
    );
    common::run_json(
        "diagnose",
        &common::model_path("two_mass_linear_accel.dyn"),
        &levels,
    )
}

/// Seed 2 of those records: the greedy search finds a cubic stiffness first and the
/// backlash on top, and the corrected model, which holds both, leaves the cubic at
/// −0.045 ± 0.023 (|p|/σ = 2.0). The report says so in a note; on any seed, a found
/// effect that is not significant in the corrected model is one a note names.
#[test]
fn a_first_effect_left_insignificant_is_said() {
    let (v, stdout) = clearance_diagnosis(2);
    let notes: Vec<&str> = v["notes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n.as_str())
        .collect();
    let insignificant = "is not significant in the corrected model";
    if common::seeds_as_documented() {
        assert!(
            notes
                .iter()
                .any(|n| n.starts_with("cubic stiffness s^3 at (m1, m2)")
                    && n.contains(insignificant)),
            "{stdout}"
        );
    }
    // On any seed: one note for each found effect the corrected model leaves within
    // t_min = 4 standard errors of zero (the default of `DiagnoseOptions`).
    let left = v["found"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["value"].as_f64().unwrap().abs() <= 4.0 * f["stderr"].as_f64().unwrap())
        .count();
    let said = notes.iter().filter(|n| n.contains(insignificant)).count();
    assert_eq!(left, said, "{stdout}");
}

/// Detection of the friction between two accelerometers over seeds 1–6 (with the long form,
/// any `DYNID_SEEDS` of 2 or more; 20 s in release), beside positions of the same kind of record
/// (the same model measured by `m1.x`, `m2.x`): 5 % noise, three levels of 300 s. From
/// either kind of record the coupling is named Coulomb friction on all six and the ground
/// element left linear (docs/detection.md, "Noisy accelerations", which quotes these counts;
/// seed 3 is the README's and
/// `detect_and_diagnose_name_the_friction_between_two_accelerometers`'s). From
/// accelerations that takes the estimator's runs from the model identified with each
/// candidate (before: named on four, the ground element flagged on four); at most one seed
/// of six may miss, or flag the ground, on other seeds (`DYNID_SEED_OFFSET`).
#[test]
fn friction_detection_over_seeds_from_accelerations_and_positions() {
    if common::seed_count(1) < 2 {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let models = |name: &str| -> (std::path::PathBuf, std::path::PathBuf) {
        let src = std::fs::read_to_string(common::model_path(&format!("{name}.dyn"))).unwrap();
        let pos = src.replace("measure m1.a, m2.a, u", "measure m1.x, m2.x, u");
        assert_ne!(pos, src);
        let path = dir.path().join(format!("{name}_pos.dyn"));
        std::fs::write(&path, pos).unwrap();
        (common::model_path(&format!("{name}.dyn")), path)
    };
    let (truth_acc, truth_pos) = models("two_mass_friction_accel");
    let (lin_acc, lin_pos) = models("two_mass_linear_accel");
    // Per kind of record: [coupling flagged, coupling named Coulomb friction, ground flagged].
    let mut counts = [[0usize; 3]; 2];
    for seed in 1..=6u64 {
        for (k, (truth, lin)) in [(&truth_acc, &lin_acc), (&truth_pos, &lin_pos)]
            .into_iter()
            .enumerate()
        {
            let out = dir.path().join(format!("s{seed}_{k}"));
            let stdout = run_ok(
                "detect",
                lin,
                &friction_levels(truth, &out, common::seed(seed)),
            );
            let verdict = |element: &str| {
                stdout
                    .lines()
                    .find_map(|l| l.strip_prefix(&format!("Element {element}: ")))
                    .unwrap_or_else(|| panic!("no verdict for {element}:\n{stdout}"))
                    .to_string()
            };
            let (coupling, ground) = (verdict("k2/d2 (m1, m2)"), verdict("k1/d1 (ground, m1)"));
            println!(
                "seed {seed}, {}: coupling {coupling}; ground {ground}",
                ["accelerations", "positions"][k]
            );
            counts[k][0] += usize::from(coupling != "linear");
            counts[k][1] += usize::from(coupling == "nonlinear: Coulomb friction");
            counts[k][2] += usize::from(ground != "linear");
        }
    }
    println!("[coupling flagged, named friction, ground flagged]: {counts:?}");
    if common::seeds_as_documented() {
        const DOC: &str = "docs/detection.md";
        let keys = [
            [
                "detect.two_mass_friction.acc.coupling",
                "detect.two_mass_friction.acc.named",
                "detect.two_mass_friction.acc.ground",
            ],
            [
                "detect.two_mass_friction.pos.coupling",
                "detect.two_mass_friction.pos.named",
                "detect.two_mass_friction.pos.ground",
            ],
        ];
        for (kind, count) in keys.iter().zip(&counts) {
            for (key, n) in kind.iter().zip(count) {
                figures::check(DOC, key, *n as f64);
            }
        }
    }
    assert_eq!(counts[1], [6, 6, 0], "positions");
    assert!(
        counts[0][0] == 6 && counts[0][1] >= 5 && counts[0][2] <= 1,
        "accelerations: {:?}",
        counts[0]
    );
}
