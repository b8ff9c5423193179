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

/// Arguments of `dynid compile`.
#[derive(clap::Args, Debug)]
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
            let source = std::fs::read_to_string(&args.model)
                .map_err(|e| miette::miette!("cannot read {}: {e}", args.model.display()))?;
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
