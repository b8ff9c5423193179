//! `dynid identify MODEL.dyn DATA.csv...`: identify the unknown parameters from one CSV file
//! per excitation level, print the identified equations and optionally write JSON.
//!
//! This file holds the command's arguments and the order of its steps (identification,
//! corner check, closed-loop hint, refinement); [`text`] writes the report on the terminal,
//! [`json`] the document of `--json` (the runtime's schema).

use super::common::{check_outputs, inputs, write_atomically, CsvArgs, EstimatorArgs};
use dsl_parser::ir::ModelIr;
use dynid_runtime::data::read_record_within;
use dynid_runtime::data::{FileSource, LevelSource};
use dynid_runtime::ident::{check_corners, Identification};
use dynid_runtime::identify;
use dynid_runtime::record::Record;
use dynid_runtime::refine::{self, RefineOptions};
use dynid_runtime::sim::DEFAULT_SUBSTEPS;
use miette::miette;
use std::path::PathBuf;

const LONG_HELP: &str = "\
Identifies every unknown parameter of MODEL by the covariance method: the data of all
levels are filtered (no numerical differentiation), their filter covariances pooled into
one least-squares problem and solved by SVD. Each CSV file is one excitation level with a
header naming the model's measured signals (`m1.x`, `m1.v`, `u`; extra columns are
ignored) and a uniform time column `t` (or give `--sample`). Velocities may be left
unmeasured (declare them so in the model): terms linear in them move onto the filters, and
nonlinear ones (`sign(v)`, `v*abs(v)`) use a zero-phase estimate from the position, named
in the output. Accelerations never need to be measured. The default filter corners fit the
band of the data and the record length; a record too short for given corners is refused
with corners that fit it.

On a servo axis's kind of record — Coulomb friction (`sign(v)`), a measured force,
velocities estimated from an encoder's quiet positions, a model that holds — identify
chooses the rows of the filtered equation with an unknown delay of the force (`u.delay`,
seconds) and says so (`rows: …`): on the simulated servo axis far more precise than the
default instrument rows (docs/method.md §2). --instrument-rows keeps those.

Example:
  dynid simulate models/two_mass.dyn --out data/
  dynid identify models/two_mass.dyn data/level_1.csv data/level_2.csv data/level_3.csv \\
      --json result.json

    parameter             value   std. error      rel.
    m2                    1.999     6.105e-5     0.00%
    k3                    1.499     7.983e-5     0.01%
    ...
    condition 8.917e0, 108 rows, filter corners 0.5000, ... 16.00 rad/s

Data too large for one machine: `dynid moments MODEL DATA... --out PART.dynm` on each piece,
then `dynid identify MODEL --from PART.dynm...` (see `dynid moments --help`).

Standard errors come from a batch-means sandwich over time blocks. A value within two
standard errors of zero is kept in the fit and marked `(n.s.)`: the data do not show
that term. A parameter the data cannot resolve (never excited, or collinear with partners)
is named and given no number. A negative mass, damping, friction coefficient or spring
stiffness is reported on stderr. Columns with other names: `--map disp=m1.x`.

With --refine the covariance estimate starts an output-error refinement: Levenberg-Marquardt
on the free-run (simulation) error of all levels, with the Jacobian from forward
sensitivities of the simulation. Both estimates are printed side by side with their
free-run RMS errors on the estimation files and on the --test files:
  dynid identify models/sdof_duffing.dyn data/level_*.csv --refine --test test/level_1.csv
Every record is simulated from its measured initial state (velocities not measured: from
the first three positions), in the fit as in the scores. Long records: --shooting SECONDS
cuts them into sub-records, the later ones started from fitted initial states (multiple
shooting); a fit whose whole-record free run ends worse than its start is not applied and
says why. --weight m1.x=2 weighs a compared signal. Models with control laws are refused
before any work (refine the plant, driven by the recorded controller output).";

