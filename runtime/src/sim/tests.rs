use super::test_models::{integration_error, sdof, tracking, two_mass_chain, SdofParams};
use super::*;
use crate::describe::{mean, std_dev};
use dynid_ir::ir::FormFilter;
use nalgebra::DMatrix;

fn lowpass() -> FormFilter {
    FormFilter::Lowpass { corner: 10.0 }
}

fn cfg(duration: f64) -> SimConfig {
    SimConfig {
        duration,
        burn_in: 30.0,
        ..SimConfig::default()
    }
}

fn col<'a>(r: &'a Record, name: &str) -> &'a [f64] {
    r.column(name).unwrap()
}

fn mean_prod(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>() / a.len() as f64
}

/// Stationary covariance `P` of `z' = A z + w`, `E{w wᵀ} = W δ`: `A P + P Aᵀ + W = 0`,
/// solved through its Kronecker form.
fn lyapunov(a: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let id = DMatrix::<f64>::identity(n, n);
    let k = id.kronecker(a) + a.kronecker(&id);
    let rhs = -DMatrix::from_column_slice(n * n, 1, w.as_slice());
    let p = k.lu().solve(&rhs).unwrap();
    DMatrix::from_column_slice(n, n, p.as_slice())
}

#[test]
fn linear_sdof_variance_matches_lyapunov() {
    // m x'' + d x' + k x = u, u' = −a u + level w. The relative standard error of a
    // variance estimate here is ≈ sqrt(4 ∫ρ² / T) ≈ 1 % per level over 8000 s, and three
    // independent levels are pooled, so 3 % is a > 4σ bound.
    let (m, d, k, a) = (1.0, 2.0, 4.0, 10.0);
    let levels = vec![1.0, 2.0, 4.0];
    let ir = sdof(&SdofParams::linear(m, d, k), lowpass(), levels.clone());
    let out = simulate(
        &ir,
        &SimConfig {
            substeps: 5,
            ..cfg(8000.0)
        },
    )
    .unwrap();
    let amat = DMatrix::from_row_slice(
        3,
        3,
        &[0.0, 1.0, 0.0, -k / m, -d / m, 1.0 / m, 0.0, 0.0, -a],
    );
    let mut w = DMatrix::zeros(3, 3);
    w[(2, 2)] = 1.0;
    let p = lyapunov(&amat, &w);
    for (i, name) in ["m1.x", "m1.v", "u"].iter().enumerate() {
        let ratio = mean(
            &out.records
                .iter()
                .zip(&levels)
                .map(|(r, l)| std_dev(col(r, name)).powi(2) / (l * l * p[(i, i)]))
                .collect::<Vec<_>>(),
        );
        assert!((ratio - 1.0).abs() < 0.03, "{name}: var / theory = {ratio}");
    }
}

#[test]
fn two_mass_chain_variance_matches_lyapunov() {
    // Checks the multi-body sign conventions (coupling element, input on the second body).
    let (m, k, d) = ([1.0, 0.5], [4.0, 2.0], [1.0, 0.8]);
    let ir = two_mass_chain(m, k, d, lowpass(), vec![1.0, 1.0, 1.0]);
    let out = simulate(
        &ir,
        &SimConfig {
            substeps: 5,
            ..cfg(6000.0)
        },
    )
    .unwrap();
    #[rustfmt::skip]
    let amat = DMatrix::from_row_slice(5, 5, &[
        0.0, 1.0, 0.0, 0.0, 0.0,
        -(k[0] + k[1]) / m[0], -(d[0] + d[1]) / m[0], k[1] / m[0], d[1] / m[0], 0.0,
        0.0, 0.0, 0.0, 1.0, 0.0,
        k[1] / m[1], d[1] / m[1], -k[1] / m[1], -d[1] / m[1], 1.0 / m[1],
        0.0, 0.0, 0.0, 0.0, -10.0,
    ]);
    let mut w = DMatrix::zeros(5, 5);
    w[(4, 4)] = 1.0;
    let p = lyapunov(&amat, &w);
    for (i, name) in ["m1.x", "m1.v", "m2.x", "m2.v"].iter().enumerate() {
        let ratio = mean(
            &out.records
                .iter()
                .map(|r| std_dev(col(r, name)).powi(2) / p[(i, i)])
                .collect::<Vec<_>>(),
        );
        assert!((ratio - 1.0).abs() < 0.04, "{name}: var / theory = {ratio}");
    }
}

