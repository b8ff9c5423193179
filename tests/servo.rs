//! A real-shaped record: a position-controlled servo axis (mass 50 kg, viscous friction
//! 120 N·s/m, Coulomb friction 15 N, a constant force offset of −2 N), one closed-loop
//! record of 25 s at 1 kHz, positions from a 1 µm encoder and the drive's force only — no
//! velocity channel, a force that is not white, a response that is not stationary, a
//! controller that updates ten times per sample interval (so the force has content between
//! samples) and follows a smooth random trajectory of 10 cm RMS (velocity RMS about
//! 0.5 m/s). Identified with the default settings: the filters are designed from the
//! record, the velocity in the Coulomb term is estimated from the encoder positions.
//!
//! What the method reaches here, on this trajectory and on a slower one (3 cm RMS, velocity
//! RMS 0.15 m/s) that sticks at its reversals, is quoted once, in the servo example of
//! README.md ("Real records"); `servo_axis_from_encoder_and_force_alone` and
//! `slow_trajectory_errors` check those figures (`cargo test --test servo -- --nocapture`
//! prints every seed). Each bound below states the spread it comes from.
mod common;
mod figures;
mod servo_common;

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::ident::Identification;
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, test_models::ServoAxis};
use dynid::runtime::{identify, IdentifyOptions};
use servo_common::{errors, planned_record, TRUTH};

/// The axis of the module doc at `seed`, identified; `measured_velocity` records the
/// velocity and gives it to the identification instead of estimating it.
fn servo(seed: u64, measured_velocity: bool) -> Identification {
    servo_at(0.1, seed, measured_velocity)
}

/// The servo record with a reference of `rms` metres.
fn record(rms: f64, seed: u64, measured_velocity: bool) -> (ModelIr, Record) {
    let mut axis = ServoAxis::standard();
    axis.reference.rms = rms;
    axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
    let mut ir = axis.model();
    ir.signals[1].measured = measured_velocity;
    let mut cfg = axis.config(common::seed(seed));
    cfg.input_oversample = 10;
    let mut out = sim::simulate(&ir, &cfg).expect("closed-loop simulation");
    assert_eq!(out.records.len(), 1, "one record");
    (ir, out.records.remove(0))
}

/// [`servo`] with a reference of `rms` metres.
fn servo_at(rms: f64, seed: u64, measured_velocity: bool) -> Identification {
    servo_with(
        rms,
        seed,
        measured_velocity,
        &IdentifyOptions::instrument_rows(),
    )
}

/// [`servo_at`] with the identification options `opts`.
fn servo_with(
    rms: f64,
    seed: u64,
    measured_velocity: bool,
    opts: &IdentifyOptions,
) -> Identification {
    let (ir, rec) = record(rms, seed, measured_velocity);
    let rec = &rec;
    assert_eq!(rec.column("m.v").is_some(), measured_velocity);
    let src = RecordSource::new(rec, &ir, "servo").expect("record");
    let levels: Vec<&dyn LevelSource> = vec![&src];
    identify(&ir, &levels, opts).expect("identification")
}

/// RMS relative error over `seeds` of each parameter of [`TRUTH`], and the fraction of
/// seeds whose error is within two standard errors.
fn rms_and_coverage(
    seeds: std::ops::RangeInclusive<u64>,
    opts: &IdentifyOptions,
) -> Vec<(f64, f64)> {
    let ids: Vec<Identification> = seeds
        .map(|seed| servo_with(0.1, seed, false, opts))
        .collect();
    rms_and_cover(&ids)
}

/// RMS relative error per parameter of [`TRUTH`] over identifications, and the fraction
/// whose error is within two standard errors.
fn rms_and_cover(ids: &[Identification]) -> Vec<(f64, f64)> {
    let n = ids.len() as f64;
    let mut acc = vec![(0.0, 0.0); TRUTH.len()];
    for id in ids {
        for (a, (e, s)) in acc.iter_mut().zip(errors(id)) {
            a.0 += e * e / n;
            a.1 += f64::from(u8::from(e.abs() < 2.0 * s)) / n;
        }
    }
    acc.iter().map(|&(m, c)| (m.sqrt(), c)).collect()
}

/// The errors as one line, two decimals.
fn row(errs: &[(f64, f64)]) -> String {
    servo_common::row(errs, 2)
}

