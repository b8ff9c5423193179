//! `dynid._dynid`: the native half of the Python package `dynid`.
//!
//! A thin layer over the same crates as the `dynid` command line: models are compiled by
//! `dsl-parser`, and simulation, identification, detection and diagnosis are the runtime's
//! functions. The Python half (`dynid/__init__.py`) turns DataFrames and dicts into the
//! level tuples taken here and wraps the JSON results in small classes.
//!
//! Data cross over without a copy where NumPy's layout allows: each column arrives as a
//! contiguous `float64` array and is streamed by [`ArraySource`] straight from NumPy's
//! buffer (diagnosis alone copies the records, as the command line does, because its free
//! runs hold whole trajectories). The interpreter lock is released while the runtime works.
//!
//! Errors become the exceptions of `dynid.errors`: `CompileError` (with the rendered
//! diagnostic, line and column), `DataError` (a `ValueError` naming the level, column and
//! sample) and `DynidError` for everything else, each with the runtime's code and help.

use dynid::dsl_parser::{
    self,
    ir::{ModelIr, SignalKind},
    CompileErrors,
};
use dynid::runtime::data::{
    read_record_within, CsvOptions, CutAt, DataError as RtDataError, FileSource, LevelSource,
    RecordSource, Split, SplitChoice, MIN_SAMPLES,
};
use dynid::runtime::detect::{detect_from_data, levels_too_alike, DetectOptions};
use dynid::runtime::diagnose::{self as rt_diagnose, DiagnoseOptions};
use dynid::runtime::ident::print::format_equations;
use dynid::runtime::record::Record;
use dynid::runtime::refine::{self as rt_refine, RefineOptions};
use dynid::runtime::sim::{self, SimConfig, Start, DEFAULT_SUBSTEPS};
use dynid::runtime::{identify, IdentifyError, IdentifyOptions};
use dynid::schema::{self, RefineReport};
use miette::Diagnostic;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::BoundObject;
use std::path::{Path, PathBuf};

/// Relative tolerance on the time step of a `t` column (as for CSV files).
const TIME_TOL: f64 = 1e-3;

/// An exception of `dynid.errors` with `message` and the given attributes.
fn raise(py: Python<'_>, class: &str, message: String, attrs: Vec<(&str, Py<PyAny>)>) -> PyErr {
    let build = || -> PyResult<PyErr> {
        let cls = py.import("dynid.errors")?.getattr(class)?;
        let exc = cls.call1((message.clone(),))?;
        for (k, v) in attrs {
            exc.setattr(k, v)?;
        }
        Ok(PyErr::from_value(exc))
    };
    build().unwrap_or_else(|e| e)
}

/// Run one call into the runtime, turning a panic into `DynidError` (code
/// `dynid::internal`) with its message: Python code catching `Exception` must see every
/// failure, and a `pyo3_runtime.PanicException` is not an `Exception`.
fn guarded<T>(py: Python<'_>, call: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(call)) {
        Ok(r) => r,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".into());
            let help = "this is a bug in dynid, not in your data or model: please report it \
                        with the model and data that caused it";
            Err(raise_located(
                py,
                "DynidError",
                format!("internal error: {what}"),
                help,
                "dynid::internal",
                None,
                None,
                None,
            ))
        }
    }
}

fn obj<'py, T: IntoPyObject<'py>>(py: Python<'py>, v: T) -> Py<PyAny> {
    match v.into_pyobject(py) {
        Ok(b) => b.into_any().unbind(),
        Err(_) => py.None(),
    }
}

/// The level number in a label `level N`, if it is one.
fn level_of(origin: &str) -> Option<usize> {
    origin
        .strip_prefix("level ")?
        .split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

/// A runtime error as a Python exception: `DataError` (a `ValueError`) for problems with
/// the data (codes `dynid::data::…`), `DynidError` otherwise; the message carries the help
/// line and the code, as the command line prints them.
fn runtime_error(py: Python<'_>, e: &dyn Diagnostic) -> PyErr {
    runtime_error_at(py, e, None, None, None)
}

fn runtime_error_at(
    py: Python<'_>,
    e: &dyn Diagnostic,
    level: Option<usize>,
    column: Option<String>,
    sample: Option<usize>,
) -> PyErr {
    let code = e.code().map(|c| c.to_string()).unwrap_or_default();
    let help = e.help().map(|h| h.to_string()).unwrap_or_default();
    let text = e.to_string();
    let level = level.or_else(|| level_of(&text));
    let class = error_class(&code);
    raise_located(
        py,
        class,
        text,
        &help,
        &code,
        level,
        column.as_deref(),
        sample,
    )
}

/// The exception of `dynid.errors` for a runtime error's code: `DataError` for the data
/// (and the inputs a simulation is driven by), `ParameterError` for parameter values,
/// `OptionError` for settings of a call (all three are `ValueError`s), `DynidError` for
/// the rest (a model the method cannot handle, a run that failed).
fn error_class(code: &str) -> &'static str {
    if code.starts_with("dynid::data::")
        || (code.starts_with("dynid::split::")
            && !matches!(
                code,
                "dynid::split::segments" | "dynid::split::several_files" | "dynid::split::cut"
            ))
        || matches!(
            code,
            "dynid::sim::missing_input"
                | "dynid::sim::bad_input_data"
                | "dynid::refine::column"
                | "dynid::refine::record"
        )
    {
        "DataError"
    } else if matches!(code, "dynid::sim::no_nominal" | "dynid::refine::start") {
        "ParameterError"
    } else if code.ends_with("::option")
        || matches!(
            code,
            "dynid::split::segments" | "dynid::split::several_files" | "dynid::split::cut"
        )
        || matches!(
            code,
            "dynid::sim::config"
                | "dynid::sim::too_long"
                | "dynid::refine::weight"
                | "dynid::refine::segment"
        )
    {
        "OptionError"
    } else {
        "DynidError"
    }
}

