//! Levels: split and duplicated records, per-level weighting, and the corner check.

use super::*;

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig {
        cases: 6,
        rng_seed: proptest::test_runner::RngSeed::Fixed(12),
        ..proptest::prelude::ProptestConfig::default()
    })]
    /// The same record given twice is two identical levels: the estimate is the same and
    /// every variance halves, exactly. A record cut in two pieces (two levels) gives
    /// estimates within the standard errors of the whole record's.
    #[test]
    fn duplicated_record_halves_the_variance_and_split_agrees(
        positions_only in proptest::bool::ANY,
        duration in 150.0f64..400.0,
        seed in 0u64..1000,
    ) {
        let ir = if positions_only { duffing_model() } else { sdof_model("") };
        let recs = simulate_short(&ir, &[15.0], duration, 0.05, seed);
        let one = run(&ir, &recs, &IdentifyOptions::default());
        let two = run(&ir, &[recs[0].clone(), recs[0].clone()], &IdentifyOptions::default());
        proptest::prop_assert_eq!(one.params.len(), two.params.len());
        for (a, b) in one.params.iter().zip(&two.params) {
            proptest::prop_assert!((a.value - b.value).abs() <= 1e-9 * a.value.abs(), "{:?} {:?}", a, b);
            let ratio = a.stderr / b.stderr;
            proptest::prop_assert!((ratio / 2f64.sqrt() - 1.0).abs() < 1e-9, "{}: ratio {}", a.name, ratio);
        }
        let n = recs[0].len();
        let halves = [slice(&recs[0], 0, n / 2), slice(&recs[0], n / 2, n)];
        let split = run(&ir, &halves, &IdentifyOptions::default());
        for a in &one.params {
            let b = split.param(&a.name).unwrap();
            // Both estimates see (nearly) the same data; they differ by the filter start
            // and the boundary terms at the cut. Measured: up to 1.0 standard errors of the
            // whole record (Duffing, positions only, 261 s, seed 651). A random case once
            // gave 4.6 SE (sdof, velocity measured, 259.6 s, seed 601): pinned, with what was
            // found about it, in `split_record_case_601`. The cases are drawn from a fixed
            // seed so that the suite is deterministic.
            proptest::prop_assert!((a.value - b.value).abs() < 2.0 * a.stderr.max(b.stderr), "{:?} {:?}", a, b);
        }
    }
}

/// The case a random draw of `duplicated_record_halves_the_variance_and_split_agrees` once
/// found outside its bound (sdof, velocity measured, 5 % noise, one level of 15, 259.6 s,
/// seed 601): k = 3.825 ± 0.052 whole against 4.066 ± 0.056 split, 4.6 standard errors
/// apart (truth 4). Re-measured on the current method (`cargo test -p dynid-runtime
/// split_record_case_601 -- --nocapture`): whole k = 3.822 ± 0.134, split 4.009 ± 0.048
/// (1.4 standard errors of the larger apart), halves 3.922 ± 0.135 and 3.827 ± 0.164. The
/// whole record's standard error of k is now 2.6 times the one recorded and covers the
/// difference: that was the 4.6. Not explained: the split estimate (k, and k3 = 1.98 against
/// 2.08 and 2.28) lies outside both halves' and its standard errors are about a third of
/// each half's, where two independent halves would give 1/√2 — pooling the two halves of
/// one level as two levels gains more than their data hold. Pinned here, so that both the
/// agreement and the pooled standard error are watched on this record.
#[test]
fn split_record_case_601() {
    let ir = sdof_model("");
    let recs = simulate_short(&ir, &[15.0], 259.6, 0.05, 601);
    let one = run(&ir, &recs, &IdentifyOptions::default());
    let n = recs[0].len();
    let halves = [slice(&recs[0], 0, n / 2), slice(&recs[0], n / 2, n)];
    let split = run(&ir, &halves, &IdentifyOptions::default());
    let h: Vec<Identification> = halves
        .iter()
        .map(|r| run(&ir, std::slice::from_ref(r), &IdentifyOptions::default()))
        .collect();
    for a in &one.params {
        let b = split.param(&a.name).unwrap();
        let (c, d) = (h[0].param(&a.name).unwrap(), h[1].param(&a.name).unwrap());
        eprintln!(
            "{}: whole {:.4} ± {:.4}, split {:.4} ± {:.4}, halves {:.4} ± {:.4} / {:.4} ± {:.4}",
            a.name, a.value, a.stderr, b.value, b.stderr, c.value, c.stderr, d.value, d.stderr
        );
        // The bound of the property test.
        assert!(
            (a.value - b.value).abs() < 2.0 * a.stderr.max(b.stderr),
            "{a:?} {b:?}"
        );
    }
    // Both within two of their standard errors of the truth (k: 1.3 and 0.2 measured).
    for id in [&one, &split] {
        let k = id.param("k").unwrap();
        assert!((k.value - 4.0).abs() < 2.0 * k.stderr, "{k:?}");
    }
    // The pooled standard error of k, against each half's (measured 0.35 and 0.29 of them):
    // if it grows to 1/√2 the anomaly is gone and this comment must go with it.
    let ratio = |i: usize| split.param("k").unwrap().stderr / h[i].param("k").unwrap().stderr;
    eprintln!(
        "pooled/half standard error of k: {:.2}, {:.2}",
        ratio(0),
        ratio(1)
    );
    assert!(
        ratio(0) < 0.5 && ratio(1) < 0.5,
        "{} {}",
        ratio(0),
        ratio(1)
    );
}

