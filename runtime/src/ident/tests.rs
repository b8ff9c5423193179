//! Recovery and identity tests of the covariance method (fixed seeds).

use super::columns::term_moment;
use super::moments::{Hat, MomentView};
use super::plan::BasisMoment;
use super::*;
use crate::data::RecordSource;
use crate::record::Record;
use crate::sim::{self, SimConfig};
use std::sync::OnceLock;

#[path = "../../../tests/figures/mod.rs"]
mod figures;

/// Seconds per level, as in the method's reference measurements.
const DURATION: f64 = 2000.0;

/// The method's benchmark SDOF (m = 1 known; d, k, k3, r unknown with the true values as
/// nominals, which the simulator uses), with `extra` lines added to the model body.
fn sdof_model(extra: &str) -> ModelIr {
    let src = format!(
        "model sdof {{
            body m1 = 1.0
            input u on m1
            damper d (ground, m1) ~ 0.4
            spring k (ground, m1) ~ 4.0
            force nl (ground, m1) = k3 ~ 2.0 * s^3 + r ~ 0.3 * sign(v)
            excite u: lowpass(corner = 10) levels [6, 15, 40]
            {extra}
        }}"
    );
    dsl_parser::compile_str("sdof", &src).expect("valid model")
}

/// The plan of `ir` under `opts` (bank, structure, rows) with the filter corners fixed at
/// `corners`, as `measure` makes it before streaming.
fn plan_for(ir: &ModelIr, opts: &IdentifyOptions, corners: &[f64]) -> plan::Plan {
    let bank = measure::choose_bank(ir, opts).unwrap();
    let mut plan = plan::build_structure(ir, false, &bank).unwrap();
    plan.set_corners(ir, corners);
    plan
}

/// The Duffing oscillator measured by position and input only.
fn duffing_model() -> ModelIr {
    dsl_parser::compile_str(
        "duffing",
        "model duffing {
            body m1 = 1.0
            input u on m1
            measure m1.x, u
            damper d (ground, m1) ~ 0.4
            spring k (ground, m1) ~ 4.0
            force nl (ground, m1) = k3 ~ 2.0 * s^3
            excite u: lowpass(corner = 10) levels [6, 15, 40]
        }",
    )
    .expect("valid model")
}

fn simulate(ir: &ModelIr, noise: f64, seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration: DURATION,
        noise,
        seed,
        ..Default::default()
    };
    sim::simulate(ir, &cfg).expect("simulation").records
}

fn sdof_data() -> &'static Vec<Record> {
    static DATA: OnceLock<Vec<Record>> = OnceLock::new();
    DATA.get_or_init(|| simulate(&sdof_model(""), 0.0, 1000))
}

fn run(ir: &ModelIr, recs: &[Record], opts: &IdentifyOptions) -> Identification {
    let srcs: Vec<RecordSource> = recs
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect();
    let dyns: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    identify(ir, &dyns, opts).unwrap()
}

fn rel_errors(id: &Identification, truth: &[(&str, f64)]) -> Vec<f64> {
    truth
        .iter()
        .map(|(n, t)| {
            let p = id
                .param(n)
                .unwrap_or_else(|| panic!("{n} not identified: {id:#?}"));
            (p.value - t) / t
        })
        .collect()
}

fn sdof_truth() -> Vec<(&'static str, f64)> {
    vec![("d", 0.4), ("k", 4.0), ("k3", 2.0), ("r", 0.3)]
}

/// Records with 5 % measurement noise on every measured signal, inputs included.
fn noisy_sdof_data() -> &'static Vec<Record> {
    static DATA: OnceLock<Vec<Record>> = OnceLock::new();
    DATA.get_or_init(|| simulate(&sdof_model(""), 0.05, 1000))
}

fn fmt_errs(e: &[f64]) -> String {
    e.iter()
        .map(|v| format!("{:+.2}%", 100.0 * v))
        .collect::<Vec<_>>()
        .join(", ")
}

