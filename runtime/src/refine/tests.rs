use super::sens::{SensModel, SensRk4};
use super::*;
use crate::sim::{simulate, simulate_driven_from, SimConfig, Start};

const DUFFING: &str = "model duffing {
    body m ~ 1.0
    input u on m
    measure m.x, u
    spring k (ground, m) ~ 4.0
    damper d (ground, m) ~ 0.4
    force cubic (ground, m) = k3 ~ 2.0 * s^3
    excite u: lowpass(corner = 10) levels [6, 15]
}";

fn duffing() -> ModelIr {
    dsl_parser::compile_str("duffing", DUFFING).expect("model compiles")
}

fn records(ir: &ModelIr, duration: f64, oversample: usize, seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration,
        seed,
        burn_in: 10.0,
        input_oversample: oversample,
        ..Default::default()
    };
    simulate(ir, &cfg).expect("simulation").records
}

fn truth(ir: &ModelIr) -> Vec<f64> {
    ir.unknowns()
        .iter()
        .map(|p| ir.params[p.index()].nominal().expect("nominal"))
        .collect()
}

#[test]
fn values_match_the_driven_simulation() {
    // The value part of the sensitivity run is the driven simulation, bit for bit.
    let ir = duffing();
    let recs = records(&ir, 20.0, 1, 3);
    let p = truth(&ir);
    let opts = RefineOptions::default();
    let pb = Problem::new(&ir, &recs[..1], &p, &opts).expect("problem");
    let x0 = pb.measured_state(pb.segments[0]);
    let mut direction = vec![None; ir.params.len()];
    for (k, id) in pb.unknowns.iter().enumerate() {
        direction[id.index()] = Some(k);
    }
    let m = SensModel::new(&ir, &pb.params(&p), &direction).expect("model");
    let mut rk = SensRk4::new(&m, &x0[..1], &x0[1..]);
    let driven =
        simulate_driven_from(&ir, &recs[0], opts.substeps, Start::Measured).expect("driven run");
    let (y, u) = (
        driven.column("m.x").expect("m.x"),
        recs[0].column("u").expect("u"),
    );
    for k in 0..y.len() {
        assert_eq!(rk.x[0].to_bits(), y[k].to_bits(), "sample {k}");
        if k + 1 < y.len() {
            rk.advance(&m, &[u[k]], &[u[k + 1]], recs[0].ts, opts.substeps);
        }
    }
}

#[test]
fn sensitivities_match_difference_quotients_of_the_trajectory() {
    // A check of the forward sensitivities (the refinement never uses differences).
    let ir = duffing();
    let recs = records(&ir, 5.0, 1, 4);
    let p = truth(&ir);
    let opts = RefineOptions::default();
    let pb = Problem::new(&ir, &recs[..1], &p, &opts).expect("problem");
    let seg = pb.segments[0];
    let x0 = pb.measured_state(seg);
    let params = pb.params(&p);
    let mut direction = vec![None; ir.params.len()];
    for (k, id) in pb.unknowns.iter().enumerate() {
        direction[id.index()] = Some(k);
    }
    let run = |params: &[f64], x0: &[f64]| -> (f64, Vec<f64>) {
        let m = SensModel::new(&ir, params, &direction).expect("model");
        let mut rk = SensRk4::new(&m, &x0[..1], &x0[1..]);
        let u = recs[0].column("u").expect("u");
        for k in 0..300 {
            rk.advance(&m, &[u[k]], &[u[k + 1]], recs[0].ts, opts.substeps);
        }
        (rk.x[0], rk.x[1..].to_vec())
    };
    let (_, der) = run(&params, &x0);
    // Parameter directions.
    for (k, id) in pb.unknowns.iter().enumerate() {
        let h = 1e-6 * params[id.index()].abs();
        let (mut up, mut dn) = (params.clone(), params.clone());
        up[id.index()] += h;
        dn[id.index()] -= h;
        let fd = (run(&up, &x0).0 - run(&dn, &x0).0) / (2.0 * h);
        let an = der[2 + k];
        assert!(
            (fd - an).abs() <= 1e-5 * an.abs().max(1e-3),
            "{}: {an} vs {fd}",
            ir.params[id.index()].name
        );
    }
    // Initial-state directions.
    for j in 0..2 {
        let h = 1e-6;
        let (mut up, mut dn) = (x0.clone(), x0.clone());
        up[j] += h;
        dn[j] -= h;
        let fd = (run(&params, &up).0 - run(&params, &dn).0) / (2.0 * h);
        assert!(
            (fd - der[j]).abs() <= 1e-5 * der[j].abs().max(1e-3),
            "x0[{j}]"
        );
    }
}

