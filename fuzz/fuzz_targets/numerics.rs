//! Identification and detection must survive any small record: random scales (tiny, huge,
//! subnormal), constant columns, raw values and few levels give estimates that are finite
//! or an error — never a panic, a hang (libFuzzer's `-timeout`) or a non-finite result
//! (`dynid_runtime::fuzz::check_numerics`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

fn irs() -> &'static [dsl_parser::ir::ModelIr] {
    static IRS: OnceLock<Vec<dsl_parser::ir::ModelIr>> = OnceLock::new();
    IRS.get_or_init(|| {
        dynid_runtime::fuzz::NUMERIC_MODELS
            .iter()
            .map(|m| dsl_parser::compile_str("fuzz.dyn", m).expect("the model compiles"))
            .collect()
    })
}

fuzz_target!(|data: &[u8]| {
    dynid_runtime::fuzz::check_numerics(data, irs());
});
