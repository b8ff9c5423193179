//! The bank's paths against each other and against the reference chain.

use super::*;

/// First-order section with a ramp input s = t: ζ(t) = t − (1 − e^{−λt})/λ exactly.
#[test]
fn foh_is_exact_for_a_ramp_and_zoh_is_not() {
    let (lambda, ts, n) = (3.0, 0.01, 500);
    let s: Vec<f64> = (0..n).map(|k| k as f64 * ts).collect();
    let exact = |t: f64| t - (1.0 - (-lambda * t).exp()) / lambda;
    for (hold, tol) in [(Hold::FirstOrder, 1e-13), (Hold::ZeroOrder, f64::INFINITY)] {
        let d = ChainDisc::new(lambda, 1, ts, hold);
        let mut st = [0.0];
        let mut out = vec![0.0; n - 1];
        d.run(&mut st, s[0], &s[1..], &mut out, n - 1);
        let err = (1..n)
            .map(|k| (out[k - 1] - exact(k as f64 * ts)).abs())
            .fold(0.0, f64::max);
        if hold == Hold::FirstOrder {
            assert!(err < tol, "FOH error {err}");
        } else {
            // ZOH lags by half a sample: error → Tₛ/2 once the transient has decayed.
            assert!((err - ts / 2.0).abs() < 0.1 * ts, "ZOH error {err}");
        }
    }
}

/// A smooth multi-tone driving signal.
fn signal(n: usize, phase: f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64 * 0.01;
            (1.3 * t + phase).sin() + 0.4 * (7.1 * t).cos() + 0.05 * (31.0 * t + phase).sin()
        })
        .collect()
}

/// The largest difference relative to the largest value.
fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let err = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    err / scale
}

type Path = fn(&FilterBank, &mut BankState, &[&[f64]], usize, Option<(&mut [f64], usize)>);

