//! `dynid diagnose MODEL.dyn LEVEL.csv...`: where the model misses the data, which
//! unmodelled effect explains the gap, and how far it shrinks once that effect is added.

use super::common::{check_outputs, inputs, CsvArgs, SplitArgs, Staged};
use super::identify::{progress_bar, render_refined, RefineReport};
use dsl_parser::ir::ModelIr;
use dynid_runtime::data::{FileSource, RecordSource, Split};
use dynid_runtime::diagnose::{self, DiagnoseOptions, Diagnosis};
use dynid_runtime::record::Record;
use dynid_runtime::refine::{self, RefineOptions};
use indicatif::{ProgressBar, ProgressStyle};
use miette::IntoDiagnostic;
use std::path::{Path, PathBuf};

const LONG_HELP: &str = "\
Compares the simulation MODEL (nominal values) with measured levels and answers three
questions:
  where  - free-run gap per level and signal (the model driven by the measured input from
           the measured initial state): the headline compares spectrum and std of each
           response signal (statistical), the pathwise NRMSE is shown beside it;
           covariance-equation residual per body, parameters that drift with the level;
  which  - candidate unmodelled effects (cubic and quadratic stiffness, Coulomb friction,
           quadratic damping, backlash with a gap search, prestress) at every element and
           body-to-ground, each fitted on all levels but one and scored on the withheld one;
  how far - the gap of the nominal model, of the model re-identified on the other levels
           and of the corrected model (withheld levels): what re-tuning achieves, what
           the winner adds (and a second effect on top when it still pays), with the
           identified value and a confidence.

Example:
  dynid simulate models/two_mass_friction.dyn --out data/
  dynid diagnose models/two_mass_linear.dyn data/level_*.csv \\
      --report gap.html --write-model fixed.dyn --json gap.json

    Most likely missing effect: Coulomb friction sign(v) at (m1, m2) (element k2, d2)
      identified r_fix = 0.3 ± ... (...); withheld gap ... → ... (... smaller; pathwise ...)
    Re-identification alone: ... → ...; the effect: ... → ... (... of the re-identified gap removed)
    Overall (nominal → corrected): ... → ... (... of the gap removed); pathwise ... → ...

