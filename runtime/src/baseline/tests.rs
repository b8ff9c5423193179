use super::*;
use crate::sim::{self, test_models::ServoAxis};
use std::f64::consts::PI;

/// Truth of the servo axis of `tests/servo.rs`, in the order of [`SERVO_TERMS`].
const TRUTH: [(&str, f64); 4] = [("m", 50.0), ("d", 120.0), ("r", 15.0), ("f0", -2.0)];

/// The servo record of `tests/servo.rs` (1 kHz, 25 s, 10 cm RMS random reference,
/// controller ten times per sample, offset −2 N), with or without the 1 µm encoder.
fn servo(seed: u64, quantised: bool) -> Record {
    let mut axis = ServoAxis::standard();
    axis.reference.rms = 0.1;
    axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
    let ir = axis.model();
    let mut cfg = axis.config(seed);
    cfg.input_oversample = 10;
    if !quantised {
        cfg.quantise = None;
    }
    let mut out = sim::simulate(&ir, &cfg).expect("closed-loop simulation");
    out.records.remove(0)
}

/// Relative errors and relative standard errors `(e, se_ols, se_hac)` against [`TRUTH`].
fn errors(fit: &Fit) -> Vec<(f64, f64, f64)> {
    TRUTH
        .iter()
        .zip(&fit.estimates)
        .zip(fit.stderr_ols.iter().zip(&fit.stderr_hac))
        .map(|(((_, t), v), (so, sh))| (v / t - 1.0, so / t.abs(), sh / t.abs()))
        .collect()
}

fn show(what: &str, fit: &Fit) {
    let e: Vec<String> = TRUTH
        .iter()
        .zip(errors(fit))
        .map(|((n, _), (e, so, sh))| {
            format!(
                "{n} {:+.3} % (±{:.3} % OLS, ±{:.3} % HAC)",
                100.0 * e,
                100.0 * so,
                100.0 * sh
            )
        })
        .collect();
    println!(
        "{what}: {}; {} rows, cond {:.1}",
        e.join(", "),
        fit.rows,
        fit.condition
    );
}

#[test]
fn butterworth_has_unit_gain_and_minus_3_db_at_the_corner() {
    let (ts, fc) = (1e-3, 100.0);
    for order in [1, 2, 4, 5] {
        let b = Butterworth::lowpass(order, fc, ts);
        let gain = |f: f64| {
            let z = num_complex(2.0 * PI * f * ts);
            b.sections.iter().fold(1.0, |g, s| {
                let num = poly(&[s[0], s[1], s[2]], z);
                let den = poly(&[1.0, s[3], s[4]], z);
                g * (num.0.hypot(num.1) / den.0.hypot(den.1))
            })
        };
        assert!((gain(0.0) - 1.0).abs() < 1e-12, "order {order}");
        assert!(
            (gain(fc) - 0.5f64.sqrt()).abs() < 1e-9,
            "order {order}: {}",
            gain(fc)
        );
    }
}

/// `e^{−iω}` as `(re, im)`.
fn num_complex(w: f64) -> (f64, f64) {
    (w.cos(), -w.sin())
}

/// `c₀ + c₁ z + c₂ z²` for complex `z`.
fn poly(c: &[f64; 3], z: (f64, f64)) -> (f64, f64) {
    let z2 = (z.0 * z.0 - z.1 * z.1, 2.0 * z.0 * z.1);
    (c[0] + c[1] * z.0 + c[2] * z2.0, c[1] * z.1 + c[2] * z2.1)
}

#[test]
fn filtfilt_has_no_phase_and_keeps_the_ends() {
    // A 5 Hz sine on a ramp through a 100 Hz low-pass: the middle is the signal scaled by
    // |H(5 Hz)|² (≈ 1), without delay; the ends are within 10⁻³ of it.
    let ts = 1e-3;
    let x: Vec<f64> = (0..2000)
        .map(|k| {
            let t = k as f64 * ts;
            (2.0 * PI * 5.0 * t).sin() + 3.0 * t
        })
        .collect();
    let b = Butterworth::lowpass(4, 100.0, ts);
    let mut y = Vec::new();
    b.filtfilt(&x, 60, &mut y);
    let err = x
        .iter()
        .zip(&y)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-3, "largest difference {err}");
    let mid = x[200..1800]
        .iter()
        .zip(&y[200..1800])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(mid < 1e-6, "largest difference away from the ends {mid}");
}