#[test]
fn servo_axis_from_encoder_and_force_alone() {
    let mut worst = [0.0f64; 4];
    // Σ (error / SE)² per parameter, for the RMS of error / SE that docs/method.md §6 quotes.
    let mut z2 = [0.0f64; 4];
    for seed in 1..=12 {
        let id = servo(seed, false);
        assert!(id.unidentifiable.is_empty(), "{:?}", id.unidentifiable);
        assert_eq!(id.estimated.len(), 1, "the velocity is estimated");
        let errs = errors(&id);
        println!("seed {seed}: {}", row(&errs));
        for (z, (e, s)) in z2.iter_mut().zip(&errs) {
            *z += (e / s).powi(2);
        }
        // Seeds 1–12: m 0.03 %, d 1.12 %, r 3.31 %, f0 4.61 % at most (printed above with
        // `-- --nocapture`; d and r checked below against README.md); each bound about
        // twice that.
        for (((name, _), (e, s)), w) in TRUTH.iter().zip(&errs).zip(&mut worst) {
            *w = w.max(100.0 * e.abs());
            let bound = match *name {
                "m" => 0.0006,
                "d" => 0.025,
                "r" => 0.07,
                _ => 0.095,
            };
            assert!(
                e.abs() < bound,
                "seed {seed}: `{name}` off by {:+.2} % (bound {} %)",
                100.0 * e,
                100.0 * bound
            );
            assert!(
                *name == "m" || e.abs() < 3.0 * s,
                "seed {seed}: `{name}` off by {:+.2} %, standard error {:.2} %",
                100.0 * e,
                100.0 * s
            );
        }
    }
    // README.md quotes the largest errors of d and r.
    figures::check("README.md", "servo.d", worst[1]);
    figures::check("README.md", "servo.r", worst[2]);
    let z: Vec<f64> = z2.iter().map(|s| (s / 12.0).sqrt()).collect();
    println!(
        "RMS error / SE: m {:.2}, d {:.2}, r {:.2}, f0 {:.2}",
        z[0], z[1], z[2], z[3]
    );
    if common::seeds_as_documented() {
        figures::check("docs/method.md", "servo.d_z", z[1]);
        figures::check("docs/method.md", "servo.r_z", z[2]);
        figures::check("docs/method.md", "servo.f0_z", z[3]);
    }
}

/// The same seeds with the velocity measured instead of estimated: the RMS errors over the
/// seeds of d and r (measured: see `-- --nocapture`) are no more than 1.5 times those with
/// the measured velocity.
#[test]
fn estimated_velocity_costs_no_accuracy() {
    let seeds = 1..=12;
    let rms = |measured: bool| -> Vec<f64> {
        let mut sum = [0.0; 4];
        for seed in seeds.clone() {
            for (s, (e, _)) in sum.iter_mut().zip(errors(&servo(seed, measured))) {
                *s += e * e;
            }
        }
        sum.iter()
            .map(|s| (s / seeds.clone().count() as f64).sqrt())
            .collect()
    };
    let (est, mea) = (rms(false), rms(true));
    for (k, (name, _)) in TRUTH.iter().enumerate() {
        println!(
            "{name}: RMS error {:.3} % estimated, {:.3} % measured",
            100.0 * est[k],
            100.0 * mea[k]
        );
    }
    for k in [1, 2] {
        assert!(
            est[k] < 1.5 * mea[k],
            "`{}`: RMS error {:.3} % with the estimated velocity, {:.3} % measured",
            TRUTH[k].0,
            100.0 * est[k],
            100.0 * mea[k]
        );
    }
}

/// Stops at the reversals of the motion, from the true velocity (seed 1): the fraction of
/// samples with |v| < 10⁻⁵ m/s and the longest run with |v| < 10⁻⁴ m/s, at the slow (3 cm)
/// and the test's (10 cm) trajectory. Measured: 1.17 % / 50 ms and 0.12 % / 19 ms.
#[test]
fn the_slow_trajectory_sticks() {
    let stops = |rms: f64| {
        let (_, rec) = record(rms, 1, true);
        let v = rec.column("m.v").expect("velocity recorded");
        let still = v.iter().filter(|v| v.abs() < 1e-5).count() as f64 / v.len() as f64;
        let (mut run, mut longest) = (0usize, 0usize);
        for v in v {
            run = if v.abs() < 1e-4 { run + 1 } else { 0 };
            longest = longest.max(run);
        }
        println!(
            "reference {rms} m: {:.2} % still, longest stop {longest} ms",
            100.0 * still
        );
        (still, longest)
    };
    let (slow, fast) = (stops(0.03), stops(0.1));
    assert!(
        slow.0 > 5.0 * fast.0 && slow.1 > 2 * fast.1,
        "{slow:?} {fast:?}"
    );
}

