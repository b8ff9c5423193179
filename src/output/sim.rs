//! The files of a simulation run: `DIR/level_k.csv` (or `DIR/driven.csv`) and
//! `DIR/truth.json`. A run owns its directory's run files: writing a run replaces the whole
//! set of an earlier one there (a stale `level_4.csv` of a 4-level run is removed when a
//! 3-level run replaces it), so a directory never mixes two runs. Other files are left
//! alone.

use super::{cleanup, create_dir, write_error, Staged};
use dsl_parser::ir::ModelIr;
use dynid_runtime::sim::{
    self, level_file_names, CsvSink, SampleSink, SimConfig, SimOutput, Truth,
};
use miette::IntoDiagnostic;
use std::path::{Path, PathBuf};

/// Whether a file name is one that a run writes: `truth.json`, `driven.csv`,
/// `level_<digits>.csv`.
fn is_run_file(name: &str) -> bool {
    name == "truth.json"
        || name == "driven.csv"
        || name
            .strip_prefix("level_")
            .and_then(|n| n.strip_suffix(".csv"))
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// The run files now in `dir` (sorted; none if it does not exist): what a new run there
/// replaces or removes.
pub fn run_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| !t.is_dir()))
        .filter(|e| e.file_name().to_str().is_some_and(is_run_file))
        .map(|e| dir.join(e.file_name()))
        .collect();
    files.sort();
    files
}

/// The run files of `dir` that a run writing `names` does not replace.
fn stale(dir: &Path, names: &[String]) -> Vec<PathBuf> {
    run_files(dir)
        .into_iter()
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_none_or(|n| !names.iter().any(|m| m == n))
        })
        .collect()
}

/// Bytes a CSV number takes on average, separator included: the files' bytes over their
/// rows × columns are 16.4–17.0 for `dynid simulate models/sdof_linear.dyn --duration
/// 20000 --burn-in 1 --out d` and 17.0–17.6 for `dynid simulate models/two_mass.dyn
/// --duration 100 --noise 0.05 --out d` (a quantised record is shorter). The estimate is
/// for refusing what clearly cannot fit; a run that fills the disk all the same leaves
/// nothing behind.
const BYTES_PER_NUMBER: u64 = 17;

/// An estimate of the bytes of `levels` CSV files of `rows` rows and `columns` columns
/// (the time column included).
pub fn csv_bytes(levels: usize, rows: u64, columns: usize) -> u64 {
    rows.saturating_mul(columns as u64)
        .saturating_mul(BYTES_PER_NUMBER)
        .saturating_mul(levels as u64)
}

/// One simulated level file being written: its CSV and, for the summary, the running mean
/// and variance of every column (Welford's update).
struct LevelFile {
    csv: CsvSink<std::io::BufWriter<std::fs::File>>,
    n: usize,
    mean: Vec<f64>,
    m2: Vec<f64>,
    /// The first write error (the simulator reports it in its own terms; the file's error
    /// names the file and a full disk).
    error: Option<std::io::Error>,
}

impl LevelFile {
    fn keep_error<T>(&mut self, r: std::io::Result<T>) -> std::io::Result<T> {
        if let Err(e) = &r {
            self.error
                .get_or_insert_with(|| std::io::Error::new(e.kind(), e.to_string()));
        }
        r
    }
}

impl SampleSink for LevelFile {
    fn begin(&mut self, names: &[String], ts: f64) -> std::io::Result<()> {
        self.mean = vec![0.0; names.len()];
        self.m2 = vec![0.0; names.len()];
        let r = self.csv.begin(names, ts);
        self.keep_error(r)
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
        let r = self.csv.push(cols, len);
        self.keep_error(r)
    }
}

/// A written level: its file, sample count and the std of each column.
pub struct LevelWritten {
    pub path: PathBuf,
    pub samples: usize,
    pub std: Vec<f64>,
}

/// Simulate `ir` under `cfg` straight into `DIR/level_k.csv` (streamed: memory does not
/// grow with the duration) and write `DIR/truth.json`, all or nothing, replacing an
/// earlier run in `DIR`; `DIR` is created if missing (and removed again, if it was created
/// and the run fails or is interrupted). The free space is checked first against an
/// estimate of the files' size. Returns what was simulated and the level files.
pub fn simulate_to_dir(
    ir: &ModelIr,
    cfg: &SimConfig,
    dir: &Path,
    progress: &(dyn Fn(u64) + Sync),
) -> miette::Result<(Truth, Vec<LevelWritten>)> {
    simulate_signal_to_dir(ir, cfg, None, dir, progress)
}

