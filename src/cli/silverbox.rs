//! `dynid silverbox`: the Silverbox benchmark on the real measurement — identify on the
//! multisines, free-run simulate the arrow and the multisine test, compare with the
//! published results; optionally export the arrow as excitation levels for detection.

use dsl_parser::ir::ModelIr;
use dynid::output::Staged;
use dynid_runtime::record::Record;
use dynid_runtime::refine::RefineOptions;
use dynid_runtime::silverbox::{self, RunOptions, SilverboxReport, PUBLISHED};
use dynid_runtime::sim::level_file_names;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::{Path, PathBuf};

const LONG_HELP: &str = "\
Runs the Silverbox benchmark (an electronic Duffing oscillator, m y'' + d y' + a y + b y^3 = u)
on the original measurement: means removed, identification on the estimation part of the
multisines only, free-run RMS error (mV) on the arrow test and on the multisine test next
to the published figures.

Examples:
  dynid silverbox                                     # the cubic model, default data path
  dynid silverbox --model models/silverbox_linear.dyn --model models/silverbox_cubic.dyn
  dynid silverbox --refine --model models/silverbox_damping.dyn   # 0.339 mV refined, 8 params
  dynid silverbox --model models/silverbox_linear.dyn --export-levels arrow/
  dynid diagnose models/silverbox_linear.dyn arrow/level_*.csv   # names the cubic spring

The procedure, the segment boundaries and the figures are in docs/silverbox.md.";

/// Arguments of `dynid silverbox`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// Directory holding SNLS80mV.csv [default: $DYNID_SILVERBOX_DATA, else
    /// ../shared/data/silverbox].
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Model(s) to identify and score (repeatable).
    #[arg(
        long = "model",
        value_name = "MODEL",
        default_value = DEFAULT_MODEL
    )]
    pub models: Vec<PathBuf>,
    /// Write the reports as JSON to this file.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// RK4 sub-steps per (upsampled) sample in the free-run simulations.
    #[arg(long, default_value_t = 4, value_parser = super::common::at_least_one)]
    pub substeps: usize,
    /// Band-limited (windowed-sinc) interpolation factor before identification and
    /// simulation; 1 = linear interpolation between the measured samples.
    #[arg(long, default_value_t = 4, value_parser = super::common::at_least_one)]
    pub upsample: usize,
    /// Identification filter corners in rad/s (default: the model's, else 100…1000 rad/s).
    #[arg(
        long = "filter-corners",
        value_delimiter = ',',
        value_name = "A,B,C",
        allow_hyphen_values = true
    )]
    pub filter_corners: Option<Vec<f64>>,
    /// Sections per identification low-pass chain.
    #[arg(long = "filter-order", value_name = "N")]
    pub filter_order: Option<usize>,
    /// Signals driving the identification filters (default: the input only).
    #[arg(long = "drivers", value_delimiter = ',', value_name = "SIGNALS")]
    pub drivers: Option<Vec<String>>,
    /// Cut the arrow into levels, write DIR/level_k.csv (header `t,<output>,<input>` of the
    /// first model, at the `--upsample` rate; an earlier run's level files there are
    /// replaced) and print the per-level fits of the first model instead of the table.
    #[arg(long = "export-levels", value_name = "DIR")]
    pub export_levels: Option<PathBuf>,
    /// Write the estimation parts of the multisines (one per realisation, at the
    /// `--upsample` rate) as DIR/level_k.csv, e.g. for `dynid diagnose` (replacing an
    /// earlier run's level files there).
    #[arg(long = "export-estimation", value_name = "DIR")]
    pub export_estimation: Option<PathBuf>,
    /// Number of arrow levels for `--export-levels`.
    #[arg(long = "levels", default_value_t = 4, value_name = "N")]
    pub n_levels: usize,
    /// Also refine each covariance estimate by minimising the free-run error on the
    /// estimation parts, and report the refined figures beside the covariance ones.
    #[arg(long, conflicts_with_all = ["export_levels", "export_estimation"])]
    pub refine: bool,
    /// Run even when the estimated memory (8 GB) or work (1e10 RK4 steps) is above the
    /// safety limit.
    #[arg(long)]
    pub allow_large: bool,
}

/// The model `silverbox` scores without `--model`; it is built in, so the command also runs
/// outside the repository (a file of that name in the working directory takes precedence).
const DEFAULT_MODEL: &str = "models/silverbox_cubic.dyn";
const DEFAULT_MODEL_SOURCE: &str = include_str!("../../models/silverbox_cubic.dyn");

/// The model at `path`: the file, or the built-in default model where `path` is the default
/// and no such file exists here.
fn model_at(path: &Path) -> miette::Result<ModelIr> {
    if path == Path::new(DEFAULT_MODEL) && !path.exists() {
        return dsl_parser::compile_str("silverbox_cubic.dyn", DEFAULT_MODEL_SOURCE)
            .map_err(|e| miette!("invariant: the built-in model compiles: {e}"));
    }
    super::common::load_model(path)
}

