//! A five-body structure on a soft mount measured as a shaker test: one accelerometer per body
//! (the language needs the motion of every body measured, so the five-body model needs
//! five) and the force at m4, multisine excitation (0.2–10 Hz, 4 whole periods per record,
//! random phases) at four force levels (RMS 1, 3, 10, 30), a joint between m2 and m3 with a
//! clearance and Coulomb friction (`models/structure5_joint_accel.dyn`; its linear
//! counterpart `models/structure5_linear_accel.dyn`; modes 0.44–7.3 Hz, 1.3–2.9 % damping,
//! Ts = 0.01 s, 200 s per level).
//!
//! What it reaches and what it does not (README, "Accelerometers"):
//!
//! - the linear structure from noiseless accelerations: every mass and stiffness within
//!   0.14 % over seeds 1–5 with the unit-norm rows, 0.6 % with the defaults, positions of
//!   the same records within 1 %
//!   (`linear_structure_from_accelerations_as_from_positions`);
//! - detection from the accelerations and the force, 5 % noise on every channel, names the
//!   joint's element (backlash) and leaves every other element linear on seed 1
//!   (`detection_flags_the_joint`);
//!   over seeds 1–12 the joint on every seed, its pair of effects named on 9 and another
//!   element flagged on none; with the unit-norm rows (`--instrument-rows`) the pair on none
//!   and another element on 5 (`detection_over_seeds`, opt-in);
//! - a lumped model of four bodies still names the joint, from accelerations (the coupling
//!   next to it drifting too) as from positions; of three bodies it does not
//!   (`detection_by_model_size`, opt-in: `DYNID_STRUCTURE_LONG=1`);
//! - `identify` weights each row by its own estimated error on every record of
//!   accelerations: twice as precise as the unit-norm rows from 0.5 % of noise on, a
//!   little less precise below (`accel_rows_from_the_noise_up`);
//! - diagnosis against the linear model names the joint's clearance and friction together
//!   on seed 1 (`joint_from_accelerations`, opt-in); over seeds 1–5 it names that pair on
//!   three, removing 95–108 % of the gap the right model itself reaches, and nothing on
//!   the two where the right model, identified the same way, misses by nearly the linear
//!   model's gap (`diagnosis_over_seeds`, opt-in); the joint's parameters from
//!   accelerations, with the right model, come out tens of per cent low with unit-norm
//!   rows and within 7 % with the defaults (`joint_from_accelerations`, opt-in);
//! - a log sine sweep instead of the multisine: noiseless, every mass and spring within
//!   0.6 %, kb +0.8 %, r +7.5 % (the multisine's within 0.5 %; the unit-norm rows 21–29 %
//!   and 5–11 % low, `joint_from_a_sweep`);
//!   with 5 % noise, by default, masses and springs within 1.6 %, kb 4.5 %, r 10 % over
//!   four seeds (`joint_from_a_noisy_sweep`, opt-in);
//! - with 5 % noise on every channel the unit-norm rows shrink every mass and stiffness
//!   by about half; the weighted solve removes it
//!   (`noise_on_a_structure_needs_the_weighted_step`, opt-in);
//! - the clearance alone, on noiseless records of 1000 s: the right model recovers its
//!   contact stiffness from accelerations as from positions
//!   (`clearance_alone_from_accelerations`, opt-in).

mod common;
mod figures;

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, Grid, Phases, TestSignal};
use dynid::runtime::IdentifyOptions;

/// The multisine of the case: 0.2–10 Hz, 4 periods of 50 s, random phases.
fn multisine() -> TestSignal {
    TestSignal::Multisine {
        f_min_hz: 0.2,
        f_max_hz: 10.0,
        periods: 4,
        grid: Grid::Full,
        phases: Phases::Random,
    }
}

/// The four levels of `ir`, 200 s each at Ts = 0.01 s, `noise` on every channel.
fn records(ir: &ModelIr, noise: f64, seed: u64) -> Vec<Record> {
    let cfg = sim::SimConfig {
        duration: 200.0,
        sample: 0.01,
        seed: common::seed(seed),
        noise,
        noise_on_inputs: true,
        levels: Some(vec![1.0, 3.0, 10.0, 30.0]),
        ..Default::default()
    };
    sim::simulate_signal(ir, &cfg, &multisine())
        .expect("simulation")
        .records
}

/// The masses and stiffnesses of `errs` (the parameters the unit-norm rows weigh well;
/// the dampers of a 1–3 % damped structure carry a few per cent of the force).
fn inertia_and_springs(errs: &[(String, f64)]) -> Vec<(String, f64)> {
    errs.iter()
        .filter(|(n, _)| n.starts_with('m') || n.starts_with('k'))
        .cloned()
        .collect()
}

/// The largest relative error of `errs`' masses and stiffnesses, in %.
fn largest(errs: &[(String, f64)]) -> f64 {
    inertia_and_springs(errs)
        .iter()
        .map(|(_, e)| 100.0 * e.abs())
        .fold(0.0, f64::max)
}

