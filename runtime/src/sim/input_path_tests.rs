//! The noise-free bias of the covariance method is the simulated input's path between
//! samples (docs/method.md §3): a form-filter input drawn on the sample grid and linear in
//! between has a kink at every sample, and the trapezoid rule that forms the moments misses
//! the integral of an instrument times such an input by `−(Tₛ²/12)⟨ι'' u⟩`. An input drawn
//! on a finer grid is (nearly) smooth at the samples, and the bias is gone; at fixed filter
//! corners the bias falls with the square of the sample interval.

use super::*;
use crate::data::{LevelSource, RecordSource};
use crate::ident::{identify, Identification, IdentifyOptions};
use crate::record::Record;

// The doc-figure reader, also loaded by the identification tests (a module of its own in
// each, as every integration test has it).
#[allow(clippy::duplicate_mod)]
#[path = "../../../tests/figures/mod.rs"]
mod figures;

/// `sdof_cubic_coulomb` (models/), its input given by `excite`.
fn cubic_coulomb(excite: &str) -> ModelIr {
    let src = format!(
        "model sdof_cubic_coulomb {{
            body m = 1.0
            input u on m
            spring k (ground, m) ~ 4.0
            damper d (ground, m) ~ 0.4
            force nl (ground, m) = k3 ~ 2.0 * s^3 + r ~ 0.3 * sign(v)
            excite u: {excite}
        }}"
    );
    dsl_parser::compile_str("sdof_cubic_coulomb", &src).expect("valid model")
}

/// The linear SDOF (`models/sdof_linear.dyn`), its input given by `excite`.
fn linear(excite: &str) -> ModelIr {
    let src = format!(
        "model sdof_linear {{
            body m = 1.0
            input u on m
            spring k (ground, m) ~ 4.0
            damper d (ground, m) ~ 0.4
            excite u: {excite}
        }}"
    );
    dsl_parser::compile_str("sdof_linear", &src).expect("valid model")
}

/// A smooth random input: white noise through a second-order form filter (its derivative is
/// continuous), levels chosen for the variance of the models' low-pass input (`L²/2c` with
/// `c = 10` and levels 6, 15, 40; here `L²/(4 z f³)`).
const SMOOTH: &str = "second_order(freq = 10, damping = 0.7) levels [71, 177, 473]";

/// The models' own input: white noise through a first-order low-pass (a rough path).
const LOWPASS: &str = "lowpass(corner = 10) levels [6, 15, 40]";

fn records(ir: &ModelIr, cfg: &SimConfig) -> Vec<Record> {
    simulate(ir, cfg).expect("simulation").records
}

fn identify_records(ir: &ModelIr, recs: &[Record], opts: &IdentifyOptions) -> Identification {
    let srcs: Vec<RecordSource> = recs
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).expect("record"))
        .collect();
    let dyns: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    identify(ir, &dyns, opts).expect("identification")
}

/// `(name, relative error, error in standard errors)` of every unknown.
fn errors(ir: &ModelIr, id: &Identification) -> Vec<(String, f64, f64)> {
    let truth = parameter_values(ir).expect("nominal values");
    id.params
        .iter()
        .map(|p| {
            let i = ir
                .params
                .iter()
                .position(|q| q.name == p.name)
                .expect("an identified parameter is the model's");
            let t = truth[i];
            (p.name.clone(), p.value / t - 1.0, (p.value - t) / p.stderr)
        })
        .collect()
}

fn show(case: &str, e: &[(String, f64, f64)]) {
    let row: Vec<String> = e
        .iter()
        .map(|(n, r, z)| format!("{n} {:+.4} % ({z:+.1} se)", 100.0 * r))
        .collect();
    eprintln!("{case}: {}", row.join(", "));
}

fn error_of<'a>(e: &'a [(String, f64, f64)], name: &str) -> &'a (String, f64, f64) {
    e.iter().find(|(n, ..)| n == name).expect("parameter")
}

/// `sdof_cubic_coulomb`, 3 × 2000 s, noise-free, with the smooth input: drawn on the sample
/// grid (linear between samples) the damping comes out high by several standard errors;
/// drawn ten times finer every estimate lies within its standard errors. Seeds 1, 2, 3
/// (`simulate` with `--input-oversample 1` and `10`, then `identify` with the defaults, on
/// the model with this `excite` line): on the sample grid d +0.048 / +0.055 / +0.059 %
/// (4.0–4.2 se); ten times finer d −0.018 / +0.007 / −0.009 %, k, k3 within 0.004 %, r
/// within 0.047 %, no error beyond 1.2 se. The bounds are 2–3 times those.
#[test]
fn noise_free_bias_vanishes_with_a_finer_input_grid() {
    let ir = cubic_coulomb(SMOOTH);
    let on_samples = records(&ir, &SimConfig::default());
    let id = identify_records(&ir, &on_samples, &IdentifyOptions::default());
    let coarse = errors(&ir, &id);
    show("input linear between samples", &coarse);
    let fine = records(
        &ir,
        &SimConfig {
            input_oversample: 10,
            ..SimConfig::default()
        },
    );
    let id = identify_records(&ir, &fine, &IdentifyOptions::default());
    let smooth = errors(&ir, &id);
    show("input ten times finer", &smooth);
    let (_, d, z) = error_of(&coarse, "d");
    figures::check("docs/method.md", "input_path.coarse.d", 100.0 * d);
    assert!(
        *d > 0.0003 && *z > 3.0,
        "the bias on the sample grid: d {d} ({z} se)"
    );
    let (_, d, _) = error_of(&smooth, "d");
    figures::check("docs/method.md", "input_path.fine.d", 100.0 * d);
    for (name, bound) in [("k", 1e-4), ("d", 4e-4), ("k3", 1e-4), ("r", 1.2e-3)] {
        let (_, r, z) = error_of(&smooth, name);
        assert!(
            r.abs() < bound && z.abs() < 2.5,
            "{name}: {:+.4} % ({z:+.1} se) with the input ten times finer",
            100.0 * r
        );
    }
}