/// The slow trajectory of the module doc, seeds 1–8, estimated and measured velocity
/// (`cargo test --test servo slow_trajectory -- --nocapture` prints each seed): the largest
/// errors of d and r and the largest standard error of d are the figures of README.md,
/// to their last digit (fixed seeds).
#[test]
fn slow_trajectory_errors() {
    // (largest |error| of d, of r, largest standard error of d), estimated and measured.
    let mut worst = [[0.0f64; 3]; 2];
    // Σ error² of d and of r over the seeds, estimated and measured.
    let mut sq = [[0.0f64; 2]; 2];
    for seed in 1..=8 {
        for measured in [false, true] {
            let what = if measured { "measured" } else { "estimated" };
            let errs = errors(&servo_at(0.03, seed, measured));
            println!("seed {seed} {what}: {}", row(&errs));
            let w = &mut worst[usize::from(measured)];
            w[0] = w[0].max(100.0 * errs[1].0.abs());
            w[1] = w[1].max(100.0 * errs[2].0.abs());
            w[2] = w[2].max(100.0 * errs[1].1);
            let q = &mut sq[usize::from(measured)];
            q[0] += errs[1].0 * errs[1].0;
            q[1] += errs[2].0 * errs[2].0;
        }
    }
    // docs/method.md §7: the RMS errors with the estimated velocity over those with the
    // measured one.
    let ratio = |k: usize| (sq[0][k] / sq[1][k]).sqrt();
    println!(
        "RMS error ratio estimated / measured: d {:.2}, r {:.2}",
        ratio(0),
        ratio(1)
    );
    figures::check("docs/method.md", "servo.slow.rms_ratio.d", ratio(0));
    figures::check("docs/method.md", "servo.slow.rms_ratio.r", ratio(1));
    let [est, mea] = worst;
    figures::check("README.md", "servo.slow.d", est[0]);
    figures::check("README.md", "servo.slow.r", est[1]);
    figures::check("README.md", "servo.slow.d_stderr", est[2]);
    figures::check("README.md", "servo.slow.measured.d", mea[0]);
    figures::check("README.md", "servo.slow.measured.r", mea[1]);
    // The standard errors say so: every error of d within three of them (as on the fast
    // trajectory), and the worst case is not hidden behind a small one.
    assert!(est[2] > est[0], "{est:?}");
}

/// Chains driven by the model's nonlinear column (`sign(v)`, with the velocity estimated
/// from the encoder, driving its chains a velocity window late): the RMS errors over seeds
/// 1–12 of d, r and f0 shrink, the mass's grows (from a level far below the others). Measured
/// (`cargo test --test servo column_chains -- --nocapture`): RMS d 0.47 → 0.26 %, r 1.36 →
/// 0.70 %, f0 1.47 → 0.86 %, m 0.014 → 0.042 %; coverage (|error| < 2 SE) 11–12 of 12
/// either way. The bounds: ratios below 0.75 for d, r, f0 and below 5 for m.
#[test]
fn column_chains_shrink_the_damping_and_friction_errors() {
    let off = rms_and_coverage(1..=12, &IdentifyOptions::instrument_rows());
    let on = rms_and_coverage(
        1..=12,
        &IdentifyOptions {
            column_chains: true,
            ..Default::default()
        },
    );
    for (k, (name, _)) in TRUTH.iter().enumerate() {
        println!(
            "{name}: RMS error {:.3} % → {:.3} % with column chains, coverage {:.2} → {:.2}",
            100.0 * off[k].0,
            100.0 * on[k].0,
            off[k].1,
            on[k].1
        );
        let bound = if *name == "m" { 5.0 } else { 0.75 };
        assert!(
            on[k].0 < bound * off[k].0,
            "`{name}`: RMS error {:.3} % with column chains, {:.3} % without",
            100.0 * on[k].0,
            100.0 * off[k].0
        );
        assert!(on[k].1 >= 10.0 / 12.0, "`{name}`: coverage {}", on[k].1);
    }
    // docs/method.md (§1, chains driven by the model's own columns) quotes these: the RMS
    // errors in % (order of TRUTH: m, d, r, f0) and the coverage in seeds of 12.
    let doc = "docs/method.md";
    for (k, before, after) in [
        (0, "column_chains.m.off", "column_chains.m.on"),
        (1, "column_chains.d.off", "column_chains.d.on"),
        (2, "column_chains.r.off", "column_chains.r.on"),
        (3, "column_chains.f0.off", "column_chains.f0.on"),
    ] {
        figures::check(doc, before, 100.0 * off[k].0);
        figures::check(doc, after, 100.0 * on[k].0);
    }
    let seeds = |c: f64| 12.0 * c;
    let lo = off
        .iter()
        .chain(&on)
        .map(|x| seeds(x.1))
        .fold(12.0, f64::min);
    let hi = off
        .iter()
        .chain(&on)
        .map(|x| seeds(x.1))
        .fold(0.0, f64::max);
    figures::check(doc, "column_chains.coverage.lo", lo);
    figures::check(doc, "column_chains.coverage.hi", hi);
}