/// The rows `identify` chooses for accelerations (`dynid::runtime::ident::accel_rows`), on the
/// linear structure's four multisine levels of 200 s (seed 1) from noiseless to 5 % noise
/// on every channel: at every noise the defaults weight each row by its own estimated
/// error; from 0.5 % of noise on they beat the unit-norm rows on the masses and
/// stiffnesses by a factor two at least, below it they lose a little (noiseless 0.31 %
/// against 0.05 %, at 0.2 % noise 0.29 against 0.20 %; bound 0.6 %), the price of not
/// shrinking a jointed structure's noiseless records by 5–29 % (`joint_from_a_sweep`). The
/// mean |error| of the masses and stiffnesses at each noise, unit-norm rows and defaults,
/// is the table of docs/method.md §5 ("Rows for accelerations").
#[test]
fn accel_rows_from_the_noise_up() {
    let (acc, _) = common::model_and_source("structure5_linear_accel");
    let mean_abs = |id: &dynid::runtime::ident::Identification, what: &str| {
        let errs = inertia_and_springs(&common::error_row(what, &acc, id));
        100.0 * errs.iter().map(|(_, e)| e.abs()).sum::<f64>() / errs.len() as f64
    };
    // Noise, whether the defaults beat the unit-norm rows, the figures of the unit-norm rows
    // and of the defaults.
    let cases = [
        (0.0, false, "accel.rows.unit.0", "accel.rows.chosen.0"),
        (0.002, false, "accel.rows.unit.0_2", "accel.rows.chosen.0_2"),
        (0.005, true, "accel.rows.unit.0_5", "accel.rows.chosen.0_5"),
        (0.01, true, "accel.rows.unit.1", "accel.rows.chosen.1"),
        (0.05, true, "accel.rows.unit.5", "accel.rows.chosen.5"),
    ];
    let measured: Vec<_> = cases
        .iter()
        .map(|&(noise, ..)| {
            let recs = records(&acc, noise, 1);
            let unit = common::identify_with(&acc, &recs, &IdentifyOptions::instrument_rows())
                .expect("identification");
            let id = common::identify_records(&acc, &recs);
            let (e_unit, e_id) = (
                mean_abs(&unit, &format!("structure5, {noise} noise, unit")),
                mean_abs(&id, &format!("structure5, {noise} noise, defaults")),
            );
            println!("noise {noise}: unit-norm rows {e_unit:.3} %, defaults {e_id:.3} %");
            (id, e_unit, e_id)
        })
        .collect();
    for (&(noise, beats, unit_key, chosen_key), (id, e_unit, e_id)) in cases.iter().zip(measured) {
        assert!(
            id.filter.auto_rows && id.filter.weighted_rows && id.filter.weights_settled,
            "noise {noise}: {:?}",
            id.filter
        );
        if beats {
            assert!(
                e_id < 0.5 * e_unit,
                "noise {noise}: {e_id} against {e_unit}"
            );
        } else {
            assert!(e_id < 0.6, "noise {noise}: {e_id} against {e_unit}");
        }
        if common::seeds_as_documented() {
            const DOC: &str = "docs/method.md";
            figures::check(DOC, unit_key, e_unit);
            figures::check(DOC, chosen_key, e_id);
        }
    }
}

/// The guard on noisy accelerations (5 % on every channel, seed 1, four multisine levels
/// of 200 s): the right model leaves on the shaker's body m4 a residual of several times
/// the input's norm, which the guard read as a missing body; it is what the noise alone
/// leaves there (`EquationResidual::noise`), so no warning. The four-body lumped model of
/// the same records, which does lack a body, is still warned of.
#[test]
fn noisy_accelerations_are_no_missing_body() {
    use dynid::runtime::ident::FitCheck;
    let (acc, _) = common::model_and_source("structure5_linear_accel");
    let recs = records(&acc, 0.05, 1);
    let id = common::identify_records(&acc, &recs);
    let m4 = id.residual.iter().find(|r| r.equation == "m4").expect("m4");
    println!(
        "m4: residual {:?}, noise alone {:?}",
        m4.per_level, m4.noise
    );
    assert!(
        id.fit_warnings
            .iter()
            .all(|w| w.check != FitCheck::LargeResidual),
        "{:?}",
        id.fit_warnings
    );
    let (lumped, _) = common::model_and_source("structure5_lumped4_accel");
    let id = common::identify_records(&lumped, &recs);
    assert!(
        id.fit_warnings
            .iter()
            .any(|w| w.check == FitCheck::LargeResidual),
        "the lumped model: {:?}",
        id.residual
    );
}

/// The linear structure from accelerations against positions, on noiseless records of the
/// same seed (four levels of 200 s): both recover every mass and stiffness. From
/// accelerations this needs the rows freed of the unmeasured ends (`runtime/src/ident/
/// ends.rs`): without, every mass and stiffness came out low, by 6–82 % over seeds 1–5.
/// The unit-norm rows (`--instrument-rows`) carry only that; the defaults, which weight
/// each row of accelerations by its own estimated error (`accel_rows`), lose a little on
/// such friendly records (`accel_rows_from_the_noise_up`).
#[test]
fn linear_structure_from_accelerations_as_from_positions() {
    let (acc, src) = common::model_and_source("structure5_linear_accel");
    let pos = common::measured_otherwise(
        &src,
        "measure m1.a, m2.a, m3.a, m4.a, m5.a, u",
        "measure m1.x, m2.x, m3.x, m4.x, m5.x, u",
    );
    let id_p = common::identify_records(&pos, &records(&pos, 0.0, 1));
    let e_p = common::error_row("structure5 linear, positions", &pos, &id_p);
    let recs = records(&acc, 0.0, 1);
    let id_u = common::identify_with(&acc, &recs, &IdentifyOptions::instrument_rows())
        .expect("identification");
    let e_u = common::error_row(
        "structure5 linear, accelerations, unit-norm rows",
        &acc,
        &id_u,
    );
    let id_a = common::identify_records(&acc, &recs);
    let e_a = common::error_row("structure5 linear, accelerations, defaults", &acc, &id_a);
    // Seeds 1–5 (`DYNID_SEED_OFFSET=0…4 cargo test --test accel_structure linear --
    // --nocapture`), largest error of a mass or stiffness: positions 0.96 % (m4, seed 3),
    // accelerations with the unit-norm rows 0.134 % (k5, seeds 3 and 5; k5 is +0.12 …
    // +0.13 % on every seed, the sampling's share), with the defaults 0.58 % (k1, seed 2;
    // k1 is −0.47 … −0.58 % on four seeds, 1.3–3.6 of its standard errors). Bounds
    // about twice those.
    if common::seeds_as_documented() {
        figures::check("README.md", "accel.structure5.acc.max", largest(&e_u));
        figures::check(
            "README.md",
            "accel.structure5.acc.chosen_max",
            largest(&e_a),
        );
        figures::check("README.md", "accel.structure5.pos.max", largest(&e_p));
    }
    for (n, e) in inertia_and_springs(&e_p) {
        assert!(e.abs() < 0.02, "positions: `{n}` off by {:+.2}%", 100.0 * e);
    }
    for (errs, bound, rows) in [(&e_u, 0.003, "unit-norm rows"), (&e_a, 0.012, "defaults")] {
        for (n, e) in inertia_and_springs(errs) {
            assert!(
                e.abs() < bound,
                "accelerations, {rows}: `{n}` off by {:+.3}%",
                100.0 * e
            );
        }
    }
}

