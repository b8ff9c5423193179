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
//! - the linear structure from noiseless accelerations comes out with every mass and
//!   stiffness low, by 6–82 % over seeds 1–5, while positions of the same records give
//!   them within 1 % (`linear_structure_from_accelerations_is_biased_low`, which pins it);
//! - detection from the accelerations and the force, 5 % noise on every channel, flags the
//!   joint's element with Coulomb friction in its template and leaves the other couplings
//!   and the ground dampers linear, but flags the mount k1/d1 too, falsely
//!   (`detection_flags_the_joint_with_friction`);
//! - lumped models with fewer bodies do not find the joint from accelerations; from
//!   positions the four-body model still does (`detection_by_model_size`, opt-in:
//!   `DYNID_STRUCTURE_LONG=1`);
//! - diagnosis and identification of the joint's parameters from accelerations fail on
//!   these records: `identify` with the right model gives kb and r tens of per cent low,
//!   `diagnose` names a prestress at (m3, m4) (`joint_from_accelerations_is_not_reached`,
//!   opt-in, which pins it);
//! - the bias of the linear fit shrinks with the record length and grows with noise
//!   (`bias_against_record_length_and_noise`, opt-in);
//! - the clearance alone, on noiseless records of 1000 s, collapses the fit of the right
//!   model from accelerations while positions recover it
//!   (`clearance_alone_breaks_the_fit_from_accelerations`, opt-in).

mod common;
mod figures;

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, Grid, Phases, TestSignal};

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

/// The linear structure from accelerations against positions, on noiseless records of the
/// same seed (four levels of 200 s): positions recover every mass and stiffness,
/// accelerations give all of them low. The second half pins a limitation of the
/// integrations moved onto the filters on a lightly damped structure with modes over a
/// decade (docs/method.md, "Accelerations instead of positions"): when it is lifted this
/// test fails, and README's "Accelerometers" and that section need their figures again.
#[test]
fn linear_structure_from_accelerations_is_biased_low() {
    let (acc, src) = common::model_and_source("structure5_linear_accel");
    let pos = common::measured_otherwise(
        &src,
        "measure m1.a, m2.a, m3.a, m4.a, m5.a, u",
        "measure m1.x, m2.x, m3.x, m4.x, m5.x, u",
    );
    let id_p = common::identify_records(&pos, &records(&pos, 0.0, 1));
    let e_p = common::error_row("structure5 linear, positions", &pos, &id_p);
    let id_a = common::identify_records(&acc, &records(&acc, 0.0, 1));
    let e_a = common::error_row("structure5 linear, accelerations", &acc, &id_a);
    let inertia_and_springs = |e: &[(String, f64)]| -> Vec<(String, f64)> {
        e.iter()
            .filter(|(n, _)| n.starts_with('m') || n.starts_with('k'))
            .cloned()
            .collect()
    };
    // Seeds 1–5 (`DYNID_SEED_OFFSET=0…4 cargo test --test accel_structure linear --
    // --nocapture`): positions within 0.96 % (m4, seed 3), accelerations every mass and
    // stiffness low, from −6.0 % (k1, seed 1) to −82 % (m5, seed 3), with standard errors of
    // 4–93 %. Bounds: twice the largest error of the positions; half the smallest bias.
    for (n, e) in inertia_and_springs(&e_p) {
        assert!(e.abs() < 0.02, "positions: `{n}` off by {:+.2}%", 100.0 * e);
    }
    if common::seeds_as_documented() {
        let of = |errs: &[(String, f64)], p: &str| {
            100.0 * errs.iter().find(|(n, _)| n == p).expect("an error").1
        };
        figures::check("README.md", "accel.structure5.acc.k1", of(&e_a, "k1"));
        figures::check("README.md", "accel.structure5.acc.m5", of(&e_a, "m5"));
        let largest = inertia_and_springs(&e_p)
            .iter()
            .map(|(_, e)| 100.0 * e.abs())
            .fold(0.0, f64::max);
        figures::check("README.md", "accel.structure5.pos.max", largest);
    }
    for (n, e) in inertia_and_springs(&e_a) {
        assert!(
            e < -0.03,
            "accelerations: `{n}` off by {:+.2}%: the bias this test pins is gone",
            100.0 * e
        );
    }
}

