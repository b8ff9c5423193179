//! A constant force the model leaves out: the servo axis of `models/servo_axis.dyn` (a
//! 50 kg carriage with viscous and Coulomb friction under a PD position controller
//! following a random set point at three levels, positions from a 1 µm encoder, the
//! controller running ten times per recorded sample) with a constant force of −3.2 N on
//! the carriage, as a rig with an amplifier's bias or a cable has. The data come from that
//! axis; the models given lack the constant force, or the constant force and the Coulomb
//! friction.
//!
//! Most tests use the random set point; the planned moves of `servo_axis_planned.dyn`, with
//! their rests left out of the moments, are diagnosed through the command line by
//! `planned_axis_workflow_names_a_withheld_offset_friction_or_both` (the README's
//! walkthrough).
//!
//! Scored as the diagnosis scores (free runs that close the loop on the recorded set
//! point, one level withheld at a time): the share of the attainable shrink is
//! `(re-identified − corrected) / (re-identified − true model)`, the true model's own
//! withheld gap being the floor that the controller's content between samples leaves.
//!
//! Measured over four seeds each (`for o in 0 1 2 3; do DYNID_SEED_OFFSET=$o cargo test
//! --test servo_offset -- --nocapture; done`):
//! - offset withheld: the constant force named on every seed, −3.126, −3.179, −3.185,
//!   −3.157 N (truth −3.2), 100 % of the attainable shrink on each (re-identified
//!   9.1–38.7 % → corrected 0.47–0.66 %, the true model's gap);
//! - offset and Coulomb friction withheld: both named on seeds 2–5 (constant force −3.179,
//!   −3.185, −3.157, −3.205 N, friction 14.878, 15.048, 14.962, 14.929 N for 15); on seeds
//!   3 and 4 neither term alone is significant at the first step (|p|/σ 1.9 and 1.7: each
//!   leaves the other's bias), and the pair step of the search adds them together;
//! - detect, the model without the constant force: −3.205, −3.203, −3.200, −3.201 N;
//! - identify (one record), the guard's probe: −3.15, −3.19, −3.25, −3.23 N.

mod common;
mod figures;

use dynid::dsl_parser::{self, ir::ModelIr};
use dynid::runtime::diagnose::{self, DiagnoseOptions, Diagnosis};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, SimConfig};

/// The rig's constant force, as the language writes it (`force off (ground, m) = f0`).
const OFFSET: f64 = -3.2;

/// The source of `models/FILE` with `lines` added before `excite`, without the lines that
/// start with one of `drop`.
fn edited_source(file: &str, lines: &[&str], drop: &[&str]) -> String {
    let src = std::fs::read_to_string(common::model_path(file)).unwrap();
    let mut out = String::new();
    for l in src.lines() {
        if drop.iter().any(|d| l.trim_start().starts_with(d)) {
            continue;
        }
        if l.trim_start().starts_with("excite") {
            for x in lines {
                out.push_str(&format!("    {x}\n"));
            }
        }
        out.push_str(l);
        out.push('\n');
    }
    out
}

/// `models/servo_axis.dyn` edited as [`edited_source`] does, compiled as `name`.
fn axis(name: &str, lines: &[&str], drop: &[&str]) -> ModelIr {
    let out = edited_source("servo_axis.dyn", lines, drop);
    dsl_parser::compile_str(name, &out).unwrap_or_else(|e| panic!("{name}: {e:?}\n{out}"))
}

fn truth() -> ModelIr {
    axis(
        "servo_axis_offset",
        &[&format!("force off (ground, m) = f0 ~ {OFFSET:?}")],
        &[],
    )
}

/// Three levels (the moves at 0.5, 1 and 1.5 times their speed), 25 s each, at `seed`.
fn records(seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration: 25.0,
        sample: 1e-3,
        seed: common::seed(seed),
        burn_in: 2.0,
        input_oversample: 10,
        quantise: Some(1e-6),
        ..SimConfig::default()
    };
    sim::simulate(&truth(), &cfg)
        .expect("closed-loop simulation")
        .records
}

fn run(ir: &ModelIr, recs: &[Record]) -> Diagnosis {
    let origins: Vec<String> = (1..=recs.len()).map(|k| format!("level{k}")).collect();
    diagnose::diagnose(ir, recs, &origins, &DiagnoseOptions::default(), &|_, _| {})
        .expect("diagnoses")
}