/// Raise `class` with the message followed by its help line and code (each when given), as
/// the command line prints them, and the attributes `code`, `help`, `level`, `column`,
/// `sample`.
#[allow(clippy::too_many_arguments)]
fn raise_located(
    py: Python<'_>,
    class: &str,
    mut message: String,
    help: &str,
    code: &str,
    level: Option<usize>,
    column: Option<&str>,
    sample: Option<usize>,
) -> PyErr {
    let help = &pythonic(help);
    if !help.is_empty() {
        message.push_str(&format!("\n  help: {help}"));
    }
    if !code.is_empty() {
        message.push_str(&format!("\n  [{code}]"));
    }
    raise(
        py,
        class,
        message,
        vec![
            ("code", obj(py, code)),
            ("help", obj(py, help)),
            ("level", obj(py, level)),
            ("column", obj(py, column)),
            ("sample", obj(py, sample)),
        ],
    )
}

/// A help line of the runtime with the command line's flags spelled as this package's
/// keyword arguments (`--allow-large` is `allow_large=True`, `--segments 2` is
/// `segments=2`), so that the advice can be followed as written.
fn pythonic(help: &str) -> String {
    help.replace("`--allow-large`", "`allow_large=True`")
        .replace("`--filter-corners`", "`filter_corners=[...]`")
        .replace("`--segments N`", "`segments=N`")
        .replace("`--segments ", "`segments=")
        .replace("`--split-by SIGNAL`", "`split_by=\"SIGNAL\"`")
        .replace("`--cut amplitude`", "`cut=\"amplitude\"`")
}

/// An identification error; an outlier names its column and sample.
fn identify_error(py: Python<'_>, e: &IdentifyError) -> PyErr {
    match e {
        // Samples count from 1 in Python's errors, as in the messages.
        IdentifyError::Outlier { sample, column, .. } => {
            runtime_error_at(py, e, None, Some(column.clone()), Some(sample + 1))
        }
        _ => runtime_error(py, e),
    }
}

/// A data problem found here, before the runtime sees the level.
fn data_error(
    py: Python<'_>,
    level: usize,
    column: Option<&str>,
    sample: Option<usize>,
    message: String,
    help: &str,
    code: &str,
) -> PyErr {
    raise_located(
        py,
        "DataError",
        message,
        help,
        code,
        Some(level),
        column,
        sample,
    )
}

/// Line and column (1-based, in characters) of byte offset `at` in `src`.
fn line_column(src: &str, at: usize) -> (usize, usize) {
    let at = (0..=at.min(src.len()))
        .rev()
        .find(|&i| src.is_char_boundary(i))
        .unwrap_or(0);
    let before = &src[..at];
    let line = before.matches('\n').count() + 1;
    let column = before[before.rfind('\n').map_or(0, |i| i + 1)..]
        .chars()
        .count()
        + 1;
    (line, column)
}

/// Compile errors as `CompileError`: the rendered diagnostics (all of them), and the code,
/// message, help, line and column of the first.
fn compile_error(py: Python<'_>, e: &CompileErrors, src: &str) -> PyErr {
    let rendered = e.render_plain(100);
    let mut errors = Vec::new();
    for err in &e.errors {
        let d = PyDict::new(py);
        let (line, column) = match err.span() {
            Some(s) => {
                let (l, c) = line_column(src, s.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        let items: [(&str, Py<PyAny>); 5] = [
            ("code", obj(py, err.kind().code())),
            ("message", obj(py, err.message())),
            ("help", obj(py, err.help_text())),
            ("line", obj(py, line)),
            ("column", obj(py, column)),
        ];
        for (k, v) in items {
            if let Err(e) = d.set_item(k, v) {
                return e;
            }
        }
        errors.push(d.into_any().unbind());
    }
    let first = |k: &str| -> Py<PyAny> {
        errors
            .first()
            .and_then(|d| d.bind(py).get_item(k).ok())
            .map_or_else(|| py.None(), |v| v.unbind())
    };
    let attrs = vec![
        ("rendered", obj(py, rendered.clone())),
        ("line", first("line")),
        ("column", first("column")),
        ("code", first("code")),
        ("help", first("help")),
        ("errors", obj(py, errors)),
    ];
    raise(py, "CompileError", rendered, attrs)
}

/// A compiled model (the IR), immutable.
#[pyclass(module = "dynid._dynid", frozen)]
struct CompiledModel {
    ir: ModelIr,
}

/// One level as the Python half hands it over: label, names, columns (contiguous
/// `float64`), an optional time column and an optional sample interval.
type LevelArg<'py> = (
    String,
    Vec<String>,
    Vec<PyReadonlyArray1<'py, f64>>,
    Option<PyReadonlyArray1<'py, f64>>,
    Option<f64>,
);

/// One simulated level: signal names, columns, sample interval, start time.
type SimLevel<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>, f64, f64);

/// A detection: JSON, the table, warnings and `(element, verdict)` in words.
type DetectOut = (String, String, Vec<String>, Vec<(String, String)>);

/// A level streamed from NumPy's buffers (no copy).
struct ArraySource<'a> {
    origin: String,
    ts: f64,
    /// By signal index: the column of a measured signal, `None` for the others.
    cols: Vec<Option<&'a [f64]>>,
    n: usize,
}

impl LevelSource for ArraySource<'_> {
    fn origin(&self) -> String {
        self.origin.clone()
    }
    fn ts(&self) -> f64 {
        self.ts
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), RtDataError> {
        let mut start = 0;
        let mut cols: Vec<&[f64]> = vec![&[]; self.cols.len()];
        while start < self.n {
            let len = max_len.max(1).min(self.n - start);
            for (out, c) in cols.iter_mut().zip(&self.cols) {
                *out = match c {
                    Some(c) => &c[start..start + len],
                    None => &[],
                };
            }
            sink(&cols, len);
            start += len;
        }
        Ok(())
    }
}

fn fmt_t(t: f64) -> String {
    dsl_parser::num::sig(t, 9, false)
}

/// One level as the Python half hands it over: a data file (path, `(column, signal)`
/// renamings, sample interval) or arrays ([`LevelArg`]).
#[derive(FromPyObject)]
enum LevelIn<'py> {
    File(PathBuf, Vec<(String, String)>, Option<f64>),
    Arrays(LevelArg<'py>),
}

/// A bound level: a data file read in chunks, or NumPy's buffers.
type Source<'a> = Box<dyn LevelSource + 'a>;

