//! Recovery and identity tests of the covariance method (fixed seeds), by topic, with the
//! shared models, records and helpers.

use super::accumulate::{LevelAccumulator, TASK_LEN};
use super::bank::choose_bank;
use super::columns::term_moment;
use super::moments::{Hat, LevelMoments, MomentView};
use super::noise::fix::fill_extra;
use super::plan::BasisMoment;
use super::*;
use crate::data::{LevelSource, RecordSource};
use crate::record::Record;
use crate::sim::{self, SimConfig};
use crate::tape::Tape;
use dynid_ir::ir::ModelIr;
use std::sync::OnceLock;

#[path = "../../../../tests/figures/mod.rs"]
mod figures;

mod estimates;
mod identities;
mod levels;
mod noise;
mod passes;
mod recovery;

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
    let bank = choose_bank(ir, opts).unwrap();
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
