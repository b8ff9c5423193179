//! Helpers shared by the subcommands.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::CsvOptions;
use miette::{miette, IntoDiagnostic, WrapErr};
use std::path::{Path, PathBuf};

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

fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// A set of output files written all or nothing: each file goes to a temporary name beside
/// its target (keeping the extension, which some writers use to pick a format) and all are
/// renamed into place by [`Staged::commit`]. Dropping an uncommitted set removes its
/// temporary files, so an error never leaves a partial output behind.
#[derive(Default)]
pub struct Staged {
    files: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    pub fn new() -> Self {
        Self::default()
    }

    /// Reserve a temporary path for `target`; the caller writes it.
    pub fn temp_for(&mut self, target: &Path) -> miette::Result<PathBuf> {
        let name = target
            .file_name()
            .ok_or_else(|| miette!("`{}` is not a file name", target.display()))?
            .to_string_lossy();
        let ext = target
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let tmp = parent_dir(target).join(format!(
            ".{name}.{}.{}.tmp{ext}",
            std::process::id(),
            self.files.len()
        ));
        self.files.push((tmp.clone(), target.to_path_buf()));
        Ok(tmp)
    }

    /// Stage `bytes` as the content of `target`.
    pub fn write(&mut self, target: &Path, bytes: &[u8]) -> miette::Result<()> {
        let tmp = self.temp_for(target)?;
        std::fs::write(&tmp, bytes)
            .into_diagnostic()
            .wrap_err_with(|| format!("cannot write `{}`", target.display()))
    }

    /// Move every staged file to its target.
    pub fn commit(mut self) -> miette::Result<()> {
        let files = std::mem::take(&mut self.files);
        for (k, (tmp, target)) in files.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, target) {
                for (t, _) in &files[k..] {
                    let _ = std::fs::remove_file(t);
                }
                return Err(e)
                    .into_diagnostic()
                    .wrap_err_with(|| format!("cannot write `{}`", target.display()));
            }
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (tmp, _) in &self.files {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Write one file all or nothing.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> miette::Result<()> {
    let mut staged = Staged::new();
    staged.write(path, bytes)?;
    staged.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_set_leaves_no_file_behind() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("a.json");
        let mut staged = Staged::new();
        staged.write(&good, b"{}").unwrap();
        let bad = dir.path().join("missing").join("b.json");
        assert!(staged.write(&bad, b"{}").is_err());
        drop(staged);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_committed_set_is_in_place_without_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let mut staged = Staged::new();
        for n in ["a.json", "b.svg"] {
            staged.write(&dir.path().join(n), n.as_bytes()).unwrap();
        }
        staged.commit().unwrap();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["a.json", "b.svg"]);
        assert_eq!(std::fs::read(dir.path().join("b.svg")).unwrap(), b"b.svg");
    }

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