/// Arguments of `dynid identify`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// The model file.
    pub model: PathBuf,
    /// One data file per excitation level: CSV (header with `t` and the measured signals),
    /// MATLAB .mat, HDF5 or Parquet (variables or columns named by the signals).
    #[arg(required_unless_present = "from")]
    pub data: Vec<PathBuf>,
    /// Solve merged moment statistics (`dynid moments MODEL DATA... --out PART.dynm`)
    /// instead of reading data: the same result as identifying their records together
    /// (without the corner check and the closed-loop hint, which read the data).
    #[arg(
        long = "from",
        value_name = "PART.dynm",
        num_args = 1..,
        conflicts_with_all = ["data", "refine", "filter_corners", "balance", "no_balance", "no_noise_correction", "column_chains", "keep_rests", "filtered_equation", "weighted_rows", "input_delay"]
    )]
    pub from: Vec<PathBuf>,
    /// Write the result as JSON to this file.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    #[command(flatten)]
    pub csv: CsvArgs,
    #[command(flatten)]
    pub estimator: EstimatorArgs,
    /// Leave out the virial / power-balance rows. They are left out unless `--balance` is
    /// given; this flag only makes that explicit in a script.
    #[arg(long = "no-balance", conflicts_with = "balance")]
    pub no_balance: bool,
    /// Skip the corner check: by default the fit is repeated with the highest filter corner
    /// a factor 4 lower and higher (two more passes over the data), and an estimate that
    /// moves by more than its standard error gets a warning naming the range
    #[arg(long = "no-corner-check")]
    pub no_corner_check: bool,
    /// Refine the covariance estimate by minimising the free-run simulation error.
    #[arg(long)]
    pub refine: bool,
    /// Records (CSV, one per level) on which to report the free-run errors of both
    /// estimates; not used for fitting.
    #[arg(long = "test", value_name = "CSV", num_args = 1.., requires = "refine")]
    pub test: Vec<PathBuf>,
    /// Weight of a compared signal in the refinement (repeatable), e.g. `--weight m1.x=2`.
    #[arg(long = "weight", value_name = "SIGNAL=W", requires = "refine")]
    pub weight: Vec<String>,
    /// Longest sub-record of the refinement in seconds (multiple shooting); default: whole
    /// records. (`--segment` is an old name of this flag.)
    #[arg(
        long = "shooting",
        alias = "segment",
        value_name = "SECONDS",
        requires = "refine"
    )]
    pub segment: Option<f64>,
    /// Not an option of identify: `detect` and `diagnose` cut one record into levels with
    /// `--segments N`; identify fits every file whole (refused with that explanation).
    #[arg(long, hide = true, value_name = "N", num_args = 0..=1)]
    pub segments: Option<Option<String>>,
    /// RK4 sub-steps per sample interval of the refinement's simulations.
    #[arg(long, default_value_t = DEFAULT_SUBSTEPS, value_parser = super::common::at_least_one, requires = "refine")]
    pub substeps: usize,
    /// With --refine: run even when the refinement's simulations (every record's samples
    /// × the sub-steps, per iteration) are above the safety limit (1e10 RK4 steps).
    #[arg(long, requires = "refine")]
    pub allow_long: bool,
    /// Run even when the memory estimated before reading the data (of the moments and the
    /// least-squares problem, or of the records read whole for --refine) is above the
    /// safety limit (8 GB).
    #[arg(long)]
    pub allow_large: bool,
}

mod json;
mod text;

pub use dynid::schema::RefineReport;
pub use text::{render, render_refined};