/// Bind every level: files are opened as the command line opens them (header matched to
/// the measured signals, sample interval fixed), arrays are checked by [`bind_arrays`].
fn bind<'a>(py: Python<'_>, ir: &ModelIr, levels: &'a [LevelIn<'_>]) -> PyResult<Vec<Source<'a>>> {
    Ok(bind_held(py, ir, levels)?.0)
}

/// [`bind`], with the memory (bytes) the levels' measured columns take when read whole:
/// estimated from a file's size, counted for arrays (diagnosis copies them).
fn bind_held<'a>(
    py: Python<'_>,
    ir: &ModelIr,
    levels: &'a [LevelIn<'_>],
) -> PyResult<(Vec<Source<'a>>, f64)> {
    let mut out: Vec<Source<'a>> = Vec::with_capacity(levels.len());
    let mut held = 0.0;
    for (i, level) in levels.iter().enumerate() {
        match level {
            LevelIn::File(path, map, ts) => {
                let opts = file_options(py, ir, i, map, *ts)?;
                // Any format the command line reads (text, MAT, HDF5, Parquet; by content).
                let src = FileSource::open(path, ir, &opts)
                    .map_err(|e| runtime_error_at(py, &e, Some(i + 1), None, None))?;
                held += src.whole_bytes();
                out.push(Box::new(src));
            }
            LevelIn::Arrays(arg) => {
                let src = bind_arrays(py, ir, i, arg)?;
                held += (src.n * ir.measured_signals().len() * 8) as f64;
                out.push(Box::new(src));
            }
        }
    }
    Ok((out, held))
}

/// The reader options of level `i` (0-based), each renaming checked against the model.
fn file_options(
    py: Python<'_>,
    ir: &ModelIr,
    i: usize,
    map: &[(String, String)],
    ts: Option<f64>,
) -> PyResult<CsvOptions> {
    let mut opts = CsvOptions {
        ts,
        ..CsvOptions::default()
    };
    for (c, sig) in map {
        let pair = CsvOptions::parse_map(&format!("{c}={sig}"), ir)
            .map_err(|e| runtime_error_at(py, &e, Some(i + 1), Some(c.clone()), None))?;
        opts.map.push(pair);
    }
    Ok(opts)
}

/// How one record is cut into levels, from the keyword arguments `segments`, `split_by`
/// and `cut` (`"auto"`, `"cycles"` or `"amplitude"`).
fn split_choice(
    py: Python<'_>,
    segments: Option<usize>,
    split_by: Option<String>,
    cut: &str,
) -> PyResult<SplitChoice> {
    let cut = CutAt::parse(cut).ok_or_else(|| {
        option_error(
            py,
            format!("cut = {cut:?} is not a place to cut"),
            "give cut=\"auto\" (cycles of a repeated trajectory, else by amplitude), \
             \"cycles\" or \"amplitude\"",
            "dynid::split::cut",
        )
    })?;
    Ok(SplitChoice {
        segments,
        split_by,
        cut,
    })
}

/// One record cut into levels: the split, the segments' records (all columns) and their
/// labels (`origin [t0–t1 s]`).
type SplitLevels = (Split, Vec<Record>, Vec<String>);

/// With one level, cut it into levels as the command line cuts one file
/// ([`SplitChoice::split`]); with several, `None` (an error when a split option was
/// given). A file is read whole, refused above the memory limit unless `allow_large`; an
/// array level is taken with all its columns (a `t` column sets the start time).
fn split_levels(
    py: Python<'_>,
    ir: &ModelIr,
    levels: &[LevelIn<'_>],
    choice: &SplitChoice,
    allow_large: bool,
) -> PyResult<Option<SplitLevels>> {
    if !choice
        .applies(levels.len())
        .map_err(|e| runtime_error(py, &e))?
    {
        return Ok(None);
    }
    let Some(level) = levels.first() else {
        return Ok(None);
    };
    let (record, origin) = match level {
        LevelIn::File(path, map, ts) => {
            let origin = path.display().to_string();
            choice
                .response(ir, &origin)
                .map_err(|e| runtime_error(py, &e))?;
            let opts = file_options(py, ir, 0, map, *ts)?;
            let rec = read_record_within(path, &opts, allow_large)
                .map_err(|e| runtime_error_at(py, &e, Some(1), None, None))?;
            (rec, origin)
        }
        LevelIn::Arrays(arg) => {
            // The checks of a level (measured columns, time, finite values) first.
            let src = bind_arrays(py, ir, 0, arg)?;
            let (label, names, arrays, t, _) = arg;
            choice
                .response(ir, label)
                .map_err(|e| runtime_error(py, &e))?;
            let mut columns = Vec::with_capacity(arrays.len());
            for a in arrays {
                columns.push(a.as_array().iter().copied().collect::<Vec<f64>>());
            }
            let t0 = t
                .as_ref()
                .and_then(|t| t.as_array().iter().next().copied())
                .unwrap_or(0.0);
            let rec = Record {
                names: names.clone(),
                columns,
                ts: src.ts,
                t0,
            };
            (rec, label.clone())
        }
    };
    // (The error boxed: it is large, and crosses the detached closure's boundary.)
    let split = py
        .detach(|| choice.split(ir, &record, &origin).map_err(Box::new))
        .map_err(|e| runtime_error(py, &*e))?;
    let labels = (0..split.segments.len())
        .map(|i| split.label(&origin, i))
        .collect();
    let records = split.records(&record);
    Ok(Some((split, records, labels)))
}

/// The segments' records as levels (the model's measured columns checked as a file's).
fn segment_sources<'a>(
    py: Python<'_>,
    ir: &ModelIr,
    records: &'a [Record],
    labels: &[String],
) -> PyResult<Vec<Source<'a>>> {
    let mut out: Vec<Source<'a>> = Vec::with_capacity(records.len());
    for (i, (r, o)) in records.iter().zip(labels).enumerate() {
        let src = RecordSource::new(r, ir, o.clone())
            .map_err(|e| runtime_error_at(py, &e, Some(i + 1), None, None))?;
        out.push(Box::new(src));
    }
    Ok(out)
}

