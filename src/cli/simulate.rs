//! `dynid simulate`: synthetic test data from a model, or the model's response to
//! measured inputs.

use super::common::{check_run_dir, load_model, Staged};
use dsl_parser::ir::ModelIr;
use dynid_runtime::data;
use dynid_runtime::record::Record;
use dynid_runtime::sim::{self, SimConfig, DEFAULT_SUBSTEPS};
use miette::{Context, IntoDiagnostic};
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

fn run_driven(ir: &ModelIr, args: &Args, input: &Path) -> miette::Result<()> {
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
    let summary = level_summary(&response, &csv, None);
    match args.format {
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
fn read_input_csv(path: &Path, allow_large: bool) -> miette::Result<Record> {
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

fn level_summary(r: &Record, path: &Path, level: Option<f64>) -> serde_json::Value {
    serde_json::json!({
        "file": path.display().to_string(),
        "level": level,
        "samples": r.len(),
        "signals": r.names,
        "std": r.columns.iter().map(|c| std_dev(c)).collect::<Vec<_>>(),
    })
}

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

use dynid_runtime::describe::std_dev;

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn input_csv_errors_name_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        // The error's code, and its text (which must name the line and column).
        let err = |text: &str| {
            let e = read_input_csv(&write(dir.path(), "a.csv", text), false).unwrap_err();
            let code = e.code().map(|c| c.to_string()).unwrap_or_default();
            (code, format!("{e:?}"))
        };
        let is = |(code, e): (String, String), want: &str, line: &str| {
            assert_eq!(code, want, "{e}");
            assert!(e.contains(line), "{e}");
        };
        is(
            err("u\n1\n2\n"),
            "dynid::data::no_sample_interval",
            "no `t` column",
        );
        is(err("t,u\n0,1\n0.1\n"), "dynid::data::ragged", "line 3");
        let nan = err("t,u\n0,1\n0.1,NaN\n");
        assert!(nan.1.contains("`u`"), "{}", nan.1);
        is(nan, "dynid::data::non_finite", "line 3");
        is(
            err("t,u\n0,1\n0.1,x\n"),
            "dynid::data::not_a_number",
            "line 3",
        );
        // A step of two intervals: a dropped sample, named as such (the same code as an
        // uneven step, told apart by the message).
        let (code, e) = err("t,u\n0,1\n0.1,2\n0.3,2\n0.35,1\n");
        assert_eq!(code, "dynid::data::non_uniform_time", "{e}");
        assert!(e.contains("line 4: a sample is missing"), "{e}");
        let (code, e) = err("t,u\n0,1\n0.1,2\n0.25,2\n0.35,1\n");
        assert_eq!(code, "dynid::data::non_uniform_time", "{e}");
        assert!(e.contains("line 4: the time step"), "{e}");
        let r = read_input_csv(
            &write(dir.path(), "b.csv", "t,u\n1,1\n1.5,2\n2,3\n\n"),
            false,
        )
        .unwrap();
        assert_eq!(
            (r.t0, r.ts, r.names.clone()),
            (1.0, 0.5, vec!["u".to_string()])
        );
        assert_eq!(r.columns, vec![vec![1.0, 2.0, 3.0]]);
    }

    fn args(model: PathBuf, out: PathBuf) -> Args {
        Args {
            model,
            levels: Some(vec![6.0, 15.0]),
            duration: 20.0,
            sample: 0.01,
            seed: 3,
            noise: 0.0,
            clean_inputs: false,
            substeps: DEFAULT_SUBSTEPS,
            burn_in: 5.0,
            input_oversample: 1,
            quantise: None,
            pd: None,
            reference_rms: 0.03,
            reference_corner: 5.0,
            smooth_reference: false,
            tachometer: false,
            out,
            excitation: Default::default(),
            input: None,
            format: Format::Json,
            allow_long: false,
            allow_large: false,
        }
    }

    #[test]
    fn writes_levels_and_truth_then_drives_with_a_level() {
        use dynid_runtime::sim::test_models::{sdof, SdofParams};
        let dir = tempfile::tempdir().unwrap();
        let ir = sdof(
            &SdofParams::benchmark(),
            dsl_parser::ir::FormFilter::Lowpass { corner: 10.0 },
            vec![1.0],
        );
        let model = write(
            dir.path(),
            "sdof.json",
            &serde_json::to_string(&ir).unwrap(),
        );
        let out = dir.path().join("out");
        run(args(model.clone(), out.clone())).unwrap();
        let mut files: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        files.sort();
        assert_eq!(files, ["level_1.csv", "level_2.csv", "truth.json"]);
        let truth: sim::Truth =
            serde_json::from_str(&std::fs::read_to_string(out.join("truth.json")).unwrap())
                .unwrap();
        assert_eq!(truth.levels, [6.0, 15.0]);
        assert_eq!(truth.files, ["level_1.csv", "level_2.csv"]);
        let level = read_input_csv(&out.join("level_2.csv"), false).unwrap();
        assert_eq!(level.names, ["m1.x", "m1.v", "u"]);
        assert_eq!(level.len(), 2000);

        let driven_out = dir.path().join("driven");
        let mut a = args(model, driven_out.clone());
        a.input = Some(out.join("level_2.csv"));
        run(a).unwrap();
        let driven = read_input_csv(&driven_out.join("driven.csv"), false).unwrap();
        assert_eq!(driven.len(), level.len());
        assert_eq!(driven.column("u"), level.column("u"));
    }

    #[test]
    fn closed_loop_quantised_oversampled_run_writes_the_reference() {
        use dynid_runtime::sim::test_models::ServoAxis;
        let dir = tempfile::tempdir().unwrap();
        let model = write(
            dir.path(),
            "servo.json",
            &serde_json::to_string(&ServoAxis::standard().model()).unwrap(),
        );
        let out = dir.path().join("out");
        let mut a = args(model, out.clone());
        a.levels = None;
        a.duration = 2.0;
        a.burn_in = 1.0;
        a.sample = 1e-3;
        a.input_oversample = 4;
        a.quantise = Some(1e-6);
        a.pd = Some(vec![80000.0, 2680.0]);
        run(a).unwrap();
        let level = read_input_csv(&out.join("level_1.csv"), false).unwrap();
        assert_eq!(level.names, ["m.x", "u", "m.x_ref"]);
        assert_eq!(level.len(), 2000);
        let truth: sim::Truth =
            serde_json::from_str(&std::fs::read_to_string(out.join("truth.json")).unwrap())
                .unwrap();
        assert_eq!(truth.input_oversample, 4);
        assert_eq!(truth.control.unwrap().kd, 2680.0);
        let mut bad = args(dir.path().join("servo.json"), dir.path().join("bad"));
        bad.pd = Some(vec![1.0]);
        let e = run(bad).unwrap_err();
        assert!(format!("{e:?}").contains("two gains"), "{e:?}");
    }

    #[test]
    fn failures_leave_no_output() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let e = run(args(dir.path().join("missing.json"), out.clone())).unwrap_err();
        assert!(format!("{e:?}").contains("missing.json"));
        let e = run(args(write(dir.path(), "m.dyn", "model m {}"), out.clone())).unwrap_err();
        assert!(format!("{e:?}").contains("m.dyn"));
        assert!(!out.exists());
    }
}
