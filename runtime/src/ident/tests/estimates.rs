//! Estimates and their standard errors: flags, warnings, coverage.

use super::*;

#[test]
fn insignificant_parameter_is_kept_flagged_and_not_refitted() {
    // Quadratic damping that the data do not contain (true value 0), 5 % noise, 300 s.
    let ir = sdof_model("force q (ground, m1) = cq ~ 0.0 * v * abs(v)");
    let recs = simulate_short(&ir, &[6.0, 15.0], 300.0, 0.05, 7);
    let id = run(&ir, &recs, &IdentifyOptions::default());
    let cq = id
        .param("cq")
        .expect("an insignificant parameter keeps its value");
    eprintln!("cq = {:.3e} ± {:.1e}", cq.value, cq.stderr);
    assert!(!cq.significant, "{cq:?}");
    assert!(cq.value.abs() <= SIGNIFICANCE_T * cq.stderr);
    assert!(id.unidentifiable.is_empty());
    for n in ["d", "k", "k3", "r"] {
        assert!(id.param(n).unwrap().significant);
    }
    // With pruning (the structure search's choice) `cq` is left out and the others are
    // refitted without it: they move, which the default fit must not do.
    let srcs: Vec<RecordSource> = recs
        .iter()
        .map(|r| RecordSource::new(r, &ir, "level").unwrap())
        .collect();
    let dyns: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let tape = Tape::compile(&ir, &ir.eval_roots());
    let mut m = measure(&ir, &tape, &dyns, &IdentifyOptions::default()).unwrap();
    assert_eq!(m.identify_pooled().param("d"), id.param("d"));
    m.prune_insignificant(true);
    let pruned = m.identify_pooled();
    assert!(pruned.param("cq").is_none());
    assert!(pruned.unidentifiable[0].reason.contains("left out"));
    assert_ne!(
        pruned.param("d").unwrap().value,
        id.param("d").unwrap().value
    );
}

#[test]
fn unphysical_estimates_are_warned_about_by_kind() {
    let ir = sdof_model("force q (ground, m1) = cq ~ 0.0 * v * abs(v)");
    let kinds: Vec<Option<Quantity>> = ["d", "k", "k3", "r", "cq"]
        .iter()
        .map(|n| stats::quantity_of(&ir, n).map(|q| q.0))
        .collect();
    assert_eq!(
        kinds,
        [
            Some(Quantity::Damping),
            Some(Quantity::Stiffness),
            None,
            Some(Quantity::Friction),
            None
        ]
    );
    let mass = dsl_parser::compile_str(
        "m",
        "model m {
            body m1 ~ 1.0
            input u on m1
            spring k (ground, m1) ~ 4.0
            damper d (ground, m1) ~ 0.4
        }",
    )
    .unwrap();
    assert_eq!(stats::quantity_of(&mass, "m1").unwrap().0, Quantity::Mass);
    let est = |name: &str, value: f64, stderr: f64| ParamEstimate {
        name: name.into(),
        value,
        stderr,
        significant: value.abs() > SIGNIFICANCE_T * stderr,
    };
    let w = stats::physical_warnings(
        &mass,
        &[
            est("m1", -0.5, 0.01),
            est("k", 4.0, 0.1),
            est("d", -0.001, 0.01),
        ],
    );
    assert_eq!(w.len(), 2, "{w:?}");
    assert!(w[0].unphysical && w[0].quantity == Quantity::Mass, "{w:?}");
    assert!(w[0].message.contains("negative mass") && w[0].message.contains("unphysical"));
    assert!(
        !w[1].unphysical && w[1].quantity == Quantity::Damping,
        "{w:?}"
    );
    assert!(w[1].message.contains("do not show"), "{}", w[1].message);
    // End to end: a known damper of twice the true damping leaves the unknown one at
    // about −0.4, far below zero.
    let over = sdof_model("damper d0 (ground, m1) = 0.8");
    let recs = simulate_short(&sdof_model(""), &[15.0], 200.0, 0.0, 3);
    let id = run(&over, &recs, &IdentifyOptions::default());
    let d = id.param("d").unwrap();
    assert!(d.value < -0.3, "{d:?}");
    assert_eq!(id.warnings.len(), 1, "{:?}", id.warnings);
    assert!(id.warnings[0].unphysical && id.warnings[0].param == "d");
}

/// Coverage of the standard errors: over 20 seeds (three levels of 200 s, 5 % noise on
/// every channel) the error of each parameter should be within two standard errors in about
/// 95 % of the cases. Measured (this test, `-- --nocapture`): 76 of 80 (95 %), per
/// parameter (d, k, k3, r) 20, 18, 19, 19 of 20; rms z 1.04, 1.04, 1.04, 1.05. The blocks
/// are chosen from the record (80 of 2.5 s here, [`design::blocks`]); with the former fixed
/// 20 blocks of 10 s the same seeds gave 71 of 80 (89 %), rms z 1.19–1.31, and two other
/// sets of 20 seeds (`100 + seed` replaced by `300 + seed`, `600 + seed`) 91 → 95 % and
/// 88 → 91 %. (Without the noise correction `k3` kept about one standard error of
/// errors-in-variables bias: 65 of 80 with 20 blocks, k3 13 of 20, rms z 1.77.) A bias
/// remains noise-free, the simulated input's path between samples (docs/method.md §3 and
/// §7, "Known bias"; its size at Tₛ = 0.01 and 0.005 s is measured by
/// `the_known_bias_falls_with_the_sample_interval`: about a tenth of a per cent), well
/// inside these standard errors (0.2–1.5 %).
#[test]
fn standard_errors_cover_the_error() {
    let ir = sdof_model("");
    let truth = sdof_truth();
    let seeds = 20;
    let mut inside = vec![0usize; truth.len()];
    let mut z2 = vec![0.0; truth.len()];
    for seed in 0..seeds {
        let recs = simulate_short(&ir, &[6.0, 15.0, 40.0], 200.0, 0.05, 100 + seed);
        let id = run(&ir, &recs, &IdentifyOptions::default());
        assert!(id.levels.iter().all(|l| l.blocks == design::MAX_BLOCKS));
        for (k, (n, t)) in truth.iter().enumerate() {
            let p = id.param(n).unwrap();
            let z = (p.value - t) / p.stderr;
            z2[k] += z * z;
            if z.abs() < 2.0 {
                inside[k] += 1;
            }
        }
    }
    let total: usize = inside.iter().sum();
    let frac = total as f64 / (seeds as usize * truth.len()) as f64;
    eprintln!(
        "|error| < 2 se: {total} of {} ({:.0} %); per parameter {inside:?}; rms z {:?}",
        seeds as usize * truth.len(),
        100.0 * frac,
        z2.iter()
            .map(|v| format!("{:.2}", (v / seeds as f64).sqrt()))
            .collect::<Vec<_>>()
    );
    assert!(frac >= 0.9, "coverage {frac}");
    for (k, n) in inside.iter().enumerate() {
        assert!(*n >= 17, "{}: {n} of {seeds}", truth[k].0);
    }
    // Standard errors of the right order: an error estimate erratic by a factor of up
    // to ten, or an uncorrected noise bias, would fail this.
    for (k, v) in z2.iter().enumerate() {
        let rms = (v / seeds as f64).sqrt();
        assert!(rms < 1.25, "{}: rms z {rms}", truth[k].0);
    }
}