/// [`simulate_to_dir`] with the inputs driven by a multisine or sweep
/// ([`sim::simulate_signal_into`]).
pub fn simulate_signal_to_dir(
    ir: &ModelIr,
    cfg: &SimConfig,
    signal: Option<&sim::TestSignal>,
    dir: &Path,
    progress: &(dyn Fn(u64) + Sync),
) -> miette::Result<(Truth, Vec<LevelWritten>)> {
    let n = sim::level_count(ir, cfg)?;
    let rows = (cfg.duration / cfg.sample).ceil().max(0.0) as u64 + 1;
    let columns = ir.measured_signals().len() + 1 + usize::from(cfg.control.is_some());
    super::check_space(
        dir,
        csv_bytes(n, rows, columns),
        &format!("{n} level file(s)"),
    )?;
    let created = !dir.exists();
    create_dir(dir)?;
    let _registered = created.then(|| cleanup::register_dir(dir));
    let result = (|| {
        let names = level_file_names(n);
        let mut staged = Staged::new();
        staged.remove_on_commit(stale(
            dir,
            &[names.clone(), vec!["truth.json".into()]].concat(),
        ));
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
                error: None,
            });
        }
        let mut sinks: Vec<&mut dyn SampleSink> =
            files.iter_mut().map(|f| f as &mut dyn SampleSink).collect();
        let simulated = sim::simulate_signal_into(ir, cfg, signal, progress, &mut sinks);
        drop(sinks);
        if let Some((f, name)) = files
            .iter_mut()
            .zip(&names)
            .find(|(f, _)| f.error.is_some())
        {
            let e = f.error.take().expect("invariant: found with an error");
            return Err(write_error(&dir.join(name), e));
        }
        let mut truth = simulated?;
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

/// Stage `DIR/level_k.csv` for every level and `DIR/truth.json` (replacing an earlier run
/// in `DIR` when the set is committed). Returns the paths staged (truth.json last).
pub fn write_simulation(
    staged: &mut Staged,
    dir: &Path,
    out: &SimOutput,
) -> miette::Result<Vec<PathBuf>> {
    let names = level_file_names(out.records.len());
    let mut truth = out.truth.clone();
    truth.files = names.clone();
    staged.remove_on_commit(stale(
        dir,
        &[names.clone(), vec!["truth.json".into()]].concat(),
    ));
    let mut paths = Vec::with_capacity(names.len() + 1);
    for (name, rec) in names.iter().zip(&out.records) {
        let p = dir.join(name);
        super::stage_csv(staged, &p, rec)?;
        paths.push(p);
    }
    let json = serde_json::to_string_pretty(&truth).into_diagnostic()? + "\n";
    let p = dir.join("truth.json");
    staged.write(&p, json.as_bytes())?;
    paths.push(p);
    Ok(paths)
}

/// Stage `records` as `DIR/level_k.csv`, replacing an earlier run in `DIR` when the set is
/// committed.
pub fn stage_levels(
    staged: &mut Staged,
    dir: &Path,
    records: &[dynid_runtime::record::Record],
) -> miette::Result<()> {
    let names = level_file_names(records.len());
    staged.remove_on_commit(stale(dir, &names));
    for (name, rec) in names.iter().zip(records) {
        super::stage_csv(staged, &dir.join(name), rec)?;
    }
    Ok(())
}

/// Stage the files of a run driven by measured inputs: `DIR/driven.csv` and
/// `DIR/truth.json`, replacing an earlier run in `DIR` when the set is committed.
pub fn stage_driven(
    staged: &mut Staged,
    dir: &Path,
    response: &dynid_runtime::record::Record,
    truth_json: &str,
) -> miette::Result<()> {
    let names = ["driven.csv".to_string(), "truth.json".to_string()];
    staged.remove_on_commit(stale(dir, &names));
    super::stage_csv(staged, &dir.join(&names[0]), response)?;
    staged.write(&dir.join(&names[1]), truth_json.as_bytes())
}

/// The run files a run writing `new_names` into `dir` writes or removes: the new names and
/// the run files there now. Checked against the inputs before the work.
pub fn run_outputs(dir: &Path, new_names: &[String]) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = new_names.iter().map(|n| dir.join(n)).collect();
    out.extend(stale(dir, new_names));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_files_are_levels_driven_and_truth() {
        for n in ["truth.json", "driven.csv", "level_1.csv", "level_012.csv"] {
            assert!(is_run_file(n), "{n}");
        }
        for n in [
            "level_.csv",
            "level_1.json",
            "level_a.csv",
            "model.dyn",
            "truth.json.bak",
        ] {
            assert!(!is_run_file(n), "{n}");
        }
    }

    #[test]
    fn a_new_run_replaces_the_whole_earlier_set() {
        let dir = tempfile::tempdir().unwrap();
        for n in [
            "level_1.csv",
            "level_2.csv",
            "level_3.csv",
            "level_4.csv",
            "truth.json",
            "notes.txt",
        ] {
            std::fs::write(dir.path().join(n), "old").unwrap();
        }
        let rec = dynid_runtime::record::Record {
            names: vec!["u".into()],
            columns: vec![vec![1.0, 2.0]],
            ts: 0.1,
            t0: 0.0,
        };
        let mut staged = Staged::new();
        stage_levels(&mut staged, dir.path(), &[rec.clone(), rec]).unwrap();
        staged.commit().unwrap();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names, ["level_1.csv", "level_2.csv", "notes.txt"]);
    }
}
