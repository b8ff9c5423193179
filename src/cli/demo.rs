//! `dynid demo`: simulate a two-mass system with Coulomb friction in its coupling (the
//! "real" system), then diagnose the friction-free model against that data.

use dynid::output::{create_dir, write_simulation, Staged};
use dynid_runtime::sim::{level_count, level_file_names, simulate, SimConfig};
use std::path::PathBuf;
use std::time::Instant;

const TRUTH: &str = include_str!("../../models/two_mass_friction.dyn");
const MODEL: &str = include_str!("../../models/two_mass_linear.dyn");

const LONG_HELP: &str = "\
Simulates a two-mass system with Coulomb friction between the masses at three excitation
levels, then diagnoses the friction-free model against those \"measurements\": it should
name Coulomb friction at (m1, m2), identify r close to the true 0.3 and show the gap
shrinking to almost nothing. Takes a few seconds in a release build.

Example:
  dynid demo --report demo.html --keep-data demo-data/
  dynid detect demo-data/two_mass_linear.dyn demo-data/level_*.csv   # the same data";

/// Arguments of `dynid demo`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// Where to write the HTML report.
    #[arg(long, value_name = "HTML", default_value = "dynid-demo-report.html")]
    pub report: PathBuf,
    /// Keep the simulated data (CSV per level) and the models in this folder (replacing the
    /// level files and truth.json of an earlier run there).
    #[arg(long = "keep-data", value_name = "DIR")]
    pub keep_data: Option<PathBuf>,
    /// Seconds recorded per level.
    #[arg(long, default_value_t = 400.0)]
    pub duration: f64,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The models written beside the kept data.
const MODEL_FILES: [(&str, &str); 2] = [
    ("two_mass_linear.dyn", MODEL),
    ("two_mass_friction.dyn", TRUTH),
];

pub fn run(args: Args) -> miette::Result<()> {
    super::common::check_output(&args.report, "the report")?;
    let t0 = Instant::now();
    let truth = dsl_parser::compile_str("two_mass_friction.dyn", TRUTH)?;
    let cfg = SimConfig {
        duration: args.duration,
        burn_in: 50.0,
        seed: 7,
        ..Default::default()
    };
    if let Some(dir) = &args.keep_data {
        check_kept(&args, dir, level_count(&truth, &cfg)?)?;
    }
    println!("dynid demo — diagnosing a simulation model against \"measured\" data");
    println!();
    println!("The real system: two masses, springs and dampers, plus Coulomb friction");
    println!("r·sign(v) = 0.3·sign(v) between m1 and m2. The model under test");
    println!("(two_mass_linear.dyn) does not know about the friction.");
    println!();
    let out = simulate(&truth, &cfg)?;
    let n = out.records.len();
    println!(
        "Simulated {n} excitation levels × {} s at Ts = {} s ({:.1} s).",
        args.duration,
        cfg.sample,
        t0.elapsed().as_secs_f64()
    );
    if let Some(dir) = &args.keep_data {
        create_dir(dir)?;
        let mut staged = Staged::new();
        write_simulation(&mut staged, dir, &out)?;
        for (name, text) in MODEL_FILES {
            staged.write(&dir.join(name), text.as_bytes())?;
        }
        staged.commit()?;
        println!("Data and models kept in {}", dir.display());
    }
    let origins: Vec<String> = (1..=n).map(|k| format!("level{k}")).collect();
    let t1 = Instant::now();
    let model = dsl_parser::compile_str("two_mass_linear.dyn", MODEL)?;
    let d = super::diagnose::run_diagnosis(&model, &out.records, &origins, args.quiet, false)?;
    println!("Diagnosed in {:.1} s.", t1.elapsed().as_secs_f64());
    println!();
    print!("{}", d.summary());
    println!();
    println!("Truth for comparison: r = 0.3 at (m1, m2).");
    super::diagnose::write_outputs(&d, Some(&args.report), None, None)?;
    println!(
        "Total {:.1} s. Open {} in a browser for the figures.",
        t0.elapsed().as_secs_f64(),
        args.report.display()
    );
    Ok(())
}

/// Before the work: `--keep-data DIR` can be a writable directory, and the report is none
/// of the files kept there (nor of the earlier run's files that they replace).
fn check_kept(args: &Args, dir: &std::path::Path, n_levels: usize) -> miette::Result<()> {
    let names: Vec<String> = level_file_names(n_levels)
        .into_iter()
        .chain(["truth.json".to_string()])
        .chain(MODEL_FILES.iter().map(|(n, _)| n.to_string()))
        .collect();
    super::common::check_run_dir(
        dir,
        "--keep-data",
        &names,
        [],
        [(args.report.as_path(), "the report")],
    )
}
