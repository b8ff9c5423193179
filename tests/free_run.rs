//! One convention for free runs: the refinement fits, and every output scores, the model
//! driven by the recorded inputs from the measured initial state of each record (positions
//! from the first sample, velocities from their column or from the first three positions).
//! A refinement therefore never prints a worse score than its start, `simulate --input`
//! gives the same trajectory as the scores, a model with control laws is refused before any
//! work, and an open-loop model on a closed-loop record gets the `reference` / `control`
//! hint.

mod common;
mod figures;

use common::{dynid, model_path, stderr};
use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::record::Record;
use dynid::runtime::refine::{self, RefineOptions, FREE_RUN_START};
use dynid::runtime::sim::{self, test_models::ServoAxis};
use std::path::Path;

/// The servo axis without its controller, friction or offset: an open-loop model of the
/// closed-loop records.
const OPEN_LOOP_AXIS: &str = "model axis {\n body m ~ 50\n input u on m\n measure m.x, u\n \
     damper d (ground, m) ~ 120\n}\n";

/// The servo axis of `ServoAxis::standard` (random set point, closed loop, 1 µm encoder)
/// for `duration` s: the open-loop model `servo_axis` (m, d, r unknown; driven by `u`) and
/// its record (`m.x`, `u`, `m.x_ref`).
fn servo(duration: f64, seed: u64) -> (ModelIr, Record) {
    let mut axis = ServoAxis::standard();
    axis.duration = duration;
    let ir = axis.model();
    let mut out = sim::simulate(&ir, &axis.config(common::seed(seed))).expect("simulation");
    (ir, out.records.remove(0))
}