/// The levels as `&dyn LevelSource`.
fn refs<'a>(sources: &'a [Source<'_>]) -> Vec<&'a dyn LevelSource> {
    sources
        .iter()
        .map(|s| s.as_ref() as &dyn LevelSource)
        .collect()
}

/// Check one level of arrays against the model and bind it as an [`ArraySource`]: every
/// measured signal present, columns of one length, finite values, a uniform time column or
/// a positive sample interval, enough samples.
fn bind_arrays<'a>(
    py: Python<'_>,
    ir: &ModelIr,
    i: usize,
    (label, names, arrays, t, ts): &'a LevelArg<'_>,
) -> PyResult<ArraySource<'a>> {
    {
        let level = i + 1;
        let mut slices: Vec<&[f64]> = Vec::with_capacity(arrays.len());
        for (name, a) in names.iter().zip(arrays) {
            slices.push(a.as_slice().map_err(|_| {
                data_error(
                    py,
                    level,
                    Some(name),
                    None,
                    format!("{label}, column `{name}`: the array is not contiguous"),
                    "pass a contiguous float64 array (numpy.ascontiguousarray)",
                    "dynid::data::layout",
                )
            })?);
        }
        let n = slices.first().map_or(0, |s| s.len());
        for (name, s) in names.iter().zip(&slices) {
            if s.len() != n {
                return Err(data_error(
                    py,
                    level,
                    Some(name),
                    None,
                    format!(
                        "{label}, column `{name}`: {} samples, but `{}` has {n}",
                        s.len(),
                        names[0]
                    ),
                    "all columns of a level must have the same length",
                    "dynid::data::ragged_record",
                ));
            }
        }
        let t = match t {
            Some(a) => Some(a.as_slice().map_err(|_| {
                data_error(
                    py,
                    level,
                    Some("t"),
                    None,
                    format!("{label}, column `t`: the array is not contiguous"),
                    "pass a contiguous float64 array (numpy.ascontiguousarray)",
                    "dynid::data::layout",
                )
            })?),
            None => None,
        };
        if let Some(t) = t {
            if t.len() != n {
                return Err(data_error(
                    py,
                    level,
                    Some("t"),
                    None,
                    format!(
                        "{label}, column `t`: {} samples, but the signals have {n}",
                        t.len()
                    ),
                    "all columns of a level must have the same length",
                    "dynid::data::ragged_record",
                ));
            }
        }
        let check_finite = |name: &str, s: &[f64]| -> PyResult<()> {
            if let Some(k) = s.iter().position(|v| !v.is_finite()) {
                return Err(data_error(
                    py,
                    level,
                    Some(name),
                    Some(k + 1),
                    format!(
                        "{label}, column `{name}`, sample {}: {} is not a finite number",
                        k + 1,
                        s[k]
                    ),
                    "remove or repair samples with NaN or infinite values (cut the record into clean pieces)",
                    "dynid::data::non_finite",
                ));
            }
            Ok(())
        };
        let ts = match (t, ts) {
            (Some(t), _) if n >= 2 => {
                check_finite("t", t)?;
                let ts = t[1] - t[0];
                for k in 1..n {
                    let step = t[k] - t[k - 1];
                    if step <= 0.0 {
                        return Err(data_error(
                            py,
                            level,
                            Some("t"),
                            Some(k + 1),
                            format!(
                                "{label}, column `t`, sample {}: the time stamp {} s does not increase (the sample before has {} s)",
                                k + 1,
                                fmt_t(t[k]),
                                fmt_t(t[k - 1])
                            ),
                            "the samples must be in time order without repeats: sort by `t` and drop repeated samples",
                            "dynid::data::non_uniform_time",
                        ));
                    }
                    let tol = TIME_TOL * ts + 1e-12 * t[k].abs();
                    let whole = (step / ts).round();
                    if (2.0..1e15).contains(&whole) && (step - whole * ts).abs() <= tol {
                        // A whole number of intervals: samples dropped, not a jittery clock.
                        return Err(data_error(
                            py,
                            level,
                            Some("t"),
                            Some(k + 1),
                            format!(
                                "{label}, column `t`, sample {}: {} sample(s) missing between t = {} s and t = {} s (sample interval {} s)",
                                k + 1,
                                whole as u64 - 1,
                                fmt_t(t[k - 1]),
                                fmt_t(t[k]),
                                fmt_t(ts)
                            ),
                            "the filters need a record without gaps, and joining the two sides would splice the motion across the gap: cut the record at the gap and give the pieces as separate records",
                            "dynid::data::non_uniform_time",
                        ));
                    }
                    if (step - ts).abs() > tol {
                        return Err(data_error(
                            py,
                            level,
                            Some("t"),
                            Some(k + 1),
                            format!(
                                "{label}, column `t`, sample {}: the time step is {} s, but the sample interval is {} s",
                                k + 1,
                                fmt_t(step),
                                fmt_t(ts)
                            ),
                            "identification needs uniformly sampled data: resample the record onto a uniform time grid; only if the time stamps merely jitter around a uniform grid drop `t` and give `sample=TS`",
                            "dynid::data::non_uniform_time",
                        ));
                    }
                }
                ts
            }
            (Some(_), _) => f64::NAN,
            (None, Some(ts)) => *ts,
            (None, None) => {
                return Err(data_error(
                    py,
                    level,
                    None,
                    None,
                    format!("{label}: no sample interval: the data have no `t` column"),
                    "add a `t` column or give the interval with `sample=TS` (seconds)",
                    "dynid::data::no_sample_interval",
                ))
            }
        };
        let mut cols = vec![None; ir.signals.len()];
        for s in ir.measured_signals() {
            let name = &ir.signal(s).name;
            match names.iter().position(|n| n == name) {
                Some(k) => cols[s.index()] = Some(slices[k]),
                None => {
                    return Err(data_error(
                        py,
                        level,
                        Some(name),
                        None,
                        format!(
                            "{label}: no column for the measured signal `{name}` (columns: {})",
                            names.join(", ")
                        ),
                        &format!("name a column `{name}`, rename one to it, or declare `{name}` unmeasured in the model"),
                        "dynid::data::missing_column",
                    ))
                }
            }
        }
        for s in ir.measured_signals() {
            if let Some(c) = cols[s.index()] {
                check_finite(&ir.signal(s).name, c)?;
            }
        }
        if n < MIN_SAMPLES {
            return Err(data_error(
                py,
                level,
                None,
                None,
                format!("{label}: only {n} samples; at least {MIN_SAMPLES} are needed"),
                "record a longer run (the slowest identification filter needs many time constants)",
                "dynid::data::too_few_samples",
            ));
        }
        if !(ts.is_finite() && ts > 0.0) {
            return Err(data_error(
                py,
                level,
                None,
                None,
                format!("{label}: invalid sample interval {ts}"),
                "the sample interval is a positive number of seconds",
                "dynid::data::bad_sample_interval",
            ));
        }
        Ok(ArraySource {
            origin: label.clone(),
            ts,
            cols,
            n,
        })
    }
}