pub fn run(args: Args) -> miette::Result<()> {
    if args.segments.is_some() {
        return Err(miette!(
            code = "dynid::identify::segments",
            help = "give the record whole to identify; `dynid diagnose MODEL.dyn ONE.csv \
                    --segments N` cuts it into levels (at the cycles of a repeated trajectory, \
                    or by amplitude) and withholds each in turn; the refinement's sub-records \
                    are `--refine --shooting SECONDS`",
            "identify does not cut records into segments: it fits all samples of every file \
             together, and a cut would only add filter start-up transients at every seam"
        ));
    }
    if !args.from.is_empty() {
        return identify_from(&args);
    }
    check_outputs(
        [(args.json.as_deref(), "the JSON output")],
        inputs(&args.model, &args.data).chain(args.test.iter().map(PathBuf::as_path)),
    )?;
    let ir = super::common::load_model(&args.model)?;
    let opts = refine_options(&args)?;
    if opts.is_some() {
        refuse_control_laws(&ir)?;
        check_whole_records(&ir, &args)?;
    }
    let id = identify_files(&ir, &args)?;
    print!("{}", render(&ir, &id));
    for w in &id.warnings {
        eprintln!("warning: {w}");
    }
    for w in &id.fit_warnings {
        eprintln!("warning: {w}");
    }
    for m in &id.filter.corner_moves {
        eprintln!("warning: {}", m.describe());
    }
    let hint = closed_loop_hint(&ir, &args, &id);
    if let Some(h) = &hint {
        println!("\nNote: {h}");
    }
    if let Some(h) = rows_hint(&ir, &id) {
        println!("\nNote: {h}");
    }
    let refined = match &opts {
        Some(o) => {
            let r = refine_files(&ir, &args, &id, o)?;
            print!("{}", render_refined(&r));
            Some(r)
        }
        None => None,
    };
    if let Some(out) = &args.json {
        // The hint only where there is one: otherwise the document is that of the Python
        // package's `to_dict()`.
        let text = json::document(&id, refined.as_ref(), hint.as_deref())?;
        write_atomically(out, text.as_bytes())?;
    }
    Ok(())
}

/// `identify MODEL --from PART.dynm...`: merge the statistics, solve, and report as for the
/// records they were made from.
fn identify_from(args: &Args) -> miette::Result<()> {
    check_outputs(
        [(args.json.as_deref(), "the JSON output")],
        inputs(&args.model, &args.from),
    )?;
    let ir = super::common::load_model(&args.model)?;
    let merged = super::moments::read_merged(&args.from)?;
    let id = merged.identify(&ir)?;
    print!("{}", render(&ir, &id));
    for w in &id.warnings {
        eprintln!("warning: {w}");
    }
    for w in &id.fit_warnings {
        eprintln!("warning: {w}");
    }
    if let Some(h) = rows_hint(&ir, &id) {
        println!("\nNote: {h}");
    }
    if let Some(out) = &args.json {
        let text = json::document(&id, None, None)?;
        write_atomically(out, text.as_bytes())?;
    }
    Ok(())
}

/// The note pointing at the rows `identify` chooses where it did not choose them: asked for
/// other rows (`--instrument-rows`, or another row flag), or identified from moments
/// (`--from`). The rows of the filtered equation with the input's delay where the record
/// is of a servo axis's kind ([`dynid_runtime::ident::servo_rows`]) and the model can form
/// them; the rows each weighted by its own estimated error where the record measures
/// accelerations ([`dynid_runtime::ident::accel_rows`]).
fn rows_hint(ir: &ModelIr, id: &Identification) -> Option<String> {
    if id.filter.corners_from.filtered || id.filter.auto_rows {
        return None;
    }
    let defaults = dynid_runtime::IdentifyOptions::default();
    if !id.filter.weighted_rows && dynid_runtime::ident::accel_rows(ir, &defaults).is_some() {
        return Some(
            "the record measures accelerations: there the rows each weighted by its own \
             estimated error, which `identify` chooses for such records from their files \
             unless another row flag or --instrument-rows is given, keep a many-body \
             structure's masses and stiffnesses from shrinking with the noise and with the \
             error of a nonlinear element's motion integrated from accelerations \
             (docs/method.md §2, \"Rows for accelerations\")"
                .into(),
        );
    }
    let opts = dynid_runtime::ident::servo_rows(ir, id, &defaults)?;
    dynid_runtime::ident::memory::estimate(ir, id.levels.len(), &opts).ok()?;
    Some(
        "Coulomb friction, a measured force and positions without noise worth a correction \
         (velocities estimated from them), as on a servo axis: there the rows of the filtered \
         equation with the input's delay, which `identify` chooses for such records from \
         their files unless another row flag or --instrument-rows is given, may be far more \
         precise (on the simulated servo axis, bench `servo_precision`: RMS errors 50–500 \
         times smaller on random set points, about 3 times on planned moves, the offset \
         level; docs/method.md §2, \"The input between samples\")"
            .into(),
    )
}

