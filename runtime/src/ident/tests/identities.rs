//! The moment formulas against direct quadrature, and the hold assumption.

use super::*;

/// The moment formulas against direct quadrature with the analytic derivatives, on a smooth
/// deterministic signal (filters at arbitrary corners, finite record, boundary terms on).
fn check_identity(corners: &[f64], n_blocks: usize) -> f64 {
    check_identity_with(corners, n_blocks, &[])
}

/// [`check_identity`] with the sample ranges `rests` left out of the moments (blocks
/// laid out by [`rests::layout`]); the direct quadrature then runs over the kept blocks.
fn check_identity_with(corners: &[f64], n_blocks: usize, rest: &[(usize, usize)]) -> f64 {
    let ir = duffing_model();
    let ts = 0.01;
    let n = 20_000;
    let w = [0.7, 1.9, 3.3];
    let amp = [1.0, 0.4, 0.2];
    let x = |t: f64| {
        (0..3)
            .map(|i| amp[i] * (w[i] * t + i as f64).sin())
            .sum::<f64>()
    };
    let xd = |t: f64| {
        (0..3)
            .map(|i| amp[i] * w[i] * (w[i] * t + i as f64).cos())
            .sum::<f64>()
    };
    let xdd = |t: f64| {
        (0..3)
            .map(|i| -amp[i] * w[i] * w[i] * (w[i] * t + i as f64).sin())
            .sum::<f64>()
    };
    let rec = Record {
        names: vec!["m1.x".into(), "u".into()],
        columns: vec![
            (0..n).map(|k| x(k as f64 * ts)).collect(),
            (0..n).map(|k| (0.3 * k as f64 * ts).cos()).collect(),
        ],
        ts,
        t0: 0.0,
    };
    let opts = IdentifyOptions {
        corners: Some(corners.to_vec()),
        n_blocks: Some(n_blocks),
        chunk_len: 777,
        ..Default::default()
    };
    let plan = plan_for(&ir, &opts, corners);
    let tape = Tape::compile(&ir, &plan.roots);
    let src = RecordSource::new(&rec, &ir, "smooth").unwrap();
    let mut acc = if rest.is_empty() {
        LevelAccumulator::new(&plan, &tape, ts, n, n_blocks, Hold::FirstOrder)
    } else {
        let (bounds, kept) = rests::layout(n, n_blocks, rest);
        LevelAccumulator::with_blocks(&plan, &tape, ts, n, bounds, kept, Hold::FirstOrder)
    };
    src.stream(opts.chunk_len, &mut |c, l| acc.push(c, l))
        .unwrap();
    let (lm, _) = acc.finish();
    let view = lm.view();
    let hats: Vec<MomentView> = (0..=lm.n_blocks()).map(|j| lm.hat(j)).collect();
    // Hat weights φ_j per sample (linear in the sample index within each block).
    let bounds: Vec<usize> = std::iter::once(0)
        .chain(lm.lens.iter().scan(0, |a, l| {
            *a += l;
            Some(*a)
        }))
        .collect();
    let phi = |j: usize, k: usize| -> f64 {
        let rise = j > 0 && lm.kept[j - 1] && k >= bounds[j - 1] && k <= bounds[j];
        let fall = j < lm.n_blocks() && lm.kept[j] && k >= bounds[j] && k <= bounds[j + 1];
        if rise {
            (k - bounds[j - 1]) as f64 / lm.lens[j - 1] as f64
        } else if fall {
            1.0 - (k - bounds[j]) as f64 / lm.lens[j] as f64
        } else {
            0.0
        }
    };
    // Direct: run the same filters and integrate ζ ẋ and ζ ẍ by the trapezoid rule.
    let xs = &rec.columns[0];
    let mut worst: f64 = 0.0;
    for (c, &lam) in corners.iter().enumerate() {
        let chain = filter::ChainDisc::new(lam, plan.order, ts, Hold::FirstOrder);
        let mut st = vec![0.0; plan.order];
        let mut out = vec![0.0; plan.order * n];
        chain.run(&mut st, xs[0], &xs[1..], &mut out[1..], n);
        for deg in plan.min_degree..=plan.order {
            let z = &out[(deg - 1) * n..deg * n];
            // The trapezoid rule over the kept blocks, per record interval kept.
            let trap = |f: &dyn Fn(usize) -> f64| {
                let (mut s, mut len) = (0.0, 0usize);
                let kept = bounds.windows(2).zip(&lm.kept).filter(|(_, k)| **k);
                for (w, _) in kept {
                    s += (w[0]..=w[1]).map(f).sum::<f64>() - 0.5 * (f(w[0]) + f(w[1]));
                    len += w[1] - w[0];
                }
                s / len as f64
            };
            let d1 = trap(&|k| z[k] * xd(k as f64 * ts));
            let d2 = trap(&|k| z[k] * xdd(k as f64 * ts));
            let state = plan.state(0, c, deg - 1);
            let ins = plan
                .instruments
                .iter()
                .find(|i| i.a == vec![(state, 1.0)])
                .unwrap();
            let xw = plan.roots.len() + plan.y_of[0].unwrap();
            let q = plan.n_col_signals();
            let m1 = term_moment(ins, &BasisMoment::D1Pos(xw), &view);
            let m2 = term_moment(ins, &BasisMoment::D2Pos(xw, q), &view);
            let scale1 = trap(&|k| z[k].abs() * xd(k as f64 * ts).abs());
            let scale2 = trap(&|k| z[k].abs() * xdd(k as f64 * ts).abs());
            worst = worst
                .max((m1 - d1).abs() / scale1)
                .max((m2 - d2).abs() / scale2);
            // Hat contributions: each against its own φ-weighted quadrature, and their sum
            // against the whole record (exact up to rounding).
            let (mut s1, mut s2) = (0.0, 0.0);
            for (j, hv) in hats.iter().enumerate() {
                let h1 = term_moment(ins, &BasisMoment::D1Pos(xw), hv);
                let h2 = term_moment(ins, &BasisMoment::D2Pos(xw, q), hv);
                // Read entry by entry (as the rows are formed), bit for bit the same.
                let lazy = Hat::new(&lm, j);
                let l1 = term_moment(ins, &BasisMoment::D1Pos(xw), &lazy);
                let l2 = term_moment(ins, &BasisMoment::D2Pos(xw, q), &lazy);
                assert_eq!((l1.to_bits(), l2.to_bits()), (h1.to_bits(), h2.to_bits()));
                s1 += h1;
                s2 += h2;
                let e1 = trap(&|k| phi(j, k) * z[k] * xd(k as f64 * ts));
                let e2 = trap(&|k| phi(j, k) * z[k] * xdd(k as f64 * ts));
                worst = worst
                    .max((h1 - e1).abs() / scale1)
                    .max((h2 - e2).abs() / scale2);
            }
            assert!((s1 - m1).abs() < 1e-10 * scale1, "hats {s1} vs whole {m1}");
            assert!((s2 - m2).abs() < 1e-10 * scale2, "hats {s2} vs whole {m2}");
        }
    }
    worst
}

