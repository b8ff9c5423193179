//! `dynid simulate --input`: the model driven by measured inputs, from the measured state,
//! its response written as `driven.csv` beside a `truth.json`.

use super::{level_summary, print_summary, Args, Format};
use crate::cli::common::{check_run_dir, Staged};
use dsl_parser::ir::ModelIr;
use dynid_runtime::data;
use dynid_runtime::record::Record;
use dynid_runtime::sim;
use miette::{Context, IntoDiagnostic};
use std::path::Path;

/// Drive the model with the inputs of `input` and write its response (see the module
/// documentation).
pub(super) fn run_driven(ir: &ModelIr, args: &Args, input: &Path) -> miette::Result<()> {
    check_run_dir(
        &args.out,
        "--out",
        &["driven.csv".into(), "truth.json".into()],
        [
            (args.model.as_path(), "the model"),
            (input, "the input file"),
        ],
        [],
    )?;
    let record = read_input_csv(input, args.allow_large)?;
    check_response_memory(ir, &record, input, args.allow_large)?;
    sim::check_steps(
        record.len() as f64 * args.substeps as f64,
        &format!(
            "driving `{}` with {} samples × {} RK4 sub-steps",
            ir.name,
            record.len(),
            args.substeps
        ),
        "--allow-long",
        args.allow_long,
    )?;
    // The free-run convention of every comparison with data: from the measured state when
    // the file holds positions, else from rest.
    let measured = ir.bodies.iter().enumerate().any(|(b, _)| {
        record.column(&ir.signals[2 * b].name).is_some()
            || record.column(&ir.signals[2 * b + 1].name).is_some()
    });
    let response = sim::simulate_driven_from(ir, &record, args.substeps, sim::Start::Measured)
        .map_err(miette::Report::new)
        .wrap_err_with(|| format!("driving `{}` with `{}`", ir.name, input.display()))?;
    let params = sim::parameter_values(ir).map_err(miette::Report::new)?;
    dynid::output::create_dir(&args.out)?;
    let csv = args.out.join("driven.csv");
    let truth = serde_json::json!({
        "model": ir.name,
        "mode": "driven",
        "input": input.display().to_string(),
        "parameters": ir.params.iter().zip(&params)
            .map(|(p, v)| (p.name.clone(), *v))
            .collect::<std::collections::BTreeMap<_, _>>(),
        "substeps": args.substeps,
        "initial_state": if measured { sim::FREE_RUN_START } else { "rest (no position or velocity column)" },
        "files": ["driven.csv"],
    });
    let json_path = args.out.join("truth.json");
    let mut staged = Staged::new();
    dynid::output::stage_driven(
        &mut staged,
        &args.out,
        &response,
        &(serde_json::to_string_pretty(&truth).into_diagnostic()? + "\n"),
    )?;
    staged.commit()?;
    print_driven(
        ir,
        args.format,
        input,
        &response,
        &csv,
        &json_path,
        measured,
        &truth,
    )
}

/// What `simulate --input` prints: the truth and the response file's summary, as JSON or
/// as text.
#[allow(clippy::too_many_arguments)] // the pieces of one report, named where they are made
fn print_driven(
    ir: &ModelIr,
    format: Format,
    input: &Path,
    response: &Record,
    csv: &Path,
    json_path: &Path,
    measured: bool,
    truth: &serde_json::Value,
) -> miette::Result<()> {
    let summary = level_summary(response, csv, None);
    match format {
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(
                &serde_json::json!({ "truth": truth, "levels": [summary] })
            )
            .into_diagnostic()?
        ),
        Format::Text => {
            println!(
                "simulated `{}` driven by `{}` ({} samples, Ts = {} s, from {})",
                ir.name,
                input.display(),
                response.len(),
                response.ts,
                if measured {
                    sim::FREE_RUN_START
                } else {
                    "rest: the file has no position or velocity column"
                }
            );
            print_summary(&summary);
            println!("  {}", json_path.display());
        }
    }
    Ok(())
}

/// The driving inputs: the shared CSV reader, whose errors name the file and line; a
/// record whose memory (estimated from the file's size) is above the limit is refused
/// before it is read, unless `allow_large`.
pub(super) fn read_input_csv(path: &Path, allow_large: bool) -> miette::Result<Record> {
    Ok(data::read_record_within(
        path,
        &data::CsvOptions::default(),
        allow_large,
    )?)
}

/// Refuse a driven simulation whose response (every signal of the model at every sample
/// of `record`, held whole) would take more than the memory limit, unless `allow_large`.
fn check_response_memory(
    ir: &ModelIr,
    record: &Record,
    input: &Path,
    allow_large: bool,
) -> miette::Result<()> {
    use dynid_runtime::limits::{bytes_in_words, MAX_BYTES};
    let bytes = record.len() as f64 * (ir.signals.len() as f64 + 1.0) * 8.0;
    if allow_large || bytes <= MAX_BYTES {
        return Ok(());
    }
    Err(miette::miette!(
        code = "dynid::sim::too_large",
        help = "drive the model with a shorter record, or give `--allow-large` to run it anyway",
        "driving `{}` with the {} samples of `{}` would hold a response of {} in memory \
         ({} signals), above the limit of {}",
        ir.name,
        record.len(),
        input.display(),
        bytes_in_words(bytes),
        ir.signals.len() + 1,
        bytes_in_words(MAX_BYTES)
    ))
}
