//! The streamed moment pass against a serial computation, across chunks and tasks.

use super::*;

/// The time-parallel moment pass against a direct serial computation: every chain by the
/// per-chain recursion of [`filter::ChainDisc::run`] over the whole record, every block sum
/// by a plain loop over the samples. Fed in chunks of 777 samples cut into tasks of 37 (about
/// 400 tasks, so hundreds of composed start states), in chunks of 8192 with the default
/// tasks, and in one chunk; every sum within 1e-12 of the sum of the magnitudes of its
/// terms. The result does not depend on the number of threads (bit for bit).
#[test]
fn time_parallel_pass_matches_the_serial_recursion() {
    let ir = sdof_model("");
    let ts = 0.01;
    let cfg = SimConfig {
        levels: Some(vec![15.0]),
        duration: 150.0,
        sample: ts,
        seed: 7,
        ..Default::default()
    };
    let rec = sim::simulate(&ir, &cfg).unwrap().records.remove(0);
    let n = rec.len();
    // Five corners: the last block of lanes of each driver is padded.
    let corners = [0.4, 1.0, 2.6, 7.0, 15.0];
    let n_blocks = 7;
    let opts = IdentifyOptions {
        corners: Some(corners.to_vec()),
        n_blocks: Some(n_blocks),
        column_chains: true,
        ..Default::default()
    };
    let plan = plan_for(&ir, &opts, &corners);
    let tape = Tape::compile(&ir, &plan.roots);
    let src = RecordSource::new(&rec, &ir, "sdof").unwrap();
    let run = |chunk: usize, task: usize| {
        let mut acc = LevelAccumulator::new(&plan, &tape, ts, n, n_blocks, Hold::FirstOrder);
        acc.set_task_len(task);
        src.stream(chunk, &mut |c, l| acc.push(c, l)).unwrap();
        assert!(acc.non_finite.is_none());
        acc.finish().0
    };

    // Direct computation over the whole record.
    let mut cols: Vec<Vec<f64>> = Vec::new();
    src.stream(n, &mut |c, l| {
        assert_eq!(l, n);
        cols = c.iter().map(|s| s.to_vec()).collect();
    })
    .unwrap();
    let view: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
    let (n_row_signals, n_col_signals, n_snap_cols, n_filter_states, n_g) = (
        plan.n_row_signals(),
        plan.n_col_signals(),
        plan.n_snap_cols(),
        plan.n_filter_states(),
        plan.roots.len(),
    );
    let mut w = vec![0.0; n_col_signals * n];
    crate::basis::BasisEval::eval_block(&tape, &view, n, &mut w[..n_g * n], &mut Vec::new());
    for (j, s) in plan.y.iter().enumerate() {
        w[(n_g + j) * n..(n_g + j + 1) * n].copy_from_slice(view[s.index()]);
    }
    let mut iota = vec![0.0; n_row_signals * n];
    // Signal drivers, then column drivers (the model's `s^3` and `sign(v)`; the velocity
    // is measured, so no column driver is delayed).
    assert_eq!(plan.root_drivers.len(), 2);
    for d in 0..plan.n_drivers() {
        let x = match d.checked_sub(plan.drivers.len()) {
            None => view[plan.drivers[d].index()],
            Some(r) => {
                assert!(!plan.root_drivers[r].delayed);
                let g = plan.root_drivers[r].root;
                &w[g * n..(g + 1) * n]
            }
        };
        for (c, &lam) in plan.corners.iter().enumerate() {
            let chain = filter::ChainDisc::new(lam, plan.order, ts, Hold::FirstOrder);
            let mut st = vec![0.0; plan.order];
            let mut out = vec![0.0; plan.order * n];
            chain.run(&mut st, x[0], &x[1..], &mut out[1..], n);
            for i in 0..plan.order {
                let r = plan.state(d, c, i);
                iota[r * n..(r + 1) * n].copy_from_slice(&out[i * n..(i + 1) * n]);
            }
        }
    }
    for (j, s) in plan.y.iter().enumerate() {
        iota[(n_filter_states + j) * n..(n_filter_states + j + 1) * n]
            .copy_from_slice(view[s.index()]);
    }
    let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
    let widths = vec![1.0; plan.extra.len()];
    fill_extra(
        &plan.extra,
        &widths,
        &ys,
        n,
        &mut w[(n_g + plan.y.len()) * n..],
    );
    let bounds: Vec<usize> = (0..=n_blocks).map(|b| b * (n - 1) / n_blocks).collect();
    let mut want = vec![
        (
            vec![0.0; n_row_signals * n_col_signals],
            vec![0.0; n_row_signals * n_col_signals]
        );
        n_blocks
    ];
    let mut scale = want.clone();
    for b in 0..n_blocks {
        for k in bounds[b]..bounds[b + 1] {
            let s = (k - bounds[b]) as f64;
            for i in 0..n_row_signals {
                for j in 0..n_col_signals {
                    let v = iota[i * n + k] * w[j * n + k];
                    want[b].0[i * n_col_signals + j] += v;
                    want[b].1[i * n_col_signals + j] += s * v;
                    scale[b].0[i * n_col_signals + j] += v.abs();
                    scale[b].1[i * n_col_signals + j] += s * v.abs();
                }
            }
        }
    }

    let check = |lm: &LevelMoments, what: &str| {
        assert_eq!(
            lm.lens,
            bounds.windows(2).map(|w| w[1] - w[0]).collect::<Vec<_>>()
        );
        let mut worst = 0.0f64;
        for b in 0..n_blocks {
            for (got, (want, scale)) in [
                (&lm.sums[b], (&want[b].0, &scale[b].0)),
                (&lm.tsums[b], (&want[b].1, &scale[b].1)),
            ] {
                for ((g, w), s) in got.iter().zip(want).zip(scale) {
                    worst = worst.max((g - w).abs() / s.max(f64::MIN_POSITIVE));
                }
            }
        }
        for (b, &k) in bounds.iter().enumerate() {
            for i in 0..n_row_signals {
                for j in 0..n_col_signals {
                    let v = iota[i * n + k] * w[j * n + k];
                    let g = lm.snaps[b][i * n_snap_cols + j];
                    worst = worst.max((g - v).abs() / v.abs().max(f64::MIN_POSITIVE));
                }
            }
        }
        eprintln!("{what}: worst relative difference {worst:e}");
        assert!(worst <= 1e-12, "{what}: relative difference {worst:e}");
    };
    let in_pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(777, 37))
    };
    let one = in_pool(1);
    check(&one, "chunks of 777, tasks of 37");
    let two = in_pool(2);
    assert!(one.sums == two.sums && one.tsums == two.tsums && one.snaps == two.snaps);
    check(&run(8192, TASK_LEN), "chunks of 8192");
    check(&run(n, n), "one chunk");
}

