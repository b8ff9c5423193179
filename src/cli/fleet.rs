//! `dynid fleet [NAME=]MACHINE.json ...`: machines of one model, each identified on its own,
//! tested against their fleet (docs/fleet.md).

use super::common::{check_outputs, write_atomically};
use dynid_runtime::fleet::{
    assess, FleetOptions, FleetView, Machine, MachineEstimate, MachineParam, Status,
};
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
    print!("{}", table(&view));
    Ok(())
}

/// The text report: the fleet's model, the flagged machines with what moved, the machines
/// not tested, and a count of the rest.
pub fn table(v: &FleetView) -> String {
    use dsl_parser::num::sig;
    let mut out = String::new();
    let line = |out: &mut String, s: String| {
        out.push_str(&s);
        out.push('\n');
    };
    line(
        &mut out,
        format!(
            "Fleet of {} machine(s): {} tested, {} consistent, {} flagged (family-wise α = {}: d² > {} for {} parameters)",
            v.machines.len(),
            v.tested,
            v.held,
            v.flagged().count(),
            sig(v.alpha, 3, false),
            sig(v.critical_d2, 3, false),
            v.params.len()
        ),
    );
    line(&mut out, String::new());
    line(
        &mut out,
        format!(
            "  {:<12} {:>12} {:>10} {:>22} {:>12}",
            "parameter", "fleet", "± (mean)", "between machines", "within"
        ),
    );
    for p in &v.params {
        let rel = if p.value != 0.0 {
            format!(" ({} %)", sig(100.0 * p.spread / p.value.abs(), 2, false))
        } else {
            String::new()
        };
        line(
            &mut out,
            format!(
                "  {:<12} {:>12} {:>10} {:>22} {:>12}",
                p.name,
                sig(p.value, 4, false),
                sig(p.stderr, 2, false),
                format!("{}{rel}", sig(p.spread, 2, false)),
                sig(p.within, 2, false)
            ),
        );
    }
    if v.between_clipped > 0 {
        line(
            &mut out,
            format!(
                "  ({} direction(s) without between-machine spread: the machines scatter there no more than their own errors)",
                v.between_clipped
            ),
        );
    }
    let flagged: Vec<_> = v.flagged().collect();
    if !flagged.is_empty() {
        line(&mut out, String::new());
        line(&mut out, "Flagged (inconsistent with the fleet):".into());
    }
    for m in flagged {
        let t = m
            .test
            .as_ref()
            .expect("invariant: a flagged machine was tested");
        let p = if t.p_value > 0.0 {
            format!("p = {}", sig(t.p_value, 2, false))
        } else {
            "p < 1e-300".into()
        };
        let moved: Vec<String> = m.moved.iter().map(describe).collect();
        line(
            &mut out,
            format!(
                "  {:<12} d² = {} ({} dof, {p}): {}",
                m.name,
                sig(t.d2, 4, false),
                t.dof,
                moved.join(", ")
            ),
        );
    }
    let untested: Vec<_> = v
        .machines
        .iter()
        .filter(|m| matches!(m.status, Status::Failed | Status::RankDeficient))
        .collect();
    if !untested.is_empty() {
        line(&mut out, String::new());
        line(&mut out, "Not tested:".into());
    }
    for m in untested {
        line(
            &mut out,
            format!("  {:<12} {}", m.name, m.note.as_deref().unwrap_or("")),
        );
    }
    let notes: Vec<_> = v
        .machines
        .iter()
        .filter(|m| m.test.is_some() && m.note.is_some())
        .collect();
    for m in notes {
        line(
            &mut out,
            format!("  {:<12} {}", m.name, m.note.as_deref().unwrap_or("")),
        );
    }
    out
}

/// `fv 2.03× fleet (+41 σ)`.
fn describe(p: &MachineParam) -> String {
    let ratio = p.ratio.map_or(String::new(), |r| {
        format!(" {}× fleet", dsl_parser::num::sig(r, 3, true))
    });
    format!("{}{ratio} ({:+.0} σ)", p.name, p.z)
}