/// The vector paths of [`FilterBank::advance`] this processor can run. Each path is
/// reported as `vector path NAME: tested` or `vector path NAME: SKIPPED (why)` (shown
/// with `--nocapture`, and in the output of a failing test), so that a run on a
/// processor without AVX-512 says so. `DYNID_REQUIRE_VECTOR_PATHS=avx,avx512` turns a
/// skip of a named path into a failure (for a machine known to have it).
fn vector_paths() -> Vec<(&'static str, Path)> {
    #[allow(unused_mut)]
    let mut paths: Vec<(&'static str, Path)> = Vec::new();
    #[allow(unused_mut)]
    let mut skipped: Vec<(&'static str, &'static str)> = Vec::new();
    #[cfg(target_arch = "x86_64")]
    {
        if super::x86::has_avx_fma() {
            // SAFETY: the processor has what the path needs (checked just above).
            paths.push(("avx", |b, s, d, l, o| unsafe { b.advance_avx(s, d, l, o) }));
        } else {
            skipped.push(("avx", "the processor lacks avx and fma"));
        }
        if super::x86::has_avx512() {
            // SAFETY: the processor has what the path needs (checked just above).
            paths.push(("avx512", |b, s, d, l, o| unsafe {
                b.advance_avx512(s, d, l, o)
            }));
        } else {
            skipped.push(("avx512", "the processor lacks avx512f"));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    skipped.extend([("avx", "not x86_64"), ("avx512", "not x86_64")]);
    for (name, _) in &paths {
        eprintln!("vector path {name}: tested");
    }
    for (name, why) in &skipped {
        eprintln!("vector path {name}: SKIPPED ({why})");
    }
    let required = std::env::var("DYNID_REQUIRE_VECTOR_PATHS").unwrap_or_default();
    for name in required.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        assert!(
            paths.iter().any(|(p, _)| *p == name),
            "DYNID_REQUIRE_VECTOR_PATHS names `{name}`, which this processor cannot run \
             (tested: {:?}, skipped: {skipped:?})",
            paths.iter().map(|(p, _)| *p).collect::<Vec<_>>()
        );
    }
    paths
}

/// Which vector paths this processor runs and which the tests skip: `.ci/run` shows
/// this test's output, so a CI machine without AVX-512 states it.
#[test]
fn vector_paths_tested_and_skipped() {
    let paths = vector_paths();
    #[cfg(target_arch = "x86_64")]
    assert_eq!(
        paths.iter().any(|(n, _)| *n == "avx512"),
        super::x86::has_avx512(),
        "the AVX-512 path is tested exactly where the processor has it"
    );
    #[cfg(not(target_arch = "x86_64"))]
    assert!(paths.is_empty());
}

/// The bank (structure of arrays, fed in uneven pieces) against the per-chain recursion
/// of `ChainDisc::run`, for every order with an odd number of corners (a padded block),
/// to 1e-12 of the largest value of each state.
#[test]
fn bank_equals_the_per_chain_recursion() {
    let (ts, n) = (0.01, 3001);
    let drivers = [signal(n, 0.0), signal(n, 1.0), signal(n, 2.5)];
    // Every count of chains per driver up to 13: whole and partial last blocks, one to
    // three blocks per driver (the vector path's sizes) and four (the portable path).
    let many: Vec<f64> = (0..13).map(|c| 0.3 * 1.35f64.powi(c)).collect();
    let cases = (1..=13).map(|nc| (MAX_ORDER, many[..nc].to_vec()));
    let cases = cases.chain((1..=MAX_ORDER).map(|o| (o, vec![0.3, 1.1, 2.5, 6.0, 19.0])));
    let paths = vector_paths();
    for (order, corners) in cases {
        let bank = FilterBank::new(&corners, drivers.len(), order, ts, Hold::FirstOrder);
        let stride = bank.n_rows() + 3;
        let prev: Vec<f64> = drivers.iter().map(|s| s[0]).collect();
        // Every path this processor has, fed in uneven pieces.
        let run = |path: Path| {
            let mut st = bank.state(&prev);
            let mut out = vec![f64::NAN; (n - 1) * stride];
            let mut k0 = 1;
            for piece in [1, 17, 1000, 1981, 1] {
                let ds: Vec<&[f64]> = drivers.iter().map(|s| &s[k0..k0 + piece]).collect();
                let o = Some((&mut out[(k0 - 1) * stride..], stride));
                path(&bank, &mut st, &ds, piece, o);
                k0 += piece;
            }
            assert_eq!(k0, n);
            (st, out)
        };
        let (st, out) = run(FilterBank::advance);
        // The portable path, in one piece, and every vector path give the same values
        // bit for bit.
        let mut st_any = bank.state(&prev);
        let mut out_any = vec![f64::NAN; (n - 1) * stride];
        let ds: Vec<&[f64]> = drivers.iter().map(|s| &s[1..]).collect();
        bank.advance_any(&mut st_any, &ds, n - 1, Some((&mut out_any, stride)));
        for &(name, path) in &paths {
            let (st_v, out_v) = run(path);
            assert_eq!(st_v, st_any, "{name}, order {order}");
            assert!(
                out_v
                    .iter()
                    .zip(&out_any)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}, order {order}, {} corners",
                corners.len()
            );
        }
        assert_eq!(st_any, st, "order {order}");
        for (k, (a, b)) in out.iter().zip(&out_any).enumerate() {
            if k % stride < bank.n_rows() {
                assert_eq!(a.to_bits(), b.to_bits(), "order {order}, {k}");
            } else {
                assert!(a.is_nan(), "written past the rows: {k}");
            }
        }
        let mut worst = 0.0f64;
        for (d, s) in drivers.iter().enumerate() {
            for (c, &lambda) in corners.iter().enumerate() {
                let chain = ChainDisc::new(lambda, order, ts, Hold::FirstOrder);
                let mut z = vec![0.0; order];
                let mut want = vec![0.0; order * (n - 1)];
                chain.run(&mut z, s[0], &s[1..], &mut want, n - 1);
                for i in 0..order {
                    let got: Vec<f64> = (0..n - 1)
                        .map(|k| out[k * stride + bank.row(d, c, i)])
                        .collect();
                    worst = worst.max(rel_diff(&got, &want[i * (n - 1)..(i + 1) * (n - 1)]));
                }
                worst = worst.max(rel_diff(&st.chain(&bank, d, c), &z));
            }
        }
        assert!(
            worst <= 1e-12,
            "order {order}: relative difference {worst:e}"
        );
        assert_eq!(
            st.prev(),
            &[drivers[0][n - 1], drivers[1][n - 1], drivers[2][n - 1]]
        );
    }
}

/// Linearity, as the time-parallel pass uses it: the run from a state equals the run
/// from rest plus the free response `Φ^m ζ` of that state.
#[test]
fn a_run_is_the_run_from_rest_plus_the_free_response() {
    let (ts, n) = (0.01, 1500);
    let corners = [0.5, 2.0, 9.0];
    let s = signal(n + 1, 0.3);
    for order in [1, 2, 3, 5] {
        let mut bank = FilterBank::new(&corners, 1, order, ts, Hold::FirstOrder);
        bank.prepare_propagation(n);
        // A state reached by running for a while.
        let mut start = bank.state(&[s[0]]);
        let warm = signal(400, 2.0);
        bank.advance(&mut start, &[&warm], warm.len(), None);
        let start = BankState {
            prev: vec![s[0]],
            ..start
        };
        for m in [1, 2, 7, 64, 1000, n] {
            let mut direct = start.clone();
            bank.advance(&mut direct, &[&s[1..]], m, None);
            let mut rest = bank.state(&[s[0]]);
            bank.advance(&mut rest, &[&s[1..]], m, None);
            let mut composed = start.clone();
            bank.propagate(&mut composed, m);
            bank.add(&mut composed, &rest);
            for c in 0..corners.len() {
                let (a, b) = (composed.chain(&bank, 0, c), direct.chain(&bank, 0, c));
                let err = rel_diff(&a, &b);
                assert!(err <= 1e-12, "order {order}, m = {m}, corner {c}: {err:e}");
            }
        }
    }
}

#[test]
fn chains_match_the_generic_loop() {
    let d = ChainDisc::new(2.5, 3, 0.01, Hold::FirstOrder);
    let s: Vec<f64> = (0..200).map(|k| (k as f64 * 0.05).sin()).collect();
    let mut a = [0.1, 0.2, 0.3];
    let mut b = a;
    let mut oa = vec![0.0; 3 * 199];
    let mut ob = oa.clone();
    d.run3(&mut a, s[0], &s[1..], &mut oa, 199);
    // Generic path through a 3-chain built as order 3 but forced through the loop.
    let mut prev = s[0];
    for (k, &sk) in s[1..].iter().enumerate() {
        let next: [f64; 3] = std::array::from_fn(|i| {
            let lin: f64 = (0..=i).map(|j| d.phi[i * 3 + j] * b[j]).sum();
            lin + d.g0[i] * prev + d.g1[i] * sk
        });
        b = next;
        for i in 0..3 {
            ob[i * 199 + k] = b[i];
        }
        prev = sk;
    }
    for (a, b) in oa.iter().zip(&ob) {
        assert!((a - b).abs() < 1e-14, "{a} vs {b}");
    }
}

/// The chain's noise covariance is the sum of products of its impulse response as `run`
/// produces it (a unit sample, then zeros), and for one first-order section the closed form
/// `g₁² + (φ g₁ + g₀)² / (1 − φ²)`.
#[test]
fn noise_covariance_sums_the_impulse_response_of_run() {
    let (lambda, ts) = (30.0, 0.01);
    let d = ChainDisc::new(lambda, 1, ts, Hold::FirstOrder);
    let (phi, g0, g1) = (d.phi[0], d.g0[0], d.g1[0]);
    let closed = g1 * g1 + (phi * g1 + g0).powi(2) / (1.0 - phi * phi);
    let p = d.noise_covariance();
    assert!((p[0] / closed - 1.0).abs() < 1e-9, "{} vs {closed}", p[0]);
    for order in [3, 4] {
        let d = ChainDisc::new(lambda, order, ts, Hold::FirstOrder);
        let n = 4000;
        let mut s = vec![0.0; n];
        s[0] = 1.0;
        let mut st = vec![0.0; order];
        let mut out = vec![0.0; order * n];
        d.run(&mut st, 0.0, &s, &mut out, n);
        let p = d.noise_covariance();
        for i in 0..order {
            for j in 0..order {
                let direct: f64 = (0..n).map(|k| out[i * n + k] * out[j * n + k]).sum();
                assert!(
                    (p[i * order + j] - direct).abs() < 1e-9 * direct.abs().max(1e-12),
                    "order {order} ({i}, {j}): {} vs {direct}",
                    p[i * order + j]
                );
            }
        }
    }
}
