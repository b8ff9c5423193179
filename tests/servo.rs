//! A real-shaped record: a position-controlled servo axis (mass 50 kg, viscous friction
//! 120 N·s/m, Coulomb friction 15 N, a constant force offset of −2 N), one closed-loop
//! record of 25 s at 1 kHz, positions from a 1 µm encoder and the drive's force only — no
//! velocity channel, a force that is not white, a response that is not stationary, a
//! controller that updates ten times per sample interval (so the force has content between
//! samples) and follows a smooth random trajectory. Identified with the default settings:
//! the filters are designed from the record, the velocity in the Coulomb term is estimated
//! from the encoder positions.
//!
//! What the method reaches here (seeds 1–6, printed with `--nocapture`): mass +0.19 to
//! +0.38 % (a small bias beyond its standard errors of 0.1–0.4 %), offset within 3.6 %,
//! viscous friction within 4.9 % and Coulomb friction within 3.9 % (standard errors
//! 1.1–10 %). The issue-level goal of 2 % for the two frictions is not reached on 25 s;
//! the test asserts mass < 0.8 %, d < 10 %, r < 8 %, f0 < 5 %, and d, r, f0 within three
//! standard errors. Where the friction error comes from (the same axis through `dynid
//! simulate … --pd 80000,2680 --smooth-reference --input-oversample 10 --quantise 1e-6`,
//! seeds 1–3, then `identify`): with a tachometer controller and the velocity *measured*
//! instead of estimated, d is within 1 % and r within 0.8 %; the zero-phase estimate rounds off the velocity's kinks
//! at every reversal of the motion, exactly where `sign(v)` switches. A controller that
//! differenced the encoder over one 0.1 ms step instead of one sample interval put ±27 N
//! of force jitter between samples, and d, r off by up to 23 %.
mod common;

use dynid::runtime::data::{LevelSource, RecordSource};
use dynid::runtime::ident::Identification;
use dynid::runtime::sim::{self, test_models::ServoAxis};
use dynid::runtime::{identify, IdentifyOptions};

const TRUTH: [(&str, f64); 4] = [("m", 50.0), ("d", 120.0), ("r", 15.0), ("f0", -2.0)];

fn servo(seed: u64) -> Identification {
    let mut axis = ServoAxis::standard();
    axis.extra_forces = vec![("offset".into(), "f0 ~ -2.0".into())];
    let ir = axis.model();
    let mut cfg = axis.config(common::seed(seed));
    cfg.input_oversample = 10;
    let out = sim::simulate(&ir, &cfg).expect("closed-loop simulation");
    assert_eq!(out.records.len(), 1, "one record");
    let rec = &out.records[0];
    assert!(rec.column("m.v").is_none(), "no velocity channel");
    let src = RecordSource::new(rec, &ir, "servo").expect("record");
    let levels: Vec<&dyn LevelSource> = vec![&src];
    identify(&ir, &levels, &IdentifyOptions::default()).expect("identification")
}

#[test]
fn servo_axis_from_encoder_and_force_alone() {
    for seed in 1..=6 {
        let id = servo(seed);
        assert!(id.unidentifiable.is_empty(), "{:?}", id.unidentifiable);
        assert_eq!(id.estimated.len(), 1, "the velocity is estimated");
        let mut row = Vec::new();
        for (name, t) in TRUTH {
            let p = id.param(name).expect("estimated");
            let (e, s) = (p.value / t - 1.0, p.stderr / t.abs());
            row.push(format!("{name} {:+.2} % (±{:.2} %)", 100.0 * e, 100.0 * s));
            // Seeds 1–6 (`cargo test --test servo -- --nocapture`): m +0.19…+0.38 %, d up to
            // 4.9 %, r 3.9 %, f0 3.6 % (module documentation).
            let bound = match name {
                "m" => 0.008,
                "d" => 0.10,
                "r" => 0.08,
                _ => 0.05,
            };
            assert!(
                e.abs() < bound,
                "seed {seed}: `{name}` off by {:+.2} % (bound {} %)",
                100.0 * e,
                100.0 * bound
            );
            assert!(
                name == "m" || (p.value - t).abs() < 3.0 * p.stderr,
                "seed {seed}: `{name}` = {} ± {}, truth {t}",
                p.value,
                p.stderr
            );
        }
        println!("seed {seed}: {}", row.join(", "));
    }
}
