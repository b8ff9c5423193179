//! Helpers shared by the subcommands.

use dsl_parser::ir::ModelIr;
use dynid_runtime::data::CutAt as RtCutAt;
use dynid_runtime::data::{read_record_within, CsvOptions, Split, SplitChoice};
use dynid_runtime::record::Record;
use miette::miette;
use std::path::{Path, PathBuf};

/// Load a model: `.dyn` source through the compiler (all diagnostics rendered against the
/// file), or a `.json` file holding a compiled `ModelIr` (`dynid compile --emit json`).
pub fn load_model(path: &Path) -> miette::Result<ModelIr> {
    if path.extension().is_some_and(|e| e == "json") {
        let text = read_json_model(path).map_err(|e| {
            miette!(
                code = "dynid::model::io",
                help = "check the path and the file permissions (a compiled model is UTF-8 JSON)",
                "cannot read the model `{}`: {e}",
                path.display()
            )
        })?;
        let ir: ModelIr = serde_json::from_str(&text).map_err(|e| {
            miette!(
                code = "dynid::model::json",
                help = "a `.json` model is the output of `dynid compile M.dyn --emit json`; give the `.dyn` file instead",
                "`{}` is not a compiled model (JSON IR): {e}",
                path.display()
            )
        })?;
        ir.check_invariants().map_err(|e| {
            miette!(
                code = "dynid::model::json",
                help = "write the model as .dyn and compile it (`dynid compile M.dyn --emit json`) instead of editing the JSON",
                "`{}` is not a consistent model: {e}",
                path.display()
            )
        })?;
        return Ok(ir);
    }
    Ok(dsl_parser::compile_file(path)?)
}

/// Largest compiled model (JSON IR) read: 64 MiB, hundreds of times the IR of a model with
/// hundreds of bodies; a bigger file is not a model and would be read whole into memory.
pub const MAX_JSON_MODEL: u64 = 64 << 20;

/// The text of a JSON model, read once and at most [`MAX_JSON_MODEL`] bytes of it.
fn read_json_model(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(MAX_JSON_MODEL + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > MAX_JSON_MODEL {
        return Err(std::io::Error::other(format!(
            "it holds more than {} MiB, which is not a compiled model",
            MAX_JSON_MODEL >> 20
        )));
    }
    Ok(text)
}

/// A count of at least one (clap value parser): `0` is refused, never read as 1.
pub fn at_least_one(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("{e}: give a whole number of at least 1")),
    }
}