/// At fixed corners the bias of the models' own low-pass input falls with the square of
/// the sample interval, as `(λTₛ)²/12` does: linear SDOF, 3 × 500 s, seed 1, corners
/// 0.75 … 31.4 rad/s (`identify --filter-corners 0.75,1.58,3.33,7.04,14.9,31.4` on
/// `simulate models/sdof_linear.dyn --duration 500 --sample 0.01` and `0.005`): d −0.195 %
/// (17 se) at Tₛ = 0.01 s, −0.048 % at 0.005 s, a ratio of 4.0 (at 0.001 s: −0.002 %). With the default corners the top corner follows the
/// sample rate and the bias falls more slowly (d −0.11 % at 0.01 s, −0.06 % at 0.005 s on
/// `sdof_cubic_coulomb`).
#[test]
fn input_path_bias_falls_with_the_square_of_the_sample_interval() {
    let ir = linear(LOWPASS);
    let opts = IdentifyOptions {
        corners: Some(vec![0.75, 1.58, 3.33, 7.04, 14.9, 31.4]),
        ..IdentifyOptions::default()
    };
    let mut ds = Vec::new();
    for sample in [0.01, 0.005] {
        let cfg = SimConfig {
            duration: 500.0,
            sample,
            ..SimConfig::default()
        };
        let id = identify_records(&ir, &records(&ir, &cfg), &opts);
        let e = errors(&ir, &id);
        show(&format!("low-pass input, Ts = {sample} s"), &e);
        ds.push(error_of(&e, "d").1);
    }
    figures::check("docs/method.md", "input_path.ts.d", 100.0 * ds[0]);
    figures::check("docs/method.md", "input_path.ts2.d", 100.0 * ds[1]);
    let ratio = ds[0] / ds[1];
    assert!(
        ds[0] < -0.001 && (3.0..5.5).contains(&ratio),
        "d {:+.4} % at 0.01 s, {:+.4} % at 0.005 s: ratio {ratio:.2}, not 4",
        100.0 * ds[0],
        100.0 * ds[1]
    );
}

/// Model error the identification model does not contain: the servo axis of `tests/servo.rs`
/// (random smooth reference, 25 s at 1 kHz, 1 µm encoder, the controller ten times per
/// sample, force and position only) on a guide whose friction ripples along the travel,
/// `±1.5 N · sin(2π x / 20 mm) · sign(v)` (a tenth of the Coulomb friction), identified
/// with the model without the ripple; the standard errors must cover what it leaves.
/// Seeds 1–8 (`cargo test -p dynid-runtime --features test-support --lib
/// servo_errors_stay_honest -- --nocapture`): 22 of 24 errors within 2 se, the largest
/// 3.1 se. The two beyond are the mass (+0.43 % ± 0.14 %, +0.23 % ± 0.09 %): the mass comes
/// out high on every seed (+0.2 … +3.2 %), which this test does not explain (no run
/// without the ripple on these seeds was compared). On this slow trajectory (3 cm RMS) the
/// axis sticks at reversals and two seeds carry little information (standard errors of d
/// of 320 % and 2300 %), honestly reported. Bounds: at least 80 % within 2 se, none beyond
/// 4 se.
#[test]
fn servo_errors_stay_honest_with_an_unmodelled_friction_ripple() {
    use crate::sim::test_models::ServoAxis;
    let axis = ServoAxis {
        model_error: vec![ServoAxis::friction_ripple(1.5, 0.02)],
        ..ServoAxis::standard()
    };
    let ir = axis.model();
    let truth = [("m", axis.mass), ("d", axis.viscous), ("r", axis.coulomb)];
    let seeds = 1..=8u64;
    let (mut inside, mut total, mut worst) = (0, 0, 0.0f64);
    for seed in seeds {
        let mut cfg = axis.config(seed);
        cfg.input_oversample = 10;
        let recs = records(&axis.true_model(), &cfg);
        let id = identify_records(&ir, &recs, &IdentifyOptions::default());
        let row: Vec<String> = truth
            .iter()
            .map(|&(n, t)| {
                let p = id.param(n).expect("identified");
                let z = (p.value - t) / p.stderr;
                total += 1;
                inside += usize::from(z.abs() < 2.0);
                worst = worst.max(z.abs());
                format!(
                    "{n} {:+.2} % ± {:.2} % ({z:+.1} se)",
                    100.0 * (p.value / t - 1.0),
                    100.0 * p.stderr / t
                )
            })
            .collect();
        eprintln!("seed {seed}: {}", row.join(", "));
    }
    eprintln!("|error| < 2 se: {inside} of {total}; largest |error| {worst:.2} se");
    assert!(
        inside * 10 >= total * 8 && worst < 4.0,
        "{inside} of {total}, worst {worst}"
    );
}