#[test]
fn sdof_noise_free_within_one_percent() {
    let ir = sdof_model("");
    for balance in [false, true] {
        let opts = IdentifyOptions {
            balance: Some(balance),
            ..Default::default()
        };
        let id = run(&ir, sdof_data(), &opts);
        let e = rel_errors(&id, &sdof_truth());
        eprintln!(
            "noise 0 %, balance {balance}: (d, k, k3, r) {} cond {:.1} corners {:?}",
            fmt_errs(&e),
            id.condition,
            id.filter.corners
        );
        // The known bias of noise-free data (docs/method.md, "Known bias"): d −0.12 % and
        // r −0.08 % without balancing, the doc's figures to their last digit (fixed data);
        // every error within 0.3 %, 2.5 times the largest.
        if !balance {
            figures::check("docs/method.md", "bias.d", 100.0 * e[0]);
            figures::check("docs/method.md", "bias.r", 100.0 * e[3]);
        }
        assert!(e.iter().all(|e| e.abs() < 0.003), "{}", fmt_errs(&e));
        assert!(id.unidentifiable.is_empty());
        // The standard errors are of the size of the errors, not orders of magnitude off.
        for (p, e) in id.params.iter().zip(&e) {
            assert!(p.stderr > 0.0 && p.stderr < 0.01 * p.value.abs(), "{p:?}");
            assert!(
                (e * p.value).abs() < 6.0 * p.stderr + 1e-3 * p.value.abs(),
                "{p:?} err {e}"
            );
        }
    }
}

#[test]
fn sdof_five_percent_noise_within_two_percent() {
    let ir = sdof_model("");
    let recs = noisy_sdof_data();
    for balance in [false, true] {
        let opts = IdentifyOptions {
            balance: Some(balance),
            ..Default::default()
        };
        let id = run(&ir, recs, &opts);
        let e = rel_errors(&id, &sdof_truth());
        eprintln!(
            "noise 5 %, balance {balance}: (d, k, k3, r) {}",
            fmt_errs(&e)
        );
        assert!(e.iter().all(|e| e.abs() < 0.02), "{}", fmt_errs(&e));
    }
}

/// From 8192 samples up the chunk length is only how the streamed work is cut: the same
/// filter corners (designed from the first pass) and the same estimates to rounding, on
/// noisy records (noise on every channel). Measured: values within 1.7e-15, standard
/// errors within 1.9e-14 (relative; chunks of 30 000 and 10⁶ against 8192). With the
/// zero-crossing reference taken from the whole first chunk the corners differed.
#[test]
fn chunks_of_8192_samples_and_more_give_the_same_identification() {
    let ir = sdof_model("");
    let recs = noisy_sdof_data();
    let with = |chunk_len| {
        let opts = IdentifyOptions {
            chunk_len,
            ..Default::default()
        };
        run(&ir, recs, &opts)
    };
    let base = with(8192);
    for chunk in [30_000, 1_000_000] {
        let id = with(chunk);
        assert_eq!(id.filter.corners, base.filter.corners, "chunks of {chunk}");
        assert_eq!(id.params.len(), base.params.len());
        for (a, b) in id.params.iter().zip(&base.params) {
            assert_eq!(a.name, b.name);
            let (dv, ds) = (
                (a.value - b.value).abs() / b.value.abs(),
                (a.stderr - b.stderr).abs() / b.stderr,
            );
            assert!(
                dv < 1e-14 && ds < 1e-13,
                "chunks of {chunk}, {}: {} ± {} against {} ± {}",
                a.name,
                a.value,
                a.stderr,
                b.value,
                b.stderr
            );
        }
    }
}

#[test]
fn duffing_from_positions_only_within_one_percent() {
    let ir = duffing_model();
    let truth = [("d", 0.4), ("k", 4.0), ("k3", 2.0)];
    for eta in [0.0, 0.05] {
        let recs = simulate(&ir, eta, 2000);
        let id = run(&ir, &recs, &IdentifyOptions::default());
        let e = rel_errors(&id, &truth);
        eprintln!(
            "displacement only, noise {eta}: (d, k, k3) {} order {} degrees {:?}",
            fmt_errs(&e),
            id.filter.order,
            id.filter.instrument_degrees
        );
        let tol = if eta == 0.0 { 0.01 } else { 0.02 };
        assert!(e.iter().all(|e| e.abs() < tol), "{}", fmt_errs(&e));
    }
}