fn json<T: serde::Serialize>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))
}

#[pymethods]
impl CompiledModel {
    /// The model's name.
    #[getter]
    fn name(&self) -> String {
        self.ir.name.clone()
    }
    /// The equations of motion, one line per body.
    fn equations(&self) -> String {
        dsl_parser::print::render_equations(&self.ir)
    }
    /// The unknown parameters, in declaration order.
    fn unknowns(&self) -> Vec<String> {
        self.ir
            .unknowns()
            .iter()
            .map(|p| self.ir.params[p.index()].name.clone())
            .collect()
    }
    /// The measured signals (the columns a level needs).
    fn measured(&self) -> Vec<String> {
        self.ir
            .measured_signals()
            .iter()
            .map(|s| self.ir.signal(*s).name.clone())
            .collect()
    }
    /// The measured responses with their units: `(name, unit)` of every measured
    /// position (m), velocity (m/s) and acceleration (m/s²).
    fn responses(&self) -> Vec<(String, String)> {
        self.ir
            .measured_signals()
            .iter()
            .filter_map(|s| {
                let sig = self.ir.signal(*s);
                let unit = match sig.kind {
                    SignalKind::Position(_) => "m",
                    SignalKind::Velocity(_) => "m/s",
                    SignalKind::Acceleration(_) => "m/s²",
                    _ => return None,
                };
                Some((sig.name.clone(), unit.to_string()))
            })
            .collect()
    }
    /// The model with the unknown parameters `values` (name, value) as nominal values.
    #[pyo3(signature = (values=None))]
    fn with_values(
        &self,
        py: Python<'_>,
        values: Option<Vec<(String, f64)>>,
    ) -> PyResult<CompiledModel> {
        guarded(py, || {
            Ok(CompiledModel {
                ir: with_values(py, &self.ir, values.as_deref().unwrap_or(&[]))?,
            })
        })
    }
    /// The model as `.dyn` source.
    fn source(&self) -> String {
        dsl_parser::print::to_source(&self.ir)
    }
    /// The compiled model as JSON (`dynid compile --emit json`).
    fn to_json(&self) -> PyResult<String> {
        json(&self.ir)
    }

    /// Simulate every level: `([(names, columns, ts, t0)], truth_json)`.
    #[pyo3(signature = (levels=None, duration=2000.0, seed=1, sample=0.01, noise=0.0, burn_in=100.0))]
    // The keyword arguments of `Model.simulate`, one each.
    #[allow(clippy::too_many_arguments)]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        levels: Option<Vec<f64>>,
        duration: f64,
        seed: u64,
        sample: f64,
        noise: f64,
        burn_in: f64,
    ) -> PyResult<(Vec<SimLevel<'py>>, String)> {
        guarded(py, || {
            let cfg = SimConfig {
                levels,
                duration,
                seed,
                sample,
                noise,
                burn_in,
                ..SimConfig::default()
            };
            let ir = &self.ir;
            let out = py
                .detach(|| sim::simulate(ir, &cfg))
                .map_err(|e| runtime_error(py, &e))?;
            let truth = json(&out.truth)?;
            let records = out
                .records
                .into_iter()
                .map(|r| {
                    let cols = r
                        .columns
                        .into_iter()
                        .map(|c| PyArray1::from_vec(py, c))
                        .collect();
                    (r.names, cols, r.ts, r.t0)
                })
                .collect();
            Ok((records, truth))
        })
    }

    /// Drive the model with measured inputs, one run per record `(names, columns, ts, t0)`:
    /// the unknown parameters at `values` (name, value; the others at their nominal
    /// values), each run from the record's measured initial state ([`sim::FREE_RUN_START`]) or
    /// from rest. Returns one `(names, columns, ts, t0)` per record: the measured signals of
    /// the model, simulated.
    #[pyo3(signature = (records, values=None, from_rest=false, substeps=DEFAULT_SUBSTEPS))]
    fn simulate_inputs<'py>(
        &self,
        py: Python<'py>,
        records: Vec<InputRecord<'py>>,
        values: Option<Vec<(String, f64)>>,
        from_rest: bool,
        substeps: usize,
    ) -> PyResult<Vec<SimLevel<'py>>> {
        guarded(py, || {
            let ir = with_values(py, &self.ir, values.as_deref().unwrap_or(&[]))?;
            let mut inputs = Vec::with_capacity(records.len());
            for (names, cols, ts, t0) in &records {
                let mut columns = Vec::with_capacity(cols.len());
                for c in cols {
                    columns.push(c.as_array().iter().copied().collect());
                }
                inputs.push(Record {
                    names: names.clone(),
                    columns,
                    ts: *ts,
                    t0: *t0,
                });
            }
            let start = if from_rest {
                Start::Rest
            } else {
                Start::Measured
            };
            let ir = &ir;
            let runs = py
                .detach(|| {
                    inputs
                        .iter()
                        .map(|r| sim::simulate_driven_from(ir, r, substeps, start))
                        .collect::<Result<Vec<_>, _>>()
                })
                .map_err(|e| runtime_error(py, &e))?;
            Ok(runs
                .into_iter()
                .map(|r| {
                    let cols = r
                        .columns
                        .into_iter()
                        .map(|c| PyArray1::from_vec(py, c))
                        .collect();
                    (r.names, cols, r.ts, r.t0)
                })
                .collect())
        })
    }

    /// Identify the unknown parameters from all levels pooled: `(json, equations)`, the
    /// JSON that of `dynid identify --json` (with `refined` after a refinement).
    #[pyo3(signature = (levels, corners=None, noise_correction=true, balance=false, column_chains=false, keep_rests=false, allow_large=false, refine=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn identify(
        &self,
        py: Python<'_>,
        levels: Vec<LevelIn<'_>>,
        corners: Option<Vec<f64>>,
        noise_correction: bool,
        balance: bool,
        column_chains: bool,
        keep_rests: bool,
        allow_large: bool,
        refine: Option<RefineArg<'_>>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<(String, String)> {
        guarded(py, || {
            let ir = &self.ir;
            if refine.is_some() && !ir.controls.is_empty() {
                let e = dynid::runtime::refine::RefineError::ControlLaws {
                    model: ir.name.clone(),
                };
                return Err(runtime_error(py, &e));
            }
            let sources = bind(py, ir, &levels)?;
            let opts = IdentifyOptions {
                corners,
                balance: Some(balance),
                noise_correction,
                column_chains,
                keep_rests,
                allow_large,
                ..Default::default()
            };
            let id = py
                .detach(|| identify(ir, &refs(&sources), &opts))
                .map_err(|e| identify_error(py, &e))?;
            let mut value = schema::identification(&id);
            if let Some((weights, shooting, substeps, test, allow_long)) = refine {
                let test = bind(py, ir, &test)?;
                let est = read_records(py, ir, &sources)?;
                let test = read_records(py, ir, &test)?;
                let samples: usize = est.iter().map(Record::len).sum();
                sim::check_steps(
                    samples as f64 * substeps as f64,
                    &format!(
                        "one free run of {samples} samples × {substeps} RK4 sub-steps (of the refinement's many)"
                    ),
                    "allow_long=True",
                    allow_long,
                )
                .map_err(|e| runtime_error(py, &e))?;
                let mut ropts = RefineOptions {
                    substeps,
                    weights,
                    ..Default::default()
                };
                if let Some(s) = shooting {
                    if !(s.is_finite() && s > 0.0) {
                        return Err(option_error(
                            py,
                            format!("shooting = {s} is not a positive duration"),
                            "give the longest sub-record in seconds, e.g. shooting=20",
                            "dynid::refine::segment",
                        ));
                    }
                    if let Some(r) = est.first() {
                        ropts.segment = Some(((s / r.ts).round() as usize).max(3));
                    }
                }
                let start = rt_refine::start_from(ir, &id);
                let cb = progress.as_ref();
                let report = py
                    .detach(|| {
                        RefineReport::compute(ir, &start, &est, &test, &ropts, &|p| {
                            report_progress(cb, "refinement", p.iteration, p.max_iter)
                        })
                    })
                    .map_err(|e| report_error(py, &e))?;
                value["refined"] = serde_json::to_value(&report)
                    .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
            }
            Ok((json(&value)?, format_equations(ir, &id)))
        })
    }
}