#[test]
fn state_variable_filter_states_are_derivatives() {
    // A 3 Hz sine through the 80 Hz filter: state d is the d-th derivative of state 0
    // (checked by central differences, error O(Tₛ² ω²) ≈ 10⁻³ relative), and far below the
    // corner the filtered sine is the sine delayed by `delay()`.
    let ts = 1e-3;
    let w = 2.0 * PI * 3.0;
    let x: Vec<f64> = (0..3000).map(|k| (w * k as f64 * ts).sin()).collect();
    let f = StateVariableFilter::new(80.0, ts);
    let (mut s0, mut s1, mut s2) = (Vec::new(), Vec::new(), Vec::new());
    f.run(&x, &mut [&mut s0, &mut s1, &mut s2]);
    for k in 1000..2999 {
        let d1 = (s0[k + 1] - s0[k - 1]) / (2.0 * ts);
        let d2 = (s1[k + 1] - s1[k - 1]) / (2.0 * ts);
        assert!((d1 - s1[k]).abs() < 5e-4 * w, "k {k}: {d1} vs {}", s1[k]);
        assert!(
            (d2 - s2[k]).abs() < 5e-4 * w * w,
            "k {k}: {d2} vs {}",
            s2[k]
        );
        let delayed = (w * (k as f64 * ts - f.delay())).sin();
        assert!((s0[k] - delayed).abs() < 1e-4, "k {k}");
    }
}

/// A linear axis `m x'' + d x' + k x + f0 = u` with `x` a sum of three sines (0.7–4.3 Hz)
/// and `u` computed from it exactly, 10 s at 1 kHz: both baselines recover all four
/// parameters. Measured (`cargo test -p dynid-runtime baseline::tests::exact --
/// --nocapture`), largest relative error: IDIM-LS 7.0·10⁻⁵, SVF-LS 1.8·10⁻⁷ at 10 Hz and
/// 9.3·10⁻⁵ at 80 Hz — the error of central differences and of interpolating `x` and `u`
/// linearly between samples, `O(ω² Tₛ²)`, which the faster filter passes.
#[test]
fn exact_linear_record_is_recovered() {
    let (m, d, k, f0) = (2.0, 3.0, 50.0, -1.0);
    let ts = 1e-3;
    let sines = [(0.02, 0.7, 0.3), (0.01, 2.1, 1.1), (0.004, 4.3, 2.0)];
    let (mut x, mut u) = (Vec::new(), Vec::new());
    for i in 0..10_000 {
        let t = i as f64 * ts;
        let (mut p, mut v, mut a) = (0.0, 0.0, 0.0);
        for (amp, hz, ph) in sines {
            let w = 2.0 * PI * hz;
            p += amp * (w * t + ph).sin();
            v += amp * w * (w * t + ph).cos();
            a -= amp * w * w * (w * t + ph).sin();
        }
        x.push(p);
        u.push(m * a + d * v + k * p + f0);
    }
    let rec = Record {
        names: vec!["x".into(), "u".into()],
        columns: vec![x, u],
        ts,
        t0: 0.0,
    };
    let terms = vec![
        Term::Acceleration,
        Term::Velocity,
        Term::Position,
        Term::Constant,
    ];
    let idim = IdimOptions {
        terms: terms.clone(),
        rest: 0.0,
        ..IdimOptions::default()
    };
    let fits = [
        (
            "IDIM-LS",
            idim_ls(&rec, "x", "u", &idim).expect("IDIM-LS"),
            2e-4,
        ),
        (
            "SVF-LS 10 Hz",
            svf_ls(
                &rec,
                "x",
                "u",
                &SvfOptions {
                    terms: terms.clone(),
                    ..SvfOptions::at(10.0)
                },
            )
            .expect("SVF-LS"),
            1e-6,
        ),
        (
            "SVF-LS 80 Hz",
            svf_ls(
                &rec,
                "x",
                "u",
                &SvfOptions {
                    terms,
                    ..SvfOptions::at(80.0)
                },
            )
            .expect("SVF-LS"),
            2e-4,
        ),
    ];
    for (what, fit, bound) in fits {
        let worst = fit
            .estimates
            .iter()
            .zip([m, d, k, f0])
            .map(|(e, t)| (e / t - 1.0).abs())
            .fold(0.0, f64::max);
        println!(
            "{what}: {:?}, largest relative error {worst:.2e}",
            fit.estimates
        );
        assert!(worst < bound, "{what}: {:?}", fit.estimates);
    }
}