/// The masses and stiffnesses of the linear structure from accelerations, on four
/// multisine levels of `duration` seconds with `noise` (seed 1): their mean relative error
/// and the largest.
fn structure_errors(duration: f64, noise: f64, opts: &IdentifyOptions) -> (f64, f64) {
    let (acc, _) = common::model_and_source("structure5_linear_accel");
    let cfg = sim::SimConfig {
        duration,
        sample: 0.01,
        seed: common::seed(1),
        noise,
        noise_on_inputs: true,
        levels: Some(vec![1.0, 3.0, 10.0, 30.0]),
        ..Default::default()
    };
    let recs = sim::simulate_signal(&acc, &cfg, &multisine())
        .expect("simulation")
        .records;
    let id = common::identify_with(&acc, &recs, opts).expect("identification");
    let rows = match (id.filter.weighted_rows, id.filter.auto_rows) {
        (false, _) => "unit-norm rows",
        (true, false) => "weighted rows",
        (true, true) => "defaults (weighted rows chosen)",
    };
    let errs = common::error_row(
        &format!("structure5, accelerations, {duration} s, noise {noise}, {rows}"),
        &acc,
        &id,
    );
    let mk = inertia_and_springs(&errs);
    let mean = mk.iter().map(|(_, e)| e).sum::<f64>() / mk.len() as f64;
    (mean, largest(&errs))
}

/// Noise on a many-body structure (opt-in, `DYNID_STRUCTURE_LONG=1`, about a minute):
/// noiseless records give the masses and stiffnesses from accelerations within a fraction
/// of a per cent at 200 s and at 1000 s; with 5 % noise on every channel the unit-norm
/// rows shrink every one of them by the same large factor, and the weighted solve
/// (`IdentifyOptions::efficient`) removes it. Seed 1, mean error of the masses and
/// stiffnesses: noiseless, unit-norm rows, +0.04 % at 200 s and +0.03 % at 1000 s (largest
/// 0.12 %); 5 %
/// noise at 1000 s −47 % with the unit-norm rows, −0.35 % with `--weighted-rows` (the
/// two-step solve, largest 0.50 %), −0.03 % (largest 0.17 %) with the defaults, which
/// weight each row by its own estimated error there and iterate the weighting until the
/// estimate settles (`accel_rows`; read once, before: −1.30 %, largest 2.0 %).
///
/// Why: bodies without an input and of unknown mass give equations with a zero right-hand
/// side, `C θ = 0`. Their rows, each scaled to unit norm, weigh the band-pass instruments
/// of all six drivers alike, many of them nearly pure noise, and noise in the entries of
/// `C` pulls the least-squares solution of a homogeneous block towards zero (attenuation,
/// as in errors-in-variables). Weighting the rows by the inverse of their estimated
/// covariance gives the noisy rows the little weight they deserve.
#[test]
fn noise_on_a_structure_needs_the_weighted_step() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let unit = IdentifyOptions::instrument_rows();
    let asked = IdentifyOptions {
        efficient: true,
        ..Default::default()
    };
    let (short, short_max) = structure_errors(200.0, 0.0, &unit);
    let (long, long_max) = structure_errors(1000.0, 0.0, &unit);
    let (noisy, _) = structure_errors(1000.0, 0.05, &unit);
    let (weighted, weighted_max) = structure_errors(1000.0, 0.05, &asked);
    let (chosen, chosen_max) = structure_errors(1000.0, 0.05, &IdentifyOptions::default());
    println!(
        "mean error: 200 s {short:+.4} (largest {short_max:.3} %), 1000 s {long:+.4} \
         (largest {long_max:.3} %), 1000 s noisy {noisy:+.3}, weighted {weighted:+.4} \
         (largest {weighted_max:.2} %), defaults {chosen:+.4} (largest {chosen_max:.2} %)"
    );
    if common::seeds_as_documented() {
        const DOC: &str = "docs/method.md";
        figures::check(DOC, "accel.structure5.bias.short", 100.0 * short);
        figures::check(DOC, "accel.structure5.bias.long", 100.0 * long);
        figures::check(DOC, "accel.structure5.bias.noisy", 100.0 * noisy);
        figures::check(DOC, "accel.structure5.bias.weighted", 100.0 * weighted);
        figures::check(DOC, "accel.structure5.bias.chosen", 100.0 * chosen);
        figures::check(DOC, "accel.structure5.bias.chosen_max", chosen_max);
        figures::check("README.md", "accel.structure5.bias.chosen", 100.0 * chosen);
        figures::check(
            "README.md",
            "accel.structure5.bias.weighted",
            100.0 * weighted,
        );
    }
    assert!(short_max < 0.3 && long_max < 0.3, "{short_max} {long_max}");
    assert!(
        noisy < -0.2,
        "the attenuation this test pins is gone: {noisy}"
    );
    assert!(
        weighted.abs() < 0.01 && weighted_max < 1.5,
        "{weighted} {weighted_max}"
    );
    assert!(
        chosen.abs() < 0.001 && chosen_max < 0.4,
        "{chosen} {chosen_max}"
    );
}

/// The measure line of the structure's models with `a` (accelerometers) read as `x`.
fn by_positions(src: &str) -> String {
    let line = src
        .lines()
        .find(|l| l.trim_start().starts_with("measure "))
        .expect("a measure line");
    src.replace(line, &line.replace(".a,", ".x,"))
}

/// `models/NAME.dyn`, measured by accelerations or (`positions`) by positions, written
/// into `dir`; its path.
fn model_file(dir: &std::path::Path, name: &str, positions: bool) -> std::path::PathBuf {
    let (_, src) = common::model_and_source(name);
    let src = if positions { by_positions(&src) } else { src };
    let path = dir.join(format!("{name}{}.dyn", if positions { "_x" } else { "" }));
    std::fs::write(&path, src).unwrap();
    path
}

/// The joint's structure simulated by `dynid simulate` into `dir/data`: four multisine
/// levels of 200 s, 5 % noise on every channel (seed 1); the level files.
fn joint_levels(dir: &std::path::Path, positions: bool) -> Vec<std::path::PathBuf> {
    let data = if positions { "data_x" } else { "data" };
    simulated_joint(dir, positions, "multisine", 0.05, 1, data)
}

