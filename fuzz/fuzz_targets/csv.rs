//! The CSV level reader must return data or an error for any bytes, never panic; data it
//! returns must be complete and finite (`dynid_runtime::data::fuzz::check_csv_bytes`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

fn ir() -> &'static dsl_parser::ir::ModelIr {
    static IR: OnceLock<dsl_parser::ir::ModelIr> = OnceLock::new();
    IR.get_or_init(|| dsl_parser::compile_str("fuzz.dyn", dynid_runtime::data::fuzz::FUZZ_MODEL).expect("the model compiles"))
}

fuzz_target!(|data: &[u8]| {
    // From memory, through the same parser as a file (no file written per input).
    dynid_runtime::data::fuzz::check_csv_bytes(std::path::Path::new("fuzz.csv"), data, ir());
});
