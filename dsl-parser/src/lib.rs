//! The `.dyn` modelling language front end.
//!
//! Architecture invariant: stages only call forward, `parse → lower → validate → emit`;
//! the only thing that leaves this crate for the back ends is [`ir::ModelIr`], which is
//! plain data (no pest or syn types, no I/O).
//!
//! API boundary: [`compile_str`] and [`compile_file`] (source → IR or all diagnostics of
//! the file), [`error`] (the diagnostics), [`codegen`] (the Rust code generator of the
//! macros), and, re-exported from the IR crate `dynid-ir`, [`ir`] (the IR), [`print`]
//! (readable views of an IR and the inverse of compilation, [`print::to_source`]),
//! [`edit`] (model edits on the IR) and [`num`] (number formats).
//!
//! ```
//! let ir = dsl_parser::compile_str("sdof.dyn", "
//!     model sdof {
//!         body m = 1.0
//!         input u on m
//!         spring k (ground, m) ~ 4.0
//!         damper d (ground, m) ~ 0.4
//!     }").unwrap();
//! assert_eq!(ir.unknowns().len(), 2);
//! assert_eq!(
//!     dsl_parser::print::render_equations(&ir),
//!     "m: 1 m.x'' + k m.x + d m.x' = u\n"
//! );
//! ```

mod ast;
pub mod codegen;
pub mod error;
mod grammar;
mod lower;
mod syntax_error;

pub use dynid_ir::{edit, ir, num, print, text};

pub use error::{CompileError, CompileErrors, ErrorKind};

use std::path::Path;

/// Compile `.dyn` source text. `name` is the file name shown in diagnostics.
///
/// Returns every error of the file, not only the first (a syntax error stops the parse, so
/// it is reported alone). A byte-order mark at the start (as some editors write) is skipped;
/// anywhere else it is an error that names it.
pub fn compile_str(name: &str, source: &str) -> Result<ir::ModelIr, CompileErrors> {
    let source = source.strip_prefix('\u{feff}').unwrap_or(source);
    let mut sink = error::ErrorSink::new(name, source);
    let ir = ast::parse(source, &mut sink).map(|ast| lower::lower(&ast, &mut sink));
    match ir {
        Some(ir) if sink.errors.is_empty() => {
            debug_assert_eq!(ir.check_invariants(), Ok(()));
            Ok(ir)
        }
        _ => {
            // Report in source order, however the passes found them.
            let mut errors = sink.errors;
            errors.sort_by_key(|e| e.span().map_or(usize::MAX, |s| s.start));
            Err(CompileErrors {
                name: name.to_string(),
                src: sink.src,
                errors,
            })
        }
    }
}

/// Largest model source read: 8 MiB. The largest example model is a few kilobytes; a
/// bigger file is not a model (`/dev/zero`, a data file given by mistake), and reading it
/// whole would take the memory it holds.
pub const MAX_SOURCE: u64 = 8 << 20;

/// The bytes of the file at `path`, read once (a pipe or device cannot be read twice), at
/// most [`MAX_SOURCE`] of them: `Ok(None)` when the file holds more.
pub fn read_source(path: &Path) -> std::io::Result<Option<Vec<u8>>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(MAX_SOURCE + 1)
        .read_to_end(&mut bytes)?;
    Ok((bytes.len() as u64 <= MAX_SOURCE).then_some(bytes))
}

/// Read and compile a `.dyn` file. A read failure is reported as a `dyn::io` diagnostic.
pub fn compile_file(path: &Path) -> Result<ir::ModelIr, CompileErrors> {
    let name = path.display().to_string();
    let io_error = |d: error::Draft| {
        let sink = error::ErrorSink::new(&name, "");
        let err = CompileError::build(ErrorKind::Io, d, sink.src.clone());
        Err(CompileErrors {
            name: name.clone(),
            src: sink.src,
            errors: vec![err],
        })
    };
    let bytes = match read_source(path) {
        Ok(Some(b)) => b,
        Ok(None) => {
            return io_error(error::Draft {
                message: format!(
                    "`{name}` holds more than {} MiB: it is not a model source",
                    MAX_SOURCE >> 20
                ),
                help: "a model is a `.dyn` text file of a few kilobytes; check the path".into(),
                ..Default::default()
            })
        }
        Err(e) => {
            return io_error(error::Draft {
                message: format!("cannot read `{name}`: {e}"),
                help: "check the path and the file permissions".into(),
                ..Default::default()
            })
        }
    };
    compile_bytes(&name, &bytes)
}

/// Compile the bytes of a `.dyn` file (`name` is shown in diagnostics): UTF-8 text, else a
/// `dyn::io` diagnostic pointing at the first byte that is not.
pub fn compile_bytes(name: &str, bytes: &[u8]) -> Result<ir::ModelIr, CompileErrors> {
    let name = name.to_string();
    let io_error = |source: &str, d: error::Draft| {
        let sink = error::ErrorSink::new(&name, source);
        let err = CompileError::build(ErrorKind::Io, d, sink.src.clone());
        Err(CompileErrors {
            name: name.clone(),
            src: sink.src,
            errors: vec![err],
        })
    };
    if let Some(kind) = text::utf16_kind(bytes) {
        return io_error(
            "",
            error::Draft {
                message: format!("`{name}` is {kind} text, not UTF-8"),
                help: "save the model as UTF-8 (most editors: \"Save with encoding\"; or \
                       `iconv -f UTF-16 -t UTF-8 FILE > NEW.dyn`)"
                    .into(),
                ..Default::default()
            },
        );
    }
    match std::str::from_utf8(bytes) {
        Ok(src) => compile_str(&name, src),
        Err(e) => {
            // Point at the first byte that is not UTF-8, in a lossy copy of the text.
            let good = e.valid_up_to();
            let prefix = std::str::from_utf8(&bytes[..good]).unwrap_or_default();
            let line = prefix.matches('\n').count() + 1;
            let column = prefix[prefix.rfind('\n').map_or(0, |i| i + 1)..]
                .chars()
                .count()
                + 1;
            let lossy = String::from_utf8_lossy(bytes);
            io_error(
                &lossy,
                error::Draft {
                    message: format!(
                        "`{name}` is not UTF-8 text: line {line}, column {column} holds the byte \
                         0x{:02x}",
                        bytes[good]
                    ),
                    // The lossy copy holds U+FFFD (3 bytes) in place of the bad byte.
                    span: Some(ir::Span::new(good, good + '\u{fffd}'.len_utf8())),
                    label: "not UTF-8".into(),
                    help: "save the model as UTF-8 (most editors: \"Save with encoding\")".into(),
                    ..Default::default()
                },
            )
        }
    }
}