/// The rows of the filtered equation (`--filtered-equation`: one corner at the information
/// bandwidth, at most 0.5/Ts = 500 rad/s here; slow passages left out with the filter's
/// memory after them) against the defaults, over seeds 1–12 of the random records. The
/// mass, friction and offset errors shrink; the damping carries a bias of about 0.15 % that
/// its standard error does not cover (the same as SVF-LS's with its rows near rest dropped,
/// bench `servo_precision`), so its coverage is the doc's figure, not a claim.
/// Measured (`cargo test --test servo filtered_equation -- --nocapture`): see
/// docs/method.md §2, "Rows of the filtered equation", whose figures this checks.
#[test]
fn filtered_equation_rows_shrink_the_mass_friction_and_offset_errors() {
    let off = rms_and_coverage(1..=12, &IdentifyOptions::instrument_rows());
    let on = rms_and_coverage(
        1..=12,
        &IdentifyOptions {
            filtered: true,
            ..Default::default()
        },
    );
    let doc = "docs/method.md";
    for (k, (name, _)) in TRUTH.iter().enumerate() {
        println!(
            "{name}: RMS error {:.3} % → {:.3} % with the filtered equation, coverage {:.2} → {:.2}",
            100.0 * off[k].0,
            100.0 * on[k].0,
            off[k].1,
            on[k].1
        );
    }
    // docs/method.md (§2, rows of the filtered equation) and README quote these: the RMS
    // errors in % (order of TRUTH: m, d, r, f0) and the coverage in seeds of 12.
    let keys = [
        ("filtered.m.off", "filtered.m.on", "filtered.m.cover"),
        ("filtered.d.off", "filtered.d.on", "filtered.d.cover"),
        ("filtered.r.off", "filtered.r.on", "filtered.r.cover"),
        ("filtered.f0.off", "filtered.f0.on", "filtered.f0.cover"),
    ];
    for (k, (before, after, cover)) in keys.into_iter().enumerate() {
        figures::check(doc, before, 100.0 * off[k].0);
        figures::check(doc, after, 100.0 * on[k].0);
        figures::check("README.md", after, 100.0 * on[k].0);
        figures::check(doc, cover, 12.0 * on[k].1);
    }
    // m, r, f0: ratios measured 0.48, 0.082, 0.078 (see the doc); bounds 1.5–2 times those.
    for (k, bound) in [(0, 1.0), (2, 0.12), (3, 0.15)] {
        assert!(
            on[k].0 < bound * off[k].0,
            "`{}`: RMS error {:.3} % with the filtered equation, {:.3} % without",
            TRUTH[k].0,
            100.0 * on[k].0,
            100.0 * off[k].0
        );
    }
    // The damping: 0.16 % against 0.47 %, a bias its standard errors do not cover (its
    // coverage is the doc's figure above); ratio 0.34, bound 0.65.
    assert!(
        on[1].0 < 0.65 * off[1].0,
        "`d`: RMS error {:.3} % with the filtered equation, {:.3} % without",
        100.0 * on[1].0,
        100.0 * off[1].0
    );
}