/// The closed-loop hint of `identify`: a column of the first file that the open-loop model
/// does not read and that a measured position follows ([`set_point::set_points`]), while
/// the free run of that position, driven by the recorded inputs with the identified values
/// from the measured initial state, drifts (relative RMS error ≥ [`set_point::DRIFTS`] %).
/// A hint only: a first file too large to read whole, or a free run longer than the step
/// limit, gets none; a free run that diverges drifts.
fn closed_loop_hint(ir: &ModelIr, args: &Args, id: &Identification) -> Option<String> {
    use dynid_runtime::set_point;
    let positions = ir
        .signals
        .iter()
        .any(|s| s.measured && matches!(s.kind, dsl_parser::ir::SignalKind::Position(_)));
    if !ir.controls.is_empty() || !positions {
        return None;
    }
    let csv = args.csv.options(ir).ok()?;
    // The file is read a second time: not a pipe or other stream, which gave its data once.
    let first = args.data.first()?;
    if !std::fs::metadata(first).is_ok_and(|m| m.is_file()) {
        return None;
    }
    let rec = read_record_within(first, &csv, args.allow_large).ok()?;
    let found = set_point::set_points(ir, &rec);
    if found.is_empty() {
        return None;
    }
    dynid_runtime::sim::check_steps(
        rec.len() as f64 * args.substeps as f64,
        "the free run of the closed-loop hint",
        "--allow-long",
        args.allow_long,
    )
    .ok()?;
    let errors = refine::free_run_errors(
        ir,
        &refine::start_from(ir, id),
        std::slice::from_ref(&rec),
        args.substeps,
    );
    found.into_iter().find_map(|sp| {
        // In %; a run that diverged drifts.
        let drift = match &errors {
            Ok(e) => 100.0 * e.iter().find(|e| e.signal == sp.position)?.relative,
            Err(_) => f64::INFINITY,
        };
        (drift >= set_point::DRIFTS).then(|| sp.note(if drift.is_finite() { drift } else { 100.0 }))
    })
}

/// The refinement settings of `args` (`None` without `--refine`); weights are checked
/// against the model by the refinement itself.
fn refine_options(args: &Args) -> miette::Result<Option<RefineOptions>> {
    if !args.refine {
        return Ok(None);
    }
    let mut weights = Vec::new();
    for spec in &args.weight {
        let parsed = spec.split_once('=').and_then(|(n, w)| {
            w.trim()
                .parse::<f64>()
                .ok()
                .map(|w| (n.trim().to_string(), w))
        });
        weights.push(parsed.ok_or_else(|| {
            miette!(
                code = "dynid::refine::weight",
                help = "write `--weight SIGNAL=W`, e.g. `--weight m1.x=2`",
                "cannot read the weight `{spec}`"
            )
        })?);
    }
    if let Some(s) = args.segment {
        if !(s.is_finite() && s > 0.0) {
            return Err(miette!(
                code = "dynid::refine::segment",
                help = "give the longest sub-record in seconds, e.g. `--shooting 20`",
                "--shooting {s} is not a positive duration"
            ));
        }
    }
    Ok(Some(RefineOptions {
        substeps: args.substeps,
        weights,
        ..Default::default()
    }))
}

/// Refuse a refinement of a model with control laws before any work: the refinement
/// simulates open-loop models driven by the recorded inputs.
pub fn refuse_control_laws(ir: &ModelIr) -> miette::Result<()> {
    if ir.controls.is_empty() {
        return Ok(());
    }
    Err(refine::RefineError::ControlLaws {
        model: ir.name.clone(),
    }
    .into())
}