#[test]
fn second_order_excitation_reaches_the_model() {
    let (w, z, level) = (6.0, 0.4, 3.0);
    let filter = FormFilter::SecondOrder {
        freq: w,
        damping: z,
    };
    let ir = sdof(&SdofParams::linear(1.0, 2.0, 4.0), filter, vec![level; 3]);
    let out = simulate(&ir, &cfg(4000.0)).unwrap();
    let theory = level * level / (4.0 * z * w * w * w);
    let ratio = mean(
        &out.records
            .iter()
            .map(|r| std_dev(col(r, "u")).powi(2) / theory)
            .collect::<Vec<_>>(),
    );
    assert!((ratio - 1.0).abs() < 0.03, "var(u) / theory = {ratio}");
}

#[test]
fn power_balance_holds_for_the_benchmark() {
    // Stationarity of the kinetic + potential energy: the input power equals the power
    // dissipated by the damper and the friction, ⟨u v⟩ = d ⟨v²⟩ + r ⟨|v|⟩. The spring and
    // the cubic term store energy and drop out. This checks signs and the input coupling.
    let p = SdofParams::benchmark();
    let ir = sdof(&p, lowpass(), vec![6.0, 15.0, 40.0]);
    let out = simulate(&ir, &cfg(1000.0)).unwrap();
    for r in &out.records {
        let (u, v) = (col(r, "u"), col(r, "m1.v"));
        let input = mean_prod(u, v);
        let abs_v = mean(&v.iter().map(|v| v.abs()).collect::<Vec<_>>());
        let dissipated = p.d * mean_prod(v, v) + p.r.unwrap() * abs_v;
        assert!(
            (input / dissipated - 1.0).abs() < 0.03,
            "input {input} vs dissipated {dissipated}"
        );
    }
}

#[test]
fn free_vibration_conserves_energy() {
    // An undamped hardening oscillator kicked by a short input pulse: after the pulse the
    // energy m v²/2 + k x²/2 + k3 x⁴/4 must stay constant (RK4 error only).
    let p = SdofParams {
        m: 2.0,
        d: 0.0,
        k: 4.0,
        k3: Some(2.0),
        r: None,
    };
    let ir = sdof(&p, lowpass(), vec![1.0]);
    let n = 5000;
    let mut u = vec![0.0; n];
    for (i, u) in u.iter_mut().enumerate().take(21).skip(1) {
        *u = 30.0 * (std::f64::consts::PI * i as f64 / 20.0).sin();
    }
    let input = Record {
        names: vec!["u".into()],
        columns: vec![u],
        ts: 0.01,
        t0: 0.0,
    };
    let r = simulate_driven(&ir, &input, 20).unwrap();
    let (x, v) = (col(&r, "m1.x"), col(&r, "m1.v"));
    let e: Vec<f64> = (30..n)
        .map(|i| p.m * v[i] * v[i] / 2.0 + p.k * x[i] * x[i] / 2.0 + 2.0 * x[i].powi(4) / 4.0)
        .collect();
    assert!(e[0] > 1.0, "pulse must put energy in: {}", e[0]);
    let drift = e.iter().map(|x| (x / e[0] - 1.0).abs()).fold(0.0, f64::max);
    assert!(drift < 1e-9, "energy drift {drift}");
}

