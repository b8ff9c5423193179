//! `dynid detect LINEAR_MODEL.dyn LEVEL1.csv LEVEL2.csv ...`: which force elements of a
//! linear model hide a nonlinearity, which kind, and how sure.

use super::common::{check_outputs, inputs, CsvArgs, SplitArgs, Staged};
use dynid::plot::draw_curves;
use dynid_runtime::data::{FileSource, LevelSource, RecordSource};
use dynid_runtime::detect::{detect_from_data_with_progress, DetectOptions, SigmaVSource};
use dynid_runtime::IdentifyOptions;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::PathBuf;

const EXAMPLE: &str = "\
How it works: the LINEAR model is identified separately at every level (one CSV file per
excitation level, at least 2, better 3-8 spanning a factor >= 3 in amplitude). A linear
element gives the same stiffness and damping at every level; an element hiding a
nonlinearity gives a value that drifts with the level, and the shape of the drift over the
element's intensity (std of its relative displacement s or velocity v) names the effect:
cubic stiffness, Coulomb friction, quadratic damping, backlash or prestress. Each element
gets a verdict (linear / nonlinear: EFFECT / ambiguous / unexplained) with the implied
nonlinear parameter (e.g. k3, r) and its standard error.

Example:
  dynid simulate models/sdof_duffing.dyn --duration 300 --out data/
  dynid detect models/sdof_linear.dyn data/level_1.csv data/level_2.csv data/level_3.csv \\
      --plot curves.png --json detect.json

  Element k/d (ground, m): nonlinear: cubic stiffness
    k3 = 1.98 ± 0.28; explains 94.2 % of the drift, χ²/dof = 5.234