/// A column with an estimated velocity (`sign(v)` of a body measured by position only)
/// drives its chains a velocity window late; the delay line runs across chunk boundaries,
/// so chunks shorter than the delay, longer ones and the whole record give the same sums
/// (within 1e-12 of the sum of the magnitudes, as the time-parallel pass).
#[test]
fn a_delayed_column_driver_does_not_depend_on_the_chunks() {
    let ir = dsl_parser::compile_str(
        "coulomb",
        "model coulomb {
            body m1 = 1.0
            input u on m1
            measure m1.x, u
            damper d (ground, m1) ~ 0.4
            spring k (ground, m1) ~ 4.0
            force f (ground, m1) = r ~ 0.3 * sign(v)
            excite u: lowpass(corner = 10) levels [6]
        }",
    )
    .expect("valid model");
    let ts = 0.01;
    let cfg = SimConfig {
        duration: 120.0,
        sample: ts,
        seed: 3,
        ..Default::default()
    };
    let rec = sim::simulate(&ir, &cfg).unwrap().records.remove(0);
    let n = rec.len();
    let corners = [0.5, 2.0, 8.0];
    let n_blocks = 5;
    let opts = IdentifyOptions {
        corners: Some(corners.to_vec()),
        n_blocks: Some(n_blocks),
        column_chains: true,
        ..Default::default()
    };
    let plan = plan_for(&ir, &opts, &corners);
    assert_eq!(plan.root_drivers.len(), 1);
    assert!(plan.root_drivers[0].delayed);
    let tape = Tape::compile(&ir, &plan.roots);
    let src = RecordSource::new(&rec, &ir, "coulomb").unwrap();
    let targets: Vec<(usize, usize)> = plan
        .estimated
        .iter()
        .map(|(v, x)| (v.index(), x.index()))
        .collect();
    let est = velocity::EstimatedVelocity::design(&src, &targets, 8192).unwrap();
    let delay = est.designs()[0].2 + 1;
    assert!(delay > 20, "a window of {delay} samples");
    let run = |chunk: usize| {
        let mut acc = LevelAccumulator::new(&plan, &tape, ts, n, n_blocks, Hold::FirstOrder);
        acc.set_root_delay(delay);
        est.stream(chunk, &mut |c, l| acc.push(c, l)).unwrap();
        acc.finish().0
    };
    let whole = run(n);
    for chunk in [7, delay - 1, delay, 777] {
        let lm = run(chunk);
        for (b, (got, want)) in lm.sums.iter().zip(&whole.sums).enumerate() {
            let scale: f64 = want.iter().map(|v| v.abs()).sum();
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (g - w).abs() <= 1e-12 * scale,
                    "chunks of {chunk}, block {b}: {g} against {w}"
                );
            }
        }
    }
}