#[test]
fn unexcited_deadzone_is_named_and_gets_no_value() {
    // A gap larger than any displacement: the deadzone term is identically zero.
    let ir = sdof_model("force gap (ground, m1) = kgap ~ 1.0 * deadzone(s, 1000)");
    let id = run(&ir, sdof_data(), &IdentifyOptions::default());
    assert!(id.param("kgap").is_none());
    let u = id.unidentifiable.iter().find(|u| u.name == "kgap").unwrap();
    assert!(u.reason.contains("never excited"), "{}", u.reason);
    let e = rel_errors(&id, &sdof_truth());
    assert!(e.iter().all(|e| e.abs() < 0.01), "{}", fmt_errs(&e));
}

#[test]
fn duplicated_column_is_reported_as_collinear() {
    // A second linear spring on the same coordinate: `k` and `k_b` cannot be told apart.
    let ir = sdof_model("spring k_b (ground, m1)");
    let id = run(&ir, &sdof_data()[..2], &IdentifyOptions::default());
    assert_eq!(id.unidentifiable.len(), 1, "{:?}", id.unidentifiable);
    let u = &id.unidentifiable[0];
    assert!(u.reason.contains("collinear with `"), "{}", u.reason);
    // The remaining spring carries the whole stiffness.
    let k = id.param("k").or(id.param("k_b")).unwrap();
    assert!((k.value / 4.0 - 1.0).abs() < 0.01);
}

#[test]
fn printer_writes_the_identified_equation() {
    let ir = sdof_model("");
    let id = run(&ir, sdof_data(), &IdentifyOptions::default());
    let s = print::format_equations(&ir, &id);
    assert!(
        s.starts_with("m1: 1.000 m1.x'' + 0.39") || s.starts_with("m1: 1.000 m1.x'' + 0.40"),
        "{s}"
    );
    assert!(s.contains("(±0.00"), "{s}");
    assert!(
        s.contains(" m1.x^3 + ") && s.contains(" sign(m1.v) = u"),
        "{s}"
    );
}

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
            let q = plan.n_w();
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

/// Simulate `ir` at the given levels for `duration` seconds (burn-in 50 s).
fn simulate_short(
    ir: &ModelIr,
    levels: &[f64],
    duration: f64,
    noise: f64,
    seed: u64,
) -> Vec<Record> {
    let cfg = SimConfig {
        levels: Some(levels.to_vec()),
        duration,
        noise,
        seed,
        burn_in: 50.0,
        ..Default::default()
    };
    sim::simulate(ir, &cfg).expect("simulation").records
}

/// Samples `a..b` of a record.
fn slice(rec: &Record, a: usize, b: usize) -> Record {
    Record {
        names: rec.names.clone(),
        columns: rec.columns.iter().map(|c| c[a..b].to_vec()).collect(),
        ts: rec.ts,
        t0: rec.t0 + a as f64 * rec.ts,
    }
}

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
/// remains noise-free, the simulated input's path between samples (docs/method.md §3;
/// d −0.10 %, r −0.09 %, k −0.02 %, k3 −0.03 % at Tₛ = 0.01 s; −0.06 %, −0.04 %, −0.007 %,
/// −0.010 % at 0.005 s with the default corners, whose top follows the sample rate;
/// unchanged with 80 instead of 20 simulator sub-steps), well inside these standard
/// errors (0.2–1.5 %).
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
    // Standard errors of the right order: a jackknife that was erratic by a factor of up
    // to ten, or an uncorrected noise bias, would fail this.
    for (k, v) in z2.iter().enumerate() {
        let rms = (v / seeds as f64).sqrt();
        assert!(rms < 1.25, "{}: rms z {rms}", truth[k].0);
    }
}

/// Mean relative errors of (d, k, k3, r) over three seeds at noise `eta` on every channel.
fn mean_noisy_errors(eta: f64, duration: f64, correction: bool) -> Vec<f64> {
    let ir = sdof_model("");
    let seeds = [11, 12, 13];
    let mut mean = vec![0.0; 4];
    for seed in seeds {
        let cfg = SimConfig {
            duration,
            noise: eta,
            seed,
            ..Default::default()
        };
        let recs = sim::simulate(&ir, &cfg).expect("simulation").records;
        let opts = IdentifyOptions {
            noise_correction: correction,
            ..Default::default()
        };
        let id = run(&ir, &recs, &opts);
        if correction {
            assert_eq!(id.noise.corrected, ["m1.x^3", "sign(m1.v)"]);
        }
        for l in &id.levels {
            for s in ["m1.x", "m1.v"] {
                let f = l.noise[s] / l.std[s];
                // The noise is a fraction of the clean signal's std: eta/√(1+eta²) of the
                // noisy one.
                assert!(
                    (f / (eta / (1.0 + eta * eta).sqrt()) - 1.0).abs() < 0.03,
                    "{s}: {f}"
                );
            }
        }
        for (m, e) in mean.iter_mut().zip(rel_errors(&id, &sdof_truth())) {
            *m += e / seeds.len() as f64;
        }
    }
    mean
}