/// The joint's structure (measured by positions where `positions`) simulated by `dynid
/// simulate` into `dir/out`: `signal` (multisine or sweep) over 0.2–10 Hz, four periods
/// in each of the four levels of 200 s, `noise` on every channel, seed `seed`; the level
/// files.
fn simulated_joint(
    dir: &std::path::Path,
    positions: bool,
    signal: &str,
    noise: f64,
    seed: u64,
    out: &str,
) -> Vec<std::path::PathBuf> {
    let model = model_file(dir, "structure5_joint_accel", positions);
    let (seed, noise) = (common::seed(seed).to_string(), noise.to_string());
    common::simulate_levels(
        &model,
        [
            "--signal",
            signal,
            "--band-hz",
            "0.2,10",
            "--periods",
            "4",
            "--duration",
            "200",
            "--noise",
            &noise,
            "--seed",
            &seed,
        ],
        &dir.join(out),
        4,
    )
}

/// `dynid detect` of `model` on `levels`: its verdict line per element, `Element ` and
/// the element's name cut off (`k3/d3 (m2, m3)` → `nonlinear: backlash`).
fn verdicts(model: &std::path::Path, levels: &[std::path::PathBuf]) -> Vec<(String, String)> {
    verdicts_with(model, levels, &[])
}

/// [`verdicts`] of `dynid detect` with `flags`.
fn verdicts_with(
    model: &std::path::Path,
    levels: &[std::path::PathBuf],
    flags: &[&str],
) -> Vec<(String, String)> {
    let out = common::dynid()
        .arg("detect")
        .arg(model)
        .args(levels)
        .args(flags)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("Element "))
        .filter_map(|l| l.split_once("): "))
        .map(|(e, v)| (format!("{e})"), v.to_string()))
        .collect()
}

/// The verdict on `element`; panics naming the verdicts when it has none.
fn verdict<'v>(v: &'v [(String, String)], element: &str) -> &'v str {
    v.iter()
        .find(|(e, _)| e == element)
        .map(|(_, v)| v.as_str())
        .unwrap_or_else(|| panic!("no verdict on {element}: {v:?}"))
}

/// Detection from the accelerations and the force, against the linear model, on four
/// levels of 200 s with 5 % noise on every channel (seed 1), with the defaults (each row
/// weighted by its own estimated error, chosen for records of accelerations) and with the
/// unit-norm rows (`--instrument-rows`); every element but the joint's is linear either
/// way. Weighted, the joint's element is named (`nonlinear: backlash`, Coulomb friction
/// suspected), and the mount's stiffness, which drifts by 4 %, is reported linear as the
/// leak of the joint's pair (identified with the linear model and run through the
/// estimator). At unit norm the joint "drifts, unexplained (best template explains 95 %)":
/// the pair backlash + Coulomb friction explains 95 % but ranks fourth, its five
/// parameters on eight curve points.
#[test]
fn detection_flags_the_joint() {
    let dir = tempfile::tempdir().unwrap();
    let levels = joint_levels(dir.path(), false);
    let model = common::model_path("structure5_linear_accel.dyn");
    let joint = "k3/d3 (m2, m3)";
    for rows in [None, Some("--instrument-rows")] {
        let v = verdicts_with(&model, &levels, rows.as_slice());
        for (e, verdict) in &v {
            println!("structure5, accelerations, {rows:?}: {e}: {verdict}");
        }
        let on_joint = verdict(&v, joint);
        let expected = if rows.is_none() {
            "nonlinear"
        } else {
            "drifts"
        };
        assert!(on_joint.starts_with(expected), "{rows:?}: {on_joint}");
        for e in [
            "k1/d1 (ground, m1)",
            "k2/d2 (m1, m2)",
            "k4/d4 (m3, m4)",
            "k5/d5 (m4, m5)",
            "g2 (ground, m2)",
            "g3 (ground, m3)",
            "g4 (ground, m4)",
            "g5 (ground, m5)",
        ] {
            assert_eq!(verdict(&v, e), "linear", "{rows:?}: {e}");
        }
    }
}