/// The choices of the estimator that `identify` and `moments` share (a design made by
/// `moments --design-only` must be the one `identify` would make with the same flags).
#[derive(clap::Args, Debug, Default, Clone)]
pub struct EstimatorArgs {
    /// Identification filter corners in rad/s (default: the model's filter block, else
    /// designed from the data).
    #[arg(
        long = "filter-corners",
        value_delimiter = ',',
        value_name = "A,B,C",
        allow_hyphen_values = true
    )]
    pub filter_corners: Option<Vec<f64>>,
    /// Add virial / power-balance rows where velocities are measured (off by default).
    #[arg(long)]
    pub balance: bool,
    /// Leave the moments of nonlinear terms uncorrected for measurement noise (by default
    /// they are de-biased where the estimated noise is significant).
    #[arg(long = "no-noise-correction")]
    pub no_noise_correction: bool,
    /// Let the model's nonlinear columns (`sign(v)`, `s^3`, …) drive filter chains of their
    /// own, besides the chains of measured positions and inputs: their states are
    /// instruments that carry each column's own information (often smaller errors for
    /// damping and friction, see docs/method.md §2)
    #[arg(long = "column-chains")]
    pub column_chains: bool,
    /// Keep the rests in the moments: by default the intervals where a body with a
    /// `sign` of its own velocity stands still (speed below 1 % of its RMS for at least 50 ms)
    /// are left out, since its friction force is then anywhere in ±r and the model does
    /// not hold there (docs/method.md §7)
    #[arg(long = "keep-rests")]
    pub keep_rests: bool,
    /// Rows of the filtered equation: at one corner (given by --filter-corners, else the
    /// band where the measured signals stand above their noise floor, at most 0.5/Ts rad/s;
    /// with --input-delay on a chain of six sections unless the model's filter block gives
    /// an order, and at most 0.25/Ts on fewer)
    /// the equation passed through the low-pass chain is regressed on its own filtered
    /// terms, as moments; every slow passage of a body with a `sign` of its velocity (a rest
    /// or a reversal) is left out with what the filter remembers of it. On the simulated
    /// servo axis (48 seeds, bench `servo_precision`) it lowers the mass, friction and
    /// offset errors 2.3–31 fold against the defaults, but its damping carries a bias its standard error does not cover unless
    /// --input-delay takes up the force's path between samples (docs/method.md §2, "Rows of
    /// the filtered equation")
    #[arg(long = "filtered-equation")]
    pub filtered_equation: bool,
    /// Solve a second time with each level's rows weighted by their estimated covariance,
    /// shrunk halfway to its diagonal (two-step weighting), instead of each at unit norm. On
    /// a structure measured by accelerometers with noise on every channel it removes a
    /// large shrinkage of the masses and stiffnesses that unit-norm rows give (five bodies,
    /// 5 % noise: −47 % → −0.35 %), but its standard errors come out smaller than the
    /// spread they stand for, 2–10 times on smaller records; without the flag `identify`
    /// weights each row by its own estimated error alone on records of accelerations
    /// (docs/method.md §2, "Rows for accelerations")
    #[arg(long = "weighted-rows")]
    pub weighted_rows: bool,
    /// Estimate a delay of each measured input (force) against its record: one more
    /// unknown per input, `u.delay` in seconds, for a force that acts later than it is
    /// recorded or that changes between samples in a way a straight line between them does
    /// not follow (a current loop updated faster than the record). With
    /// --filtered-equation on the simulated servo axis it removes the damping bias that the
    /// standard errors do not cover, and a designed corner is also tried halved and
    /// quartered, keeping the one with the smallest standard errors (three passes over the
    /// data; docs/method.md §2, "The input between samples"). Not with `moments` or --from
    #[arg(long = "input-delay")]
    pub input_delay: bool,
    /// Keep the instrument rows, each at unit norm, where `identify` would choose others
    /// (and say so) when no other row, corner or noise flag is given: on a servo axis's
    /// kind of record — friction with a sign of a velocity, a measured force, velocities
    /// estimated from measured positions with no noise worth a correction — the rows of the
    /// filtered equation with the input's delay, 50–500 times more precise on random set
    /// points and about 3 times on planned moves of the simulated servo axis (bench
    /// `servo_precision`, docs/method.md §2); on records of measured accelerations, the
    /// rows each weighted by its own estimated error, which keep a many-body structure's
    /// masses and stiffnesses from shrinking by tens of per cent with the noise or the
    /// error of a joint's motion integrated from them (docs/method.md §2, "Rows for
    /// accelerations").
    /// `moments` always takes the instrument rows
    #[arg(long = "instrument-rows")]
    pub instrument_rows: bool,
}

impl EstimatorArgs {
    /// The library's options for these flags.
    pub fn options(&self, allow_large: bool) -> dynid_runtime::IdentifyOptions {
        dynid_runtime::IdentifyOptions {
            corners: self.filter_corners.clone(),
            balance: self.balance,
            noise_correction: !self.no_noise_correction,
            column_chains: self.column_chains,
            keep_rests: self.keep_rests,
            filtered: self.filtered_equation,
            efficient: self.weighted_rows,
            input_delay: self.input_delay,
            auto_rows: !self.instrument_rows,
            allow_large,
            ..Default::default()
        }
    }
}

/// How the data files' columns are read; shared by every command that reads level files
/// (CSV or other delimited text, MATLAB .mat, HDF5, Parquet: see docs/formats.md).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct CsvArgs {
    /// Read column (or variable) COLUMN as signal SIGNAL (repeatable), e.g. `--map disp=m1.x`.
    #[arg(long = "map", value_name = "COLUMN=SIGNAL")]
    pub map: Vec<String>,
    /// Sample interval in seconds (needed when the files have no `t` column).
    #[arg(long = "sample", value_name = "TS")]
    pub sample: Option<f64>,
    /// Text files: the character between fields, e.g. `;`, `|` or `tab` (default `,`).
    #[arg(long = "delimiter", value_name = "CHAR", value_parser = dynid_runtime::data::CsvOptions::parse_delimiter)]
    pub delimiter: Option<u8>,
    /// Text files: skip lines starting with CHAR (e.g. `#`), before the header and between
    /// samples.
    #[arg(long = "comment", value_name = "CHAR", value_parser = comment_char)]
    pub comment: Option<u8>,
    /// Text files: the line after the header holds units (e.g. `s,m,m/s,N`), not a sample.
    #[arg(long = "units-row")]
    pub units_row: bool,
}