/// The share of the attainable shrink the corrected model of `d` reaches, with `floor` the
/// true model's withheld (re-identified) gap on the same data.
fn share(d: &Diagnosis, floor: f64) -> f64 {
    (d.gap_reidentified - d.gap_after) / (d.gap_reidentified - floor)
}

#[test]
fn diagnose_names_a_withheld_constant_force_with_its_size() {
    let recs = records(1);
    let floor = run(&truth(), &recs).gap_reidentified;
    let d = run(&axis("servo_axis_no_offset", &[], &[]), &recs);
    let text = d.summary();
    println!("{text}");
    assert_eq!(d.found.len(), 1, "{text}");
    let f = &d.found[0];
    assert_eq!(f.effect.kind(), "constant_force", "{text}");
    assert_eq!(
        (f.location.a.as_str(), f.location.b.as_str()),
        ("ground", "m")
    );
    assert_eq!(f.unit, Some("N"));
    let s = share(&d, floor);
    println!(
        "constant force {:.3} ± {:.3} N (truth {OFFSET}); gap re-identified {:.3} % → \
         corrected {:.3} %, true model {floor:.3} %: {:.0} % of the attainable shrink",
        f.value,
        f.stderr,
        d.gap_reidentified,
        d.gap_after,
        100.0 * s
    );
    assert!(s >= 0.8, "{:.2} of the attainable shrink\n{text}", s);
    assert!((f.value - OFFSET).abs() < 0.2, "{} N\n{text}", f.value);
    // README.md (a constant force the model leaves out) quotes this seed's figure.
    if common::seeds_as_documented() {
        figures::check("README.md", "servo.offset.diagnose", f.value);
    }
    // The text names the force with its unit; the prestress that mimics it is not chosen.
    assert!(
        text.contains("constant force at (ground, m): -3."),
        "{text}"
    );
    assert!(
        !d.found.iter().any(|f| f.effect.kind() == "prestress"),
        "{text}"
    );
    // The corrected model writes it as a user would.
    assert!(
        d.fixed_source
            .contains("force gap_fix (ground, m) = offset_fix ~ -3."),
        "{}",
        d.fixed_source
    );
}

/// Whether the diagnosis of the axis missing both its constant force and its Coulomb
/// friction names both at (ground, m) with their sizes; else what it got wrong.
fn names_offset_and_friction(d: &Diagnosis) -> Result<(), String> {
    let kinds: Vec<&str> = d.found.iter().map(|f| f.effect.kind()).collect();
    if kinds.len() != 2 || !kinds.contains(&"constant_force") || !kinds.contains(&"coulomb") {
        return Err(format!("found {kinds:?}"));
    }
    for f in &d.found {
        if (f.location.a.as_str(), f.location.b.as_str()) != ("ground", "m") {
            return Err(format!("{} at {}", f.effect.kind(), f.location.label()));
        }
        let (truth, tol) = if f.effect.kind() == "coulomb" {
            (15.0, 0.3)
        } else {
            (OFFSET, 0.1)
        };
        println!("{}: {:.3} ± {:.3}", f.effect.kind(), f.value, f.stderr);
        if (f.value - truth).abs() >= tol {
            return Err(format!("{} = {} for {truth}", f.effect.kind(), f.value));
        }
    }
    Ok(())
}

#[test]
fn diagnose_names_a_withheld_constant_force_and_coulomb_friction() {
    // A rate over seeds 2, 3, … (`DYNID_SEEDS=N` for N of them): both named on all of
    // seeds 2–11 (`DYNID_SEEDS=10 cargo test --test servo_offset constant_force_and_coulomb
    // -- --nocapture`, 10 of 10); on 6 of those 10 no single effect reduces the gap at the
    // first step and the pair step of the search adds the two together.
    let seeds: Vec<u64> = (2..2 + common::seed_count(4) as u64).collect();
    let model = axis("servo_axis_no_offset_no_friction", &[], &["force friction"]);
    let mut pass = 0;
    for &seed in &seeds {
        let d = run(&model, &records(seed));
        match names_offset_and_friction(&d) {
            Ok(()) => pass += 1,
            Err(e) => println!("seed {seed}: {e}\n{}", d.summary()),
        }
    }
    println!(
        "offset and friction both named on {pass} of {} seeds",
        seeds.len()
    );
    assert_eq!(
        pass,
        seeds.len(),
        "both named on {pass} of {} seeds",
        seeds.len()
    );
}

