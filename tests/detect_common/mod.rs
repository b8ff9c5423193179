//! Helpers of detection on simulated data, shared by `tests/detect_models.rs` and
//! `examples/detect_measurements.rs`: compile a model of `models/`, simulate its levels,
//! run detection with the linear counterpart.

use dynid::dsl_parser::{compile_file, ir::ModelIr};
use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::detect::{
    detect_from_data, DetectOptions, Detection, ElementFinding, LevelFits,
};
use dynid::runtime::record::Record;
use dynid::runtime::sim::{simulate, SimConfig};
use dynid::runtime::IdentifyOptions;
use std::path::Path;

/// `models/NAME.dyn`, compiled.
pub fn model(name: &str) -> ModelIr {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(format!("{name}.dyn"));
    compile_file(&p).unwrap_or_else(|e| panic!("{name}: {e:?}"))
}

/// The model's excitation levels, `duration` seconds each after a 20 s burn-in.
pub fn simulate_levels(ir: &ModelIr, duration: f64, seed: u64) -> Vec<Record> {
    let cfg = SimConfig {
        duration,
        seed,
        burn_in: 20.0,
        ..Default::default()
    };
    simulate(ir, &cfg).expect("simulate").records
}

/// Detection with the linear model `ir` on `records` (one per level).
pub fn detect_levels(ir: &ModelIr, records: &[Record], balance: bool) -> (Detection, LevelFits) {
    let srcs: Vec<RecordSource> = records
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)).unwrap())
        .collect();
    let levels: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = IdentifyOptions {
        balance: Some(balance),
        ..Default::default()
    };
    detect_from_data(ir, &levels, &opts, &DetectOptions::default(), &[]).expect("detect")
}

/// The finding of `element`.
pub fn finding<'a>(d: &'a Detection, element: &str) -> &'a ElementFinding {
    d.elements
        .iter()
        .find(|e| e.element == element)
        .unwrap_or_else(|| panic!("no element {element}"))
}