#[test]
fn deterministic_across_thread_counts() {
    let ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0, 15.0, 40.0]);
    let c = SimConfig {
        noise: 0.05,
        ..cfg(50.0)
    };
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| simulate(&ir, &c).unwrap())
    };
    let (a, b) = (run(1), run(2));
    for (ra, rb) in a.records.iter().zip(&b.records) {
        for (ca, cb) in ra.columns.iter().zip(&rb.columns) {
            assert!(ca.iter().zip(cb).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }
    // Another seed gives another record.
    let other = simulate(
        &ir,
        &SimConfig {
            seed: 2,
            ..c.clone()
        },
    )
    .unwrap();
    assert_ne!(other.records[0].columns[0], a.records[0].columns[0]);
}

#[test]
fn noise_has_the_requested_fraction_and_leaves_the_trajectory_alone() {
    let ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0, 40.0]);
    let clean = simulate(&ir, &cfg(200.0)).unwrap();
    let noisy = simulate(
        &ir,
        &SimConfig {
            noise: 0.05,
            ..cfg(200.0)
        },
    )
    .unwrap();
    for (rc, rn) in clean.records.iter().zip(&noisy.records) {
        for (c, n) in rc.columns.iter().zip(&rn.columns) {
            let diff: Vec<f64> = n.iter().zip(c).map(|(n, c)| n - c).collect();
            let frac = std_dev(&diff) / std_dev(c);
            // 20 000 samples: the std of a std estimate is 0.5 %.
            assert!((frac / 0.05 - 1.0).abs() < 0.025, "noise fraction {frac}");
            let corr = mean_prod(&diff, c) / (std_dev(&diff) * std_dev(c));
            assert!(
                corr.abs() < 0.03,
                "noise correlates with the signal: {corr}"
            );
        }
    }
    let clean_u = simulate(
        &ir,
        &SimConfig {
            noise: 0.05,
            noise_on_inputs: false,
            ..cfg(200.0)
        },
    )
    .unwrap();
    assert_eq!(col(&clean_u.records[0], "u"), col(&clean.records[0], "u"));
}

#[test]
fn integration_error_of_the_default_substeps_is_negligible() {
    let e = integration_error(DEFAULT_SUBSTEPS, 100.0);
    // Measured 1.0e-4 over 500 s (see the module doc).
    assert!(e < 2e-4, "relative RMS integration error {e}");
}

#[test]
fn driven_run_reproduces_the_excited_run_from_rest() {
    let ir = sdof(&SdofParams::benchmark(), lowpass(), vec![15.0]);
    let c = SimConfig {
        burn_in: 0.0,
        ..cfg(20.0)
    };
    let out = simulate(&ir, &c).unwrap();
    let rec = &out.records[0];
    let input = Record {
        names: vec!["t_unused".into(), "u".into()],
        columns: vec![vec![0.0; rec.len()], col(rec, "u").to_vec()],
        ts: rec.ts,
        t0: rec.t0,
    };
    let driven = simulate_driven(&ir, &input, c.substeps).unwrap();
    assert_eq!(driven.names, rec.names);
    assert_eq!(&driven, rec);
}

#[test]
fn driven_run_from_the_measured_state_has_no_start_transient() {
    // With a burn-in the record starts in motion.
    let mut ir = sdof(&SdofParams::benchmark(), lowpass(), vec![15.0]);
    let out = simulate(&ir, &cfg(20.0)).unwrap();
    let rec = &out.records[0];
    let x = col(rec, "m1.x");
    let sx = std_dev(x);
    let max_err = |driven: &Record, n: usize| {
        col(driven, "m1.x")[..n]
            .iter()
            .zip(&x[..n])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / sx
    };
    let rest = simulate_driven(&ir, rec, 20).unwrap();
    assert!(max_err(&rest, 100) > 0.1, "{}", max_err(&rest, 100));
    let measured = simulate_driven_from(&ir, rec, 20, Start::Measured).unwrap();
    assert!(max_err(&measured, rec.len()) < 1e-12);
    // Without a measured velocity it comes from the first three positions.
    ir.signals[1].measured = false;
    let positions = Record {
        names: vec!["m1.x".into(), "u".into()],
        columns: vec![x.to_vec(), col(rec, "u").to_vec()],
        ts: rec.ts,
        t0: rec.t0,
    };
    let from_x = simulate_driven_from(&ir, &positions, 20, Start::Measured).unwrap();
    let e = max_err(&from_x, rec.len());
    assert!(e < 1e-3, "{e}");
}