/// The mean relative error of the masses and stiffnesses of the linear structure from
/// accelerations, on four multisine levels of `duration` seconds with `noise` (seed 1).
fn mean_bias(duration: f64, noise: f64) -> f64 {
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
    let id = common::identify_records(&acc, &recs);
    let errs = common::error_row(
        &format!("structure5, accelerations, {duration} s, noise {noise}"),
        &acc,
        &id,
    );
    let mk: Vec<f64> = errs
        .iter()
        .filter(|(n, _)| n.starts_with('m') || n.starts_with('k'))
        .map(|(_, e)| *e)
        .collect();
    mk.iter().sum::<f64>() / mk.len() as f64
}

/// The bias of the linear structure from accelerations against record length and noise
/// (opt-in, `DYNID_STRUCTURE_LONG=1`, about a minute): longer records shrink it, as the
/// dropped boundary terms of the identity would; 5 % noise on every channel makes it
/// larger, which those terms do not explain. Seed 1, mean error of the masses and
/// stiffnesses: noiseless −15 % at 200 s, −2.5 % at 1000 s; with noise −46 % at 1000 s
/// (standard errors about a third of it: the bias is not covered by them).
#[test]
fn bias_against_record_length_and_noise() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let short = mean_bias(200.0, 0.0);
    let long = mean_bias(1000.0, 0.0);
    let noisy = mean_bias(1000.0, 0.05);
    println!("mean bias: 200 s {short:+.3}, 1000 s {long:+.3}, 1000 s noisy {noisy:+.3}");
    if common::seeds_as_documented() {
        const DOC: &str = "docs/method.md";
        figures::check(DOC, "accel.structure5.bias.short", 100.0 * short);
        figures::check(DOC, "accel.structure5.bias.long", 100.0 * long);
        figures::check(DOC, "accel.structure5.bias.noisy", 100.0 * noisy);
    }
    assert!(short < 0.0 && long < 0.0 && noisy < 0.0);
    assert!(long.abs() < 0.5 * short.abs(), "{short} {long}");
    assert!(noisy.abs() > 2.0 * long.abs(), "{long} {noisy}");
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
    let model = model_file(dir, "structure5_joint_accel", positions);
    let data = dir.join(if positions { "data_x" } else { "data" });
    let st = common::dynid()
        .arg("simulate")
        .arg(&model)
        .args([
            "--signal",
            "multisine",
            "--band-hz",
            "0.2,10",
            "--periods",
            "4",
            "--duration",
            "200",
            "--noise",
            "0.05",
            "--seed",
        ])
        .arg(common::seed(1).to_string())
        .arg("--out")
        .arg(&data)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", common::stderr(&st));
    (1..=4)
        .map(|i| data.join(format!("level_{i}.csv")))
        .collect()
}

/// `dynid detect` of `model` on `levels`: its verdict line per element, `Element ` and
/// the element's name cut off (`k3/d3 (m2, m3)` → `nonlinear: backlash`).
fn verdicts(model: &std::path::Path, levels: &[std::path::PathBuf]) -> Vec<(String, String)> {
    let out = common::dynid()
        .arg("detect")
        .arg(model)
        .args(levels)
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
/// levels of 200 s with 5 % noise on every channel (seed 1): the joint's element drifts
/// with Coulomb friction in its template; the other couplings and the ground dampers are
/// linear. The mount k1/d1 is flagged as well (printed, not asserted: a false detection,
/// which the same structure measured by positions does not give: the study below).
#[test]
fn detection_flags_the_joint_with_friction() {
    let dir = tempfile::tempdir().unwrap();
    let levels = joint_levels(dir.path(), false);
    let model = common::model_path("structure5_linear_accel.dyn");
    let v = verdicts(&model, &levels);
    for (e, verdict) in &v {
        println!("structure5, accelerations: {e}: {verdict}");
    }
    let joint = verdict(&v, "k3/d3 (m2, m3)");
    assert!(
        joint.starts_with("nonlinear") && joint.contains("Coulomb friction"),
        "{joint}"
    );
    for e in [
        "k2/d2 (m1, m2)",
        "k4/d4 (m3, m4)",
        "k5/d5 (m4, m5)",
        "g2 (ground, m2)",
        "g3 (ground, m3)",
        "g4 (ground, m4)",
        "g5 (ground, m5)",
    ] {
        assert_eq!(verdict(&v, e), "linear", "{e}");
    }
}

/// The study of model size (`DYNID_STRUCTURE_LONG=1 cargo test --test accel_structure --
/// --nocapture`, about a minute): detection of the joint by the five-body model and by
/// lumped models of four and three bodies, from accelerations and, on the same structure
/// and noise, from positions. Seed 1, what it measured (README, "Accelerometers"):
///
/// | model | accelerations | positions |
/// |---|---|---|
/// | 5 bodies | joint: cubic stiffness + Coulomb friction; mount: backlash (false) | joint: backlash; all else linear |
/// | 4 bodies | mount: cubic stiffness (false); joint linear | joint: backlash; all else linear |
/// | 3 bodies | all linear | all linear |
///
/// From accelerations the lumped models' masses collapse towards zero (m4 0.007 of 1.2 in
/// the four-body model): their fit carries no information about the joint.
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
            let expected = matches!((bodies, positions), (5, _) | (4, true));
            assert_eq!(named, expected, "{bodies} bodies, {signals}: {v:?}");
            if positions && bodies > 3 {
                assert_eq!(flagged.len(), 1, "{bodies} bodies, positions: {flagged:?}");
            }
        }
    }
}

