//! `examples/embed.rs` runs as part of the test suite and recovers the parameters it
//! simulated with.

#[path = "../examples/embed.rs"]
mod embed;

#[test]
fn embedding_example_identifies_two_mass() {
    let found = embed::run().unwrap();
    let truth = embed::TwoMassParams::default();
    for ((name, f), t) in embed::TwoMass::PARAM_NAMES
        .iter()
        .zip(found.to_vec())
        .zip(truth.to_vec())
    {
        // 300 s of noise-free data: within a few percent of the truth.
        assert!((f - t).abs() <= 0.05 * t.abs(), "{name}: {f} vs {t}");
    }
}