#[test]
fn centred_records_get_no_constant_force() {
    // Without a mean in the data the column of a constant force is zero: it is no
    // candidate, whatever else the data show.
    let recs = common::centred(&records(3));
    let d = run(&axis("servo_axis_no_offset", &[], &[]), &recs);
    let text = d.summary();
    println!("{text}");
    assert!(
        !d.found.iter().any(|f| f.effect.kind() == "constant_force"),
        "{text}"
    );
    let c = d
        .ranking
        .iter()
        .find(|c| c.effect.kind() == "constant_force")
        .expect("the candidate is listed");
    assert!(!c.value.is_finite(), "{c:?}");
    assert_eq!(c.note, "not resolved by the data", "{c:?}");
}

/// The servo axis of `ServoAxis::planned` (the same axis as a Rust value, its loop closed
/// by the simulator) with the constant force, one record at `seed`; identified with the
/// model that lacks the constant force.
fn identify_without_offset(seed: u64) -> dynid::runtime::ident::Identification {
    use dynid::runtime::data::{LevelSource, RecordSource};
    use dynid::runtime::sim::test_models::ServoAxis;
    let mut axis = ServoAxis::standard();
    axis.model_error = vec![("offset".into(), format!("f0 ~ {OFFSET:?}"))];
    let mut cfg = axis.config(common::seed(seed));
    cfg.input_oversample = 10;
    let out = sim::simulate(&axis.true_model(), &cfg).expect("closed-loop simulation");
    let ir = axis.model();
    let src = RecordSource::new(&out.records[0], &ir, "servo").expect("record");
    let levels: Vec<&dyn LevelSource> = vec![&src];
    dynid::runtime::identify(
        &ir,
        &levels,
        &dynid::runtime::IdentifyOptions::instrument_rows(),
    )
    .expect("identification")
}

