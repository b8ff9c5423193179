//! The property the `numerics` fuzz target (`fuzz/fuzz_targets/numerics.rs`) and its smoke
//! tests check: a small simulated record, scaled to the edges of double precision, through
//! identification and detection gives finite estimates or a typed error — never a panic.
//! (The readers' own properties are `data::fuzz`.)

use crate::data::{LevelSource, RecordSource};
use dynid_ir::ir::ModelIr;

/// Small models (`.dyn` source) for [`check_numerics`]: linear, cubic, two bodies.
pub const NUMERIC_MODELS: &[&str] = &[
    "model linear {
        body m = 1.0
        input u on m
        measure m.x, m.v, u
        spring k (ground, m) ~ 4.0
        damper d (ground, m) ~ 0.4
        excite u: lowpass(corner = 10) levels [1]
    }",
    "model duffing {
        body m = 1.0
        input u on m
        measure m.x, u
        spring k (ground, m) ~ 4.0
        damper d (ground, m) ~ 0.4
        force c (ground, m) = k3 ~ 1.0 * s^3
        excite u: lowpass(corner = 10) levels [1]
    }",
    "model two {
        body m1 = 1.0
        body m2 = 0.5
        input u on m1
        measure m1.x, m2.x, u
        spring k1 (ground, m1) ~ 4.0
        spring k2 (m1, m2) ~ 2.0
        damper d1 (ground, m1) ~ 0.4
        damper d2 (m1, m2) ~ 0.2
        excite u: lowpass(corner = 10) levels [1]
    }",
];

/// Scales a fuzzed column is multiplied by: units from micro to mega, and magnitudes at and
/// beyond the edges of double precision (subnormal products, overflowing squares).
const SCALES: &[f64] = &[
    1.0, 1e-6, 1e6, 1e-100, 1e100, 1e-150, 1e-155, 1e-160, 1e150, 1e155, 1e-300, 1e-308, 1e-310,
    1e-320, 1e300, 0.0,
];

/// The property of the `numerics` fuzz target: a small record derived from `bytes` — one
/// of the models `irs`, 1 to 3 levels of 300 to 810 samples simulated with a seed, noise
/// and levels taken from the bytes, then every measured column scaled by a factor from
/// [`SCALES`] (all together, or one by one), made constant, or replaced by raw values from the bytes — through
/// identification (pooled and per level) and detection. Panics if any returns a
/// non-finite estimate or standard error (a panic inside is the other failure the fuzzer
/// finds; a hang shows as its timeout).
///
/// Longer than most functions here: the bytes are consumed in one order (model, levels,
/// noise, scaling), and that order is the fuzz target's input format.
pub fn check_numerics(bytes: &[u8], irs: &[ModelIr]) -> Reached {
    let mut reached = Reached::default();
    use crate::ident::{identify, identify_per_level, IdentifyOptions};
    use crate::sim::{simulate, SimConfig};
    if bytes.len() < 12 || irs.is_empty() {
        return reached;
    }
    let byte = |i: usize| bytes.get(i).copied().unwrap_or(0);
    let ir = &irs[usize::from(byte(0)) % irs.len()];
    let n_levels = usize::from(byte(1) % 3) + 1;
    let n = 300 + 2 * usize::from(byte(2));
    let seed = u64::from_le_bytes(bytes[3..11].try_into().expect("invariant: 8 bytes"));
    let levels: Vec<f64> = (0..n_levels)
        .map(|l| 0.5 * f64::from(1 + (byte(11) >> (2 * l)) % 4))
        .collect();
    let cfg = SimConfig {
        levels: Some(levels),
        duration: n as f64 * 0.01,
        sample: 0.01,
        seed,
        noise: f64::from(byte(11) >> 6) * 0.02,
        burn_in: 1.0,
        ..Default::default()
    };
    let out = match simulate(ir, &cfg) {
        Ok(out) => out,
        Err(e) => {
            reached.sim_error = Some(e.to_string());
            return reached;
        }
    };
    reached.simulated = true;
    let mut records = out.records;
    // Every column of the records in other units (legitimate: the estimates scale).
    if byte(1) & 0x40 != 0 {
        let s = SCALES[usize::from(byte(1) >> 2) % SCALES.len()];
        for c in records.iter_mut().flat_map(|r| r.columns.iter_mut()) {
            c.iter_mut().for_each(|x| *x *= s);
        }
    }
    // One control byte per column of every level, then raw values.
    let mut at = 12;
    let mut raw = bytes[at.min(bytes.len())..].chunks_exact(8).skip(64);
    for rec in &mut records {
        for col in &mut rec.columns {
            let c = byte(at);
            at += 1;
            match c >> 5 {
                0 => {
                    let v = col.first().copied().unwrap_or(0.0);
                    col.iter_mut().for_each(|x| *x = v);
                }
                1 => {
                    for x in col.iter_mut() {
                        if let Some(b) = raw.next() {
                            let v = f64::from_le_bytes(b.try_into().expect("invariant: 8 bytes"));
                            if v.is_finite() {
                                *x = v;
                            }
                        }
                    }
                }
                _ => {}
            }
            // A quarter of the columns scaled on their own.
            if c & 0x18 == 0x18 {
                let s = SCALES[usize::from(c) % SCALES.len()];
                col.iter_mut().for_each(|x| *x *= s);
            }
        }
    }
    let srcs: Vec<RecordSource> = match records
        .iter()
        .enumerate()
        .map(|(i, r)| RecordSource::new(r, ir, format!("level {}", i + 1)))
        .collect()
    {
        Ok(s) => s,
        Err(_) => return reached,
    };
    let refs: Vec<&dyn LevelSource> = srcs.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = IdentifyOptions {
        corners: Some(vec![20.0, 40.0]),
        ..Default::default()
    };
    let finite = |id: &crate::ident::Identification, what: &str| {
        for p in &id.params {
            assert!(
                p.value.is_finite() && p.stderr.is_finite(),
                "{what}: {} = {} ± {}",
                p.name,
                p.value,
                p.stderr
            );
        }
        for r in &id.residual {
            assert!(
                r.per_level.iter().all(|v| v.is_finite()),
                "{what}: residual {r:?}"
            );
        }
    };
    match identify(ir, &refs, &opts) {
        Ok(id) => {
            finite(&id, "pooled");
            reached.identified = true;
        }
        Err(e) => reached.ident_error = Some(e.to_string()),
    }
    if let Ok(ids) = identify_per_level(ir, &refs, &opts) {
        for id in &ids {
            finite(id, "per level");
        }
    }
    if refs.len() >= 2 {
        reached.detected = crate::detect::detect_from_data(
            ir,
            &refs,
            &opts,
            &crate::detect::DetectOptions::default(),
            &[],
        )
        .is_ok();
    }
    reached
}

