//! The data-file readers — MAT v5/v7, MAT v7.3, HDF5, Parquet, told apart by content, and
//! delimited text for anything else — must return data or an error for any bytes, never
//! panic or allocate without bound; data they return must be complete and finite
//! (`dynid_runtime::data::fuzz::check_data_file`). The binary readers read files, so every
//! input is written to one file in a directory of this process first.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn ir() -> &'static dsl_parser::ir::ModelIr {
    static IR: OnceLock<dsl_parser::ir::ModelIr> = OnceLock::new();
    IR.get_or_init(|| dsl_parser::compile_str("fuzz.dyn", dynid_runtime::data::fuzz::FUZZ_MODEL).expect("the model compiles"))
}

fn file() -> &'static PathBuf {
    static FILE: OnceLock<PathBuf> = OnceLock::new();
    FILE.get_or_init(|| {
        let base = if std::path::Path::new("/dev/shm").is_dir() {
            PathBuf::from("/dev/shm")
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("dynid-fuzz-binary-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a scratch directory");
        dir.join("level")
    })
}

fuzz_target!(|data: &[u8]| {
    let path = file();
    std::fs::write(path, data).expect("the scratch file is writable");
    dynid_runtime::data::fuzz::check_data_file(path, ir());
});