/// The figures of docs/method.md ("Measurement noise"): the largest mean error with the
/// correction at 5 % and 10 % noise, k3 and r without it at 10 %. The seeds are fixed, so
/// each is the doc's to its last digit.
#[test]
fn noise_correction_removes_the_errors_in_variables_bias() {
    for (eta, name) in [(0.05, "noise.corrected_5"), (0.1, "noise.corrected_10")] {
        let e = mean_noisy_errors(eta, 2000.0, true);
        eprintln!(
            "noise {eta}, corrected: mean (d, k, k3, r) {}",
            fmt_errs(&e)
        );
        let worst = e.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        figures::check("docs/method.md", name, 100.0 * worst);
    }
    // Without the correction the cubic stiffness is biased low by about −1 % at 10 %.
    let e = mean_noisy_errors(0.1, 2000.0, false);
    eprintln!(
        "noise 0.1, uncorrected: mean (d, k, k3, r) {}",
        fmt_errs(&e)
    );
    figures::check("docs/method.md", "noise.uncorrected_k3", 100.0 * e[2]);
    figures::check("docs/method.md", "noise.uncorrected_r", 100.0 * e[3]);
}

#[test]
fn clean_data_is_not_corrected() {
    let ir = sdof_model("");
    let on = run(&ir, sdof_data(), &IdentifyOptions::default());
    let off = run(
        &ir,
        sdof_data(),
        &IdentifyOptions {
            noise_correction: false,
            ..Default::default()
        },
    );
    assert!(on.noise.corrected.is_empty(), "{:?}", on.noise);
    for s in ["m1.x", "m1.v"] {
        assert!(on.noise.fraction[s] < 1e-3, "{:?}", on.noise);
    }
    for (a, b) in on.params.iter().zip(&off.params) {
        assert!((a.value / b.value - 1.0).abs() < 1e-4, "{a:?} {b:?}");
    }
}

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
    let (n_i, n_w, n_q, n_z, n_g) = (
        plan.n_i(),
        plan.n_w(),
        plan.n_q(),
        plan.n_z(),
        plan.roots.len(),
    );
    let mut w = vec![0.0; n_w * n];
    crate::basis::BasisEval::eval_block(&tape, &view, n, &mut w[..n_g * n], &mut Vec::new());
    for (j, s) in plan.y.iter().enumerate() {
        w[(n_g + j) * n..(n_g + j + 1) * n].copy_from_slice(view[s.index()]);
    }
    let mut iota = vec![0.0; n_i * n];
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
        iota[(n_z + j) * n..(n_z + j + 1) * n].copy_from_slice(view[s.index()]);
    }
    let ys: Vec<&[f64]> = plan.y.iter().map(|s| view[s.index()]).collect();
    let widths = vec![1.0; plan.extra.len()];
    noise::fill_extra(
        &plan.extra,
        &widths,
        &ys,
        n,
        &mut w[(n_g + plan.y.len()) * n..],
    );
    let bounds: Vec<usize> = (0..=n_blocks).map(|b| b * (n - 1) / n_blocks).collect();
    let mut want = vec![(vec![0.0; n_i * n_w], vec![0.0; n_i * n_w]); n_blocks];
    let mut scale = want.clone();
    for b in 0..n_blocks {
        for k in bounds[b]..bounds[b + 1] {
            let s = (k - bounds[b]) as f64;
            for i in 0..n_i {
                for j in 0..n_w {
                    let v = iota[i * n + k] * w[j * n + k];
                    want[b].0[i * n_w + j] += v;
                    want[b].1[i * n_w + j] += s * v;
                    scale[b].0[i * n_w + j] += v.abs();
                    scale[b].1[i * n_w + j] += s * v.abs();
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
            for i in 0..n_i {
                for j in 0..n_w {
                    let v = iota[i * n + k] * w[j * n + k];
                    let g = lm.snaps[b][i * n_q + j];
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
    check(&run(8192, moments::TASK_LEN), "chunks of 8192");
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
