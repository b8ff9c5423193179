//! Measurements of the simulator and of the noise correction that are too slow for the test
//! suite: they print the figures quoted in the module documentation of `sim`, in
//! docs/performance.md (the noise correction) and in docs/method.md instead of asserting.
//!
//! `cargo run --release -p dynid-runtime --features test-support --example measurements -- <which>`
//! where `<which>` is
//!
//! - `integration`: the RK4 integration error against 4× the sub-steps for 5…40 sub-steps,
//!   and the time of a default simulation (module doc of `sim`);
//! - `servo`: tracking error and force autocorrelation of the standard servo axis, seeds 1–6
//!   (the bounds of `sim::tests::servo_axis_tracks_its_reference_with_a_coloured_force`);
//! - `noise`: errors of (d, k, k3, r) with and without the noise correction at 0 / 5 / 10 %
//!   noise on every channel, seeds 11–13, and the estimated noise levels (docs/performance.md).

use dynid_ir::ir::FormFilter;
use dynid_runtime::data::{LevelSource, RecordSource};
use dynid_runtime::sim::test_models::{integration_error, sdof, tracking, SdofParams, ServoAxis};
use dynid_runtime::sim::{self, SimConfig};
use dynid_runtime::{identify, IdentifyOptions};

const WHICH: [&str; 3] = ["integration", "servo", "noise"];

fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    match which.as_str() {
        "integration" => integration(),
        "servo" => servo(),
        "noise" => noise(),
        _ => {
            eprintln!(
                "usage: cargo run --release -p dynid-runtime --features test-support \
                 --example measurements -- <which>\nwhere <which> is one of: {}",
                WHICH.join(", ")
            );
            std::process::exit(2);
        }
    }
}

fn integration() {
    for s in [5, 10, 20, 40] {
        println!(
            "substeps {s:3}: max rel RMS diff to 4x = {:.2e}",
            integration_error(s, 500.0)
        );
    }
    let ir = benchmark();
    let t = std::time::Instant::now();
    sim::simulate(&ir, &SimConfig::default()).expect("simulates");
    println!(
        "3 levels x (100 + 2000) s, Ts 0.01, 20 substeps: {:?}",
        t.elapsed()
    );
}

fn servo() {
    let axis = ServoAxis::standard();
    let ir = axis.model();
    for seed in 1..=6 {
        let out = sim::simulate(&ir, &axis.config(seed)).expect("simulates");
        let (err, rho) = tracking(&out.records[0]);
        println!(
            "seed {seed}: relative tracking error {err:.4}, lag-1 autocorrelation of u {rho:.4}"
        );
    }
}

fn noise() {
    let ir = benchmark();
    let truth = [("d", 0.4), ("k", 4.0), ("k3", 2.0), ("r", 0.3)];
    for dur in [1000.0, 2000.0] {
        for (eta, inputs) in [(0.0, true), (0.05, true), (0.1, true), (0.1, false)] {
            for seed in [11, 12, 13] {
                let cfg = SimConfig {
                    duration: dur,
                    noise: eta,
                    noise_on_inputs: inputs,
                    seed,
                    ..Default::default()
                };
                let recs = sim::simulate(&ir, &cfg).expect("simulates").records;
                let srcs: Vec<RecordSource> = recs
                    .iter()
                    .enumerate()
                    .map(|(i, r)| RecordSource::new(r, &ir, format!("level {}", i + 1)).unwrap())
                    .collect();
                let levels: Vec<&dyn LevelSource> =
                    srcs.iter().map(|s| s as &dyn LevelSource).collect();
                for corr in [false, true] {
                    let opts = IdentifyOptions {
                        noise_correction: corr,
                        ..Default::default()
                    };
                    let id = identify(&ir, &levels, &opts).expect("identifies");
                    let e: Vec<f64> = truth
                        .iter()
                        .map(|(n, t)| (id.param(n).expect(n).value - t) / t)
                        .collect();
                    let errs: Vec<String> =
                        e.iter().map(|v| format!("{:+.2}%", 100.0 * v)).collect();
                    let est: Vec<String> = id
                        .levels
                        .iter()
                        .map(|l| {
                            l.noise
                                .iter()
                                .map(|(s, n)| format!("{s} {:.2}%", 100.0 * n / l.std[s]))
                                .collect::<Vec<_>>()
                                .join(" ")
                        })
                        .collect();
                    println!(
                        "T {dur} noise {eta} inputs {inputs} seed {seed} corr {corr}: (d, k, k3, r) {} max {:.2}% | {} | {:?}",
                        errs.join(", "),
                        100.0 * e.iter().map(|v| v.abs()).fold(0.0, f64::max),
                        est.join(" / "),
                        id.noise.corrected
                    );
                }
            }
        }
    }
}

/// m x'' + 0.4 x' + 4 x + 2 x³ + 0.3 sign(x') = u at levels 6 / 15 / 40 (low-pass 10 rad/s).
fn benchmark() -> dynid_ir::ir::ModelIr {
    sdof(
        &SdofParams::benchmark(),
        FormFilter::Lowpass { corner: 10.0 },
        vec![6.0, 15.0, 40.0],
    )
}