/// A `--comment` character: one ASCII character that cannot start a number.
fn comment_char(s: &str) -> Result<u8, String> {
    match s.as_bytes() {
        [b] if b.is_ascii_punctuation() && !matches!(b, b'.' | b'-' | b'+' | b'"') => Ok(*b),
        _ => Err(format!(
            "`{s}` is not a comment character: give one such as `#`, `%` or `;`"
        )),
    }
}

impl CsvArgs {
    /// The reader options, with each `--map` checked against the model's signals.
    pub fn options(&self, ir: &ModelIr) -> miette::Result<CsvOptions> {
        let mut csv = CsvOptions {
            map: Vec::new(),
            ts: self.sample,
            delimiter: self.delimiter,
            comment: self.comment,
            skip_after_header: usize::from(self.units_row),
        };
        for spec in &self.map {
            csv.map.push(CsvOptions::parse_map(spec, ir)?);
        }
        Ok(csv)
    }
}

/// A count of at least two (clap value parser for `--segments`).
pub fn at_least_two(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n < 2 => Err("must be at least 2 (a split gives at least two levels)".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("{e}: give a whole number of at least 2")),
    }
}

/// Where one data file is cut (`--cut`).
#[derive(clap::ValueEnum, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum CutAt {
    /// At the cycles of a repeated trajectory when the record repeats with one amplitude,
    /// else by amplitude.
    #[default]
    Auto,
    /// At the cycles of a repeated trajectory (refused when the record does not repeat).
    Cycles,
    /// By the local amplitude of the response.
    Amplitude,
}

/// How one data file is cut into levels (`detect` and `diagnose`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct SplitArgs {
    /// With ONE data file: cut it into N contiguous segments, one level each [default: one
    /// per cycle of a repeated trajectory, else 3 by amplitude].
    #[arg(long, value_name = "N", value_parser = at_least_two)]
    pub segments: Option<usize>,
    /// With ONE data file: judge the amplitude by this signal [default: the first measured
    /// position of the model].
    #[arg(long = "split-by", value_name = "SIGNAL")]
    pub split_by: Option<String>,
    /// With ONE data file: cut at the cycles of a repeated trajectory (found by the
    /// autocorrelation of the model's references, the judged response, then its inputs),
    /// or by amplitude.
    #[arg(long = "cut", value_enum, default_value_t = CutAt::Auto, value_name = "AT")]
    pub cut: CutAt,
}

/// One data file cut into levels by [`SplitArgs`].
pub struct SplitLevels {
    /// One record per segment (by amplitude: quietest first; at cycles: in time order),
    /// each with all columns of the file.
    pub records: Vec<Record>,
    /// `file [t0–t1 s]` per segment.
    pub origins: Vec<String>,
    pub split: Split,
}

impl SplitArgs {
    /// The choices as the runtime takes them ([`SplitChoice`], shared with Python).
    pub fn choice(&self) -> SplitChoice {
        SplitChoice {
            segments: self.segments,
            split_by: self.split_by.clone(),
            cut: match self.cut {
                CutAt::Auto => RtCutAt::Auto,
                CutAt::Cycles => RtCutAt::Cycles,
                CutAt::Amplitude => RtCutAt::Amplitude,
            },
        }
    }

    /// With one data file, cut it into levels ([`SplitChoice::split`]) and print the
    /// segment table to stderr; with several, `None` (and an error when a split option was
    /// given). The file is read whole: above the memory limit it is refused before reading
    /// unless `allow_large`.
    pub fn levels(
        &self,
        ir: &ModelIr,
        data: &[PathBuf],
        csv: &CsvOptions,
        allow_large: bool,
    ) -> miette::Result<Option<SplitLevels>> {
        let choice = self.choice();
        if !choice.applies(data.len())? {
            return Ok(None);
        }
        let Some(path) = data.first() else {
            return Ok(None);
        };
        let origin = path.display().to_string();
        // The response is checked before the file is read.
        choice.response(ir, &origin)?;
        let record = read_record_within(path, csv, allow_large)?;
        let split = choice.split(ir, &record, &origin)?;
        eprint!("{origin}: {}", split.table());
        let origins = (0..split.segments.len())
            .map(|i| split.label(&origin, i))
            .collect();
        Ok(Some(SplitLevels {
            records: split.records(&record),
            origins,
            split,
        }))
    }
}