#[test]
fn errors_name_the_culprit() {
    let mut ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0]);
    let r = ir.params.iter_mut().find(|p| p.name == "r").unwrap();
    r.kind = ParamKind::Unknown { nominal: None };
    let e = simulate(&ir, &cfg(10.0)).unwrap_err();
    assert!(e.to_string().contains("`r`"), "{e}");

    // Negative damping: the run blows up and says where.
    let ir = sdof(
        &SdofParams::linear(1.0, -1.0, 4.0),
        lowpass(),
        vec![6.0, 15.0],
    );
    let e = simulate(&ir, &cfg(2000.0)).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, SimError::Diverged { .. }), "{msg}");
    assert!(msg.contains("level"), "{msg}");
    // Time counts from the start of the run (never a negative time in the warm-up).
    assert!(msg.contains("s after the start"), "{msg}");
    assert!(!msg.contains("t = -"), "{msg}");

    // Negative damping bounded by a hardening spring: a limit cycle far above the Nyquist
    // frequency, which must not pass as data.
    let p = SdofParams {
        d: -1.5,
        ..SdofParams::benchmark()
    };
    let e = simulate(&sdof(&p, lowpass(), vec![6.0]), &cfg(500.0)).unwrap_err();
    assert!(matches!(e, SimError::UnderResolved { .. }), "{e}");
    assert!(e.to_string().contains("`m1`"), "{e}");

    let ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0]);
    let input = Record {
        names: vec!["f".into()],
        columns: vec![vec![0.0; 10]],
        ts: 0.01,
        t0: 0.0,
    };
    let e = simulate_driven(&ir, &input, 4).unwrap_err();
    assert!(e.to_string().contains("`u`"), "{e}");

    let mut ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0]);
    ir.excitation.clear();
    assert!(matches!(
        simulate(&ir, &cfg(10.0)),
        Err(SimError::NoExcitation { .. })
    ));
    let ir = sdof(
        &SdofParams::benchmark(),
        FormFilter::Lowpass { corner: 0.0 },
        vec![6.0],
    );
    assert!(matches!(
        simulate(&ir, &cfg(10.0)),
        Err(SimError::BadFormFilter { .. })
    ));
}

#[test]
fn records_have_the_measured_signals_and_the_time_base() {
    let mut ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0, 15.0]);
    ir.signals[1].measured = false;
    let out = simulate(
        &ir,
        &SimConfig {
            sample: 0.02,
            ..cfg(10.0)
        },
    )
    .unwrap();
    assert_eq!(out.records.len(), 2);
    let r = &out.records[0];
    assert_eq!(r.names, ["m1.x", "u"]);
    assert_eq!(r.len(), 500);
    assert_eq!(r.ts, 0.02);
    assert_eq!(out.truth.parameters["k3"], 2.0);
    assert_eq!(out.truth.unknown, ["d", "k", "k3", "r"]);
    assert_eq!(out.truth.levels, [6.0, 15.0]);
    let over = simulate(
        &ir,
        &SimConfig {
            levels: Some(vec![1.0, 2.0, 3.0]),
            ..cfg(10.0)
        },
    )
    .unwrap();
    assert_eq!(over.records.len(), 3);
    assert_eq!(over.truth.excitation[0].levels, [1.0, 2.0, 3.0]);
}

/// The benchmark driven through a low-pass form filter, no burn-in: sample interval `ts`,
/// `fine` input steps per sample and `substeps` RK4 steps per sample.
fn oversampled_run(ts: f64, fine: usize, substeps: usize, duration: f64) -> Record {
    let ir = sdof(&SdofParams::benchmark(), lowpass(), vec![15.0]);
    let out = simulate(
        &ir,
        &SimConfig {
            sample: ts,
            input_oversample: fine,
            substeps,
            burn_in: 0.0,
            ..cfg(duration)
        },
    )
    .unwrap();
    out.records.into_iter().next().unwrap()
}

#[test]
fn oversampled_input_drives_the_mechanics_between_samples() {
    // A run at Ts with 10 input steps per sample is the run at Ts/10 (same random stream,
    // same RK4 steps) read every 10th sample: the mechanics see the fine input, not a
    // line between the coarse samples.
    let (ts, n) = (0.01, 10);
    let coarse = oversampled_run(ts, n, 2 * n, 20.0);
    let fine = oversampled_run(ts / n as f64, 1, 2, 20.0);
    assert_eq!(fine.len(), n * coarse.len());
    for name in ["u", "m1.x", "m1.v"] {
        let (c, f) = (col(&coarse, name), col(&fine, name));
        assert!(
            c.iter().zip(f.iter().step_by(n)).all(|(a, b)| a == b),
            "{name} differs from the fine run's samples"
        );
    }
}

