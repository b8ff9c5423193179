//! The macro path's diagnostics, one bad model per error kind (`tests/ui/*.rs`, expected
//! compiler output in the `.stderr` files beside them), and models that must compile and
//! run (`tests/ui/pass/`).
//!
//! After a deliberate change of a message: `TRYBUILD=overwrite cargo test --test macro_ui`,
//! then review the `.stderr` diff.

use std::path::{Path, PathBuf};

/// trybuild compiles the cases as bins of a crate it generates in
/// `<target dir>/tests/trybuild/<package>`; that is the calling crate's
/// `CARGO_MANIFEST_DIR`, which `include_model!` resolves model paths against.
fn trybuild_crate_dir() -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let target = tmp
        .parent()
        .expect("CARGO_TARGET_TMPDIR is <target dir>/tmp");
    target
        .join("tests")
        .join("trybuild")
        .join(env!("CARGO_PKG_NAME"))
}

#[test]
fn macro_diagnostics() {
    // Put the cases' model files where a crate keeps them: `models/` beside its Cargo.toml.
    let models = trybuild_crate_dir().join("models");
    std::fs::create_dir_all(&models).unwrap();
    let ours = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ui/models");
    for entry in std::fs::read_dir(&ours).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, models.join(path.file_name().unwrap())).unwrap();
    }

    build_dependencies_once();
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/*.rs");
    t.pass("tests/ui/pass/*.rs");
}

/// trybuild builds the dependencies (all of dynid's, the numerics included) with one set of
/// rustflags and then the cases with `--diagnostic-width=140` added, and cargo builds every
/// dependency again for the changed flags. Giving all its cargo calls the same flags (the
/// environment overrides the `--config` flags trybuild passes) and no debug info cuts the
/// cold build to about a third. The flags are left alone when RUSTFLAGS asks for something
/// (trybuild passes coverage instrumentation on).
fn build_dependencies_once() {
    std::env::set_var("CARGO_PROFILE_DEV_DEBUG", "0");
    if std::env::var_os("RUSTFLAGS").is_some()
        || std::env::var_os("CARGO_ENCODED_RUSTFLAGS").is_some()
    {
        return;
    }
    // trybuild's own flags (`--cfg trybuild --verbose -A dead_code`) and its diagnostic width.
    let flags = [
        "--cfg",
        "trybuild",
        "--verbose",
        "-A",
        "dead_code",
        "--diagnostic-width=140",
    ];
    std::env::set_var("CARGO_ENCODED_RUSTFLAGS", flags.join("\x1f"));
}
