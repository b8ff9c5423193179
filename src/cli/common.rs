//! Helpers shared by the subcommands.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::CsvOptions;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::Path;

/// Load a model: `.dyn` source through the compiler (all diagnostics rendered against the
/// file), or a `.json` file holding a compiled `ModelIr` (`dynid compile --emit json`).
pub fn load_model(path: &Path) -> miette::Result<ModelIr> {
    if path.extension().is_some_and(|e| e == "json") {
        let text = std::fs::read_to_string(path)
            .into_diagnostic()
            .wrap_err_with(|| format!("cannot read the model `{}`", path.display()))?;
        let ir: ModelIr = serde_json::from_str(&text)
            .into_diagnostic()
            .wrap_err_with(|| format!("`{}` is not a compiled model (JSON IR)", path.display()))?;
        ir.check_invariants()
            .map_err(|e| miette!("`{}` is not a consistent model: {e}", path.display()))?;
        return Ok(ir);
    }
    Ok(dsl_parser::compile_file(path)?)
}

/// How the data files' columns are read; shared by every command that reads level CSVs.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct CsvArgs {
    /// Read column COLUMN as signal SIGNAL (repeatable), e.g. `--map disp=m1.x`.
    #[arg(long = "map", value_name = "COLUMN=SIGNAL")]
    pub map: Vec<String>,
    /// Sample interval in seconds (needed when the files have no `t` column).
    #[arg(long = "sample", value_name = "TS")]
    pub sample: Option<f64>,
}

impl CsvArgs {
    /// The reader options, with each `--map` checked against the model's signals.
    pub fn options(&self, ir: &ModelIr) -> miette::Result<CsvOptions> {
        let mut csv = CsvOptions {
            map: Vec::new(),
            ts: self.sample,
        };
        for spec in &self.map {
            csv.map.push(CsvOptions::parse_map(spec, ir)?);
        }
        Ok(csv)
    }
}

/// Fail before any work if `path` cannot be an output file: its directory must exist and
/// the path must not name a directory. (Writing can still fail later, e.g. on a full disk;
/// [`Staged`] then leaves nothing behind.)
pub fn check_output(path: &Path, what: &str) -> miette::Result<()> {
    let dir = parent_dir(path);
    if path.file_name().is_none() || path.is_dir() {
        return Err(miette!(
            help = "give the path of a file (it may be inside that directory)",
            "{what} `{}` is a directory, not a file",
            path.display()
        ));
    }
    if !dir.is_dir() {
        return Err(miette!(
            help = format!("create it first (`mkdir -p {}`)", dir.display()),
            "the directory of {what} `{}` does not exist",
            path.display()
        ));
    }
    Ok(())
}

/// [`check_output`] for every output a command was asked for.
pub fn check_outputs<'a>(
    outputs: impl IntoIterator<Item = (Option<&'a Path>, &'a str)>,
) -> miette::Result<()> {
    for (p, what) in outputs {
        if let Some(p) = p {
            check_output(p, what)?;
        }
    }
    Ok(())
}

pub use dynid::output::{parent_dir, write_atomically, Staged};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_checked_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let e = check_output(&dir.path().join("nope").join("r.html"), "the report")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the directory of the report") && e.contains("does not exist"),
            "{e}"
        );
        let e = check_output(dir.path(), "the report")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a directory"), "{e}");
        assert!(check_output(&dir.path().join("r.html"), "the report").is_ok());
    }
}