/// The largest relative error over seeds 1–4 of noise-free, unquantised servo records
/// (measured, `cargo test -p dynid-runtime baseline::tests::noise_free -- --nocapture`):
/// m, d, r, f0 of IDIM-LS 0.050, 0.28, 1.09, 1.8 %; of SVF-LS at 10 Hz 0.124, 0.32, 1.25,
/// 1.9 %; at 80 Hz 0.037, 0.105, 0.159, 0.34 %. These are the estimators' own biases: the
/// Coulomb column is `sign` of a filtered velocity where the force carries the filtered
/// `sign` (IDIM-LS, and SVF-LS at the slow corner where the aligned sign switches away from
/// the velocity's zero crossings), and the mass is high by about 0.03 % in all three.
#[test]
fn noise_free_servo_axis_is_recovered() {
    // Bounds: about twice the largest measured error.
    let bounds = [
        ("IDIM-LS", [0.001, 0.006, 0.02, 0.04]),
        ("SVF-LS 10 Hz", [0.0025, 0.007, 0.025, 0.04]),
        ("SVF-LS 80 Hz", [0.0008, 0.0025, 0.0035, 0.008]),
    ];
    for seed in 1..=4 {
        let rec = servo(seed, false);
        let fits = [
            idim_ls(&rec, "m.x", "u", &IdimOptions::default()).expect("IDIM-LS"),
            svf_ls(&rec, "m.x", "u", &SvfOptions::at(10.0)).expect("SVF-LS"),
            svf_ls(&rec, "m.x", "u", &SvfOptions::at(80.0)).expect("SVF-LS"),
        ];
        for ((what, bound), fit) in bounds.iter().zip(&fits) {
            show(&format!("seed {seed} {what}"), fit);
            for (((name, _), (e, _, _)), b) in TRUTH.iter().zip(errors(fit)).zip(bound) {
                assert!(
                    e.abs() < *b,
                    "seed {seed} {what}: `{name}` off by {:+.3} % (bound {} %)",
                    100.0 * e,
                    100.0 * b
                );
            }
        }
    }
}

/// A baseline by name.
type Method<'a> = (&'static str, &'a dyn Fn(&Record) -> Fit);

/// What the standard errors describe: the scatter that the noise of the record (here the
/// 1 µm encoder, through the loop) adds to the estimate. On seeds 1–`seeds` the change of
/// each estimate between the unquantised and the quantised record of one seed is compared
/// with the quantised record's standard errors; returns, per method, the fraction within
/// 2 SE (classical, Newey–West) and the same fractions for the error against the truth.
fn coverage(seeds: u64) -> Vec<(&'static str, [f64; 4])> {
    let methods: [Method; 3] = [
        ("IDIM-LS", &|r| {
            idim_ls(r, "m.x", "u", &IdimOptions::default()).expect("IDIM-LS")
        }),
        ("SVF-LS 10 Hz", &|r| {
            svf_ls(r, "m.x", "u", &SvfOptions::at(10.0)).expect("SVF-LS")
        }),
        ("SVF-LS 80 Hz", &|r| {
            svf_ls(r, "m.x", "u", &SvfOptions::at(80.0)).expect("SVF-LS")
        }),
    ];
    let mut counts = vec![[0usize; 4]; methods.len()];
    for seed in 1..=seeds {
        let (clean, noisy) = (servo(seed, false), servo(seed, true));
        for ((what, f), c) in methods.iter().zip(counts.iter_mut()) {
            let (a, b) = (f(&clean), f(&noisy));
            show(&format!("seed {seed} {what}"), &b);
            for (j, (_, t)) in TRUTH.iter().enumerate() {
                let change = b.estimates[j] - a.estimates[j];
                let error = b.estimates[j] - t;
                let (so, sh) = (b.stderr_ols[j], b.stderr_hac[j]);
                for (slot, inside) in c.iter_mut().zip([
                    change.abs() < 2.0 * so,
                    change.abs() < 2.0 * sh,
                    error.abs() < 2.0 * so,
                    error.abs() < 2.0 * sh,
                ]) {
                    *slot += inside as usize;
                }
            }
        }
    }
    let total = (seeds as usize * TRUTH.len()) as f64;
    methods
        .iter()
        .zip(counts)
        .map(|((what, _), c)| {
            let f = c.map(|c| c as f64 / total);
            println!(
                "{what}: the noise's share within 2 SE: {:.0} % (OLS), {:.0} % (HAC); \
                 the error: {:.0} % (OLS), {:.0} % (HAC)",
                100.0 * f[0],
                100.0 * f[1],
                100.0 * f[2],
                100.0 * f[3]
            );
            (*what, f)
        })
        .collect()
}