/// Detection of the joint over seeds (opt-in, `DYNID_STRUCTURE_LONG=1`; `DYNID_SEEDS=N` for
/// N seeds from 1, default 12; about five minutes with `--release`): the records of
/// `detection_flags_the_joint` with seeds 1–12, detected with the unit-norm rows
/// (`--instrument-rows`) and with the defaults (each row weighted by its own estimated
/// error, chosen for records of accelerations). What it measured is in docs/detection.md
/// ("Noisy accelerations"), every figure checked here: with either rows the joint is
/// flagged on every seed; at unit norm another element too on 5 seeds and the joint's
/// pair of effects named on none, weighted another element on none and the pair on 9, and the
/// curves of the elements away from the joint scatter about their means as their standard
/// errors allow (χ²/dof about 1). Bounds: the rates measured, less one seed in twelve.
#[test]
fn detection_over_seeds() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    const DOC: &str = "docs/detection.md";
    let dir = tempfile::tempdir().unwrap();
    let model = common::model_path("structure5_linear_accel.dyn");
    let joint = "k3/d3 (m2, m3)";
    // Curves of the elements at m4 and m5 only (k5/d5, g4, g5): no body shared with the
    // joint or with an element next to it.
    let away = ["k5", "d5", "g4", "g5"];
    // `simulated_joint` shifts each seed by `DYNID_SEED_OFFSET`.
    let seeds: Vec<u64> = (1..=common::seed_count(12) as u64).collect();
    let n = seeds.len() as f64;
    // Per rows: joint flagged, nothing else flagged, joint named backlash + Coulomb
    // friction; and the χ²/dof of the curves away from the joint.
    let mut counts = [[0usize; 3]; 2];
    let mut chi2: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    // Per rows: elements reported linear as the leak of another's effect.
    let mut leaks = [0usize; 2];
    for &seed in &seeds {
        let levels = simulated_joint(
            dir.path(),
            false,
            "multisine",
            0.05,
            seed,
            &format!("data_{seed}"),
        );
        for (k, rows) in [Some("--instrument-rows"), None].into_iter().enumerate() {
            let json = dir.path().join(format!("detect_{seed}_{k}.json"));
            let json_arg = json.to_string_lossy().to_string();
            let mut flags = vec!["--json", json_arg.as_str()];
            flags.extend(rows);
            let v = verdicts_with(&model, &levels, &flags);
            let others: Vec<&(String, String)> = v
                .iter()
                .filter(|(e, v)| e != joint && v != "linear")
                .collect();
            let on_joint = verdict(&v, joint);
            println!("seed {seed}, {rows:?}: joint {on_joint}; others {others:?}");
            counts[k][0] += usize::from(on_joint != "linear");
            counts[k][1] += usize::from(others.is_empty());
            counts[k][2] += usize::from(on_joint == "nonlinear: backlash + Coulomb friction");
            let doc: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
            let asked = ["unit_norm", "weighted_for_accelerations"][k];
            assert_eq!(doc["detection"]["rows"], asked, "seed {seed}");
            leaks[k] += doc["detection"]["elements"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|e| e["explained_by"].is_string())
                .count();
            for p in doc["detection"]["params"].as_array().unwrap() {
                let name = p["curve"]["param"].as_str().unwrap();
                if away.contains(&name) {
                    chi2[k].push(p["chi2"].as_f64().unwrap() / p["dof"].as_f64().unwrap());
                }
            }
        }
    }
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    let [d, w] = counts;
    let (chi_d, chi_w) = (mean(&chi2[0]), mean(&chi2[1]));
    println!(
        "over {n} seeds, [joint flagged, nothing else, pair named]: unit-norm rows {d:?}, \
         defaults (weighted) {w:?}; mean χ²/dof away from the joint: unit-norm {chi_d:.2}, \
         defaults {chi_w:.2}; reported as a leak: unit-norm {}, defaults {}",
        leaks[0], leaks[1]
    );
    if common::seeds_as_documented() && seeds.len() == 12 {
        figures::check(DOC, "detect.structure5.unit.joint", d[0] as f64);
        figures::check(DOC, "detect.structure5.unit.clean", d[1] as f64);
        figures::check(DOC, "detect.structure5.unit.pair", d[2] as f64);
        figures::check(DOC, "detect.structure5.weighted.joint", w[0] as f64);
        figures::check(DOC, "detect.structure5.weighted.clean", w[1] as f64);
        figures::check(DOC, "detect.structure5.weighted.pair", w[2] as f64);
        figures::check(DOC, "detect.structure5.unit.leaks", leaks[0] as f64);
        figures::check(DOC, "detect.structure5.weighted.leaks", leaks[1] as f64);
        figures::check(DOC, "detect.structure5.unit.chi2_away", chi_d);
        figures::check(DOC, "detect.structure5.weighted.chi2_away", chi_w);
    }
    let at_least = |count: usize, of_twelve: f64| count as f64 >= (of_twelve - 1.0) / 12.0 * n;
    assert!(
        at_least(d[0], 12.0) && at_least(w[0], 12.0),
        "joint flagged: {d:?} {w:?}"
    );
    assert!(at_least(d[1], 7.0), "unit-norm rows, nothing else: {d:?}");
    assert!(at_least(w[1], 12.0), "defaults, nothing else: {w:?}");
    assert!(at_least(w[2], 9.0), "defaults, the pair named: {w:?}");
    assert!(
        chi_w < 1.5,
        "defaults' curves away from the joint: χ²/dof {chi_w}"
    );
}

/// The study of model size (`DYNID_STRUCTURE_LONG=1 cargo test --test accel_structure --
/// --nocapture`, about a minute): detection of the joint by the five-body model and by
/// lumped models of four and three bodies, from accelerations and, on the same structure
/// and noise, from positions. Seed 1, what it measured (README, "Accelerometers"):
///
/// | model | accelerations (the defaults: rows weighted) | positions |
/// |---|---|---|
/// | 5 bodies | joint: backlash; all else linear (the mount's drift the joint's leak) | joint: backlash; all else linear |
/// | 4 bodies | joint: cubic stiffness + Coulomb friction; the coupling next to it (k2/d2) drifts, unexplained | joint: backlash; all else linear |
/// | 3 bodies | all linear | all linear |
///
/// With the unit-norm rows (`--instrument-rows`, the default before detection chose the
/// weighted rows for accelerations) the four-body model flagged the mount and left the
/// joint linear: its masses collapsed towards zero (m4 0.007 of 1.2).
#[test]
fn detection_by_model_size() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let joint = "k3/d3 (m2, m3)";
    for positions in [false, true] {
        let levels = joint_levels(dir.path(), positions);
        let signals = if positions {
            "positions"
        } else {
            "accelerations"
        };
        for (bodies, name) in [
            (5, "structure5_linear_accel"),
            (4, "structure5_lumped4_accel"),
            (3, "structure5_lumped3_accel"),
        ] {
            let v = verdicts(&model_file(dir.path(), name, positions), &levels);
            let flagged: Vec<String> = v
                .iter()
                .filter(|(_, v)| v != "linear")
                .map(|(e, v)| format!("{e}: {v}"))
                .collect();
            println!("{bodies} bodies, {signals}: {flagged:?}");
            let named = verdict(&v, joint) != "linear";
            // What seed 1 gives (the table above); a change means the README's study needs
            // its verdicts again.
            let expected = bodies > 3;
            assert_eq!(named, expected, "{bodies} bodies, {signals}: {v:?}");
            // The four-body model from accelerations: one false flag beside the joint (the
            // table above).
            if bodies > 3 {
                let flags = if positions || bodies == 5 { 1 } else { 2 };
                assert_eq!(
                    flagged.len(),
                    flags,
                    "{bodies} bodies, {signals}: {flagged:?}"
                );
            }
        }
    }
}

/// `dynid identify` of the joint's model on `levels` with `flags`: the relative errors of
/// the contact stiffness kb and the friction r (truth 300 and 0.2).
fn joint_errors(levels: &[std::path::PathBuf], flags: &[&str]) -> (f64, f64) {
    let errs = all_errors(levels, flags);
    let error = |name: &str| errs.iter().find(|(n, _)| n == name).map(|(_, e)| *e);
    let (kb, r) = (
        error("kb").expect("kb is estimated"),
        error("r").expect("r is estimated"),
    );
    println!(
        "joint from accelerations {flags:?}: kb {:+.1} %, r {:+.1} %",
        100.0 * kb,
        100.0 * r
    );
    (kb, r)
}

