//! `dynid simulate`: synthetic test data from a model, or the model's response to
//! measured inputs.

mod driven;

use super::common::{check_run_dir, load_model};
use driven::run_driven;
use dsl_parser::ir::ModelIr;
use dynid::output::LevelWritten;
use dynid_runtime::describe::std_dev;
use dynid_runtime::record::Record;
use dynid_runtime::sim::{self, SimConfig, DEFAULT_SUBSTEPS};
use miette::IntoDiagnostic;
use std::path::{Path, PathBuf};

/// Shown by `--help` after the options. (The subcommand's one-line description in
/// `cli/mod.rs` replaces any `long_about` set here, so the teaching text goes after.)
const LONG_HELP: &str = "\
Every input with an `excite` line is driven by its form filter (white noise of the level's
intensity, shaped by a low-pass or second-order filter), or by planned point-to-point
moves (`moves(distance = .., speed = .., accel = .., dwell = ..)`, a cycle repeated from
the start of the record; the level scales their speed); inputs without one stay zero.
Unknown parameters take their nominal values. Each level is an independent experiment:
the model starts at rest, runs for --burn-in seconds that are discarded, then --duration
seconds are recorded every --sample seconds. The columns are `t` and every measured signal
(`m1.x`, `m1.v`, …, inputs). --noise adds white measurement noise with a standard deviation
of that fraction of each signal's standard deviation. The same --seed gives the same data.

--signal multisine drives every excited input with a multisine instead (level = RMS of
the input): the lines k/T of --band-hz LOW,HIGH (in Hz), T = --duration / --periods so the
record holds whole periods (the samples must split evenly), --grid full or odd (odd
harmonics only), --phases random (per level) or schroeder. --signal sweep drives them with
a sine sweep (level = amplitude) from LOW to HIGH Hz, --sweep-law log or linear, repeated
--periods times per record. Both are evaluated exactly at every input point and linear in
between, as the form filters are (a DAC with a reconstruction filter, no zero-order
hold); the burn-in runs whole periods, and the record starts at a period's start.

--input-oversample N simulates the input processes N times per sample interval and
drives the mechanics with that finer input, so the data carries input content between
samples (the intensity keeps its meaning); samples are point values. --quantise Q rounds
every recorded position to a multiple of Q (an encoder resolution, after any noise). To
record positions without velocities, list the measured signals in the model
(`measure m.x, u`).

A model with a `control` line runs in closed loop: its law (`control u = 80000 * (xr -
m.x) - 2680 * m.v`) computes the input from the simulated state and the references every
Ts / N (N = --input-oversample), held in between; `excite xr: …` makes the set point,
and the record holds it and the law's force as columns. With --input the references are
read from the file instead (a column per reference; the controlled input needs none).

--pd KP,KD closes a position loop around the body of the model's first input:
u = KP (r − x) + KD (ṙ − v̂), v̂ the backward difference of the (quantised) position
over one sample interval Ts (--tachometer: the true velocity), updated every Ts / N and
held in between. The
reference r is white noise through a Butterworth low-pass of natural frequency
--reference-corner (rad/s) with RMS --reference-rms × level, written as the column
`<body>.x_ref`; the recorded input is the controller's output.

DIR/truth.json records the parameter values, levels and settings used, so identification
results can be scored against it. DIR holds one run: the level_k.csv, driven.csv and
truth.json of an earlier run there are replaced (other files stay), and a run that would
write or remove its own model or --input file is refused before it starts. The free space
is checked first against an estimate of the CSVs' size (about 17 bytes per number).