/// Seeds 1–4, 16 estimates per method. Measured (`cargo test -p dynid-runtime
/// baseline::tests::standard_errors -- --nocapture`): the noise's share is within 2 SE
/// (either kind) for all 16 of each method. Against the truth the coverage is poor — 38 %
/// (IDIM-LS), 62 % (SVF-LS 10 Hz), 69 % (SVF-LS 80 Hz) with Newey–West errors — because
/// the biases of `noise_free_servo_axis_is_recovered` exceed the standard errors of `r`
/// and `m`; that is printed, not asserted.
#[test]
fn standard_errors_cover_the_noise() {
    for (what, f) in coverage(4) {
        // The Newey–West errors cover the noise's share at least 14 times in 16.
        assert!(f[1] >= 14.0 / 16.0, "{what}: {f:?}");
    }
}

/// The long form of [`standard_errors_cover_the_noise`]: seeds 1–12 (`cargo test -p
/// dynid-runtime baseline::tests::coverage_12 -- --ignored --nocapture`).
#[test]
#[ignore = "long form: 12 seeds"]
fn coverage_12_seeds() {
    for (what, f) in coverage(12) {
        assert!(f[1] >= 0.85, "{what}: {f:?}");
    }
}

#[test]
fn bad_inputs_are_named() {
    let rec = Record {
        names: vec!["x".into(), "u".into()],
        columns: vec![vec![0.0; 100], vec![0.0; 100]],
        ts: 1e-3,
        t0: 0.0,
    };
    let missing = idim_ls(&rec, "m.x", "u", &IdimOptions::default()).unwrap_err();
    assert!(
        matches!(&missing, BaselineError::MissingColumn { name, .. } if name == "m.x"),
        "{missing}"
    );
    let corner = svf_ls(&rec, "x", "u", &SvfOptions::at(450.0)).unwrap_err();
    assert!(
        matches!(corner, BaselineError::BadSetting { .. }),
        "{corner}"
    );
    // A record that never moves leaves no row once rest is dropped.
    let still = idim_ls(&rec, "x", "u", &IdimOptions::default()).unwrap_err();
    assert!(matches!(still, BaselineError::TooFewRows { .. }), "{still}");
    let mut nan = rec.clone();
    nan.columns[1][7] = f64::NAN;
    let err = svf_ls(&nan, "x", "u", &SvfOptions::at(10.0)).unwrap_err();
    assert!(
        matches!(err, BaselineError::NonFinite { at: 7, .. }),
        "{err}"
    );
    // A position that does not move: its column is the constant column.
    let constant = Record {
        columns: vec![vec![0.3; 2000], vec![1.0; 2000]],
        ..rec
    };
    let opts = SvfOptions {
        terms: vec![Term::Position, Term::Constant],
        ..SvfOptions::at(10.0)
    };
    let err = svf_ls(&constant, "x", "u", &opts).unwrap_err();
    assert!(matches!(err, BaselineError::Collinear { .. }), "{err}");
}

