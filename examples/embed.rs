//! Identify the two-mass model from Rust: the model is compiled into this program by
//! `include_model!`, simulated with its nominal parameters, and identified back.
//!
//! `cargo run --release --example embed`

use dynid::runtime::sim::SimConfig;

dynid::include_model!("models/two_mass.dyn");

pub fn run() -> Result<TwoMassParams, Box<dyn std::error::Error>> {
    let model = TwoMass::new();
    let truth = TwoMassParams::default(); // the nominal values in the .dyn file
    let cfg = SimConfig {
        duration: 300.0,
        seed: 1,
        ..SimConfig::default()
    };
    let data = model.simulate(&truth, &cfg)?;
    let id = model.identify(&data.records)?;
    let found = TwoMassParams::from_identification(&id).ok_or("a parameter is unidentifiable")?;
    for p in &id.params {
        println!("{:>3} = {:9.4} ± {:.4}", p.name, p.value, p.stderr);
    }
    println!("condition number {:.1}", id.condition);
    Ok(found)
}

#[allow(dead_code)] // the test suite includes this file for `run` alone
fn main() -> Result<(), Box<dyn std::error::Error>> {
    run().map(|_| ())
}