With --input data.csv the model is instead driven by the measured input columns (named
like the model's inputs and references, plus a uniform time column `t`), starting from the
measured state of the first sample where the file has the positions (velocities from their
columns or the first three positions; as every free run dynid scores), else from rest, and its
response is written to DIR/driven.csv on the same time base — to compare the model with
reality. The file sets the time base, the length and the inputs, so the flags of the
excitation (--levels, --duration, --sample, --seed, --noise, --burn-in, --quantise, --pd,
…) are refused with --input; --substeps applies.

Example:
  dynid simulate models/sdof_cubic_coulomb.dyn --levels 6,15,40 --duration 2000 --sample 0.01 \\
      --noise 0.05 --seed 1 --out data/
  writes data/level_1.csv, data/level_2.csv, data/level_3.csv and data/truth.json";

/// Arguments of `dynid simulate`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// The model file (.dyn), or a model compiled to its JSON IR (.json).
    pub model: PathBuf,
    /// Excitation intensities, one experiment each (default: the model's `excite` levels);
    /// for `moves`, speed factors.
    #[arg(conflicts_with = "input")]
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "L1,L2,...",
        allow_hyphen_values = true
    )]
    pub levels: Option<Vec<f64>>,
    /// Recorded seconds per level.
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 2000.0, value_name = "SECONDS")]
    pub duration: f64,
    /// Sample interval in seconds.
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 0.01, value_name = "SECONDS")]
    pub sample: f64,
    /// Base seed of the random excitation and noise.
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Measurement noise as a fraction of each signal's std (0.05 = 5 %).
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 0.0, value_name = "FRACTION")]
    pub noise: f64,
    /// Keep the input columns free of measurement noise.
    #[arg(conflicts_with = "input")]
    #[arg(long)]
    pub clean_inputs: bool,
    /// RK4 steps per sample interval.
    #[arg(long, default_value_t = DEFAULT_SUBSTEPS, value_name = "N")]
    pub substeps: usize,
    /// Seconds simulated and discarded before recording, so the record is stationary.
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 100.0, value_name = "SECONDS")]
    pub burn_in: f64,
    /// Input-process steps per sample interval (1 = linear between samples).
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub input_oversample: usize,
    /// Round recorded positions to multiples of this encoder resolution.
    #[arg(conflicts_with = "input")]
    #[arg(long, value_name = "RESOLUTION")]
    pub quantise: Option<f64>,
    /// Close a PD position loop on the first input's body with these gains.
    #[arg(conflicts_with = "input")]
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "KP,KD",
        allow_hyphen_values = true
    )]
    pub pd: Option<Vec<f64>>,
    /// RMS of the controller's reference position at level 1.
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 0.03, value_name = "X")]
    pub reference_rms: f64,
    /// Natural frequency of the reference's low-pass in rad/s.
    #[arg(conflicts_with = "input")]
    #[arg(long, default_value_t = 5.0, value_name = "RAD_PER_S")]
    pub reference_corner: f64,
    /// Make the reference a third-order trajectory (continuous velocity and acceleration,
    /// as a trajectory planner makes); without it the reference velocity is rough
    /// between samples and so is the controller's force.
    #[arg(conflicts_with = "input")]
    #[arg(long)]
    pub smooth_reference: bool,
    /// The controller feeds back the true velocity instead of a position difference.
    #[arg(conflicts_with = "input")]
    #[arg(long)]
    pub tachometer: bool,
    /// Output directory (created if missing; an earlier run's files there are replaced).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub excitation: super::excitation::SignalArgs,
    /// Drive the model with the inputs in this CSV instead of the form filters.
    #[arg(long, value_name = "CSV")]
    pub input: Option<PathBuf>,
    /// Summary format on stdout.
    #[arg(long, value_enum, default_value_t = Format::Text)]
    pub format: Format,
    /// Run even when the estimated work is above the safety limit (1e10 RK4 steps).
    #[arg(long)]
    pub allow_long: bool,
    /// With --input: run even when the memory of the input record (read whole, estimated
    /// from the file's size before reading) and of the response is above the safety limit
    /// (8 GB).
    #[arg(long)]
    pub allow_large: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Text,
    Json,
}

pub fn run(args: Args) -> miette::Result<()> {
    let ir = load_model(&args.model)?;
    dynid::output::check_out_dir(&args.out, "--out")?;
    match &args.input {
        Some(input) => run_driven(&ir, &args, input),
        None => run_excited(&ir, &args),
    }
}

fn run_excited(ir: &ModelIr, args: &Args) -> miette::Result<()> {
    let cfg = SimConfig {
        levels: args.levels.clone(),
        duration: args.duration,
        sample: args.sample,
        seed: args.seed,
        noise: args.noise,
        noise_on_inputs: !args.clean_inputs,
        substeps: args.substeps,
        burn_in: args.burn_in,
        input_oversample: args.input_oversample,
        quantise: args.quantise,
        control: pd_control(ir, args)?,
    };
    let n_levels = sim::level_count(ir, &cfg)?;
    sim::check_steps(
        sim::integration_steps(&cfg, n_levels),
        &format!(
            "simulating {n_levels} level(s) of {:.3e} samples × {} RK4 sub-steps (input oversampling {})",
            (cfg.burn_in + cfg.duration) / cfg.sample,
            cfg.substeps,
            cfg.input_oversample
        ),
        "--allow-long",
        args.allow_long,
    )?;
    let names = [
        sim::level_file_names(n_levels),
        vec!["truth.json".to_string()],
    ]
    .concat();
    check_run_dir(
        &args.out,
        "--out",
        &names,
        [(args.model.as_path(), "the model")],
        [],
    )?;
    let bar = progress_bar(sim::total_samples(&cfg, n_levels));
    let signal = args.excitation.signal()?;
    let out = dynid::output::simulate_signal_to_dir(ir, &cfg, signal.as_ref(), &args.out, &|n| {
        bar.inc(n)
    });
    bar.finish_and_clear();
    let (truth, written) = out?;
    print_excited(ir, args, &cfg, &truth, &written)
}