/// Identification of the joint with the right model, and diagnosis against the linear one,
/// from the accelerations of `detection_flags_the_joint` (opt-in,
/// `DYNID_STRUCTURE_LONG=1`). Seed 1: diagnosis names Coulomb friction at the joint
/// (m2, m3). Identification with the right model and the unit-norm rows
/// (`--instrument-rows`) gives the contact stiffness kb −46 % and the friction r −44 % off
/// (the shrinkage of `noise_on_a_structure_needs_the_weighted_step`, pinned as measured);
/// with the defaults, which weight each row by its own estimated error on these records,
/// kb −2.5 % and r −2.6 % (the weighting iterated until it settles; read once, before:
/// kb −6.2 %, r −5.2 %); with `--weighted-rows` (the covariance shrunk halfway, two-step)
/// kb −4.6 % and r −0.6 %. Bounds about twice those.
#[test]
fn joint_from_accelerations() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let levels = joint_levels(dir.path(), false);
    let (kb, r) = joint_errors(&levels, &["--instrument-rows"]);
    let (kb_w, r_w) = joint_errors(&levels, &["--weighted-rows"]);
    let (kb_d, r_d) = joint_errors(&levels, &[]);
    if common::seeds_as_documented() {
        figures::check("README.md", "accel.structure5.joint.kb", 100.0 * kb);
        figures::check("README.md", "accel.structure5.joint.r", 100.0 * r);
        figures::check(
            "README.md",
            "accel.structure5.joint.kb_weighted",
            100.0 * kb_w,
        );
        figures::check(
            "README.md",
            "accel.structure5.joint.r_weighted",
            100.0 * r_w,
        );
        figures::check(
            "README.md",
            "accel.structure5.joint.kb_default",
            100.0 * kb_d,
        );
        figures::check("README.md", "accel.structure5.joint.r_default", 100.0 * r_d);
    }
    assert!(kb < -0.2 && r < -0.2, "kb {kb:+.3}, r {r:+.3}");
    assert!(
        kb_w.abs() < 0.1 && r_w.abs() < 0.04,
        "kb {kb_w:+.3}, r {r_w:+.3}"
    );
    assert!(
        kb_d.abs() < 0.06 && r_d.abs() < 0.06,
        "kb {kb_d:+.3}, r {r_d:+.3}"
    );
    let out = common::dynid()
        .arg("diagnose")
        .arg(common::model_path("structure5_linear_accel.dyn"))
        .args(&levels)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let named = stdout
        .lines()
        .find(|l| l.starts_with("Most likely missing effect:"))
        .unwrap_or_else(|| panic!("no verdict:\n{stdout}"));
    println!("{named}");
    assert!(named.contains("(m2, m3)"), "{named}");
}

/// Diagnosis of the jointed structure from its accelerations against the linear model over
/// seeds 1–5 (opt-in, `DYNID_STRUCTURE_LONG=1`; `DYNID_SEEDS=N` for N seeds; about 2 min in
/// release). What the corrected model can reach is the right model's own gap identified
/// the same way (`structure5_joint_accel.dyn` diagnosed on the same records: its
/// re-identified withheld gap), so the share of that reach it removes is
/// `(nominal − corrected) / (nominal − right)`. Measured: the pair of clearance and
/// friction at (m2, m3) on seeds 1, 4 and 5 (kb 307–316, gap 0.035–0.037, r 0.190–0.214;
/// truth 300, 0.03, 0.2), removing 99, 108 and 95 % of that reach (nominal 30–32 %,
/// corrected 15–21 %); nothing on seeds 2 and 3, where the right model itself misses by
/// 28.3 and 26.6 % against the linear model's nominal 32.1 and 30.5 % — less than the
/// acceptance margin (20 % of the gap) could ever accept. Against the right model at its
/// exact values (5.7–5.9 %, the noise) the found pairs remove 43–61 % of the gap: the
/// parameters identified from the accelerations miss the lightly damped modes' peaks.
/// Asserted: no effect anywhere but the joint; where the right model's reach is one the
/// search can accept, the joint named and 80 % of that reach removed.
#[test]
fn diagnosis_over_seeds() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let linear = common::model_path("structure5_linear_accel.dyn");
    let right = common::model_path("structure5_joint_accel.dyn");
    let (mut reachable, mut named) = (0, 0);
    for seed in 1..=common::seed_count(5) as u64 {
        let levels = simulated_joint(
            dir.path(),
            false,
            "multisine",
            0.05,
            seed,
            &format!("diagnosis{seed}"),
        );
        let (d, _) = common::run_json("diagnose", &linear, &levels);
        let floor = common::run_json("diagnose", &right, &levels).0["gap_reidentified"]
            .as_f64()
            .unwrap_or(f64::INFINITY);
        let nominal = d["gap_before"].as_f64().unwrap();
        let found: Vec<(String, String)> = d["found"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| {
                let node = |k: &str| f["location"][k].as_str().unwrap_or("").to_string();
                let at = format!("({}, {})", node("a"), node("b"));
                (f["effect"]["kind"].as_str().unwrap_or("").to_string(), at)
            })
            .collect();
        let corrected = d["gap_after"].as_f64().unwrap_or(f64::INFINITY);
        let share = (nominal - corrected) / (nominal - floor);
        let outcome = if found.is_empty() {
            "nothing found".to_string()
        } else {
            format!("corrected {corrected:.1} % (share of the reach {share:.2}); found {found:?}")
        };
        println!(
            "seed {seed}: nominal {nominal:.1} %, right model re-identified {floor:.1} %, {outcome}"
        );
        assert!(
            found.iter().all(|(_, at)| at == "(m2, m3)"),
            "seed {seed}: {found:?}"
        );
        // The acceptance margins: 20 % of the gap and 1 percentage point.
        if nominal - floor > (0.2 * nominal).max(1.0) {
            reachable += 1;
            assert!(!found.is_empty(), "seed {seed}: nothing found");
            assert!(share >= 0.8, "seed {seed}: share {share:.2}");
        }
        named += usize::from(!found.is_empty());
    }
    println!("joint named on {named}, reachable on {reachable}");
    if common::seeds_as_documented() && common::seed_count(5) == 5 {
        figures::check(
            "docs/diagnosis.md",
            "diagnose.structure5.named",
            named as f64,
        );
        figures::check(
            "docs/diagnosis.md",
            "diagnose.structure5.reachable",
            reachable as f64,
        );
    }
}