#[test]
fn moment_formulas_match_analytic_derivatives() {
    // Both sides are trapezoid sums of the same integral with O((ωTₛ)²) quadrature error
    // (ω ≤ 3.3 rad/s here, so ~1e-4); an error in a boundary term or a derivative
    // combination would show up at order one.
    let err = check_identity(&[0.3, 1.0, 4.0, 12.0], 7);
    assert!(err < 3e-4, "relative error {err:e}");
}

/// With rests left out (one at the start, two inside, one at the end of the record), the
/// moments and every hat's contribution are those of the kept runs alone, each run with
/// its own boundary terms: the same quadrature check as without rests.
#[test]
fn moment_formulas_hold_with_rests_left_out() {
    let rest = [(0, 700), (3000, 4500), (9000, 9100), (19_200, 20_000)];
    let err = check_identity_with(&[0.3, 1.0, 4.0, 12.0], 7, &rest);
    assert!(err < 3e-4, "relative error {err:e}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig {
        cases: 16,
        rng_seed: proptest::test_runner::RngSeed::Fixed(12),
        ..proptest::prelude::ProptestConfig::default()
    })]
    #[test]
    fn moment_formulas_hold_for_random_corners(
        a in 0.1f64..20.0, b in 0.1f64..20.0, blocks in 2usize..30
    ) {
        let err = check_identity(&[a, b], blocks);
        proptest::prop_assert!(err < 1e-3, "relative error {:e}", err);
    }
}

/// With first-order instruments a zero-order hold biases damping by tens of percent (the
/// filter derivative `λ(s − ζ)` sees the input half a sample late). The chains used here take
/// instruments of relative degree ≥ 2, whose derivatives never involve the input sample, so a
/// hold error only delays the instrument as a whole — which leaves every identity valid.
#[test]
fn chains_make_the_hold_assumption_nearly_harmless() {
    let ir = sdof_model("");
    let recs = &sdof_data()[..];
    let foh = run(&ir, recs, &IdentifyOptions::default());
    let zoh = run(
        &ir,
        recs,
        &IdentifyOptions {
            hold: Hold::ZeroOrder,
            ..Default::default()
        },
    );
    let d = |id: &Identification| id.param("d").unwrap().value / 0.4 - 1.0;
    eprintln!(
        "damping error: FOH {:+.2}%, ZOH {:+.2}%",
        100.0 * d(&foh),
        100.0 * d(&zoh)
    );
    assert!(d(&foh).abs() < 0.01);
    assert!(d(&zoh).abs() < 0.02);
}
