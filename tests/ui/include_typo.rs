// A typo in a `.dyn` file: the error names the file, line and column, and the code that
// uses the model reports nothing more (a placeholder with the model's API stands in).
use dynid::runtime::sim::SimConfig;

dynid::include_model!("models/typo.dyn");

fn main() {
    let model = TwoMass::new();
    let data = model
        .simulate(&TwoMassParams::default(), &SimConfig::default())
        .unwrap();
    let id = model.identify(&data.records).unwrap();
    let _found = TwoMassParams::from_identification(&id);
}