#[test]
fn recovers_a_perturbed_start_on_exact_data() {
    // Data of the model itself (inputs linear between samples, as the refinement assumes):
    // from a start 10 % off, the refinement returns to the simulated values.
    let ir = duffing();
    let recs = records(&ir, 30.0, 1, 5);
    let p = truth(&ir);
    let start: Vec<f64> = p.iter().map(|v| v * 1.1).collect();
    // With the initial states fitted the data are matched exactly.
    let opts = RefineOptions {
        estimate_initial: true,
        ..Default::default()
    };
    let r = refine(&ir, &recs, &start, &opts).expect("refines");
    assert!(r.converged, "{r:?}");
    for (e, t) in r.params.iter().zip(&p) {
        assert!((e.value / t - 1.0).abs() < 1e-6, "{e:?} vs {t}");
    }
    assert!(r.cost_end < 1e-12 * r.cost_start, "{r:?}");
    // From the measured state (the default) the unmeasured velocity comes from a
    // difference of the first three positions, off by O(Ts²); the cost is then the score.
    // Measured (`cargo test -p dynid-runtime recovers -- --nocapture`): 1.2e-4 to 2.2e-4.
    let r = refine(&ir, &recs, &start, &RefineOptions::default()).expect("refines");
    assert!(r.converged && r.applied, "{r:?}");
    assert_eq!(r.cost_end, r.free_run_end);
    for (e, t) in r.params.iter().zip(&p) {
        eprintln!("{}: {:.3e}", e.name, e.value / t - 1.0);
        assert!((e.value / t - 1.0).abs() < 1e-3, "{e:?} vs {t}");
    }
}

#[test]
fn multiple_shooting_gives_one_initial_state_per_sub_record() {
    let ir = duffing();
    let recs = records(&ir, 10.0, 4, 6);
    let p = truth(&ir);
    let opts = RefineOptions {
        segment: Some(300),
        ..Default::default()
    };
    let r = refine(&ir, &recs, &p, &opts).expect("refines");
    // 1000 samples per record in sub-records of at most 300: 4 each.
    assert_eq!(r.segments, 8);
    assert!(r.cost_end <= r.cost_start);
    // Never a worse score than the start's: applied only when the whole-record free run
    // from the measured state is not worse.
    assert_eq!(r.applied, r.free_run_end <= r.free_run_start, "{r:?}");
    assert_eq!(r.applied, r.note.is_none());
}

#[test]
fn bad_weights_and_starts_are_errors() {
    let ir = duffing();
    let recs = records(&ir, 2.0, 1, 7);
    let p = truth(&ir);
    let opts = RefineOptions {
        weights: vec![("u".into(), 1.0)],
        ..Default::default()
    };
    let e = refine(&ir, &recs, &p, &opts).unwrap_err();
    assert!(
        matches!(&e, RefineError::BadWeight { signal, .. } if signal == "u"),
        "{e:?}"
    );
    let opts = RefineOptions {
        weights: vec![("m.x".into(), 0.0)],
        ..Default::default()
    };
    let e = refine(&ir, &recs, &p, &opts).unwrap_err();
    assert!(matches!(e, RefineError::BadWeight { .. }), "{e:?}");
    let e = refine(&ir, &recs, &p[..2], &RefineOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            RefineError::StartLength {
                got: 2,
                expected: 4
            }
        ),
        "{e:?}"
    );
    let mut bad = p.clone();
    bad[1] = f64::NAN;
    let e = refine(&ir, &recs, &bad, &RefineOptions::default()).unwrap_err();
    assert!(matches!(e, RefineError::BadStart { .. }), "{e:?}");
}