One record whose amplitude varies (a run-up, a sweep of drive levels) can stand for the
levels: give ONE file and it is cut into --segments N (default 3) contiguous segments by the
local RMS of the response (--split-by SIGNAL, default the first measured position), each
long enough for identification (80/ω₀ s, ω₀ the response's dominant frequency); every
segment is then withheld in turn like a level. The segment table (time span, samples, σ)
goes to stderr and into the JSON (`segments`):

  dynid diagnose models/sdof_linear.dyn run_up.csv --segments 3

A record of one repeated trajectory (planned moves) is cut at its cycles instead: the
period from the autocorrelation of the references, the response, then the inputs, the cuts
where the signal rests, --segments N pieces of whole cycles (default one per cycle); the
table says which signal repeats, its period and the cuts. --cut cycles|amplitude forces
either way.

With --refine the corrected model's values start an output-error refinement on all levels
(Levenberg-Marquardt on the free-run error, as `identify --refine`): both sets of values and
their free-run errors are printed side by side (in-sample: the levels the refinement fitted),
the JSON gets `refined`, and --write-model writes the refined values.

The corrected model (fixed.dyn) is ordinary .dyn text, compiled before it is written.
Outputs are written all or nothing. Metrics and thresholds: docs/diagnosis.md.";

/// Arguments of `dynid diagnose`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// The simulation model (.dyn, with nominal values).
    pub model: PathBuf,
    /// One CSV file per excitation level (at least 2), or ONE file whose amplitude varies,
    /// split into levels (see --segments).
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Write an HTML report (opens offline) to this file; it shows the frequency response
    /// per level (measured H1 with coherence, and the model with the parameters identified
    /// at each level).
    #[arg(long, value_name = "HTML")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub frf: super::frf::FrfArgs,
    /// Write the diagnosis as JSON to this file.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Write the corrected model (.dyn) to this file.
    #[arg(long = "write-model", value_name = "DYN")]
    pub write_model: Option<PathBuf>,
    #[command(flatten)]
    pub csv: CsvArgs,
    #[command(flatten)]
    pub split: SplitArgs,
    /// Refine the corrected model's values by output-error minimisation on all levels (see
    /// below); --write-model then writes the refined values.
    #[arg(long)]
    pub refine: bool,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Run even when the memory estimated before reading the data (the records, read whole
    /// for the free-run comparison, with the moments and least-squares problems) is above
    /// the safety limit (8 GB).
    #[arg(long)]
    pub allow_large: bool,
}

pub fn run(args: Args) -> miette::Result<()> {
    check_outputs(
        [
            (args.report.as_deref(), "the report"),
            (args.json.as_deref(), "the JSON output"),
            (args.write_model.as_deref(), "the corrected model"),
        ],
        inputs(&args.model, &args.data),
    )?;
    let ir = super::common::load_model(&args.model)?;
    if args.refine {
        super::identify::refuse_control_laws(&ir)?;
    }
    let csv = args.csv.options(&ir)?;
    let split = args.split.levels(&ir, &args.data, &csv, args.allow_large)?;
    if split.is_none() {
        super::duplicates::refuse_duplicate_levels(
            &args.data,
            "one record cannot be both fitted and withheld as another level",
        )?;
    }
    let mut records = Vec::new();
    let origins: Vec<String> = match &split {
        Some(s) => {
            // The model's measured columns of each segment, checked like a file's.
            for (r, o) in s.records.iter().zip(&s.origins) {
                let src = RecordSource::new(r, &ir, o.clone())?;
                records.push(Record {
                    t0: r.t0,
                    ..diagnose::read_record(&src, &ir)?
                });
            }
            s.origins.clone()
        }
        None => {
            let sources = args
                .data
                .iter()
                .map(|p| FileSource::open(p, &ir, &csv))
                .collect::<Result<Vec<_>, _>>()?;
            // The records are read whole (the free-run comparison), and the moments and
            // least-squares problems come on top: both estimated before any sample is read.
            let held: f64 = sources.iter().map(FileSource::whole_bytes).sum();
            let ident = dynid_runtime::IdentifyOptions {
                allow_large: args.allow_large,
                ..DiagnoseOptions::default().ident
            };
            dynid_runtime::ident::memory::check(&ir, sources.len(), &ident, held, "diagnosis")?;
            for src in &sources {
                records.push(diagnose::read_record(src, &ir)?);
            }
            args.data.iter().map(|p| p.display().to_string()).collect()
        }
    };
    let d = run_diagnosis(&ir, &records, &origins, args.quiet, args.allow_large)?;
    print!("{}", d.summary());
    println!(
        "(free runs: every level driven by its inputs from its {})",
        dynid_runtime::sim::FREE_RUN_START
    );
    let full = match &split {
        Some(s) => s.records.first().cloned(),
        None => None,
    };
    let hint = closed_loop_hint(&ir, &d, || match full {
        Some(r) => Ok(r),
        None => Ok(dynid_runtime::data::read_record_within(
            &args.data[0],
            &csv,
            args.allow_large,
        )?),
    })?;
    if let Some(h) = &hint {
        println!("\nNote: {h}");
    }
    let frfs = if args.report.is_some() || args.json.is_some() {
        super::frf::diagnosis_frfs(&ir, &records, &d, args.frf.frf_periods)?
    } else {
        Vec::new()
    };
    let refined = if args.refine {
        let r = refine_corrected(&d, &records, args.quiet)?;
        print!("{}", render_refined(&r.0));
        Some(r)
    } else {
        None
    };
    write_outputs_with(
        &d,
        args.report.as_deref(),
        args.json.as_deref(),
        args.write_model.as_deref(),
        Extras {
            segments: split.as_ref().map(|s| &s.split),
            refined: refined.as_ref().map(|r| &r.0),
            model_text: refined.as_ref().map(|r| r.1.as_str()),
            closed_loop_hint: hint.as_deref(),
            frf: Some(&frfs),
        },
    )
}

/// The closed-loop hint: a column of the first record (read by `record`, all columns)
/// that the model does not read and that a measured position follows, while the nominal
/// free run of that position drifts (mean NRMSE over the levels ≥
/// [`set_point::DRIFTS`]). The record is read only when a position drifts.
fn closed_loop_hint(
    ir: &ModelIr,
    d: &Diagnosis,
    record: impl FnOnce() -> miette::Result<Record>,
) -> miette::Result<Option<String>> {
    use dynid_runtime::set_point;
    let drift = |signal: &str| -> Option<f64> {
        let v: Vec<f64> = d
            .nominal
            .levels
            .iter()
            .filter_map(|l| l.signals.iter().find(|g| g.signal == signal))
            .map(|g| g.nrmse)
            .collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    let drifting = ir.signals.iter().any(|s| {
        s.measured
            && matches!(s.kind, dsl_parser::ir::SignalKind::Position(_))
            && drift(&s.name).is_some_and(|e| e >= set_point::DRIFTS)
    });
    if !drifting {
        return Ok(None);
    }
    let rec = record()?;
    Ok(set_point::set_points(ir, &rec).into_iter().find_map(|sp| {
        let e = drift(&sp.position)?;
        (e >= set_point::DRIFTS).then(|| sp.note(if e.is_finite() { e } else { 100.0 }))
    }))
}

/// The corrected model refined on every level ([`refine::refine_corrected`]) with the
/// iterations on a progress bar: the report and the model's text with the refined values.
fn refine_corrected(
    d: &Diagnosis,
    records: &[Record],
    quiet: bool,
) -> miette::Result<(RefineReport, String)> {
    let fixed = dsl_parser::compile_str(&d.model, &d.fixed_source)
        .map_err(|e| miette::miette!("the corrected model does not compile: {e}"))?;
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        progress_bar(RefineOptions::default().max_iter)
    };
    let r = refine::refine_corrected(&fixed, records, &|p| {
        bar.set_length(p.max_iter as u64);
        bar.set_position(p.iteration as u64);
        bar.set_message(format!("{:.3e}", p.cost));
    });
    bar.finish_and_clear();
    let (report, text) = r?;
    // Not applied: the model written keeps the corrected model's values (the note says why).
    Ok((report, text.unwrap_or_else(|| d.fixed_source.clone())))
}

/// Run the diagnosis with a progress bar on stderr.
pub fn run_diagnosis(
    ir: &ModelIr,
    records: &[Record],
    origins: &[String],
    quiet: bool,
    allow_large: bool,
) -> miette::Result<Diagnosis> {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(0);
        b.set_style(
            ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} candidates ({elapsed})")
                .expect("invariant: valid template")
                .progress_chars("=> "),
        );
        b.set_prefix("searching unmodelled effects");
        b
    };
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let mut opts = DiagnoseOptions::default();
    opts.ident.allow_large = allow_large;
    let d = diagnose::diagnose(ir, records, origins, &opts, &progress);
    bar.finish_and_clear();
    Ok(d?)
}