/// The controller updates ten times per sample and holds: the force's staircase lags the
/// straight line between samples the filters assume, which biases the damping of the
/// filtered rows by more than their standard errors. An unknown delay of the input
/// (`--input-delay`, with it a chain of six sections, the corner designed at most
/// 0.5/Ts = 500 rad/s and searched down to a quarter of that) takes it up.
/// Seeds 1–12, random references and planned moves
/// (`cargo test --release --test servo input_delay -- --nocapture`; the bench
/// `servo_precision` sets the baselines beside it).
#[test]
fn an_input_delay_takes_up_the_force_between_samples() {
    let filtered = IdentifyOptions {
        filtered: true,
        ..Default::default()
    };
    let delayed = IdentifyOptions {
        input_delay: true,
        ..filtered.clone()
    };
    let doc = "docs/method.md";
    // docs/method.md quotes, per kind of record: the RMS errors in % and the coverage in
    // seeds of 12 (order of TRUTH: m, d, r, f0), and the mean delay in ms.
    let random_keys = (
        [
            "delay.random.m",
            "delay.random.d",
            "delay.random.r",
            "delay.random.f0",
        ],
        [
            "delay.random.m.cover",
            "delay.random.d.cover",
            "delay.random.r.cover",
            "delay.random.f0.cover",
        ],
        "delay.random.tau",
    );
    let planned_keys = (
        [
            "delay.planned.m",
            "delay.planned.d",
            "delay.planned.r",
            "delay.planned.f0",
        ],
        [
            "delay.planned.m.cover",
            "delay.planned.d.cover",
            "delay.planned.r.cover",
            "delay.planned.f0.cover",
        ],
        "delay.planned.tau",
    );
    for (kind, keys, records) in [
        (
            "random",
            random_keys,
            (1..=12)
                .map(|seed| record(0.1, seed, false))
                .collect::<Vec<_>>(),
        ),
        (
            "planned",
            planned_keys,
            (1..=12)
                .map(|seed| servo_common::planned_record(common::seed(seed)))
                .collect(),
        ),
    ] {
        let run = |opts: &IdentifyOptions| -> Vec<Identification> {
            records
                .iter()
                .map(|(ir, rec)| servo_common::identify_record(ir, rec, opts))
                .collect()
        };
        let with_delay = run(&delayed);
        let (off, on) = (rms_and_cover(&run(&filtered)), rms_and_cover(&with_delay));
        // The mean delay found, in ms.
        let delay = with_delay
            .iter()
            .map(|id| id.param("u.delay").expect("the delay estimated").value)
            .sum::<f64>()
            / with_delay.len() as f64
            / 1e-3;
        println!("{kind}: mean input delay {delay:.4} ms");
        for (k, (name, _)) in TRUTH.iter().enumerate() {
            println!(
                "{kind} {name}: RMS error {:.3} % → {:.3} % with the delay, coverage {:.2} → {:.2}",
                100.0 * off[k].0,
                100.0 * on[k].0,
                off[k].1,
                on[k].1
            );
            figures::check(doc, keys.0[k], 100.0 * on[k].0);
            figures::check(doc, keys.1[k], 12.0 * on[k].1);
        }
        figures::check(doc, keys.2, delay);
        // README.md quotes the damping (the comparison with the baselines it quotes from
        // the bench's 48 seeds).
        figures::check("README.md", keys.0[1], 100.0 * on[1].0);
        figures::check("README.md", keys.1[1], 12.0 * on[1].1);
        // The damping: measured 0.161 → 0.0018 % (random) and 0.246 → 0.059 % (planned),
        // ratios 0.011 and 0.24; bounds about three and a half and two times those.
        let bound = if kind == "random" { 0.04 } else { 0.5 };
        assert!(
            on[1].0 < bound * off[1].0,
            "{kind} `d`: RMS error {:.3} % with the delay, {:.3} % without",
            100.0 * on[1].0,
            100.0 * off[1].0
        );
        // No parameter gets worse by more than the seeds' spread allows (measured: m
        // 0.007 → 0.0004 and 0.010 → 0.0094 %, r 0.111 → 0.0051 and 0.175 → 0.083 %, f0
        // 0.114 → 0.022 and 0.290 → 0.298 %).
        for k in [0, 2, 3] {
            assert!(
                on[k].0 < 1.3 * off[k].0,
                "{kind} `{}`: RMS error {:.3} % with the delay, {:.3} % without",
                TRUTH[k].0,
                100.0 * on[k].0,
                100.0 * off[k].0
            );
        }
        // The errors now cover every parameter on most seeds (measured 10–12 of 12 for
        // each, both kinds; 88–98 % over the bench's 48 seeds; without the delay the
        // damping's on none), hence at least 9 of 12.
        for k in 0..TRUTH.len() {
            assert!(
                on[k].1 >= 0.74,
                "{kind} `{}`: coverage {:.2}",
                TRUTH[k].0,
                on[k].1
            );
        }
    }
}