/// A progress callback from Python, `callback(stage, done, total)`, callable from any
/// thread of the runtime while the interpreter is released (it attaches for the call).
/// An exception it raises is reported as unraisable and the work goes on.
fn report_progress(callback: Option<&Py<PyAny>>, stage: &str, done: usize, total: usize) {
    if let Some(cb) = callback {
        Python::attach(|py| {
            if let Err(e) = cb.call1(py, (stage, done, total)) {
                e.write_unraisable(py, None);
            }
        });
    }
}

/// The refinement settings from the Python half: weights `(signal, w)`, the longest
/// sub-record in seconds, RK4 sub-steps, test levels, and whether to run above the step
/// limit.
type RefineArg<'py> = (
    Vec<(String, f64)>,
    Option<f64>,
    usize,
    Vec<LevelIn<'py>>,
    bool,
);

/// A record of measured inputs: names, columns, sample interval, start time.
type InputRecord<'py> = (Vec<String>, Vec<PyReadonlyArray1<'py, f64>>, f64, f64);

/// Every level read whole (the refinement simulates whole records).
fn read_records(py: Python<'_>, ir: &ModelIr, sources: &[Source<'_>]) -> PyResult<Vec<Record>> {
    sources
        .iter()
        .map(|s| rt_diagnose::read_record(s.as_ref(), ir).map_err(|e| runtime_error(py, &e)))
        .collect()
}

/// `ir` with the unknown parameters `values` set as their nominal values.
fn with_values(py: Python<'_>, ir: &ModelIr, values: &[(String, f64)]) -> PyResult<ModelIr> {
    let mut out = ir.clone();
    for (name, v) in values {
        out.set_nominal(name, *v).map_err(|e| {
            let known = ir
                .unknowns()
                .iter()
                .map(|p| ir.params[p.index()].name.clone())
                .collect::<Vec<_>>()
                .join(", ");
            raise_located(
                py,
                "ParameterError",
                format!("parameter `{name}` = {v}: {e}"),
                &format!("give finite values of the model's unknown parameters ({known})"),
                "dynid::parameter",
                None,
                None,
                None,
            )
        })?;
    }
    Ok(out)
}

/// An option the call refuses, as `OptionError` (a `ValueError`).
fn option_error(py: Python<'_>, message: String, help: &str, code: &str) -> PyErr {
    raise_located(py, "OptionError", message, help, code, None, None, None)
}

/// A `miette::Report` as a Python exception (its code picks the class).
fn report_error(py: Python<'_>, e: &dyn Diagnostic) -> PyErr {
    runtime_error(py, e)
}

