//! Writing output files, all or nothing. The numerics format (into any `io::Write`); only
//! this crate opens files.
//!
//! [`Staged`] is the one atomic writer: every file of a command goes to a temporary file
//! beside its target (`tempfile`, keeping the extension, which some writers use to pick a
//! format) and all are moved into place by [`Staged::commit`]. Dropping an uncommitted set
//! deletes its temporaries, so an error never leaves a partial output behind.

use dsl_parser::ir::ModelIr;
use dynid_runtime::record::Record;
use dynid_runtime::sim::{
    self, level_file_names, write_csv, CsvSink, SampleSink, SimConfig, SimOutput, Truth,
};
use miette::{miette, IntoDiagnostic};
use std::io::Write;
use std::path::{Path, PathBuf};
use tempfile::TempPath;

/// A set of output files written all or nothing.
#[derive(Default)]
pub struct Staged {
    files: Vec<(TempPath, PathBuf)>,
}

/// The directory a file is written in (`.` for a bare file name).
pub fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

impl Staged {
    pub fn new() -> Self {
        Self::default()
    }

    /// Create the (empty) temporary file for `target` and return its path; the caller
    /// writes it.
    pub fn temp_for(&mut self, target: &Path) -> miette::Result<PathBuf> {
        let name = target
            .file_name()
            .ok_or_else(|| {
                miette!(
                    code = "dynid::output::is_directory",
                    help = "give the path of a file",
                    "`{}` is not a file name",
                    target.display()
                )
            })?
            .to_string_lossy();
        let ext = target
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let file = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(&format!(".tmp{ext}"))
            .tempfile_in(parent_dir(target))
            .map_err(|e| write_error(target, e))?;
        let path = file.into_temp_path();
        let p = path.to_path_buf();
        self.files.push((path, target.to_path_buf()));
        Ok(p)
    }

    /// Stage `bytes` as the content of `target`.
    pub fn write(&mut self, target: &Path, bytes: &[u8]) -> miette::Result<()> {
        self.write_with(target, |w| w.write_all(bytes))
    }

    /// Stage the content of `target` as written by `fill` (buffered).
    pub fn write_with(
        &mut self,
        target: &Path,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> miette::Result<()> {
        let tmp = self.temp_for(target)?;
        (|| {
            let file = std::fs::File::create(&tmp)?;
            let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
            fill(&mut w)?;
            w.into_inner().map_err(|e| e.into_error())?.sync_all()
        })()
        .map_err(|e| write_error(target, e))
    }

    /// Move every staged file to its target. If one move fails, the files not yet moved
    /// are deleted (those already moved stay: a rename cannot be undone).
    pub fn commit(mut self) -> miette::Result<()> {
        for (tmp, target) in std::mem::take(&mut self.files) {
            tmp.persist(&target)
                .map_err(|e| write_error(&target, e.error))?;
        }
        Ok(())
    }
}

fn write_error(target: &Path, e: std::io::Error) -> miette::Report {
    miette!(
        code = "dynid::output::write",
        help = "check the permissions and the free space where it goes; nothing was written",
        "cannot write `{}`: {e}",
        target.display()
    )
}

/// Write one file all or nothing.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> miette::Result<()> {
    let mut staged = Staged::new();
    staged.write(path, bytes)?;
    staged.commit()
}

/// Stage `record` as a CSV file (header `t,<signals>`, numbers in shortest round-trip form).
pub fn stage_csv(staged: &mut Staged, path: &Path, record: &Record) -> miette::Result<()> {
    staged.write_with(path, |w| write_csv(w, record))
}

/// Create an output directory (and its parents) if missing.
pub fn create_dir(dir: &Path) -> miette::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        miette!(
            code = "dynid::output::write",
            help = "check the permissions and the free space where it goes",
            "cannot create the output directory `{}`: {e}",
            dir.display()
        )
    })
}

