//! What the servo tests share (`tests/servo.rs`, `tests/servo_planned.rs`): the axis's true
//! parameters, its planned record — the records of `runtime/benches/servo_precision.rs` —,
//! one identification of a record, and the estimates' relative errors.
#![allow(dead_code)] // each test binary uses a subset

use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::ident::Identification;
use dynid::runtime::record::Record;
use dynid::runtime::sim::{self, test_models, test_models::ServoAxis};
use dynid::runtime::{identify, IdentifyOptions};

/// The simulated axis's parameters: mass, viscous and Coulomb friction, constant force.
pub const TRUTH: [(&str, f64); 4] = [("m", 50.0), ("d", 120.0), ("r", 15.0), ("f0", -2.0)];

/// [`ServoAxis::planned`] (point-to-point moves of 10 cm at 0.4, 0.2 and 0.1 m/s, 0.33 s at
/// rest before each, cycles of 6.18 s, four in the 25 s record at 1 kHz) with the constant
/// force `f0 ~ -2.0`.
pub fn planned_axis() -> ServoAxis {
    let mut axis = ServoAxis::planned();
    axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
    axis
}

/// A record of `axis` simulated from `truth` at `seed`, the controller updated `updates`
/// times per sample interval, with white noise of 1 % of the force's spread on the force,
/// drawn from the seed (the encoder's rounding is deterministic: without it every seed
/// would give the same record).
pub fn planned_record_of(axis: &ServoAxis, truth: &ModelIr, seed: u64, updates: usize) -> Record {
    let mut cfg = axis.config(seed);
    cfg.input_oversample = updates;
    let mut out = sim::simulate(truth, &cfg).expect("closed-loop simulation");
    let mut rec = out.records.remove(0);
    test_models::add_noise(&mut rec, "u", 0.01, seed);
    rec
}

/// The planned record at `seed` (ten controller updates per sample) and the model that
/// identifies it, as in the bench `servo_precision`.
pub fn planned_record(seed: u64) -> (ModelIr, Record) {
    let axis = planned_axis();
    let rec = planned_record_of(&axis, &axis.true_model(), seed, 10);
    (axis.model(), rec)
}

/// Identify the one planned record `rec` with `opts`.
pub fn identify_record(ir: &ModelIr, rec: &Record, opts: &IdentifyOptions) -> Identification {
    let src = RecordSource::new(rec, ir, "planned").expect("record");
    let levels: Vec<&dyn LevelSource> = vec![&src];
    identify(ir, &levels, opts).expect("identification")
}

/// `(relative error, relative standard error)` of each parameter of [`TRUTH`].
pub fn errors(id: &Identification) -> Vec<(f64, f64)> {
    TRUTH
        .iter()
        .map(|&(name, t)| {
            let p = id.param(name).expect("estimated");
            (p.value / t - 1.0, p.stderr / t.abs())
        })
        .collect()
}

/// The errors of [`errors`] as one line, in % with `decimals` digits.
pub fn row(errs: &[(f64, f64)], decimals: usize) -> String {
    TRUTH
        .iter()
        .zip(errs)
        .map(|((n, _), (e, s))| {
            format!(
                "{n} {:+.decimals$} % (±{:.decimals$} %)",
                100.0 * e,
                100.0 * s
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}