/// The linear axis of [`exact_linear_record_is_recovered`] (60 s) with white noise of
/// 0.2 % of its spread (about 30 µm) on the position: SVF-LS at 80 Hz underestimates the
/// mass, since the noise in `(L x)''` adds to the normal matrix (errors in the variables);
/// with [`SvfOptions::position_noise_var`] that part is taken out. Measured
/// (`cargo test -p dynid-runtime baseline::tests::compensation -- --nocapture`): noise SD
/// 32 µm, mass −47 % (HAC SE 0.73 %) without and +0.71 % (SE 1.1 %) with the compensation;
/// the test asserts the bias beyond 3 SE and the compensated error within 3 SE. Rows dropped
/// at rest ([`SvfOptions::rest`], 1 mm/s: 53 336 of 59 899 rows kept) leave the noise-free
/// record recovered as exactly as with every row (largest error 9.3·10⁻⁵).
#[test]
fn compensation_removes_the_noise_bias_and_rests_drop_rows() {
    let (m, d, k, f0) = (2.0, 3.0, 50.0, -1.0);
    let ts = 1e-3;
    let sines = [(0.02, 0.7, 0.3), (0.01, 2.1, 1.1), (0.004, 4.3, 2.0)];
    let (mut x, mut u) = (Vec::new(), Vec::new());
    for i in 0..60_000 {
        let t = i as f64 * ts;
        let (mut p, mut v, mut a) = (0.0, 0.0, 0.0);
        for (amp, hz, ph) in sines {
            let w = 2.0 * PI * hz;
            p += amp * (w * t + ph).sin();
            v += amp * w * (w * t + ph).cos();
            a -= amp * w * w * (w * t + ph).sin();
        }
        x.push(p);
        u.push(m * a + d * v + k * p + f0);
    }
    let clean = x.clone();
    let mut rec = Record {
        names: vec!["x".into(), "u".into()],
        columns: vec![x, u],
        ts,
        t0: 0.0,
    };
    let terms = vec![
        Term::Acceleration,
        Term::Velocity,
        Term::Position,
        Term::Constant,
    ];
    let exact = SvfOptions {
        terms: terms.clone(),
        rest: 1e-3,
        ..SvfOptions::at(80.0)
    };
    let all = svf_ls(
        &rec,
        "x",
        "u",
        &SvfOptions {
            rest: 0.0,
            ..exact.clone()
        },
    )
    .expect("SVF-LS");
    let resting = svf_ls(&rec, "x", "u", &exact).expect("SVF-LS");
    println!(
        "rows {} of {}, {:?}",
        resting.rows, all.rows, resting.estimates
    );
    assert!(resting.rows < all.rows);
    for (e, t) in resting.estimates.iter().zip([m, d, k, f0]) {
        assert!((e / t - 1.0).abs() < 2e-4, "{:?}", resting.estimates);
    }
    sim::test_models::add_noise(&mut rec, "x", 2e-3, 7);
    let var = rec.columns[0]
        .iter()
        .zip(&clean)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / clean.len() as f64;
    let opts = SvfOptions {
        terms,
        ..SvfOptions::at(80.0)
    };
    let plain = svf_ls(&rec, "x", "u", &opts).expect("SVF-LS");
    let comp = svf_ls(
        &rec,
        "x",
        "u",
        &SvfOptions {
            position_noise_var: var,
            ..opts
        },
    )
    .expect("SVF-LS");
    let (pm, cm) = (plain.estimates[0] / m - 1.0, comp.estimates[0] / m - 1.0);
    println!(
        "noise sd {:.2e}: mass error plain {pm:.2e} (SE {:.2e}), compensated {cm:.2e} (SE {:.2e})",
        var.sqrt(),
        plain.stderr_hac[0] / m,
        comp.stderr_hac[0] / m
    );
    assert!(
        pm < -3.0 * plain.stderr_hac[0] / m,
        "the noise biases the mass"
    );
    assert!(cm.abs() < 3.0 * comp.stderr_hac[0] / m, "compensated: {cm}");
}