fn read_source(path: &Path) -> String {
    dsl_parser::read_source(path)
        .ok()
        .flatten()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

/// The text of a compiled model, read once and at most 64 MiB of it (a bigger file is not a
/// model, and would be read whole into memory).
fn read_json_text(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    const MAX: u64 = 64 << 20;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(MAX + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > MAX {
        return Err(std::io::Error::other(
            "it holds more than 64 MiB, which is not a compiled model",
        ));
    }
    Ok(text)
}

/// Compile `.dyn` source text; `name` is the file name shown in diagnostics.
#[pyfunction]
#[pyo3(signature = (source, name="<source>"))]
fn compile_source(py: Python<'_>, source: &str, name: &str) -> PyResult<CompiledModel> {
    guarded(py, || {
        dsl_parser::compile_str(name, source)
            .map(|ir| CompiledModel { ir })
            .map_err(|e| compile_error(py, &e, source))
    })
}

/// Compile a `.dyn` file, or load a `.json` compiled model (`dynid compile --emit json`).
#[pyfunction]
fn compile_file(py: Python<'_>, path: std::path::PathBuf) -> PyResult<CompiledModel> {
    guarded(py, || {
        if path.extension().is_some_and(|e| e == "json") {
            let fail = |message: String, help: &str| {
                raise(
                    py,
                    "DynidError",
                    format!("{message}\n  help: {help}\n  [dynid::model::json]"),
                    vec![
                        ("code", obj(py, "dynid::model::json")),
                        ("help", obj(py, help)),
                    ],
                )
            };
            let text = read_json_text(&path).map_err(|e| {
                fail(
                    format!("cannot read the model `{}`: {e}", path.display()),
                    "check the path and the file permissions (a compiled model is UTF-8 JSON)",
                )
            })?;
            let ir: ModelIr = serde_json::from_str(&text).map_err(|e| {
                fail(
                    format!("`{}` is not a compiled model (JSON IR): {e}", path.display()),
                    "a `.json` model is the output of `dynid compile M.dyn --emit json`; give the `.dyn` file instead",
                )
            })?;
            ir.check_invariants().map_err(|e| {
                fail(
                    format!("`{}` is not a consistent model: {e}", path.display()),
                    "write the model as .dyn and compile it instead of editing the JSON",
                )
            })?;
            return Ok(CompiledModel { ir });
        }
        dsl_parser::compile_file(&path)
            .map(|ir| CompiledModel { ir })
            .map_err(|e| compile_error(py, &e, &read_source(&path)))
    })
}

/// Detect nonlinear elements of a linear model: `(json, table, warnings, verdicts)`, the
/// JSON that of `dynid detect --json`, the verdicts as `(element, verdict)` in words. One
/// level is cut into levels as the command line cuts one file (`segments`, `split_by`,
/// `cut`); the segment table is the first warning's companion in the JSON (`segments`).
#[pyfunction]
#[pyo3(signature = (model, levels, alpha=1e-3, frf_periods=None, segments=None, split_by=None, cut="auto", allow_large=false))]
#[allow(clippy::too_many_arguments)]
fn detect(
    py: Python<'_>,
    model: &CompiledModel,
    levels: Vec<LevelIn<'_>>,
    alpha: f64,
    frf_periods: Option<usize>,
    segments: Option<usize>,
    split_by: Option<String>,
    cut: &str,
    allow_large: bool,
) -> PyResult<DetectOut> {
    guarded(py, || {
        if !(alpha > 0.0 && alpha < 1.0) {
            return Err(option_error(
                py,
                format!("alpha = {alpha} is not between 0 and 1"),
                "a probability such as 1e-3",
                "dynid::detect::option",
            ));
        }
        let ir = &model.ir;
        let choice = split_choice(py, segments, split_by, cut)?;
        let split = split_levels(py, ir, &levels, &choice, allow_large)?;
        let sources = match &split {
            Some((_, records, labels)) => segment_sources(py, ir, records, labels)?,
            None => bind(py, ir, &levels)?,
        };
        let mut dopts = DetectOptions {
            alpha,
            ..Default::default()
        };
        let iopts = IdentifyOptions {
            allow_large,
            ..Default::default()
        };
        let (det, fits, frfs) = py
            .detach(|| -> miette::Result<_> {
                let levels = refs(&sources);
                let (det, fits) = detect_from_data(ir, &levels, &iopts, &dopts, &[])?;
                let frfs = schema::level_frfs(ir, &levels, &det, &fits.fits, frf_periods)?;
                Ok((det, fits, frfs))
            })
            .map_err(|e| report_error(py, e.as_ref()))?;
        dopts.se_dof.get_or_insert(fits.n_blocks as f64 - 1.0);
        let too_alike = levels_too_alike(&det, &dopts);
        let split = split.as_ref().map(|s| &s.0);
        let cycle_note = split.and_then(Split::cycles_note);
        let mut warnings: Vec<String> = too_alike.iter().map(|w| w.message.clone()).collect();
        warnings.extend(cycle_note.clone());
        let value = schema::detection(&det, &fits, &too_alike, split, cycle_note.as_deref(), &frfs);
        let verdicts = det
            .elements
            .iter()
            .map(|e| (e.element.clone(), e.verdict.to_string()))
            .collect();
        Ok((json(&value)?, det.render_table(), warnings, verdicts))
    })
}

/// Cut one level into levels as `dynid detect`/`diagnose` cut one file:
/// `(split_json, table, [(names, columns, ts, t0)], labels)`.
#[pyfunction]
#[pyo3(signature = (model, level, segments=None, split_by=None, cut="auto", allow_large=false))]
#[allow(clippy::type_complexity)]
fn split<'py>(
    py: Python<'py>,
    model: &CompiledModel,
    level: LevelIn<'py>,
    segments: Option<usize>,
    split_by: Option<String>,
    cut: &str,
    allow_large: bool,
) -> PyResult<(String, String, Vec<SimLevel<'py>>, Vec<String>)> {
    guarded(py, || {
        let ir = &model.ir;
        let choice = split_choice(py, segments, split_by, cut)?;
        let levels = [level];
        let Some((split, records, labels)) = split_levels(py, ir, &levels, &choice, allow_large)?
        else {
            return Err(option_error(
                py,
                "no level to split".into(),
                "give one level",
                "dynid::split::option",
            ));
        };
        let out = records
            .into_iter()
            .map(|r| {
                let cols = r
                    .columns
                    .into_iter()
                    .map(|c| PyArray1::from_vec(py, c))
                    .collect();
                (r.names, cols, r.ts, r.t0)
            })
            .collect();
        Ok((json(&split)?, split.table(), out, labels))
    })
}

/// The power spectra of a diagnosis' report, per response signal of its largest level:
/// `(signal, unit, level (1-based), frequencies in Hz, measured PSD, [(model, PSD)])`,
/// each PSD one-sided in unit²/Hz.
type SpectrumOut<'py> = (
    String,
    String,
    usize,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Vec<(String, Bound<'py, PyArray1<f64>>)>,
);

fn spectra_out<'py>(py: Python<'py>, d: &rt_diagnose::Diagnosis) -> Vec<SpectrumOut<'py>> {
    d.spectra
        .iter()
        .map(|s| {
            let unit = d
                .traces
                .iter()
                .find(|t| t.signal == s.signal)
                .map(|t| t.unit.clone())
                .unwrap_or_default();
            (
                s.signal.clone(),
                unit,
                s.level + 1,
                PyArray1::from_slice(py, &s.freqs),
                PyArray1::from_slice(py, &s.measured),
                s.models
                    .iter()
                    .map(|(name, p)| (name.clone(), PyArray1::from_slice(py, p)))
                    .collect(),
            )
        })
        .collect()
}