/// Refuse, before any sample is read, a refinement whose records (read whole, the
/// estimation and the test files together) would take more memory than the limit, unless
/// `--allow-large`.
fn check_whole_records(ir: &ModelIr, args: &Args) -> miette::Result<()> {
    use dynid_runtime::limits::{bytes_in_words, MAX_BYTES};
    if args.allow_large {
        return Ok(());
    }
    let csv = args.csv.options(ir)?;
    let mut total = 0.0;
    for p in args.data.iter().chain(&args.test) {
        let src = FileSource::open(p, ir, &csv)?;
        src.check_whole(false)?;
        total += src.whole_bytes();
    }
    if total > MAX_BYTES {
        return Err(miette!(
            code = "dynid::data::too_large",
            help = "the refinement holds every record whole: give fewer or shorter records, \
                    or give `--allow-large` to read them anyway",
            "the records of the refinement would take {} of memory read whole (estimated \
             from the files' sizes), above the limit of {}",
            bytes_in_words(total),
            bytes_in_words(MAX_BYTES)
        ));
    }
    Ok(())
}

/// Read every file of `paths` whole (the refinement simulates whole records); a record
/// whose memory (estimated from the file's size) is above the limit is refused before it
/// is read, unless `--allow-large`.
fn read_all(ir: &ModelIr, args: &Args, paths: &[PathBuf]) -> miette::Result<Vec<Record>> {
    let csv = args.csv.options(ir)?;
    Ok(paths
        .iter()
        .map(|p| read_record_within(p, &csv, args.allow_large))
        .collect::<Result<Vec<_>, _>>()?)
}

/// Refine the covariance estimate `id` on the estimation files and score both estimates.
pub fn refine_files(
    ir: &ModelIr,
    args: &Args,
    id: &Identification,
    opts: &RefineOptions,
) -> miette::Result<RefineReport> {
    let est = read_all(ir, args, &args.data)?;
    let samples: usize = est.iter().map(Record::len).sum();
    dynid_runtime::sim::check_steps(
        samples as f64 * args.substeps as f64,
        &format!(
            "one free run of {samples} samples × {} RK4 sub-steps (of the refinement's many)",
            args.substeps
        ),
        "--allow-long",
        args.allow_long,
    )?;
    let mut opts = opts.clone();
    if let (Some(s), Some(r)) = (args.segment, est.first()) {
        opts.segment = Some(((s / r.ts).round() as usize).max(3));
    }
    let test = read_all(ir, args, &args.test)?;
    compute_with_bar(ir, &refine::start_from(ir, id), &est, &test, &opts, false)
}

/// [`RefineReport::compute`] with the iterations on a progress bar on stderr unless
/// `quiet` (hidden anyway when stderr is not a terminal).
pub fn compute_with_bar(
    ir: &ModelIr,
    start: &[f64],
    est: &[Record],
    test: &[Record],
    opts: &RefineOptions,
    quiet: bool,
) -> miette::Result<RefineReport> {
    let bar = if quiet {
        indicatif::ProgressBar::hidden()
    } else {
        progress_bar(opts.max_iter)
    };
    let r = RefineReport::compute(ir, start, est, test, opts, &|p| {
        bar.set_length(p.max_iter as u64);
        bar.set_position(p.iteration as u64);
        bar.set_message(format!("{:.3e}", p.cost));
    });
    bar.finish_and_clear();
    Ok(r?)
}

/// The refinement's progress bar on stderr (hidden when stderr is not a terminal).
pub(super) fn progress_bar(max_iter: usize) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(max_iter as u64),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "refining [{bar:30}] {pos}/{len} iterations, cost {msg} ({elapsed})",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// Identify from the CSV files named in `args`.
pub fn identify_files(ir: &ModelIr, args: &Args) -> miette::Result<Identification> {
    let csv = args.csv.options(ir)?;
    let sources = args
        .data
        .iter()
        .map(|p| FileSource::open(p, ir, &csv))
        .collect::<Result<Vec<_>, _>>()?;
    let levels: Vec<&dyn LevelSource> = sources.iter().map(|s| s as &dyn LevelSource).collect();
    let opts = args.estimator.options(args.allow_large);
    let mut id = identify(ir, &levels, &opts)?;
    // Estimates that move with the corners: two further identifications.
    if !args.no_corner_check {
        check_corners(ir, &levels, &opts.as_identified(&id), &mut id);
    }
    Ok(id)
}

#[cfg(test)]
mod tests;