/// The two-step (efficient) weighting keeps the properties of the sandwich: the same
/// record given twice gives the same estimate and standard errors smaller by exactly √2
/// (the weighting of each level is its own), and its estimates lie within two of the
/// one-step standard errors of the one-step estimates.
#[test]
fn efficient_weighting_is_per_level_and_agrees_with_the_first_step() {
    let ir = sdof_model("");
    let recs = simulate_short(&ir, &[15.0], 300.0, 0.05, 7);
    let eff = IdentifyOptions {
        efficient: true,
        ..Default::default()
    };
    let first = run(&ir, &recs, &IdentifyOptions::default());
    let one = run(&ir, &recs, &eff);
    let two = run(&ir, &[recs[0].clone(), recs[0].clone()], &eff);
    assert_eq!(one.params.len(), first.params.len());
    for ((a, b), f) in one.params.iter().zip(&two.params).zip(&first.params) {
        assert!(
            (a.value - b.value).abs() <= 1e-9 * a.value.abs(),
            "{a:?} {b:?}"
        );
        let ratio = a.stderr / b.stderr;
        assert!(
            (ratio / 2f64.sqrt() - 1.0).abs() < 1e-9,
            "{}: ratio {ratio}",
            a.name
        );
        assert!(a.stderr > 0.0 && a.stderr.is_finite(), "{a:?}");
        assert!(
            (a.value - f.value).abs() < 2.0 * f.stderr,
            "{a:?} against {f:?}"
        );
    }
}

/// The target: corners a factor 4 above the designed ones, and as far below as the record
/// allows (the slowest chain must settle within the record: on 25 s with four sections the
/// lowest corner is 1.6 rad/s, the designed one already), move the estimates of the servo
/// axis (1 kHz, 25 s, random set points; `tests/servo.rs`) by less than their standard
/// errors at the designed corners. Not reached: measured
/// (`cargo test -p dynid-runtime --lib corners_a_factor_four -- --ignored --nocapture`),
/// seeds 1–3, designed corners 1.6…111–131 rad/s; a quarter of them (1.6…28–33 rad/s)
/// moves m, d, r, f0 by at most 2.15, 0.51, 0.59, 0.92 standard errors, four times them
/// (6.4…442–523 rad/s, above the design's cap of a tenth of the Nyquist frequency, where
/// the piecewise-linear input model loses accuracy) by up to 1.9, 3.2, 3.4 and 22.
#[test]
#[ignore = "the target is not reached yet: shifts up to 22 standard errors (see the doc)"]
fn corners_a_factor_four_away_move_the_servo_estimates_less_than_their_errors() {
    use crate::sim::test_models::ServoAxis;
    let mut worst: f64 = 0.0;
    for seed in 1..=3 {
        let mut axis = ServoAxis::standard();
        axis.reference.rms = 0.1;
        axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
        let ir = axis.model();
        let mut cfg = axis.config(seed);
        cfg.input_oversample = 10;
        let recs = sim::simulate(&ir, &cfg)
            .expect("closed-loop simulation")
            .records;
        let base = run(&ir, &recs, &IdentifyOptions::default());
        let c = base.filter.corners.clone();
        let (lo, hi) = (c[0], c[c.len() - 1]);
        let lmin = design::min_corner(24.999, 4) * 1.001;
        let n = c.len();
        let spread = |a: f64, b: f64| -> Vec<f64> {
            (0..n)
                .map(|i| a * (b / a).powf(i as f64 / (n - 1) as f64))
                .collect()
        };
        for corners in [
            spread(4.0 * lo, 4.0 * hi),
            spread((lo / 4.0).max(lmin), hi / 4.0),
        ] {
            let opts = IdentifyOptions {
                corners: Some(corners.clone()),
                ..Default::default()
            };
            let moved = run(&ir, &recs, &opts);
            let shifts: Vec<String> = base
                .params
                .iter()
                .map(|p| {
                    let q = moved.param(&p.name).expect("the same parameters");
                    let z = (q.value - p.value) / p.stderr;
                    worst = worst.max(z.abs());
                    format!("{} {z:+.2}", p.name)
                })
                .collect();
            println!(
                "seed {seed}, corners {:.1}…{:.1} rad/s against {lo:.1}…{hi:.1}: shifts in SE {}",
                corners[0],
                corners[n - 1],
                shifts.join(", ")
            );
        }
    }
    assert!(worst < 1.0, "a shift of {worst:.2} standard errors");
}