impl Args {
    /// `--data`, else `$DYNID_SILVERBOX_DATA`, else `../shared/data/silverbox`.
    fn data_dir(&self) -> PathBuf {
        self.data
            .clone()
            .or_else(|| std::env::var_os("DYNID_SILVERBOX_DATA").map(PathBuf::from))
            .unwrap_or_else(|| PathBuf::from("../shared/data/silverbox"))
    }
}

pub fn run(args: Args) -> miette::Result<()> {
    let data_dir = args.data_dir();
    let data_file = data_dir.join(silverbox::FILE);
    super::common::check_outputs(
        [(args.json.as_deref(), "the JSON output")],
        args.models
            .iter()
            .map(PathBuf::as_path)
            .chain([data_file.as_path()]),
    )?;
    let inputs: Vec<(&std::path::Path, &str)> = args
        .models
        .iter()
        .map(|m| (m.as_path(), "the model"))
        .chain([(data_file.as_path(), "the data file")])
        .collect();
    if let Some(dir) = &args.export_levels {
        let names = level_file_names(args.n_levels);
        super::common::check_run_dir(dir, "--export-levels", &names, inputs.iter().copied(), [])?;
    }
    if let Some(dir) = &args.export_estimation {
        super::common::check_run_dir(dir, "--export-estimation", &[], inputs.iter().copied(), [])?;
    }
    let data = silverbox::load(&data_dir)?;
    silverbox::check_work(
        &data,
        args.upsample,
        args.substeps,
        "--allow-large",
        args.allow_large,
    )?;
    if let Some(dir) = &args.export_levels {
        return export_levels(&args, &data, dir);
    }
    if let Some(dir) = &args.export_estimation {
        return export_estimation(&args, &data, dir);
    }
    let split = silverbox::split(&data)?;
    println!(
        "{}: {} samples, means removed (V1 {:.4} mV, V2 {:.4} mV)",
        data.path.display(),
        data.u.len(),
        1e3 * data.means.0,
        1e3 * data.means.1
    );
    println!(
        "multisine realisations (0-based [start, end)): {}",
        split
            .realisations
            .iter()
            .map(|s| format!("[{}, {})", s.start, s.end))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let mut reports = Vec::new();
    for path in &args.models {
        let ir = model_at(path)?;
        let mut id = silverbox::default_options(&ir);
        if args.filter_corners.is_some() {
            id.corners = args.filter_corners.clone();
        }
        if args.filter_order.is_some() {
            id.order = args.filter_order;
        }
        if let Some(d) = &args.drivers {
            id.drivers = Some(
                d.iter()
                    .map(|n| {
                        ir.signal_id(n).ok_or_else(|| {
                            miette!(
                                code = "dynid::identify::option",
                                help = "name the model's positions or inputs, e.g. `--drivers y,u`",
                                "no signal `{n}` in the model"
                            )
                        })
                    })
                    .collect::<miette::Result<_>>()?,
            );
        }
        let r = silverbox::run(
            &ir,
            &data,
            &RunOptions {
                identify: id,
                substeps: args.substeps,
                upsample: args.upsample,
                refine: args.refine.then(RefineOptions::default),
            },
        )
        .wrap_err_with(|| format!("model `{}`", path.display()))?;
        print_params(&r);
        reports.push(r);
    }
    print!("{}", table(&reports));
    if let Some(out) = &args.json {
        let text = serde_json::to_string_pretty(&reports).into_diagnostic()?;
        super::common::write_atomically(out, text.as_bytes())?;
    }
    Ok(())
}

fn print_params(r: &SilverboxReport) {
    println!(
        "\n{} (filter corners {:?} rad/s, order {}, condition {:.2e})",
        r.model, r.filter_corners, r.filter_order, r.condition
    );
    for p in &r.params {
        // A relative error only where it is a number (not for an estimate of exactly 0).
        let rel = 100.0 * p.stderr / p.value.abs();
        let rel = if rel.is_finite() {
            format!(" ({rel:.2} %)")
        } else {
            String::new()
        };
        println!("  {:<6} {:>13.6e} ± {:.2e}{rel}", p.name, p.value, p.stderr);
    }
    for u in &r.unidentifiable {
        println!("  {:<6} left out: {}", u.name, u.reason);
    }
    let sim: Vec<String> = r
        .simulated
        .iter()
        .map(|(n, v)| format!("{n} = {v:.6e}"))
        .collect();
    println!("  simulated with {}", sim.join(", "));
    if let Some(f) = &r.refined {
        let x = &f.refinement;
        println!(
            "  refined (output error, {} iterations, {}): mean-square error {:.3e} -> {:.3e}",
            x.iterations,
            if x.converged {
                "converged"
            } else {
                "iteration limit"
            },
            x.cost_start,
            x.cost_end
        );
        for p in &x.params {
            println!(
                "  {:<6} {:>13.6e} -> {:>13.6e} ± {:.2e}",
                p.name, p.start, p.value, p.stderr
            );
        }
    }
}

/// The results table next to the published figures.
pub fn table(reports: &[SilverboxReport]) -> String {
    let refined = reports.iter().any(|r| r.refined.is_some());
    let mut s = if refined {
        String::from(
            "\n| model | params | arrow RMS (mV) | multisine test RMS (mV) | refined arrow RMS (mV) | refined multisine test RMS (mV) |\n|---|---:|---:|---:|---:|---:|\n",
        )
    } else {
        String::from(
            "\n| model | params | arrow RMS (mV) | multisine test RMS (mV) |\n|---|---:|---:|---:|\n",
        )
    };
    for r in reports {
        s.push_str(&format!(
            "| {} | {} | {:.3} | {:.3} |",
            r.model, r.n_params, r.arrow_rms_mv, r.multisine_test_rms_mv
        ));
        if let Some(f) = &r.refined {
            s.push_str(&format!(
                " {:.3} | {:.3} |",
                f.arrow_rms_mv, f.multisine_test_rms_mv
            ));
        } else if refined {
            s.push_str(" | |");
        }
        s.push('\n');
    }
    let pad = if refined { " | |" } else { "" };
    for (name, v) in PUBLISHED {
        s.push_str(&format!("| published: {name} | | {v:.2} | |{pad}\n"));
    }
    if let Some(r) = reports.first() {
        s.push_str(&format!(
            "\n(output RMS: arrow {:.1} mV, multisine test {:.1} mV)\n",
            r.arrow_output_rms_mv, r.multisine_test_output_rms_mv
        ));
    }
    s
}

/// Write `records` as DIR/level_k.csv, all or nothing.
/// (Replacing the run files of an earlier run in DIR; see [`dynid::output::stage_levels`].)
fn write_levels(dir: &std::path::Path, records: &[Record]) -> miette::Result<()> {
    dynid::output::create_dir(dir)?;
    let mut staged = Staged::new();
    dynid::output::stage_levels(&mut staged, dir, records)?;
    staged.commit()
}

fn export_estimation(
    args: &Args,
    data: &silverbox::SilverboxData,
    dir: &std::path::Path,
) -> miette::Result<()> {
    let path = args.models.first().expect("invariant: a default model");
    let ir = super::common::load_model(path)?;
    let split = silverbox::split(data)?;
    let records = split
        .estimation
        .iter()
        .map(|s| silverbox::record_upsampled(&ir, data, *s, args.upsample))
        .collect::<Result<Vec<_>, _>>()?;
    write_levels(dir, &records)?;
    println!(
        "{} multisine estimation parts of `{}` written to {}: {}",
        records.len(),
        ir.name,
        dir.display(),
        split
            .estimation
            .iter()
            .map(|s| format!("[{}, {})", s.start, s.end))
            .collect::<Vec<_>>()
            .join(" ")
    );
    Ok(())
}

fn export_levels(
    args: &Args,
    data: &silverbox::SilverboxData,
    dir: &std::path::Path,
) -> miette::Result<()> {
    if args.n_levels < 2 {
        return Err(miette!(
            code = "dynid::detect::too_few_levels",
            help = "detection compares at least two levels; use e.g. `--levels 4`",
            "{} arrow levels",
            args.n_levels
        ));
    }
    let path = args.models.first().expect("invariant: a default model");
    let ir = super::common::load_model(path)?;
    let mut opts = silverbox::default_options(&ir);
    if args.filter_corners.is_some() {
        opts.corners = args.filter_corners.clone();
    }
    if args.filter_order.is_some() {
        opts.order = args.filter_order;
    }
    let (records, levels) =
        silverbox::arrow_level_fits(&ir, data, args.n_levels, &opts, args.upsample)?;
    write_levels(dir, &records)?;
    let names: Vec<String> = levels[0].params.iter().map(|p| p.name.clone()).collect();
    let mut s = format!(
        "arrow levels of `{}` written to {}\n\n| level | samples | u std (mV) | y std (mV) |",
        ir.name,
        dir.display()
    );
    for n in &names {
        s.push_str(&format!(" {n} |"));
    }
    s.push_str(&format!(
        "\n|---|---|---:|---:|{}\n",
        "---:|".repeat(names.len())
    ));
    for (k, l) in levels.iter().enumerate() {
        s.push_str(&format!(
            "| {} | {}–{} | {:.2} | {:.2} |",
            k + 1,
            l.segment.start,
            l.segment.end,
            l.u_std_mv,
            l.y_std_mv
        ));
        for p in &l.params {
            s.push_str(&format!(" {:.5e} ± {:.1e} |", p.value, p.stderr));
        }
        s.push('\n');
    }
    print!("{s}");
    Ok(())
}