/// Identification of the joint with the right model, and diagnosis against the linear one,
/// from the accelerations of `detection_flags_the_joint_with_friction` (opt-in,
/// `DYNID_STRUCTURE_LONG=1`): neither is reached. Seed 1: kb −77 % and r −52 % off;
/// diagnosis names a prestress at (m3, m4), not the joint. Asserted as measured, so that
/// a change shows here and the README's account is revisited.
#[test]
fn joint_from_accelerations_is_not_reached() {
    if std::env::var("DYNID_STRUCTURE_LONG").is_err() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let levels = joint_levels(dir.path(), false);
    let out = common::dynid()
        .arg("identify")
        .arg(common::model_path("structure5_joint_accel.dyn"))
        .args(&levels)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", common::stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    // The value column of `name`'s row in the parameter table.
    let value = |name: &str| -> f64 {
        stdout
            .lines()
            .find_map(|l| {
                let mut w = l.split_whitespace();
                (w.next() == Some(name)).then(|| w.next()?.parse().ok())?
            })
            .unwrap_or_else(|| panic!("no row `{name}` in:\n{stdout}"))
    };
    let (kb, r) = (value("kb") / 300.0 - 1.0, value("r") / 0.2 - 1.0);
    println!(
        "joint from accelerations: kb {:+.1} %, r {:+.1} %",
        100.0 * kb,
        100.0 * r
    );
    if common::seeds_as_documented() {
        figures::check("README.md", "accel.structure5.joint.kb", 100.0 * kb);
        figures::check("README.md", "accel.structure5.joint.r", 100.0 * r);
    }
    assert!(kb < -0.2 && r < -0.2, "kb {kb:+.3}, r {r:+.3}");
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
    assert!(!named.contains("(m2, m3)"), "{named}");
}

/// The joint with its clearance alone (no friction), noiseless multisine records of 1000 s
/// (opt-in, `DYNID_STRUCTURE_LONG=1`): from positions the right model recovers the contact
/// stiffness, from accelerations (the joint's displacement integrated over whole periods)
/// the fit collapses. Seed 1: positions kb −0.02 %, accelerations kb −93 % with every
/// mass 67–79 % low, where the linear structure's records of the same length give them
/// −2.5 % (`bias_against_record_length_and_noise`): the clearance that engages is what
/// breaks the fit from accelerations; with the friction alone it holds. Pinned, so that a
/// fix shows here.
#[test]
fn clearance_alone_breaks_the_fit_from_accelerations() {
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
    assert!(kb(&e_a) < -0.5, "accelerations: kb {:+.4}", kb(&e_a));
    // The friction alone, from accelerations: seed 1, masses and stiffnesses −2.4 … −5.2 %
    // (bound twice the largest).
    let (_, joint) = common::model_and_source("structure5_joint_accel");
    let friction = joint.replace("kb ~ 300 * deadzone(s, 0.03) + ", "");
    assert_ne!(friction, joint);
    let friction = dynid::dsl_parser::compile_str("friction.dyn", &friction).unwrap();
    for (n, e) in fit(&friction, "friction alone, accelerations") {
        if n.starts_with('m') || n.starts_with('k') {
            assert!(
                e.abs() < 0.1,
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