One record whose amplitude varies (a run-up, a sweep of drive levels) can stand for the
levels: give ONE file and it is cut into --segments N (default 3) contiguous segments by the
local RMS of the response (--split-by SIGNAL, default the first measured position), each
long enough for identification (80/ω₀ s, ω₀ the response's dominant frequency). The
segment table (time span, samples, σ) goes to stderr and into the JSON:

  dynid detect models/sdof_linear.dyn run_up.csv --segments 4

A record of one repeated trajectory is cut at its cycles instead (--cut, see `dynid
diagnose --help`); cycles of one amplitude cannot show a drift, and a warning says so.

Levels (files or segments) whose σ are too alike for the drift test to resolve an effect
of a quarter of a parameter's value get a warning (stderr, JSON `warnings`): their
`linear` then only rules out larger effects.

Unknown masses are held at one value for all levels (a nonlinear force linearises to a
stiffness or damping, never to a mass). A second effect that a single-effect verdict
leaves unexplained is reported as `also suspected`; more levels separate the two.

Next step: add the named term to the model (e.g. `force nl (ground, m) = k3 * s^3`) and
run `dynid identify` on the same files.";

/// Arguments of `dynid detect`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = EXAMPLE, allow_negative_numbers = true)]
pub struct Args {
    /// The linear model (springs and dampers with unknown parameters).
    pub model: PathBuf,
    /// One CSV file per excitation level (header with `t` and the measured signals), or ONE
    /// file whose amplitude varies, split into levels (see --segments).
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Write the full result (curves, tests, template ranking) as JSON to this file.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Plot the parameter curves with the best templates: `.svg` or `.png` (by the name).
    /// The frequency response per level (measured H1 with coherence, and the linear model
    /// fitted at each level) goes beside it as FILE-frf.svg / FILE-frf.png.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub frf: super::frf::FrfArgs,
    #[command(flatten)]
    pub csv: CsvArgs,
    #[command(flatten)]
    pub split: SplitArgs,
    /// Significance of the constancy test of each curve.
    #[arg(long, default_value_t = 1e-3, value_name = "P")]
    pub alpha: f64,
    /// Run even when the memory estimated before reading the data (of the moments and the
    /// least-squares problems, or of a record read whole to be split) is above the safety
    /// limit (8 GB).
    #[arg(long)]
    pub allow_large: bool,
    /// Fit each level with each row weighted by its own estimated error (the rows'
    /// estimated covariance shrunk to its diagonal, in a two-step solve) instead of each row
    /// at unit norm. Chosen without this flag where the record measures accelerations (the
    /// report says so): there the unit-norm rows shrink each level's fit of a many-body
    /// structure by a different share, which draws spurious drift and misnames a joint's
    /// effect; weighted, the joint's clearance and friction are named on 9 of 12 seeds
    /// (against none) and no other element flagged (against 5) (docs/detection.md,
    /// "Noisy accelerations")
    #[arg(long = "weighted-rows", conflicts_with = "instrument_rows")]
    pub weighted_rows: bool,
    /// Keep each row at unit norm where detection would weight them (a record of measured
    /// accelerations)
    #[arg(long = "instrument-rows")]
    pub instrument_rows: bool,
    /// Hide the progress bar of the template simulations (shown on a terminal only).
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> miette::Result<()> {
    let frf_plot = args.plot.as_deref().map(super::frf::frf_plot_path);
    check_outputs(
        [
            (args.json.as_deref(), "the JSON output"),
            (args.plot.as_deref(), "the plot"),
            (frf_plot.as_deref(), "the frequency-response plot"),
        ],
        inputs(&args.model, &args.data),
    )?;
    if let Some(p) = &args.plot {
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("svg" | "png")) {
            return Err(miette!(
                code = "dynid::detect::plot_format",
                help = "name the file `….svg` or `….png`",
                "the plot `{}` would be written in a format its name does not say: dynid draws SVG or PNG",
                p.display()
            ));
        }
    }
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        return Err(miette!(
            code = "dynid::detect::option",
            help = "a probability such as 1e-3",
            "--alpha {} is not between 0 and 1",
            args.alpha
        ));
    }
    let ir = super::common::load_model(&args.model)?;
    let csv = args.csv.options(&ir)?;
    let split = args.split.levels(&ir, &args.data, &csv, args.allow_large)?;
    let cycle_note = split.as_ref().and_then(|s| s.split.cycles_note());
    if let Some(n) = &cycle_note {
        eprintln!("warning: {n}");
    }
    if split.is_none() {
        super::duplicates::refuse_duplicate_levels(
            &args.data,
            "detection compares the levels, and a copy would count as a level that agrees",
        )?;
    }
    let (files, segments) = match &split {
        Some(s) => (
            Vec::new(),
            s.records
                .iter()
                .zip(&s.origins)
                .map(|(r, o)| RecordSource::new(r, &ir, o.clone()))
                .collect::<Result<Vec<_>, _>>()?,
        ),
        None => (
            args.data
                .iter()
                .map(|p| FileSource::open(p, &ir, &csv))
                .collect::<Result<Vec<_>, _>>()?,
            Vec::new(),
        ),
    };
    let levels: Vec<&dyn LevelSource> = files
        .iter()
        .map(|s| s as &dyn LevelSource)
        .chain(segments.iter().map(|s| s as &dyn LevelSource))
        .collect();
    let dopts = DetectOptions {
        alpha: args.alpha,
        ..Default::default()
    };
    let iopts = IdentifyOptions {
        allow_large: args.allow_large,
        efficient: args.weighted_rows,
        auto_rows: !args.instrument_rows,
        ..Default::default()
    };
    let bar = template_bar(args.quiet);
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let found = detect_from_data_with_progress(&ir, &levels, &iopts, &dopts, &[], &progress);
    bar.finish_and_clear();
    let (det, fits) = found?;
    let warnings = dynid::schema::detection_warnings(&det, &fits, &dopts);
    let frfs = if args.json.is_some() || args.plot.is_some() {
        super::frf::level_frfs(&ir, &levels, &det, &fits.fits, args.frf.frf_periods)?
    } else {
        Vec::new()
    };

    // Write all outputs or none (the plot format follows the extension, which the staged
    // name keeps).
    let result = (|| -> miette::Result<()> {
        let mut staged = Staged::new();
        if let Some(out) = &args.json {
            let doc = dynid::schema::DetectDoc::new(
                &det,
                &fits,
                &warnings,
                split.as_ref().map(|s| &s.split),
                &frfs,
            );
            // Through a `Value`: the keys sorted, as the file has always had them.
            let value = serde_json::to_value(doc).into_diagnostic()?;
            let text = serde_json::to_string_pretty(&value).into_diagnostic()?;
            staged.write(out, text.as_bytes())?;
        }
        if let Some(out) = &args.plot {
            let tmp = staged.temp_for(out)?;
            draw_curves(&det, &tmp).wrap_err_with(|| format!("cannot write {}", out.display()))?;
        }
        if let (Some(out), false) = (&frf_plot, frfs.is_empty()) {
            let tmp = staged.temp_for(out)?;
            dynid::plot::draw_frf(&frfs, &tmp)
                .wrap_err_with(|| format!("cannot write {}", out.display()))?;
        }
        staged.commit()
    })();
    print!("{}", det.render_table());
    for w in &warnings {
        eprintln!("warning: {}", w.message);
    }
    if let Some(n) = &cycle_note {
        eprintln!("warning: {n}");
    }
    let estimated: Vec<&str> = fits
        .input
        .elements
        .iter()
        .zip(&fits.sigma_v_source)
        .filter(|(_, s)| **s == SigmaVSource::ZeroCrossings)
        .map(|(e, _)| e.element.as_str())
        .collect();
    if !estimated.is_empty() {
        println!(
            "\nσ_v estimated from positions (zero-crossing rate) for: {}",
            estimated.join(", ")
        );
    }
    result
}

/// The bar of the estimator's template simulations (the step that takes time on long
/// records) on stderr; indicatif draws nothing where stderr is not a terminal.
fn template_bar(quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar =
        indicatif::ProgressBar::with_draw_target(Some(0), indicatif::ProgressDrawTarget::stderr());
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "simulating the estimator's templates [{bar:30}] {pos}/{len} runs ({elapsed})",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