/// Render everything first, then write all or nothing: an error never leaves a partial set
/// of files.
pub fn write_outputs(
    d: &Diagnosis,
    report: Option<&Path>,
    json: Option<&Path>,
    model: Option<&Path>,
) -> miette::Result<()> {
    write_outputs_with(d, report, json, model, Extras::default())
}

/// What a diagnosis' outputs may carry besides the diagnosis.
#[derive(Default)]
pub struct Extras<'a> {
    /// The segments of a split record (JSON `segments`).
    pub segments: Option<&'a Split>,
    /// The refinement of the corrected model (JSON `refined`).
    pub refined: Option<&'a RefineReport>,
    /// The model to write instead of the corrected one (the refined values).
    pub model_text: Option<&'a str>,
    /// The note that the record looks closed loop (JSON `closed_loop_hint`).
    pub closed_loop_hint: Option<&'a str>,
    /// The frequency response per level (report figure, JSON `frf`).
    pub frf: Option<&'a [dynid_runtime::frf::LevelFrf]>,
}

/// [`write_outputs`], with the extras.
pub fn write_outputs_with(
    d: &Diagnosis,
    report: Option<&Path>,
    json: Option<&Path>,
    model: Option<&Path>,
    extras: Extras,
) -> miette::Result<()> {
    let html = report.map(|_| {
        let h = dynid::plot::render_html(d);
        match extras.frf.filter(|f| !f.is_empty()) {
            Some(f) => h.replacen(
                "</body>",
                &format!("{}</body>", dynid::plot::report::frf_section(f)),
                1,
            ),
            None => h,
        }
    });
    let js = match json {
        Some(_) => Some(
            serde_json::to_string_pretty(&dynid::schema::DiagnosisJson {
                schema_version: dynid::schema::SCHEMA_VERSION,
                diagnosis: d,
                segments: extras.segments,
                refined: extras.refined,
                free_run_start: dynid_runtime::sim::FREE_RUN_START,
                closed_loop_hint: extras.closed_loop_hint,
                frf: extras.frf.filter(|f| !f.is_empty()),
            })
            .into_diagnostic()?,
        ),
        None => None,
    };
    let mut staged = Staged::new();
    if let (Some(p), Some(h)) = (report, &html) {
        staged.write(p, h.as_bytes())?;
    }
    if let (Some(p), Some(j)) = (json, &js) {
        staged.write(p, j.as_bytes())?;
    }
    if let Some(p) = model {
        let text = extras.model_text.unwrap_or(&d.fixed_source);
        staged.write(p, text.as_bytes())?;
    }
    staged.commit()?;
    if let Some(p) = report {
        eprintln!("report written to {}", p.display());
    }
    if let Some(p) = model {
        eprintln!("corrected model written to {}", p.display());
    }
    Ok(())
}