#[test]
fn input_between_samples_has_the_variance_of_the_form_filter() {
    // The fine input minus the line through the coarse samples. For the stationary
    // Ornstein–Uhlenbeck input (corner a, covariance C(τ) = P e^{−a|τ|}, P = level²/2a),
    // at fraction f of the interval: Var = C(0)(1 + (1−f)² + f²) − 2(1−f) C(fT) − 2f C((1−f)T)
    // + 2 f(1−f) C(T). 200 000 intervals give the mean over f to well under 1 %.
    let (ts, n, level, a) = (0.01, 10, 15.0, 10.0);
    let fine = oversampled_run(ts / n as f64, 1, 1, 2000.0);
    let u = col(&fine, "u");
    let p = level * level / (2.0 * a);
    let c = |tau: f64| p * (-a * tau).exp();
    let (mut sum, mut theory, mut count) = (0.0, 0.0, 0);
    for k in 0..(u.len() - 1) / n {
        let (u0, u1) = (u[k * n], u[(k + 1) * n]);
        for j in 1..n {
            let f = j as f64 / n as f64;
            let d = u[k * n + j] - ((1.0 - f) * u0 + f * u1);
            sum += d * d;
            theory += c(0.0) * (1.0 + (1.0 - f).powi(2) + f * f)
                - 2.0 * (1.0 - f) * c(f * ts)
                - 2.0 * f * c((1.0 - f) * ts)
                + 2.0 * f * (1.0 - f) * c(ts);
            count += 1;
        }
    }
    let (var, theory) = (sum / count as f64, theory / count as f64);
    assert!((var / theory - 1.0).abs() < 0.02, "{var} vs {theory}");
    // Not negligible: 3.7 % of the input's variance, a fifth of its standard deviation.
    assert!(var > 0.02 * std_dev(u).powi(2), "{var}");
}

#[test]
fn oversampling_keeps_the_input_statistics_at_the_samples() {
    // The intensity keeps its meaning: a low-pass input sampled at Ts has the same variance
    // level²/2a whatever the oversampling (relative standard error ≈ 1 % per run here).
    let theory = 15.0 * 15.0 / 20.0;
    for n in [1, 20] {
        let r = oversampled_run(0.01, n, 20, 4000.0);
        let v = std_dev(col(&r, "u")).powi(2);
        assert!(
            (v / theory - 1.0).abs() < 0.04,
            "oversample {n}: {v} vs {theory}"
        );
    }
}

#[test]
fn quantised_positions_are_multiples_of_the_resolution() {
    let ir = sdof(&SdofParams::benchmark(), lowpass(), vec![6.0, 40.0]);
    let q = 1e-3;
    let c = SimConfig {
        noise: 0.02,
        ..cfg(50.0)
    };
    let plain = simulate(&ir, &c).unwrap();
    let quant = simulate(
        &ir,
        &SimConfig {
            quantise: Some(q),
            ..c.clone()
        },
    )
    .unwrap();
    for (rp, rq) in plain.records.iter().zip(&quant.records) {
        let (x, xq) = (col(rp, "m1.x"), col(rq, "m1.x"));
        assert!(xq.iter().all(|&x| q * (x / q).round() == x));
        // Rounded after the noise: within half a step of the noisy value.
        assert!(x
            .iter()
            .zip(xq)
            .all(|(a, b)| (a - b).abs() <= 0.5 * q * (1.0 + 1e-9)));
        // Several hundred distinct levels are used, so the test is not trivial.
        let mut levels: Vec<i64> = xq.iter().map(|x| (x / q).round() as i64).collect();
        levels.sort_unstable();
        levels.dedup();
        assert!(levels.len() > 100, "{} levels", levels.len());
        // Velocities and inputs are not quantised.
        assert_eq!(col(rp, "m1.v"), col(rq, "m1.v"));
        assert_eq!(col(rp, "u"), col(rq, "u"));
    }
    let e = simulate(
        &ir,
        &SimConfig {
            quantise: Some(-1.0),
            ..c
        },
    )
    .unwrap_err();
    assert!(matches!(e, SimError::InvalidConfig { .. }), "{e}");
}