pub use dynid::output::check_output;

/// A command's input files: its model and its data files.
pub fn inputs<'a>(model: &'a Path, data: &'a [PathBuf]) -> impl Iterator<Item = &'a Path> {
    std::iter::once(model).chain(data.iter().map(PathBuf::as_path))
}

/// [`check_output`] for every output a command was asked for, and that no output is one
/// of the command's `inputs` or another output (after resolving links): an input is never
/// overwritten, and two outputs never claim one file.
pub fn check_outputs<'a>(
    outputs: impl IntoIterator<Item = (Option<&'a Path>, &'a str)>,
    inputs: impl IntoIterator<Item = &'a Path>,
) -> miette::Result<()> {
    let outputs: Vec<(&Path, &str)> = outputs
        .into_iter()
        .filter_map(|(p, what)| Some((p?, what)))
        .collect();
    for (p, what) in &outputs {
        check_output(p, what)?;
    }
    check_distinct(outputs, inputs)
}

/// That no output is one of `inputs` or another output (after resolving links and
/// relative spellings, also in directories that do not exist yet).
pub fn check_distinct<'a>(
    outputs: impl IntoIterator<Item = (&'a Path, &'a str)>,
    inputs: impl IntoIterator<Item = &'a Path>,
) -> miette::Result<()> {
    let inputs: Vec<(&Path, PathBuf)> = inputs.into_iter().map(|p| (p, resolve(p))).collect();
    let mut seen: Vec<(&Path, &str, PathBuf)> = Vec::new();
    for (p, what) in outputs {
        let r = resolve(p);
        let same = |other: &PathBuf| r == *other;
        if let Some((input, _)) = inputs.iter().find(|(_, ri)| same(ri)) {
            return Err(miette!(
                code = "dynid::output::is_input",
                help = "choose another path for the output; inputs are never overwritten",
                "{what} `{}` is the input file `{}`",
                p.display(),
                input.display()
            ));
        }
        if let Some((other, other_what, _)) = seen.iter().find(|(_, _, ro)| same(ro)) {
            return Err(miette!(
                code = "dynid::output::same_file",
                help = "give each output its own path",
                "{what} `{}` and {other_what} `{}` are the same file",
                p.display(),
                other.display()
            ));
        }
        // Two outputs may share a stream (`--json /dev/stdout --report /dev/stdout`).
        if matches!(
            dynid::output::target::target(p),
            dynid::output::Target::File(_)
        ) {
            seen.push((p, what, r));
        }
    }
    Ok(())
}

/// Check, before the work, an output directory that receives a run's files (`new_names`,
/// and the removal of an earlier run's there): it is or can become a writable directory,
/// and none of those files is one of the `inputs` or of the command's other `outputs`
/// (each with what it is, e.g. "the model").
pub fn check_run_dir<'a>(
    dir: &Path,
    flag: &str,
    new_names: &[String],
    inputs: impl IntoIterator<Item = (&'a Path, &'a str)>,
    outputs: impl IntoIterator<Item = (&'a Path, &'a str)>,
) -> miette::Result<()> {
    dynid::output::check_out_dir(dir, flag)?;
    let others: Vec<(&Path, &str, bool, PathBuf)> = inputs
        .into_iter()
        .map(|(p, what)| (p, what, true))
        .chain(outputs.into_iter().map(|(p, what)| (p, what, false)))
        .map(|(p, what, input)| (p, what, input, resolve(p)))
        .collect();
    for file in dynid::output::run_outputs(dir, new_names) {
        let r = resolve(&file);
        let Some((other, what, input, _)) = others.iter().find(|o| o.3 == r) else {
            continue;
        };
        let because = format!(
            "`{flag} {}` would replace `{}`, which is {what} `{}`",
            dir.display(),
            file.display(),
            other.display()
        );
        let run = format!(
            "a run writes its files into `{flag}` and removes the level_k.csv, driven.csv \
             and truth.json of an earlier run there"
        );
        return Err(if *input {
            miette!(
                code = "dynid::output::is_input",
                help = format!(
                    "{run}; an input is never overwritten: give another `{flag}` directory \
                     or move the file"
                ),
                "{because}"
            )
        } else {
            miette!(
                code = "dynid::output::same_file",
                help = format!("{run}: give {what} a path outside `{flag}`"),
                "{because}"
            )
        });
    }
    Ok(())
}

use dynid::output::resolve;
pub use dynid::output::{write_atomically, Staged};