/// How far one input of [`check_numerics`] got (for the smoke test's coverage check).
#[derive(Debug, Default)]
pub struct Reached {
    pub simulated: bool,
    pub sim_error: Option<String>,
    pub identified: bool,
    pub ident_error: Option<String>,
    pub detected: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identification_and_detection_survive_random_small_records() {
        // A deterministic miniature of `fuzz/fuzz_targets/numerics.rs`: random bytes through
        // `check_numerics` (random scales down to subnormal, constant and raw columns,
        // 1 to 3 levels), which panics on a non-finite estimate.
        use rand::{Rng, SeedableRng};
        let irs: Vec<ModelIr> = NUMERIC_MODELS
            .iter()
            .map(|m| dsl_parser::compile_str("fuzz.dyn", m).unwrap())
            .collect();
        let mut rng = rand::rngs::StdRng::seed_from_u64(29);
        let (mut identified, mut detected) = (0, 0);
        let mut errors = std::collections::BTreeMap::new();
        for _ in 0..120 {
            let len = rng.random_range(12..200);
            let b: Vec<u8> = (0..len).map(|_| rng.random()).collect();
            let r = check_numerics(&b, &irs);
            identified += usize::from(r.identified);
            detected += usize::from(r.detected);
            for e in r.sim_error.iter().chain(&r.ident_error) {
                let head: String = e.chars().take(60).collect();
                *errors.entry(head).or_insert(0) += 1;
            }
        }
        // The inputs must reach the solve and detection, not stop at the first check.
        assert!(
            identified >= 10 && detected >= 5,
            "{identified} identified, {detected} detected; errors: {errors:#?}"
        );
    }

    #[test]
    fn the_numerics_fuzzer_finds_no_non_finite_residual() {
        // Inputs the `numerics` fuzz target once failed on (regression cases).
        let irs: Vec<ModelIr> = NUMERIC_MODELS
            .iter()
            .map(|m| dsl_parser::compile_str("fuzz.dyn", m).unwrap())
            .collect();
        let cases: [&[u8]; 2] = [
            b"\x0b\x002222222222\x19'",
            // (base64 AQARAP///zIyXQY0Ihg=: a standard error of inf)
            b"\x01\x00\x11\x00\xff\xff\xff22]\x064\"\x18",
        ];
        for bytes in cases {
            let r = check_numerics(bytes, &irs);
            println!(
                "identified {}, error {:?}, detected {}",
                r.identified, r.ident_error, r.detected
            );
        }
    }
}