/// Identify `rec` with the default options.
fn identify_record(ir: &ModelIr, rec: &Record) -> Identification {
    servo_common::identify_record(ir, rec, &IdentifyOptions::instrument_rows())
}

/// Planned moves with dwells, seeds 1–12: the rests (a third of every cycle) are left out
/// of the moments. Measured (`cargo test --test servo planned_moves -- --nocapture`): RMS
/// errors m 0.027 %, d 0.129 %, r 0.210 %, f0 0.239 %; mean standard errors 0.038 %,
/// 0.166 %, 0.242 %, 0.309 %; coverage (|error| < 2 SE) 12, 11, 11 and 12 of 12. (Before
/// the velocity estimate fitted the reversals, `runtime/src/ident/velocity.rs`, the mass
/// kept a bias of +0.06 … +0.13 % its standard error did not cover: `tests/servo_planned.rs`,
/// docs/method.md §7.) With the rests kept every parameter was off by 7–67 %. The bounds:
/// about 2.5 times the RMS errors, coverage at least 10 of 12, and every rest found (six
/// per cycle, 25 in the record).
#[test]
fn planned_moves_leave_the_rests_out() {
    let seeds = 1..=12u64;
    let n = seeds.clone().count() as f64;
    let mut acc = [(0.0, 0.0, 0.0); 4];
    // Mean squared errors with the rests kept (`--keep-rests`), for docs/method.md.
    let mut kept = [0.0; 4];
    let keep = IdentifyOptions {
        keep_rests: true,
        ..Default::default()
    };
    for seed in seeds {
        let (ir, rec) = planned_record(seed);
        for (k, (e, _)) in errors(&servo_common::identify_record(&ir, &rec, &keep))
            .iter()
            .enumerate()
        {
            kept[k] += e * e / n;
        }
        let id = identify_record(&ir, &rec);
        let rests = id.levels[0].rests.clone().expect("rests looked for");
        assert_eq!(rests.intervals, 25, "seed {seed}: {rests:?}");
        let errs = errors(&id);
        println!(
            "seed {seed}: {} — {} rests, {} samples, {} blocks",
            row(&errs),
            rests.intervals,
            rests.samples,
            id.levels[0].blocks
        );
        for (a, (e, s)) in acc.iter_mut().zip(&errs) {
            a.0 += e * e / n;
            a.1 += s / n;
            a.2 += f64::from(u8::from(e.abs() < 2.0 * s)) / n;
        }
    }
    for ((name, _), (e2, s, c)) in TRUTH.iter().zip(acc) {
        let rms = e2.sqrt();
        println!(
            "{name}: RMS error {:.3} %, mean SE {:.3} %, coverage {:.2}",
            100.0 * rms,
            100.0 * s,
            c
        );
        let bound = match *name {
            "m" => 0.0007,
            "d" => 0.0033,
            "r" => 0.004,
            _ => 0.006,
        };
        assert!(rms < bound, "`{name}`: RMS error {:.3} %", 100.0 * rms);
        assert!(c >= 10.0 / 12.0, "`{name}`: coverage {c}");
    }
    // docs/method.md §7 quotes these (fixed seeds): RMS errors, mean standard errors, the
    // coverage of d, r, f0 in seeds of 12, and the RMS errors with the rests kept.
    let doc = "docs/method.md";
    for (k, (rms, se, with_rests)) in [
        ("rests.m.rms", "rests.m.se", "rests.m.kept"),
        ("rests.d.rms", "rests.d.se", "rests.d.kept"),
        ("rests.r.rms", "rests.r.se", "rests.r.kept"),
        ("rests.f0.rms", "rests.f0.se", "rests.f0.kept"),
    ]
    .into_iter()
    .enumerate()
    {
        figures::check(doc, rms, 100.0 * acc[k].0.sqrt());
        figures::check(doc, se, 100.0 * acc[k].1);
        figures::check(doc, with_rests, 100.0 * kept[k].sqrt());
    }
    let cover: Vec<f64> = acc[1..].iter().map(|a| 12.0 * a.2).collect();
    figures::check(
        doc,
        "rests.cover.lo",
        cover.iter().copied().fold(12.0, f64::min),
    );
    figures::check(
        doc,
        "rests.cover.hi",
        cover.iter().copied().fold(0.0, f64::max),
    );
}