/// The joint's structure driven by a log sine sweep (0.2–10 Hz, four sweeps per 200 s
/// record, the four force amplitudes 1, 3, 10, 30) with `noise` on every channel, seed
/// `seed`, in `dir/sweep`; the level files.
fn sweep_levels(dir: &std::path::Path, noise: f64, seed: u64) -> Vec<std::path::PathBuf> {
    simulated_joint(dir, false, "sweep", noise, seed, "sweep")
}

/// `dynid identify` of the joint's model on `levels` with `flags`: the relative error of
/// every mass, spring, the contact stiffness and the friction, by name, against the values
/// the model simulates with.
fn all_errors(levels: &[std::path::PathBuf], flags: &[&str]) -> Vec<(String, f64)> {
    let (ir, _) = common::model_and_source("structure5_joint_accel");
    let values = sim::parameter_values(&ir).unwrap();
    let truth: Vec<(&str, f64)> = [
        "m2", "m3", "m4", "m5", "k1", "k2", "k3", "k4", "k5", "kb", "r",
    ]
    .into_iter()
    .map(|name| {
        let p = ir.params.iter().position(|p| p.name == name).unwrap();
        (name, values[p])
    })
    .collect();
    let out = common::dynid()
        .arg("identify")
        .arg(common::model_path("structure5_joint_accel.dyn"))
        .args(levels)
        .args(flags)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    truth
        .iter()
        .map(|&(name, t)| {
            (
                name.to_string(),
                common::table_value(&stdout, name) / t - 1.0,
            )
        })
        .collect()
}

/// The joint from a sine sweep's accelerations, noiseless, with the defaults (each row
/// weighted by its own estimated error, iterated), beside the multisine's noiseless records
/// in the same run. A sweep excites every line of its period, below its band too; there the
/// contact's and the friction's folded content swamped the small quasi-static displacement,
/// and every mass, spring and the joint came out 59–91 % low until the integration kept the
/// lines below a quarter of the lowest mode only where they stand out of the folded level
/// (`runtime/src/ident/integrate.rs`). The unit-norm rows (`--instrument-rows`, printed)
/// still leave every mass and spring 21–29 % low from the sweep and 5–11 % from the
/// multisine: the joint's relative motion integrated from the accelerations is poor at the
/// lowest level, where it mostly sticks, and the equations of the bodies without a force
/// shrink together to absorb it. Measured with the defaults: the sweep's masses and springs
/// within 0.6 %, kb +0.8 %, r +7.5 %; the multisine's within 0.5 %, kb +0.4 %, r +0.1 %.
/// Bounds 1.5 %, 2.5 % and 15 % (sweep), 1 %, 1 % and 3 % (multisine). With 5 % noise see
/// `joint_from_a_noisy_sweep` (opt-in).
#[test]
fn joint_from_a_sweep() {
    let dir = tempfile::tempdir().unwrap();
    for (signal, bounds) in [
        ("sweep", (0.015, 0.025, 0.15)),
        ("multisine", (0.01, 0.01, 0.03)),
    ] {
        let levels = simulated_joint(dir.path(), false, signal, 0.0, 1, signal);
        let unit = all_errors(&levels, &["--instrument-rows"]);
        println!("joint from a noiseless {signal}, unit-norm rows: {unit:.4?}");
        let errs = all_errors(&levels, &[]);
        println!("joint from a noiseless {signal}, defaults: {errs:.4?}");
        for (name, e) in &errs {
            let bound = match name.as_str() {
                "r" => bounds.2,
                "kb" => bounds.1,
                _ => bounds.0,
            };
            assert!(e.abs() < bound, "{signal}: {name} {e:+.4}: {errs:.4?}");
        }
    }
}

/// The same sweep with 5 % noise on every channel, seeds 1–4 (opt-in,
/// `DYNID_STRUCTURE_LONG=1`), with the defaults (the rows each weighted by its own
/// estimated error, the weighting re-estimated until the estimate settles). Measured:
/// masses and springs within 1.6 %, kb within 4.5 %, r +4.6 … +10 % (bounds 4 %, 12 %,
/// 25 %). With the two-step weighting alone (before the iteration) every mass and spring
/// came out 10–29 % low together: the joint's relative motion integrated from the
/// accelerations is poor at the lowest level, where the joint mostly sticks, the equations
/// of the bodies without a force shrink together to absorb it, and weights read at that
/// shrunk first estimate kept much of it. `--weighted-rows` (the covariance shrunk halfway,
/// two-step) is printed beside them: 5–34 % low.
#[test]
fn joint_from_a_noisy_sweep() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    for seed in 1..=4 {
        let dir = tempfile::tempdir().unwrap();
        let levels = sweep_levels(dir.path(), 0.05, seed);
        let halfway = all_errors(&levels, &["--weighted-rows"]);
        println!("joint from a noisy sweep, seed {seed}, --weighted-rows: {halfway:.4?}");
        let errs = all_errors(&levels, &[]);
        println!("joint from a noisy sweep, seed {seed}, defaults: {errs:.4?}");
        for (name, e) in &errs {
            let bound = match name.as_str() {
                "r" => 0.25,
                "kb" => 0.12,
                _ => 0.04,
            };
            assert!(e.abs() < bound, "seed {seed}, {name} {e:+.4}: {errs:.4?}");
        }
    }
}

