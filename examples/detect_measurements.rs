//! Measurements of detection on simulated data that are too slow or too open-ended for the
//! test suite: they print the figures quoted in docs/detection.md instead of asserting.
//!
//! `cargo run --release --example detect_measurements -- <which>` where `<which>` is
//!
//! - `false_positive_rate`: verdicts on the linear models sdof_linear and two_mass_linear
//!   over 25 seeds (the test suite checks 3);
//! - `linearisation_bias`: implied parameters with the Gaussian and with the measured
//!   linearisation on the same per-level fits, mean over seeds 7–10;
//! - `cubic_coulomb_level_count`: sdof_cubic_coulomb with 3 to 7 levels spanning the same
//!   range (6…40), for how many levels the pair of effects wins.

#[path = "../tests/detect_common/mod.rs"]
mod detect_common;

use detect_common::{detect_levels, finding, model, simulate_levels};
use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::detect::{detect, DetectOptions, Detection, LevelFits, Linearisation, Verdict};
use dynid::runtime::record::Record;

/// Seconds per level, as in tests/detect_models.rs.
const DURATION: f64 = 400.0;

const WHICH: [&str; 3] = [
    "false_positive_rate",
    "linearisation_bias",
    "cubic_coulomb_level_count",
];

fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    match which.as_str() {
        "false_positive_rate" => false_positive_rate(),
        "linearisation_bias" => linearisation_bias(),
        "cubic_coulomb_level_count" => cubic_coulomb_level_count(),
        _ => {
            eprintln!(
                "usage: cargo run --release --example detect_measurements -- <which>\n\
                 where <which> is one of: {}",
                WHICH.join(", ")
            );
            std::process::exit(2);
        }
    }
}

fn sim(truth: &str, duration: f64, seed: u64) -> Vec<Record> {
    simulate_levels(&model(truth), duration, seed)
}

fn run(linear: &str, records: &[Record]) -> (Detection, LevelFits) {
    detect_levels(&model(linear), records, false)
}

fn run_ir(ir: &ModelIr, records: &[Record]) -> (Detection, LevelFits) {
    detect_levels(ir, records, false)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b) / b
}

/// Verdicts on the linear models over 25 seeds (seeds 1000…1024, as the always-on test
/// `linear_systems_give_no_detection` uses 1000…1002).
fn false_positive_rate() {
    let two = model("two_mass_linear");
    let sdof = model("sdof_linear");
    let (mut alarms, mut total) = (0, 0);
    for seed in 0..25u64 {
        for ir in [&sdof, &two] {
            let recs = simulate_levels(ir, DURATION, 1000 + seed);
            let (d, _) = run_ir(ir, &recs);
            for e in &d.elements {
                total += 1;
                if e.verdict != Verdict::Linear {
                    alarms += 1;
                    println!("seed {seed} {}: {}", ir.name, e.verdict);
                }
            }
        }
    }
    println!("false positives: {alarms} of {total} linear elements");
}

/// Truth model, linear model, element, truth of the implied parameters.
type Case = (
    &'static str,
    &'static str,
    &'static str,
    &'static [(&'static str, f64)],
);

/// Implied parameters with Gaussian and with measured linearisation on the same per-level
/// fits, mean over seeds 7–10.
fn linearisation_bias() {
    let cases: [Case; 6] = [
        (
            "sdof_duffing",
            "sdof_linear",
            "k/d (ground, m)",
            &[("k3", 2.0)],
        ),
        (
            "sdof_coulomb",
            "sdof_linear",
            "k/d (ground, m)",
            &[("r", 0.3)],
        ),
        (
            "quadratic_damping",
            "quadratic_damping_linear",
            "k/d (ground, m)",
            &[("c", 0.2)],
        ),
        (
            "prestress",
            "prestress_linear",
            "d/k (ground, m)",
            &[("f0", 0.5)],
        ),
        (
            "backlash",
            "backlash_linear",
            "k/d (ground, m)",
            &[("kb", 4.0), ("g", 0.1)],
        ),
        (
            "sdof_cubic_coulomb",
            "sdof_linear",
            "k/d (ground, m)",
            &[("k3", 2.0)],
        ),
    ];
    let seeds = 7..11u64;
    for (truth, linear, element, expect) in cases {
        let ir = model(linear);
        let mut sums = vec![[0.0f64; 2]; expect.len()];
        for seed in seeds.clone() {
            let recs = sim(truth, DURATION, seed);
            let (_, fits) = run_ir(&ir, &recs);
            for (k, lin) in [Linearisation::Gaussian, Linearisation::Measured]
                .into_iter()
                .enumerate()
            {
                let opts = DetectOptions {
                    linearisation: lin,
                    se_dof: Some(fits.n_blocks as f64 - 1.0),
                    ..Default::default()
                };
                let d = detect(&fits.input, &[], &opts).unwrap();
                let f = finding(&d, element);
                let top = &f.ranking[0];
                for (j, (p, _)) in expect.iter().enumerate() {
                    let v = top
                        .effect_estimates()
                        .iter()
                        .find(|e| e.name == *p)
                        .map_or(f64::NAN, |e| e.value);
                    sums[j][k] += v;
                }
                println!(
                    "{truth} seed {seed} {}: {} ({})",
                    if k == 1 { "measured" } else { "gaussian" },
                    f.verdict,
                    top.summary()
                );
            }
        }
        let n = seeds.clone().count() as f64;
        for (j, (p, t)) in expect.iter().enumerate() {
            let (g, m) = (sums[j][0] / n, sums[j][1] / n);
            println!(
                "SUMMARY {truth}: {p} truth {t}: gaussian {g:.4} ({:+.1} %), measured {m:.4} ({:+.1} %)",
                100.0 * rel(g, *t),
                100.0 * rel(m, *t)
            );
        }
    }
}

/// sdof_cubic_coulomb with 3 to 7 levels spanning the same range (6…40), seeds 7, 8, 9.
fn cubic_coulomb_level_count() {
    for n in 3..=7usize {
        for seed in [7u64, 8, 9] {
            let ir = cubic_coulomb_levels(n);
            let recs = simulate_levels(&ir, DURATION, seed);
            let (d, _) = run("sdof_linear", &recs);
            let f = finding(&d, "k/d (ground, m)");
            println!(
                "LEVELS {n} seed {seed}: {} | top: {} | suspected: {:?}",
                f.verdict,
                f.ranking[0].summary(),
                f.suspected.as_ref().map(|s| (&s.effect, s.pair_delta_aicc))
            );
        }
    }
}

/// The prototype system with `n` levels geometrically spaced over 6…40 (as in
/// tests/detect_models.rs).
fn cubic_coulomb_levels(n: usize) -> ModelIr {
    let mut ir = model("sdof_cubic_coulomb");
    ir.excitation[0].levels = (0..n)
        .map(|i| {
            let t = i as f64 / (n - 1) as f64;
            // Three decimals, as a model file would write them.
            format!("{:.3}", 6.0 * (40.0f64 / 6.0).powf(t))
                .parse()
                .unwrap()
        })
        .collect();
    ir
}