/// One planned record cut into its four cycles (6.18 s each), seeds 1–4: every cycle's
/// estimate lies within two of its standard errors of the whole record's (three for the
/// mass). Measured (`cargo test --test servo planned_cycles -- --nocapture`): |z| ≤ 0.48
/// for d and r, 1.21 for f0, 2.02 for m — the cycles' masses lie −0.16 … +0.09 % from
/// the truth (11 of 16 below), the whole record's +0.06 … +0.13 %: each identified at its
/// own designed corners (a cycle alone designs higher ones). The cycles' standard errors are
/// 4–20 (m) and 10–50 (d, r) times the whole record's at those different corners; at common
/// corners they are at most 4.1 (m) and 1.8 (d, r) times, and the cycles agree pairwise
/// within their errors (`tests/servo_planned.rs::planned_cycles_agree_within_their_errors`).
#[test]
fn planned_cycles_agree_within_their_errors() {
    let cycle = 6180;
    let mut worst = Vec::new();
    for seed in 1..=4u64 {
        let (ir, rec) = planned_record(seed);
        let whole = identify_record(&ir, &rec);
        for c in 0..rec.len() / cycle {
            let mut part = rec.clone();
            for col in &mut part.columns {
                *col = col[c * cycle..(c + 1) * cycle + 1].to_vec();
            }
            let id = identify_record(&ir, &part);
            let z: Vec<(&str, f64, f64, f64)> = TRUTH
                .iter()
                .map(|(name, _)| {
                    let (p, w) = (
                        id.param(name).expect("estimated"),
                        whole.param(name).expect("estimated"),
                    );
                    (*name, p.value, p.stderr, (p.value - w.value) / p.stderr)
                })
                .collect();
            let line: Vec<String> = z
                .iter()
                .map(|(n, v, s, z)| format!("{n} {v:.4} ± {s:.4} (z {z:+.2})"))
                .collect();
            println!("seed {seed} cycle {c}: {}", line.join(", "));
            for (name, _, _, z) in z {
                worst.push((name, seed, c, z));
            }
        }
    }
    for (name, seed, c, z) in worst {
        let bound = if name == "m" { 3.0 } else { 2.0 };
        assert!(z.abs() < bound, "seed {seed} cycle {c}: `{name}` z {z:+.2}");
    }
}

/// The highest filter corner a factor 4 below and above the default (the lowest kept: the
/// record length sets it), on the random servo record: no estimate moves by more than the
/// larger standard error of the two it is compared with but on seed 3 (the mass, 1.30 of
/// its standard error, about 0.03 %: below the check's 1 % floor, so not flagged). Measured over seeds 1–12 (`cargo test --test servo corners -- --nocapture`
/// with `DYNID_SEEDS=12`): one seed flagged (seed 3, the mass), largest ratio 1.30; the
/// raised corner (about 500 rad/s) multiplies the standard errors by up to 15, the
/// lowered one (about 30 rad/s) by 0.4–2.1.
/// The corner check of `dynid identify` on one record: the parameters at the highest corner
/// a factor 4 below, as designed, and a factor 4 above.
fn corner_check(
    ir: &ModelIr,
    rec: &Record,
    opts: &IdentifyOptions,
) -> Vec<dynid::runtime::ident::CornerMove> {
    let src = RecordSource::new(rec, ir, "servo").expect("record");
    let levels: Vec<&dyn LevelSource> = vec![&src];
    let id = identify(ir, &levels, opts).expect("identification");
    dynid::runtime::ident::corner_moves(ir, &levels, &opts.as_identified(&id), &id)
        .expect("identification at the moved corners")
}

#[test]
fn estimates_hold_over_corners_a_factor_four_either_side() {
    let worst = corners_hold(&IdentifyOptions::instrument_rows(), 2.7);
    // docs/method.md quotes the largest move, the same over the suite's four seeds and
    // over the long form's twelve.
    let seeds = common::seed_count(4);
    if common::seeds_as_documented() && (seeds == 4 || seeds == 12) {
        figures::check("docs/method.md", "servo.corners.worst", worst);
    }
}

