//! The front end must return a model or diagnostics for any text, never panic; a model it
//! accepts must print back to source that compiles to the same equations.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match dsl_parser::compile_str("fuzz.dyn", text) {
        Ok(ir) => {
            let printed = dsl_parser::print::to_source(&ir);
            let again = dsl_parser::compile_str("printed.dyn", &printed)
                .expect("printed model compiles");
            assert_eq!(again.equations, ir.equations);
        }
        Err(errs) => {
            let _ = errs.render_plain(100);
        }
    }
});