/// Diagnose the gap between a model and the levels: `(json, summary, html report,
/// fixed model source, spectra)`, the JSON that of `dynid diagnose --json` (with `refined` after a
/// refinement of the corrected model, whose values the source then carries). One level is
/// cut into levels as the command line cuts one file (`segments`, `split_by`, `cut`).
#[pyfunction]
#[pyo3(signature = (model, levels, frf_periods=None, segments=None, split_by=None, cut="auto", allow_large=false, refine=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn diagnose<'py>(
    py: Python<'py>,
    model: &CompiledModel,
    levels: Vec<LevelIn<'py>>,
    frf_periods: Option<usize>,
    segments: Option<usize>,
    split_by: Option<String>,
    cut: &str,
    allow_large: bool,
    refine: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(String, String, String, String, Vec<SpectrumOut<'py>>)> {
    guarded(py, || {
        let ir = &model.ir;
        if refine && !ir.controls.is_empty() {
            let e = dynid::runtime::refine::RefineError::ControlLaws {
                model: ir.name.clone(),
            };
            return Err(runtime_error(py, &e));
        }
        let choice = split_choice(py, segments, split_by, cut)?;
        let split = split_levels(py, ir, &levels, &choice, allow_large)?;
        let mut opts = DiagnoseOptions::default();
        opts.ident.allow_large = allow_large;
        let (records, origins) = match &split {
            Some((_, segs, labels)) => {
                let sources = segment_sources(py, ir, segs, labels)?;
                let mut records = Vec::with_capacity(segs.len());
                for (src, r) in sources.iter().zip(segs) {
                    records.push(Record {
                        t0: r.t0,
                        ..rt_diagnose::read_record(src.as_ref(), ir)
                            .map_err(|e| runtime_error(py, &e))?
                    });
                }
                (records, labels.clone())
            }
            None => {
                let (sources, held) = bind_held(py, ir, &levels)?;
                // The records are read whole (the free-run comparison), and the moments and
                // least-squares problems come on top: both estimated before reading.
                dynid::runtime::ident::memory::check(
                    ir,
                    sources.len(),
                    &opts.ident,
                    held,
                    "diagnosis",
                )
                .map_err(|e| identify_error(py, &e))?;
                let records = read_records(py, ir, &sources)?;
                (records, sources.iter().map(|s| s.origin()).collect())
            }
        };
        let (d, frfs) = py
            .detach(|| -> miette::Result<_> {
                let cb = progress.as_ref();
                let d = rt_diagnose::diagnose(ir, &records, &origins, &opts, &|done, total| {
                    report_progress(cb, "searching unmodelled effects", done, total)
                })?;
                let frfs = schema::diagnosis_frfs(ir, &records, &d, frf_periods)?;
                Ok((d, frfs))
            })
            .map_err(|e| report_error(py, e.as_ref()))?;
        let refined = if refine {
            Some(refine_corrected(py, &d, &records, progress.as_ref())?)
        } else {
            None
        };
        let mut html = dynid::plot::render_html(&d);
        if !frfs.is_empty() {
            html = html.replacen(
                "</body>",
                &format!("{}</body>", dynid::plot::report::frf_section(&frfs)),
                1,
            );
        }
        let source = refined
            .as_ref()
            .map_or_else(|| d.fixed_source.clone(), |r| r.1.clone());
        let value = schema::DiagnosisJson {
            diagnosis: &d,
            segments: split.as_ref().map(|s| &s.0),
            refined: refined.as_ref().map(|r| &r.0),
            free_run_start: sim::FREE_RUN_START,
            closed_loop_hint: None,
            frf: Some(&frfs).filter(|f| !f.is_empty()).map(|f| f.as_slice()),
        };
        Ok((
            json(&value)?,
            d.summary(),
            html,
            source,
            spectra_out(py, &d),
        ))
    })
}

/// The corrected model refined by output error on every level, as `dynid diagnose
/// --refine`: the report (start: the corrected model's values) and the model's text with
/// the refined values (the corrected model's own when the refinement was not applied).
fn refine_corrected(
    py: Python<'_>,
    d: &rt_diagnose::Diagnosis,
    records: &[Record],
    progress: Option<&Py<PyAny>>,
) -> PyResult<(RefineReport, String)> {
    let fixed = dsl_parser::compile_str(&d.model, &d.fixed_source)
        .map_err(|e| compile_error(py, &e, &d.fixed_source))?;
    let (report, text) = py
        .detach(|| {
            rt_refine::refine_corrected(&fixed, records, &|p| {
                report_progress(progress, "refinement", p.iteration, p.max_iter)
            })
        })
        .map_err(|e| report_error(py, &e))?;
    Ok((report, text.unwrap_or_else(|| d.fixed_source.clone())))
}

/// Panic inside the boundary on purpose: the tests check with it that a panic reaches
/// Python as `DynidError` (code `dynid::internal`), never as `PanicException`.
#[pyfunction]
fn _panic_inside_the_boundary(py: Python<'_>) -> PyResult<()> {
    guarded(py, || {
        py.detach(|| -> PyResult<()> {
            let empty: Vec<f64> = Vec::new();
            // An out-of-bounds index, as a data-dependent size bug would make.
            let _ = empty[std::hint::black_box(1)];
            Ok(())
        })
    })
}

#[pymodule]
fn _dynid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<CompiledModel>()?;
    m.add_function(wrap_pyfunction!(compile_source, m)?)?;
    m.add_function(wrap_pyfunction!(compile_file, m)?)?;
    m.add_function(wrap_pyfunction!(detect, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(split, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_inside_the_boundary, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
