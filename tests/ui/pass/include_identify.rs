// What a crate outside the workspace does: compile a model file that sits beside its
// Cargo.toml, simulate it with the nominal parameters and identify them back.
use dynid::runtime::sim::SimConfig;

dynid::include_model!("models/duffing.dyn");

fn main() {
    let model = SdofDuffing::new();
    let truth = SdofDuffingParams::default();
    let cfg = SimConfig {
        duration: 100.0,
        burn_in: 20.0,
        seed: 7,
        ..SimConfig::default()
    };
    let data = model.simulate(&truth, &cfg).expect("the model simulates");
    let id = model.identify(&data.records).expect("the parameters are identified");
    let found = SdofDuffingParams::from_identification(&id).expect("every parameter identifiable");
    for ((name, f), t) in SdofDuffing::PARAM_NAMES
        .iter()
        .zip(found.to_vec())
        .zip(truth.to_vec())
    {
        // Noise-free data: within a few percent of the truth.
        assert!((f - t).abs() <= 0.05 * t.abs(), "{name}: {f} vs {t}");
    }
}