fn write_csv(path: &Path, rec: &Record) {
    let mut s = String::from("t");
    for n in &rec.names {
        s.push(',');
        s.push_str(n);
    }
    s.push('\n');
    for k in 0..rec.len() {
        s.push_str(&format!("{}", rec.t0 + k as f64 * rec.ts));
        for c in &rec.columns {
            s.push_str(&format!(",{:e}", c[k]));
        }
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

/// Relative free-run error of `m.x` (RMS / std) at `values`, from the measured state.
fn score(ir: &ModelIr, values: &[f64], recs: &[Record]) -> f64 {
    refine::free_run_errors(ir, values, recs, sim::DEFAULT_SUBSTEPS).expect("free run")[0].relative
}

#[test]
fn the_refinement_fits_the_score_it_prints() {
    // An integrating plant (no spring) whose free run from a fitted initial state and from
    // the measured one differ for the whole record: the fit now starts where the score does.
    let (ir, rec) = servo(6.0, 41);
    let recs = vec![rec];
    let id = common::identify_records(&ir, &recs);
    let start = refine::start_from(&ir, &id);
    let seen = std::sync::Mutex::new(Vec::new());
    let r = refine::refine_with_progress(&ir, &recs, &start, &RefineOptions::default(), &|p| {
        seen.lock().unwrap().push(p.iteration)
    })
    .expect("refines");
    // The progress callback counts the iterations.
    let seen = seen.into_inner().unwrap();
    assert_eq!(seen, (1..=r.iterations).collect::<Vec<_>>());
    let (s0, s1) = (score(&ir, &start, &recs), score(&ir, &r.values(), &recs));
    eprintln!(
        "free run m.x {:.4} % → {:.4} %, cost {:.4e} → {:.4e}",
        100.0 * s0,
        100.0 * s1,
        r.cost_start,
        r.cost_end
    );
    assert!(r.applied && r.note.is_none(), "{r:?}");
    assert_eq!(r.initial_state, FREE_RUN_START);
    // The cost is the score: one compared signal weighed by 1/σ, so cost = relative².
    assert!(
        (r.free_run_start / (s0 * s0) - 1.0).abs() < 1e-9,
        "{r:?} {s0}"
    );
    assert!(
        (r.free_run_end / (s1 * s1) - 1.0).abs() < 1e-9,
        "{r:?} {s1}"
    );
    assert!(s1 <= s0, "refined {s1} worse than the start {s0}");

    // Cut into sub-records (multiple shooting), the fit minimises another cost: whatever it
    // reaches, the values it returns never score worse than the start.
    let opts = RefineOptions {
        segment: Some(recs[0].len() / 4),
        ..Default::default()
    };
    let r = refine::refine(&ir, &recs, &start, &opts).expect("refines");
    let s2 = score(&ir, &r.values(), &recs);
    eprintln!("4 sub-records: applied {}, {:?}", r.applied, r.note);
    assert!(s2 <= s0, "{r:?}");
    assert!(
        (r.free_run_start / (s0 * s0) - 1.0).abs() < 1e-9,
        "{r:?} {s0}"
    );
    assert_eq!(r.applied, r.note.is_none());
    if !r.applied {
        assert_eq!(r.values(), start);
    }
}

#[test]
fn simulate_input_starts_from_the_measured_state_as_the_scores_do() {
    let dir = tempfile::tempdir().unwrap();
    let (ir, rec) = servo(2.0, 42);
    let csv = dir.path().join("rec.csv");
    write_csv(&csv, &rec);
    let model = dir.path().join("axis.dyn");
    std::fs::write(&model, OPEN_LOOP_AXIS).unwrap();
    let o = dynid()
        .arg("simulate")
        .arg(&model)
        .arg("--input")
        .arg(&csv)
        .arg("--out")
        .arg(dir.path().join("run"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("from measured initial state"), "{text}");
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("run/truth.json")).unwrap()).unwrap();
    assert_eq!(truth["initial_state"], FREE_RUN_START);
    let driven = std::fs::read_to_string(dir.path().join("run/driven.csv")).unwrap();
    let x: Vec<f64> = driven
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    let m = rec.column("m.x").unwrap();
    assert_eq!(x.len(), m.len());
    // The first sample is the measured one, and the run is the one the scores compare.
    assert!(
        (x[0] - m[0]).abs() <= 1e-12 * m[0].abs().max(1e-3),
        "{} {}",
        x[0],
        m[0]
    );
    let rms = (x.iter().zip(m).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / m.len() as f64).sqrt();
    let axis = dynid::dsl_parser::compile_file(&model).unwrap();
    let scored = refine::free_run_errors(
        &axis,
        &[50.0, 120.0],
        std::slice::from_ref(&rec),
        sim::DEFAULT_SUBSTEPS,
    )
    .unwrap()[0]
        .rms;
    // driven.csv holds numbers printed to about 1e-9 relative.
    assert!((rms / scored - 1.0).abs() < 1e-6, "{rms} {scored}");
    let _ = ir;
}

#[test]
fn a_model_with_control_laws_is_refused_before_any_work() {
    // The files are not even read: the refusal comes first and writes nothing.
    let dir = tempfile::tempdir().unwrap();
    let data: Vec<_> = (1..=2)
        .map(|k| {
            let p = dir.path().join(format!("level_{k}.csv"));
            std::fs::write(&p, "t,m.x,u,xr\n0,0,0,0\n0.001,0,0,0\n").unwrap();
            p
        })
        .collect();
    let (json, report) = (dir.path().join("d.json"), dir.path().join("d.html"));
    for cmd in ["identify", "diagnose"] {
        let mut c = dynid();
        c.arg(cmd)
            .arg(model_path("servo_axis_linear.dyn"))
            .args(&data)
            .arg("--refine")
            .arg("--json")
            .arg(&json);
        if cmd == "diagnose" {
            c.arg("--report").arg(&report);
        }
        let o = c.output().unwrap();
        common::assert_refused(&o, "dynid::refine::control", &["before any work"]);
        assert!(
            o.stdout.is_empty(),
            "{}",
            String::from_utf8_lossy(&o.stdout)
        );
        assert!(!json.exists() && !report.exists());
    }
}

#[test]
fn an_open_loop_model_on_a_closed_loop_record_gets_the_set_point_hint() {
    // The closed-loop axis (set point column `m.x_ref`) seen through a model driven by the
    // recorded force, without friction: its free run drifts, and `m.x` follows `m.x_ref`.
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<_> = [43, 44]
        .iter()
        .map(|&seed| {
            let (_, rec) = servo(8.0, seed);
            let csv = dir.path().join(format!("rec_{seed}.csv"));
            write_csv(&csv, &rec);
            csv
        })
        .collect();
    let model = dir.path().join("axis.dyn");
    std::fs::write(&model, OPEN_LOOP_AXIS).unwrap();
    let json = dir.path().join("d.json");
    let o = dynid()
        .arg("diagnose")
        .arg(&model)
        .args(&files)
        .args(["--quiet", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    eprintln!("{text}");
    assert!(
        text.contains(
            "free runs: every level driven by its inputs from its measured initial state"
        ),
        "{text}"
    );
    assert!(
        text.contains("column `m.x_ref` looks like a set point"),
        "{text}"
    );
    // `m.x_ref` is no name of the language: the note names the reference and maps it.
    assert!(text.contains("reference m_ref"), "{text}");
    assert!(text.contains("--map m.x_ref=m_ref"), "{text}");
    let d: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(d["free_run_start"], FREE_RUN_START);
    let hint = d["closed_loop_hint"].as_str().unwrap();
    assert!(hint.contains("control u = KP"), "{hint}");
    // The drift the hint quotes, docs/diagnosis.md's figure to its last digit (fixed seeds).
    if common::seeds_as_documented() {
        figures::check(
            "docs/diagnosis.md",
            "diagnose.free_run.hint_nrmse",
            common::hint_nrmse(hint),
        );
    }
}
