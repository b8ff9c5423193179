//! `dynid compile`: check a model and show what identification will solve.

use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// Equations, parameter table and least-squares columns, for people.
    #[default]
    Text,
    /// The same report as JSON (params, columns, equations).
    Json,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Emit {
    /// Rust code for the model's evaluator.
    Rust,
    /// The compiled IR as JSON.
    Json,
}

const LONG_HELP: &str = "\
Checks a model and shows what identification will solve for: the equations of motion, the
parameters (known, unknown with a nominal value) and the least-squares columns. All errors
of a file are reported at once with line:column and a hint; the exit code is non-zero.

Examples:
  dynid compile models/sdof_duffing.dyn
    model sdof_duffing: 1 body, 1 input, 3 parameters (3 unknown)
    equations of motion:
      m: 1 m.x'' + k m.x + d m.x' + k3 m.x^3 = u
  dynid compile models/two_mass.dyn --format json     # the same report for scripts
  dynid compile models/two_mass.dyn --emit rust       # the code include_model! generates
  dynid compile models/two_mass.dyn --emit json > two_mass.json   # compiled IR; other
                                                      # commands accept it as MODEL

The language is described in docs/language.md.";

/// Arguments of `dynid compile`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// The model file.
    pub model: PathBuf,
    /// Output format of the report.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    pub format: Format,
    /// Print a compiled artefact instead of the report.
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
}

pub fn run(args: Args) -> miette::Result<()> {
    // All diagnostics of the file are rendered by the caller through miette.
    let ir = dsl_parser::compile_file(&args.model)?;
    match (args.emit, args.format) {
        (Some(Emit::Rust), _) => {
            // Compiled above, so UTF-8 and within the size limit (unless replaced since).
            let source = dsl_parser::read_source(&args.model)
                .ok()
                .flatten()
                .and_then(|b| String::from_utf8(b).ok())
                .ok_or_else(|| {
                    miette::miette!(
                        code = "dynid::model::io",
                        "cannot read {} again for the generated code",
                        args.model.display()
                    )
                })?;
            let opts = dsl_parser::codegen::CodegenOptions {
                source_name: args
                    .model
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned()),
                ..Default::default()
            };
            print!(
                "{}",
                dsl_parser::codegen::generate_pretty(&ir, &source, &opts)
            );
            Ok(())
        }
        (Some(Emit::Json), _) => {
            let text = serde_json::to_string_pretty(&ir)
                .map_err(|e| miette::miette!("cannot serialise the IR: {e}"))?;
            println!("{text}");
            Ok(())
        }
        (None, Format::Json) => {
            let text = serde_json::to_string_pretty(&dsl_parser::print::report_json(&ir))
                .map_err(|e| miette::miette!("cannot serialise the report: {e}"))?;
            println!("{text}");
            Ok(())
        }
        (None, Format::Text) => {
            print!("{}", dsl_parser::print::render_report(&ir));
            Ok(())
        }
    }
}