#[test]
fn servo_axis_tracks_its_reference_with_a_coloured_force() {
    use super::test_models::ServoAxis;
    let axis = ServoAxis::standard();
    let ir = axis.model();
    let out = simulate(&ir, &axis.config(5)).unwrap();
    let r = &out.records[0];
    assert_eq!(r.names, ["m.x", "u", "m.x_ref"]);
    assert_eq!(r.len(), 25_000);
    let (err, rho) = tracking(r);
    // Measured 0.016 to 0.021 over seeds 1 to 6, and 0.9985 to 0.9989 for the
    // autocorrelation (white noise would give 0): `cargo run --release -p dynid-runtime
    // --features test-support --example measurements -- servo`.
    assert!(err < 0.05, "relative tracking error {err}");
    assert!(rho > 0.99, "lag-1 autocorrelation of the force {rho}");
    // The reference moves centimetres at up to about half a metre per second.
    let xr = col(r, "m.x_ref");
    let peak_speed = xr
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() / axis.sample)
        .fold(0.0, f64::max);
    assert!(std_dev(xr) > 0.01 && std_dev(xr) < 0.09, "{}", std_dev(xr));
    assert!(peak_speed > 0.2 && peak_speed < 1.0, "{peak_speed}");
    // Encoder positions.
    let q = axis.resolution;
    assert!(col(r, "m.x").iter().all(|&x| q * (x / q).round() == x));
    // Same seed, same record; another seed, another one.
    let again = simulate(&ir, &axis.config(5)).unwrap();
    assert_eq!(again.records[0], *r);
    let other = simulate(&ir, &axis.config(6)).unwrap();
    assert_ne!(col(&other.records[0], "u"), col(r, "u"));
    assert_eq!(out.truth.control, axis.config(5).control);
}

#[test]
fn tachometer_feedback_tracks_like_the_position_difference() {
    use super::test_models::ServoAxis;
    let axis = ServoAxis {
        duration: 10.0,
        ..ServoAxis::standard()
    };
    let ir = axis.model();
    let mut c = axis.config(7);
    let diff = simulate(&ir, &c).unwrap();
    c.control.as_mut().unwrap().velocity = VelocitySource::Tachometer;
    let tacho = simulate(&ir, &c).unwrap();
    let (e_diff, _) = tracking(&diff.records[0]);
    let (e_tacho, _) = tracking(&tacho.records[0]);
    assert!(
        (e_diff / e_tacho - 1.0).abs() < 0.3,
        "{e_diff} vs {e_tacho}"
    );
    assert_ne!(col(&diff.records[0], "u"), col(&tacho.records[0], "u"));
}

#[test]
fn bad_control_and_oversampling_settings_are_reported() {
    use super::test_models::ServoAxis;
    let axis = ServoAxis::standard();
    let ir = axis.model();
    let mut c = axis.config(1);
    c.control.as_mut().unwrap().input = "f".into();
    let e = simulate(&ir, &c).unwrap_err();
    assert!(e.to_string().contains("`f`"), "{e}");
    let mut c = axis.config(1);
    c.control.as_mut().unwrap().reference.corner = 0.0;
    assert!(matches!(
        simulate(&ir, &c),
        Err(SimError::InvalidConfig { .. })
    ));
    let c = SimConfig {
        input_oversample: 0,
        ..axis.config(1)
    };
    assert!(matches!(
        simulate(&ir, &c),
        Err(SimError::InvalidConfig { .. })
    ));
    // Without the controller the model has nothing to drive it.
    let c = SimConfig {
        control: None,
        ..axis.config(1)
    };
    assert!(matches!(
        simulate(&ir, &c),
        Err(SimError::NoExcitation { .. })
    ));
}

/// The servo axis of `models/servo_axis.dyn`: a PD law on `u` following the set point `xr`.
const SERVO_LOOP: &str = "model servo_loop {
    body m ~ 50
    input u on m
    reference xr
    control u = 80000 * (xr - m.x) - 2680 * m.v
    damper d (ground, m) ~ 120
    force friction (ground, m) = r ~ 15 * sign(v)
    excite xr: second_order(freq = 5, damping = 0.7071) levels [0.1, 0.9]
}";