/// One simulated level file being written: its CSV and, for the summary, the running mean
/// and variance of every column (Welford's update).
struct LevelFile {
    csv: CsvSink<std::io::BufWriter<std::fs::File>>,
    n: usize,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl SampleSink for LevelFile {
    fn begin(&mut self, names: &[String], ts: f64) -> std::io::Result<()> {
        self.mean = vec![0.0; names.len()];
        self.m2 = vec![0.0; names.len()];
        self.csv.begin(names, ts)
    }
    fn push(&mut self, cols: &[&[f64]], len: usize) -> std::io::Result<()> {
        for (j, c) in cols.iter().enumerate() {
            let (mut n, mut mean, mut m2) = (self.n as f64, self.mean[j], self.m2[j]);
            for &x in &c[..len] {
                n += 1.0;
                let d = x - mean;
                mean += d / n;
                m2 += d * (x - mean);
            }
            (self.mean[j], self.m2[j]) = (mean, m2);
        }
        self.n += len;
        self.csv.push(cols, len)
    }
}

/// A written level: its file, sample count and the std of each column.
pub struct LevelWritten {
    pub path: PathBuf,
    pub samples: usize,
    pub std: Vec<f64>,
}

/// Simulate `ir` under `cfg` straight into `DIR/level_k.csv` (streamed: memory does not
/// grow with the duration) and write `DIR/truth.json`, all or nothing; `DIR` is created if
/// missing (and removed again, if it was created and the run fails). Returns what was
/// simulated and the level files.
pub fn simulate_to_dir(
    ir: &ModelIr,
    cfg: &SimConfig,
    dir: &Path,
    progress: &(dyn Fn(u64) + Sync),
) -> miette::Result<(Truth, Vec<LevelWritten>)> {
    let n = sim::level_count(ir, cfg)?;
    let created = !dir.exists();
    create_dir(dir)?;
    let result = (|| {
        let names = level_file_names(n);
        let mut staged = Staged::new();
        let mut files = Vec::with_capacity(n);
        for name in &names {
            let target = dir.join(name);
            let tmp = staged.temp_for(&target)?;
            let f = std::fs::File::create(&tmp).map_err(|e| write_error(&target, e))?;
            files.push(LevelFile {
                csv: CsvSink::new(std::io::BufWriter::with_capacity(1 << 16, f)),
                n: 0,
                mean: Vec::new(),
                m2: Vec::new(),
            });
        }
        let mut sinks: Vec<&mut dyn SampleSink> =
            files.iter_mut().map(|f| f as &mut dyn SampleSink).collect();
        let mut truth = sim::simulate_into(ir, cfg, progress, &mut sinks)?;
        let mut written = Vec::with_capacity(n);
        for (f, name) in files.into_iter().zip(&names) {
            let target = dir.join(name);
            f.csv
                .into_inner()
                .into_inner()
                .map_err(|e| e.into_error())
                .and_then(|file| file.sync_all())
                .map_err(|e| write_error(&target, e))?;
            written.push(LevelWritten {
                path: target,
                samples: f.n,
                std: f
                    .m2
                    .iter()
                    .map(|m2| {
                        if f.n > 0 {
                            (m2 / f.n as f64).sqrt()
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            });
        }
        truth.files = names;
        let json = serde_json::to_string_pretty(&truth).into_diagnostic()? + "\n";
        staged.write(&dir.join("truth.json"), json.as_bytes())?;
        staged.commit()?;
        Ok::<_, miette::Report>((truth, written))
    })();
    if result.is_err() && created {
        let _ = std::fs::remove_dir(dir);
    }
    result
}

/// Write `DIR/level_k.csv` for every level and `DIR/truth.json`, all or nothing. Returns
/// the paths written (truth.json last).
pub fn write_simulation(dir: &Path, out: &SimOutput) -> miette::Result<Vec<PathBuf>> {
    let names = level_file_names(out.records.len());
    let mut truth = out.truth.clone();
    truth.files = names.clone();
    let mut staged = Staged::new();
    let mut paths = Vec::with_capacity(names.len() + 1);
    for (name, rec) in names.iter().zip(&out.records) {
        let p = dir.join(name);
        stage_csv(&mut staged, &p, rec)?;
        paths.push(p);
    }
    let json = serde_json::to_string_pretty(&truth).into_diagnostic()? + "\n";
    let p = dir.join("truth.json");
    staged.write(&p, json.as_bytes())?;
    paths.push(p);
    staged.commit()?;
    Ok(paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut n: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        n.sort();
        n
    }

    #[test]
    fn a_failed_set_leaves_no_file_behind() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("a.json");
        let mut staged = Staged::new();
        staged.write(&good, b"{}").unwrap();
        let bad = dir.path().join("missing").join("b.json");
        assert!(staged.write(&bad, b"{}").is_err());
        drop(staged);
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn a_committed_set_is_in_place_without_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let mut staged = Staged::new();
        for n in ["a.json", "b.svg"] {
            staged.write(&dir.path().join(n), n.as_bytes()).unwrap();
        }
        staged.commit().unwrap();
        assert_eq!(names(dir.path()), ["a.json", "b.svg"]);
        let b = std::fs::read_to_string(dir.path().join("b.svg")).unwrap();
        assert_eq!(b, "b.svg");
    }

    #[test]
    fn a_temporary_keeps_the_extension() {
        let dir = tempfile::tempdir().unwrap();
        let mut staged = Staged::new();
        let tmp = staged.temp_for(&dir.path().join("curves.png")).unwrap();
        assert_eq!(tmp.extension().unwrap(), "png");
        assert!(tmp.exists());
        drop(staged);
        assert!(!tmp.exists());
    }

    #[test]
    fn csv_has_header_time_and_exact_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv");
        let rec = Record {
            names: vec!["m1.x".into(), "u".into()],
            columns: vec![vec![0.1, 1.0 / 3.0], vec![-2.0, 1e-9]],
            ts: 0.01,
            t0: 0.0,
        };
        let mut staged = Staged::new();
        stage_csv(&mut staged, &path, &rec).unwrap();
        staged.commit().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t,m1.x,u");
        assert_eq!(lines[1], "0.00,0.1,-2");
        let row: Vec<f64> = lines[2].split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(row, [0.01, 1.0 / 3.0, 1e-9]);
        assert_eq!(names(dir.path()), ["a.csv"]);
    }
}