/// What `simulate` prints after an excited run: the truth and each level's file,
/// sample count and standard deviations, as JSON or as text.
fn print_excited(
    ir: &ModelIr,
    args: &Args,
    cfg: &SimConfig,
    truth: &sim::Truth,
    written: &[LevelWritten],
) -> miette::Result<()> {
    let mut paths: Vec<PathBuf> = written.iter().map(|w| w.path.clone()).collect();
    paths.push(args.out.join("truth.json"));
    let names: Vec<String> = ir
        .measured_signals()
        .iter()
        .map(|&s| ir.signal(s).name.clone())
        .chain(cfg.control.as_ref().map(|c| sim::reference_column(&c.body)))
        .collect();
    let stats: Vec<serde_json::Value> = written
        .iter()
        .zip(&truth.levels)
        .map(|(w, l)| {
            serde_json::json!({
                "file": w.path.display().to_string(),
                "level": l,
                "samples": w.samples,
                "signals": names,
                "std": w.std,
            })
        })
        .collect();
    match args.format {
        Format::Json => {
            let v = serde_json::json!({ "truth": truth, "levels": stats });
            println!("{}", serde_json::to_string_pretty(&v).into_diagnostic()?);
        }
        Format::Text => {
            println!(
                "simulated `{}`: {} level(s), {} s at Ts = {} s, noise {} %, seed {}",
                truth.model,
                written.len(),
                cfg.duration,
                cfg.sample,
                100.0 * cfg.noise,
                cfg.seed
            );
            for s in &stats {
                print_summary(s);
            }
            println!(
                "  {}",
                paths.last().expect("invariant: truth.json").display()
            );
        }
    }
    Ok(())
}

/// The controller of `--pd`: on the model's first input and the body it acts on.
fn pd_control(ir: &ModelIr, args: &Args) -> miette::Result<Option<sim::PdControl>> {
    let Some(gains) = &args.pd else {
        return Ok(None);
    };
    let &[kp, kd] = gains.as_slice() else {
        miette::bail!(
            code = "dynid::simulate::option",
            help = "give the position and velocity gains, e.g. `--pd 80000,2680`",
            "`--pd` takes two gains, got {}",
            gains.len()
        );
    };
    let Some(input) = ir.inputs.first() else {
        miette::bail!(
            code = "dynid::simulate::option",
            help = "declare an input (`input u on m`) for the controller to drive",
            "`--pd` needs a model input, and `{}` has none",
            ir.name
        );
    };
    Ok(Some(sim::PdControl {
        input: input.name.clone(),
        body: ir.bodies[input.body.index()].name.clone(),
        kp,
        kd,
        kf: 0.0,
        velocity: if args.tachometer {
            sim::VelocitySource::Tachometer
        } else {
            sim::VelocitySource::Difference
        },
        reference: sim::ReferenceSpec {
            rms: args.reference_rms,
            corner: args.reference_corner,
            smooth: args.smooth_reference,
            planned: None,
        },
    }))
}

/// The progress bar of an excited run, on stderr.
fn progress_bar(total: u64) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(total),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "simulating {bar:40} {percent:>3}%  {elapsed} (eta {eta})",
    ) {
        bar.set_style(style);
    }
    bar
}

/// The summary of one written level (file, level, samples, signals, their std).
fn level_summary(r: &Record, path: &Path, level: Option<f64>) -> serde_json::Value {
    serde_json::json!({
        "file": path.display().to_string(),
        "level": level,
        "samples": r.len(),
        "signals": r.names,
        "std": r.columns.iter().map(|c| std_dev(c)).collect::<Vec<_>>(),
    })
}

/// One line of text for a [`level_summary`].
fn print_summary(s: &serde_json::Value) {
    let stds = s["signals"]
        .as_array()
        .into_iter()
        .flatten()
        .zip(s["std"].as_array().into_iter().flatten())
        .map(|(n, v)| {
            format!(
                "{} {:.4}",
                n.as_str().unwrap_or(""),
                v.as_f64().unwrap_or(f64::NAN)
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    let level = s["level"]
        .as_f64()
        .map(|l| format!("level {l}: "))
        .unwrap_or_default();
    println!("  {} — {level}std {stds}", s["file"].as_str().unwrap_or(""));
}

#[cfg(test)]
mod tests;