#[test]
fn a_control_law_closes_the_loop_and_records_set_point_and_force() {
    let ir = dsl_parser::compile_str("servo_loop.dyn", SERVO_LOOP).unwrap();
    let cfg = SimConfig {
        duration: 200.0,
        sample: 1e-3,
        burn_in: 2.0,
        ..SimConfig::default()
    };
    let out = simulate(&ir, &cfg).unwrap();
    for rec in &out.records {
        assert_eq!(rec.names, ["m.x", "m.v", "u", "xr"]);
        let (x, v, u, xr) = (
            col(rec, "m.x"),
            col(rec, "m.v"),
            col(rec, "u"),
            col(rec, "xr"),
        );
        // The recorded force is the law at the sample instants.
        for k in (0..rec.len()).step_by(997) {
            let law = 80000.0 * (xr[k] - x[k]) - 2680.0 * v[k];
            assert!(
                (u[k] - law).abs() <= 1e-9 * (1.0 + law.abs()),
                "{k}: {} vs {law}",
                u[k]
            );
        }
        // The loop follows the set point (bandwidth 40 rad/s against a 5 rad/s set point;
        // the friction's lag keeps the error at 0.21 and 0.17 of the set point's std on the
        // two levels; an open loop would not follow at all).
        let e: Vec<f64> = x.iter().zip(xr).map(|(x, r)| x - r).collect();
        let rel = (mean_prod(&e, &e)).sqrt() / std_dev(xr);
        assert!(rel < 0.5, "tracking error {rel}");
    }
    // The set point's intensity scales with the level: 9× between the two levels (200 s
    // hold about 600 correlation times of the set point: a few per cent of sampling error).
    let s = |k: usize| std_dev(col(&out.records[k], "xr"));
    assert!((s(1) / s(0) - 9.0).abs() < 1.2, "{}", s(1) / s(0));
}

#[test]
fn a_driven_run_closes_the_loop_on_the_recorded_set_point() {
    // Controller and simulation on the sample grid: the driven run, started from the first
    // sample's state and fed the recorded set point, retraces the record.
    let ir = dsl_parser::compile_str("servo_loop.dyn", SERVO_LOOP).unwrap();
    let cfg = SimConfig {
        duration: 10.0,
        sample: 1e-3,
        burn_in: 2.0,
        ..SimConfig::default()
    };
    let rec = &simulate(&ir, &cfg).unwrap().records[1];
    let set_point = Record {
        names: vec!["m.x".into(), "m.v".into(), "xr".into()],
        columns: vec![
            col(rec, "m.x").to_vec(),
            col(rec, "m.v").to_vec(),
            col(rec, "xr").to_vec(),
        ],
        ts: rec.ts,
        t0: rec.t0,
    };
    let driven = simulate_driven_from(&ir, &set_point, cfg.substeps, Start::Measured).unwrap();
    for name in ["m.x", "u"] {
        let (a, b) = (col(&driven, name), col(rec, name));
        let worst = a
            .iter()
            .zip(b)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9 * std_dev(b), "{name}: {worst:e}");
    }
    // Without the set point the loop cannot run.
    let mut no_set_point = set_point.clone();
    no_set_point.names[2] = "r".into();
    let e = simulate_driven(&ir, &no_set_point, 20).unwrap_err();
    assert!(
        matches!(e, SimError::MissingInputColumn { ref input, .. } if input == "xr"),
        "{e}"
    );
}

#[test]
fn a_pd_controller_on_a_model_with_its_own_law_is_refused() {
    let ir = dsl_parser::compile_str("servo_loop.dyn", SERVO_LOOP).unwrap();
    let mut cfg = super::test_models::ServoAxis::standard().config(1);
    cfg.duration = 1.0;
    let e = simulate(&ir, &cfg).unwrap_err();
    assert!(e.to_string().contains("control law"), "{e}");
}

#[test]
fn a_control_law_undefined_on_the_state_is_named_with_the_run_time() {
    // `sqrt` of the tracking error: NaN as soon as the mass overshoots the set point.
    let src = SERVO_LOOP.replace(
        "control u = 80000 * (xr - m.x) - 2680 * m.v",
        "control u = 80000 * sqrt(xr - m.x) - 2680 * m.v",
    );
    let ir = dsl_parser::compile_str("servo_sqrt.dyn", &src).unwrap();
    let cfg = SimConfig {
        duration: 2.0,
        sample: 1e-3,
        burn_in: 2.0,
        ..SimConfig::default()
    };
    let e = simulate(&ir, &cfg).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, SimError::ControlLaw { .. }), "{msg}");
    assert!(msg.contains("`u = 80000 * sqrt(xr - m.x)"), "{msg}");
    assert!(msg.contains("NaN"), "{msg}");
    // The time counts from the start of the run, and the warm-up is named as such
    // (never a negative time).
    assert!(msg.contains("s after the start"), "{msg}");
    assert!(msg.contains("warm-up"), "{msg}");
    assert!(!msg.contains("t = -"), "{msg}");
}