/// As [`estimates_hold_over_corners_a_factor_four_either_side`] with the defaults, which
/// on this record choose the rows of the filtered equation with the force's delay: their
/// one corner (the one the search kept, 125–250 rad/s) a factor 4 below and above (capped
/// at 0.5/Ts = 500 rad/s). Measured over seeds 1–12 (`DYNID_SEEDS=12 cargo test --release
/// --test servo chosen_rows_hold -- --nocapture`): no parameter flagged, the largest move
/// 2.49 standard errors (the offset on seed 2, 0.043 %; their standard errors are 60 to 600
/// times smaller than the instrument rows', so a move of a few hundredths of a per cent is
/// several of them); on
/// seed 6 the corner lowered to 31 rad/s no longer tells the offset from the friction (the
/// friction took it up, 13.0 for 15.0), and the check leaves that side out.
#[test]
fn chosen_rows_hold_over_corners_a_factor_four_either_side() {
    let worst = corners_hold(&IdentifyOptions::default(), 5.0);
    if common::seeds_as_documented() && common::seed_count(4) == 12 {
        figures::check("docs/method.md", "servo.corners.chosen_worst", worst);
    }
}

/// The corner check on the random servo records of the seeds: no parameter flagged, no
/// move of more than `bound` standard errors (the larger of the two compared); the
/// largest move.
fn corners_hold(opts: &IdentifyOptions, bound: f64) -> f64 {
    let seeds = common::seed_count(4) as u64;
    let mut flagged = Vec::new();
    let mut worst: f64 = 0.0;
    for seed in 1..=seeds {
        let (ir, rec) = record(0.1, common::seed(seed), false);
        let moves = corner_check(&ir, &rec, opts);
        let own: Vec<_> = moves.iter().filter(|m| !m.param.contains('.')).collect();
        assert_eq!(
            own.len(),
            TRUTH.len(),
            "seed {seed}: every parameter in all three: {moves:?}"
        );
        // The model's parameters; an input's delay (`u.delay`, with the filtered rows)
        // only in the check's verdict.
        for m in &moves {
            let ratio = [0, 2]
                .iter()
                .map(|&k| (m.values[k] - m.values[1]).abs() / m.stderrs[1].max(m.stderrs[k]))
                .fold(0.0, f64::max);
            let rel = [0, 2]
                .iter()
                .map(|&k| ((m.values[k] - m.values[1]) / m.values[1]).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "seed {seed} {}: moves {ratio:.2} SE ({:.4} %) over the highest corner {:.0} … {:.0} rad/s",
                m.param,
                100.0 * rel,
                m.upper[0],
                m.upper[2]
            );
            if !m.param.contains('.') {
                worst = worst.max(ratio);
            }
            if m.moved() {
                flagged.push((seed, m.param.clone()));
                assert!(m.describe().contains(&m.param), "{}", m.describe());
            }
        }
    }
    // Tolerance about twice the largest ratio measured over 12 seeds (the instrument rows
    // 1.30, `DYNID_SEEDS=12 cargo test --test servo corners -- --nocapture`).
    assert!(worst < bound, "largest move {worst:.2} standard errors");
    assert!(flagged.is_empty(), "flagged: {flagged:?}");
    worst
}

/// The corner check where the model is wrong: the axis simulated with a Stribeck excess
/// (10 N more friction near standstill, below about 0.05 m/s) that the identified model
/// lacks. Low corners weigh the slow passages, high corners the fast ones, so the friction
/// estimates move with the highest corner, and the check names them.
#[test]
fn the_corner_check_names_friction_that_moves_with_a_missing_stribeck_term() {
    let mut axis = ServoAxis::standard();
    axis.reference.rms = 0.1;
    axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
    axis.model_error = vec![ServoAxis::stribeck(10.0, 0.05)];
    let mut cfg = axis.config(common::seed(1));
    cfg.input_oversample = 10;
    let out = sim::simulate(&axis.true_model(), &cfg).expect("closed-loop simulation");
    let moves = corner_check(
        &axis.model(),
        &out.records[0],
        &IdentifyOptions::instrument_rows(),
    );
    for m in &moves {
        eprintln!(
            "{}: {:?} ± {:?} over {:?} rad/s",
            m.param, m.values, m.stderrs, m.upper
        );
    }
    let flagged: Vec<&str> = moves
        .iter()
        .filter(|m| m.moved())
        .map(|m| m.param.as_str())
        .collect();
    eprintln!("flagged: {flagged:?}");
    assert!(
        flagged.iter().any(|p| *p == "d" || *p == "r"),
        "no friction parameter flagged: {flagged:?}"
    );
}
