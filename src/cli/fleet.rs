//! `dynid fleet [NAME=]MACHINE.json ...`: machines of one model, each identified on its own,
//! tested against their fleet (docs/fleet.md).

use super::common::{check_outputs, write_atomically};
use dynid_runtime::fleet::{assess, FleetOptions, Machine, MachineEstimate};
use dynid_runtime::schema::FleetDoc;
use miette::{miette, IntoDiagnostic};
use std::path::{Path, PathBuf};

const EXAMPLE: &str = "\
How it works: every machine is identified on its own (`dynid identify MODEL DATA... --json
m017.json`, the same model for all); the fleet's model is the mean of the machines held
consistent and their between-machine covariance (parts of one design scatter around the
nominal by more than one machine's standard error). Each machine's estimate is tested
against it by a chi-square test of d² = (p − p̄)ᵀ (Σ + C)⁻¹ (p − p̄); a machine is flagged
when its p-value is below ALPHA / n (Bonferroni over the n machines), and the parameters
that moved are named.

Example:
  for m in m001 m002 m003; do
      dynid identify axis.dyn data/$m/*.csv --json fleet/$m.json
  done
  dynid fleet fleet/*.json --json fleet.json

A machine is named by its file's stem (fleet/m017.json: m017), or NAME=FILE.";

/// Arguments of `dynid fleet`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = EXAMPLE)]
pub struct Args {
    /// One identification document per machine (`dynid identify ... --json FILE`), as FILE
    /// (named by its stem) or NAME=FILE.
    #[arg(required = true, value_name = "[NAME=]FILE")]
    pub machines: Vec<String>,
    /// Family-wise level: the chance that any machine consistent with its fleet is flagged.
    #[arg(long, default_value_t = 0.01, value_name = "ALPHA")]
    pub alpha: f64,
    /// Write the fleet's view as JSON to this file.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// A machine argument: its name and file.
fn split(arg: &str) -> (String, PathBuf) {
    match arg.split_once('=') {
        Some((name, file)) if !name.is_empty() && !Path::new(arg).exists() => {
            (name.to_string(), PathBuf::from(file))
        }
        _ => {
            let path = PathBuf::from(arg);
            let stem = path
                .file_stem()
                .map_or_else(|| arg.to_string(), |s| s.to_string_lossy().into_owned());
            (stem, path)
        }
    }
}

pub fn run(args: Args) -> miette::Result<()> {
    let named: Vec<(String, PathBuf)> = args.machines.iter().map(|a| split(a)).collect();
    check_outputs(
        [(args.json.as_deref(), "the JSON output")],
        named.iter().map(|(_, p)| p.as_path()),
    )?;
    let mut machines = Vec::with_capacity(named.len());
    for (name, path) in &named {
        let text = std::fs::read_to_string(path).map_err(|e| {
            miette!(
                code = "dynid::fleet::read",
                help = "give the identification document of every machine (`dynid identify ... --json FILE`)",
                "cannot read `{}`: {e}",
                path.display()
            )
        })?;
        let estimate = MachineEstimate::from_document(&text, &path.display().to_string())?;
        machines.push(Machine {
            name: name.clone(),
            estimate: Ok(estimate),
        });
    }
    let opts = FleetOptions {
        alpha: args.alpha,
        ..Default::default()
    };
    let view = assess(&machines, &opts)?;
    if let Some(out) = &args.json {
        let value = serde_json::to_value(FleetDoc::new(&view)).into_diagnostic()?;
        let text = serde_json::to_string_pretty(&value).into_diagnostic()?;
        write_atomically(out, text.as_bytes())?;
    }
    print!("{}", view.table());
    Ok(())
}