#[test]
fn identify_warns_of_a_withheld_constant_force() {
    // One 25 s record (the random set point): the equation of `m` leaves most of its data
    // unexplained, and the guard's probe names the constant force with its size. The CLI
    // prints these warnings on stderr and writes them under `fit_warnings` in `--json`.
    let id = identify_without_offset(4);
    println!("{:#?}\n{:#?}", id.params, id.fit_warnings);
    let w = id
        .fit_warnings
        .iter()
        .find(|w| w.subject == "m")
        .expect("a warning on the equation of `m`");
    assert!(
        w.message.contains("unmodelled constant force") && w.message.contains("N on `m`"),
        "{}",
        w.message
    );
    // No force of this model depends on the position: a sensor offset cannot be the cause.
    assert!(!w.message.contains("zero offset"), "{}", w.message);
    let size: f64 = w
        .message
        .split("identified: ")
        .nth(1)
        .and_then(|t| t.split(" ±").next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no size in: {}", w.message));
    println!("identify: constant force {size} N (truth {OFFSET})");
    // README.md and docs/method.md (§7, the guard's probe) quote this seed's figure.
    if common::seeds_as_documented() {
        figures::check("README.md", "servo.offset.identify_probe", size);
        figures::check("docs/method.md", "servo.offset.identify_probe", size);
        let se: f64 = w
            .message
            .split("identified: ")
            .nth(1)
            .and_then(|t| t.split("± ").nth(1))
            .and_then(|t| t.split(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no standard error in: {}", w.message));
        figures::check("docs/method.md", "servo.offset.identify_probe_stderr", se);
    }
    assert!((size - OFFSET).abs() < 0.15, "{}", w.message);
    assert!(
        w.message
            .contains(&format!("force off (ground, m) = f0 ~ {size}")),
        "{}",
        w.message
    );
}

/// The detection of `ir` on `recs`.
fn detect(ir: &ModelIr, recs: &[Record]) -> dynid::runtime::detect::Detection {
    use dynid::runtime::data::LevelSource;
    use dynid::runtime::detect::{detect_from_data, DetectOptions};
    let srcs = common::sources(ir, recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = dynid::runtime::IdentifyOptions::instrument_rows();
    detect_from_data(ir, &levels, &opts, &DetectOptions::default(), &[])
        .expect("detect")
        .0
}

#[test]
fn detect_reports_a_mean_the_linear_model_cannot_explain() {
    // The model without the constant force, its friction kept: the per-level fits of a
    // model that also lacks the friction scatter too much on 25 s levels for the levels
    // to agree on the mean (on three of four seeds).
    let recs = records(5);
    let linear = axis("servo_axis_no_offset", &[], &[]);
    let d = detect(&linear, &recs);
    let text = d.render_table();
    println!("{text}");
    assert_eq!(d.constant_forces.len(), 1, "{text}");
    let c = &d.constant_forces[0];
    assert_eq!(c.body, "m");
    println!("detect: constant force {:.3} ± {:.3} N", c.value, c.stderr);
    if common::seeds_as_documented() {
        let doc = "docs/detection.md";
        figures::check(doc, "detect.offset.f0", c.value);
        figures::check(doc, "detect.offset.f0_stderr", c.stderr);
        assert_eq!(c.per_level.len(), 3);
        for ((value, stderr), (f, f_se)) in c.per_level.iter().zip([
            ("detect.offset.level1", "detect.offset.level1_stderr"),
            ("detect.offset.level2", "detect.offset.level2_stderr"),
            ("detect.offset.level3", "detect.offset.level3_stderr"),
        ]) {
            figures::check(doc, f, *value);
            figures::check(doc, f_se, *stderr);
        }
    }
    assert!((c.value - OFFSET).abs() < 0.02, "{text}");
    assert!(
        text.contains("constant force at (ground, m): -3."),
        "{text}"
    );
    // Centred records carry no mean: nothing to report.
    let d = detect(&linear, &common::centred(&recs));
    assert!(d.constant_forces.is_empty(), "{}", d.render_table());
    // A model that has the constant force gets no second one.
    let d = detect(&truth(), &recs);
    assert!(d.constant_forces.is_empty(), "{}", d.render_table());
}

#[test]
fn diagnose_gives_the_levels_too_alike_warning_of_detect() {
    // `models/servo_axis_planned.dyn` at three levels of one speed (the planned moves
    // repeat, as the cycles of one record do; 1 % noise on every channel keeps the records
    // apart): the velocity spans a factor 1, so no drift of `d` could show.
    use dynid::runtime::data::LevelSource;
    use dynid::runtime::detect::{detect_from_data, levels_too_alike, DetectOptions};
    let ir =
        dsl_parser::compile_file(&common::model_path("servo_axis_planned.dyn")).expect("model");
    let cfg = SimConfig {
        levels: Some(vec![1.0; 3]),
        noise: 0.01,
        duration: 25.0,
        sample: 1e-3,
        seed: common::seed(6),
        burn_in: 2.0,
        input_oversample: 10,
        quantise: Some(1e-6),
        ..SimConfig::default()
    };
    let recs = sim::simulate(&ir, &cfg).expect("simulation").records;
    // What `dynid detect` says (src/cli/detect.rs).
    let srcs = common::sources(&ir, &recs);
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let mut opts = DetectOptions::default();
    let (det, fits) = detect_from_data(
        &ir,
        &levels,
        &dynid::runtime::IdentifyOptions::instrument_rows(),
        &opts,
        &[],
    )
    .expect("detect");
    opts.se_dof.get_or_insert(fits.n_blocks as f64 - 1.0);
    let warnings = levels_too_alike(&det, &opts);
    assert!(!warnings.is_empty(), "{}", det.render_table());
    let d = run(&ir, &recs);
    let text = d.summary();
    println!("{text}");
    for w in &warnings {
        assert!(w.message.starts_with("levels too alike"), "{}", w.message);
        assert!(
            d.notes
                .iter()
                .any(|n| n == &format!("detection warning: {}", w.message)),
            "{}\n{text}",
            w.message
        );
    }
}

#[test]
fn identify_cli_warns_of_a_withheld_constant_force_on_stderr_and_in_json() {
    // `models/servo_axis.dyn` with the constant force makes the data; `identify` is given
    // the model without it.
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(common::model_path("servo_axis.dyn")).unwrap();
    let with = src.replacen(
        "    excite",
        &format!("    force off (ground, m) = f0 ~ {OFFSET:?}\n    excite"),
        1,
    );
    let truth = dir.path().join("truth.dyn");
    std::fs::write(&truth, with).unwrap();
    let data = dir.path().join("data");
    let out = common::dynid()
        .arg("simulate")
        .arg(&truth)
        .args(["--duration", "25", "--sample", "0.001", "--burn-in", "2"])
        .args(["--input-oversample", "10", "--quantise", "1e-6"])
        .args(["--seed", &common::seed(7).to_string(), "--out"])
        .arg(&data)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    let json = dir.path().join("id.json");
    let out = common::dynid()
        .arg("identify")
        .arg(common::model_path("servo_axis.dyn"))
        .args((1..=3).map(|k| data.join(format!("level_{k}.csv"))))
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let err = common::stderr(&out);
    assert!(out.status.success(), "{err}");
    println!("{err}");
    assert!(
        err.contains("warning:")
            && err.contains("unmodelled constant force")
            && err.contains("N on `m`"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let w = v["fit_warnings"].as_array().expect("fit_warnings");
    assert!(
        w.iter().any(|w| w["cause"] == "constant_force"
            && w["message"]
                .as_str()
                .is_some_and(|m| m.contains("N on `m`"))),
        "{v}"
    );
}

/// `models/servo_axis_planned.dyn` (the axis on planned moves with dwells, its guide's
/// known friction ripple in the model) edited as [`edited_source`] does.
fn planned_source(lines: &[&str], drop: &[&str]) -> String {
    edited_source("servo_axis_planned.dyn", lines, drop)
}

/// The planned-moves workflow of the README, run through the command line: the axis with
/// a constant force of −3.2 N simulated as a rig records it (1 µm encoder, the controller
/// ten times per sample), identified with the right model, and diagnosed from models that
/// leave out the constant force, the Coulomb friction, or both. The moves are planned, so
/// the records hold no random part: one run is every seed (the force is noise-free; the
/// encoder's quantisation is the noise). Before the candidates were measured in groups
/// that leave out the same rests (`by_rests` in `runtime/src/diagnose/search.rs`), a
/// Coulomb candidate in the shared pass left the rests out of every other candidate's
/// moments, and none of them could be solved ("not resolved by the data"); before a
/// constant force was judged on the pathwise gap, the model without it was "consistent".
///
/// Measured (`cargo test --test servo_offset planned -- --nocapture`): identify m 50.0129,
/// d 119.710, r 15.0283, f0 −3.1945 (truth 50, 120, 15, −3.2); without the constant force:
/// −3.1945 ± 0.0069 N, pathwise gap 3.52 → 0.46 % (the statistical gap, blind to a mean,
/// 0.23 → 0.26 %); without the friction: r 15.028 ± 0.011, 6.60 → 0.26 % (pathwise 12.73 →
/// 0.46 %); without both: both, 28.98 → 0.26 %. The bounds are twice these errors, as for
/// fixed data: the records are the same on every run.
#[test]
fn planned_axis_workflow_names_a_withheld_offset_friction_or_both() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, src: String| {
        let p = dir.path().join(name);
        std::fs::write(&p, src).unwrap();
        p
    };
    // The rig, and the model with offset and friction (README, "Planned moves from start
    // to finish").
    let truth = common::model_path("servo_axis_planned_offset.dyn");
    let full = truth.clone();
    let with_offset = "force off (ground, m) = f0 ~ -2";
    let out = common::dynid()
        .args(["simulate"])
        .arg(&truth)
        .args(common::RIG)
        .args(["--quantise", "1e-6", "--seed", "1", "--out"])
        .arg(dir.path().join("rig"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    let levels: Vec<std::path::PathBuf> = (1..=3)
        .map(|k| dir.path().join("rig").join(format!("level_{k}.csv")))
        .collect();
    let json = |args: &[&std::ffi::OsStr]| -> serde_json::Value {
        let path = dir.path().join("out.json");
        let _ = std::fs::remove_file(&path);
        let out = common::dynid()
            .args(args)
            .arg("--json")
            .arg(&path)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", common::stderr(&out));
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
    };
    let mut args: Vec<&std::ffi::OsStr> = vec!["identify".as_ref(), full.as_os_str()];
    args.extend(levels.iter().map(|p| p.as_os_str()));
    let id = json(&args);
    let value = |name: &str| id["parameters"][name]["value"].as_f64().unwrap();
    println!(
        "identify: m {:.4}, d {:.3}, r {:.4}, f0 {:.4}",
        value("m"),
        value("d"),
        value("r"),
        value("f0")
    );
    for (name, truth, tol) in [
        ("m", 50.0, 0.05),
        ("d", 120.0, 1.0),
        ("r", 15.0, 0.1),
        ("f0", OFFSET, 0.03),
    ] {
        assert!(
            (value(name) - truth).abs() < tol,
            "{name} = {}",
            value(name)
        );
    }
    // `models/servo_axis_planned.dyn` is the model without the constant force.
    // (name, lines added, lines dropped, the effects to find)
    type Case<'a> = (&'a str, &'a [&'a str], &'a [&'a str], &'a [&'a str]);
    let cases: [Case; 3] = [
        ("no_offset", &[], &[], &["constant_force"]),
        (
            "no_friction",
            &[with_offset],
            &["force friction"],
            &["coulomb"],
        ),
        (
            "neither",
            &[],
            &["force friction"],
            &["coulomb", "constant_force"],
        ),
    ];
    for (name, lines, drop, want) in cases {
        let model = if name == "no_offset" {
            common::model_path("servo_axis_planned.dyn")
        } else {
            write(&format!("{name}.dyn"), planned_source(lines, drop))
        };
        let mut args: Vec<&std::ffi::OsStr> = vec!["diagnose".as_ref(), model.as_os_str()];
        args.extend(levels.iter().map(|p| p.as_os_str()));
        let d = json(&args);
        let found: Vec<(String, f64, f64)> = d["found"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| {
                (
                    f["effect"]["kind"].as_str().unwrap().to_string(),
                    f["value"].as_f64().unwrap(),
                    f["stderr"].as_f64().unwrap(),
                )
            })
            .collect();
        println!(
            "{name}: {}, gap {:.2} → {:.2} → {:.2} % (pathwise {:.2} → {:.2} → {:.2} %), found {found:?}",
            d["verdict"],
            d["gap_before"].as_f64().unwrap(),
            d["gap_reidentified"].as_f64().unwrap(),
            d["gap_after"].as_f64().unwrap(),
            d["pathwise_gap_before"].as_f64().unwrap(),
            d["pathwise_gap_reidentified"].as_f64().unwrap(),
            d["pathwise_gap_after"].as_f64().unwrap(),
        );
        let mut kinds: Vec<&str> = found.iter().map(|f| f.0.as_str()).collect();
        kinds.sort();
        let mut want = want.to_vec();
        want.sort();
        assert_eq!(kinds, want, "{name}: {found:?}");
        // The corrected model follows the measured paths (pathwise gap, %) as the true
        // structure does: 0.45 % measured without the constant force (docs/diagnosis.md).
        assert!(d["pathwise_gap_after"].as_f64().unwrap() < 1.0, "{name}");
        for (kind, value, _) in &found {
            let (truth, tol) = if kind == "coulomb" {
                (15.0, 1.0)
            } else {
                (OFFSET, 0.5)
            };
            assert!((value - truth).abs() < tol, "{name}: {found:?}");
        }
        if name == "no_offset" {
            // docs/diagnosis.md (the constant force accepted by its pathwise gap) quotes
            // the force found and the gaps, to their last digit (fixed seed).
            let doc = "docs/diagnosis.md";
            let (_, f0, se) = &found[0];
            figures::check(doc, "diagnose.planned.offset", *f0);
            figures::check(doc, "diagnose.planned.offset_stderr", *se);
            for (key, field) in [
                ("diagnose.planned.pathwise_before", "pathwise_gap_before"),
                ("diagnose.planned.pathwise_after", "pathwise_gap_after"),
                ("diagnose.planned.gap_before", "gap_before"),
                ("diagnose.planned.gap_after", "gap_after"),
            ] {
                figures::check(doc, key, d[field].as_f64().unwrap());
            }
        }
        if name == "no_friction" {
            // README ("Planned moves from start to finish") quotes the friction found.
            let (_, r, se) = &found[0];
            figures::check("README.md", "servo.planned.no_friction.r", *r);
            figures::check("README.md", "servo.planned.no_friction.r_stderr", *se);
        }
    }
    // One record, cut at its cycles: the constant force again (−3.2138 ± 0.0082 N measured).
    let no_offset = common::model_path("servo_axis_planned.dyn");
    let d = json(&[
        "diagnose".as_ref(),
        no_offset.as_os_str(),
        levels[1].as_os_str(),
    ]);
    let found = d["found"].as_array().unwrap();
    println!("one record: {found:?}");
    assert_eq!(d["levels"].as_array().unwrap().len(), 4, "four cycles");
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0]["effect"]["kind"], "constant_force");
    assert!((found[0]["value"].as_f64().unwrap() - OFFSET).abs() < 0.03);
}