/// The joint with its clearance alone (no friction), noiseless multisine records of 1000 s
/// (opt-in, `DYNID_STRUCTURE_LONG=1`): positions and accelerations (the joint's
/// displacement integrated over whole periods) both recover the contact stiffness. Seed 1:
/// positions kb −0.02 %, accelerations kb +0.23 % with the defaults (each row weighted by
/// its own estimated error; −0.09 % with the unit-norm rows, measured before the defaults
/// weighted noiseless records). The defaults' masses and stiffnesses are +0.23 … +0.56 %
/// off, the mount's k1 −0.53 %, at standard errors of 0.004–0.03 %: on a record without noise the weighted rows carry a
/// small systematic error that their standard errors, which stand for noise, do not cover
/// (docs/method.md §2, "Rows for accelerations"). The accelerations needed the lines far
/// below the excited band left out of the integration: the contact's kinks fold down from
/// above the Nyquist frequency into them, and divided by `ω²` they gave the joint's
/// displacement an error of 14–25 times its RMS (kb −87 %, every mass 60–72 % low,
/// before).
#[test]
fn clearance_alone_from_accelerations() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let (_, src) = common::model_and_source("structure5_joint_accel");
    let src = src.replace(" + r ~ 0.2 * sign(v)", "");
    let acc = dynid::dsl_parser::compile_str("clearance.dyn", &src).unwrap();
    let pos = common::measured_otherwise(
        &src,
        "measure m1.a, m2.a, m3.a, m4.a, m5.a, u",
        "measure m1.x, m2.x, m3.x, m4.x, m5.x, u",
    );
    let fit = |ir: &ModelIr, what: &str| {
        let cfg = sim::SimConfig {
            duration: 1000.0,
            sample: 0.01,
            seed: common::seed(1),
            levels: Some(vec![1.0, 3.0, 10.0, 30.0]),
            ..Default::default()
        };
        let recs = sim::simulate_signal(ir, &cfg, &multisine())
            .expect("simulation")
            .records;
        let id = common::identify_records(ir, &recs);
        common::error_row(what, ir, &id)
    };
    let kb = |e: &[(String, f64)]| e.iter().find(|(n, _)| n == "kb").expect("kb").1;
    let e_p = fit(&pos, "clearance alone, positions");
    let e_a = fit(&acc, "clearance alone, accelerations");
    if common::seeds_as_documented() {
        const DOC: &str = "docs/method.md";
        figures::check(DOC, "accel.structure5.clearance.pos.kb", 100.0 * kb(&e_p));
        figures::check(DOC, "accel.structure5.clearance.acc.kb", 100.0 * kb(&e_a));
    }
    assert!(kb(&e_p).abs() < 0.02, "positions: kb {:+.4}", kb(&e_p));
    assert!(kb(&e_a).abs() < 0.005, "accelerations: kb {:+.4}", kb(&e_a));
    // The friction alone, from accelerations: seed 1, masses and stiffnesses −0.63 …
    // +0.51 % with the defaults (−0.85 … +0.42 % with the unit-norm rows, measured before
    // the defaults weighted noiseless records; bound about three times the largest).
    let (_, joint) = common::model_and_source("structure5_joint_accel");
    let friction = joint.replace("kb ~ 300 * deadzone(s, 0.03) + ", "");
    assert_ne!(friction, joint);
    let friction = dynid::dsl_parser::compile_str("friction.dyn", &friction).unwrap();
    for (n, e) in fit(&friction, "friction alone, accelerations") {
        if n.starts_with('m') || n.starts_with('k') {
            assert!(
                e.abs() < 0.02,
                "friction alone: `{n}` off by {:+.2}%",
                100.0 * e
            );
        }
    }
}

/// The modes the structure's model files state: undamped 0.44–7.3 Hz, and 1.3–2.9 % of
/// critical damping in each, the dampers being Rayleigh's `C = 0.15 M + 0.0012 K` (so
/// `ζ = 0.15 / 2ω + 0.0012 ω / 2` exactly).
#[test]
fn the_structure_has_the_modes_its_model_states() {
    let (ir, _) = common::model_and_source("structure5_linear_accel");
    let values = sim::parameter_values(&ir).unwrap();
    let p = |name: &str| {
        let i = ir.params.iter().position(|q| q.name == name).unwrap();
        values[i]
    };
    let m: Vec<f64> = ir
        .bodies
        .iter()
        .map(|b| b.mass.scale * b.mass.param.map_or(1.0, |q| values[q.index()]))
        .collect();
    let k: Vec<f64> = (1..=5).map(|i| p(&format!("k{i}"))).collect();
    // The dampers are Rayleigh's: couplings 0.0012·k, ground 0.15·m (+ 0.0012·k1 at m1).
    for i in 0..5 {
        let ground = if i == 0 { 0.15 * m[0] } else { 0.0 };
        assert!((p(&format!("d{}", i + 1)) - 0.0012 * k[i] - ground).abs() < 1e-12);
        if i > 0 {
            assert!((p(&format!("g{}", i + 1)) - 0.15 * m[i]).abs() < 1e-12);
        }
    }
    // M^-1/2 K M^-1/2 of the chain from the ground, its eigenvalues by Jacobi rotations.
    let mut a = [[0.0; 5]; 5];
    for i in 0..5 {
        a[i][i] += k[i];
        if i > 0 {
            a[i - 1][i - 1] += k[i];
            a[i - 1][i] -= k[i];
            a[i][i - 1] -= k[i];
        }
    }
    for (i, row) in a.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v /= (m[i] * m[j]).sqrt();
        }
    }
    for _ in 0..50 {
        for p in 0..5 {
            for q in p + 1..5 {
                if a[p][q].abs() < 1e-300 {
                    continue;
                }
                let th = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = th.signum() / (th.abs() + (th * th + 1.0).sqrt());
                let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
                for row in a.iter_mut() {
                    let (x, y) = (row[p], row[q]);
                    row[p] = c * x - s * y;
                    row[q] = s * x + c * y;
                }
                let (rp, rq) = (a[p], a[q]);
                a[p] = std::array::from_fn(|j| c * rp[j] - s * rq[j]);
                a[q] = std::array::from_fn(|j| s * rp[j] + c * rq[j]);
            }
        }
    }
    let mut w: Vec<f64> = (0..5).map(|i| a[i][i].sqrt()).collect();
    w.sort_by(f64::total_cmp);
    let hz: Vec<f64> = w.iter().map(|w| w / std::f64::consts::TAU).collect();
    let zeta: Vec<f64> = w
        .iter()
        .map(|w| 0.15 / (2.0 * w) + 0.0012 * w / 2.0)
        .collect();
    println!("modes {hz:.3?} Hz, damping {zeta:.4?}");
    assert!(
        (hz[0] - 0.44).abs() < 0.005 && (hz[4] - 7.3).abs() < 0.05,
        "{hz:?}"
    );
    assert!(hz[4] / hz[0] > 10.0, "{hz:?}");
    let (lo, hi) = zeta
        .iter()
        .fold((1.0f64, 0.0f64), |(l, h), &z| (l.min(z), h.max(z)));
    assert!(
        (lo - 0.013).abs() < 0.0005 && (hi - 0.029).abs() < 0.0005,
        "{zeta:?}"
    );
}
