//! The levels handed over by the Python half, bound to a model: data files opened as the
//! command line opens them, NumPy arrays streamed from their buffers, one record cut into
//! levels.

use crate::errors::{data_error, option_error, runtime_error, runtime_error_at};
use dynid::dsl_parser;
use dynid::dsl_parser::ir::ModelIr;
use dynid::runtime::data::check_columns;
use dynid::runtime::data::read_record_within;
use dynid::runtime::data::CsvOptions;
use dynid::runtime::data::CutAt;
use dynid::runtime::data::DataError as RtDataError;
use dynid::runtime::data::FileSource;
use dynid::runtime::data::LevelSource;
use dynid::runtime::data::RecordSource;
use dynid::runtime::data::Split;
use dynid::runtime::data::SplitChoice;
use dynid::runtime::record::Record;
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use std::path::PathBuf;

/// Relative tolerance on the time step of a `t` column (as for CSV files).
pub(crate) const TIME_TOL: f64 = 1e-3;

/// One level as the Python half hands it over: label, names, columns (contiguous
/// `float64`), an optional time column and an optional sample interval.
pub(crate) type LevelArg<'py> = (
    String,
    Vec<String>,
    Vec<PyReadonlyArray1<'py, f64>>,
    Option<PyReadonlyArray1<'py, f64>>,
    Option<f64>,
);

/// A level streamed from NumPy's buffers (no copy).
pub(crate) struct ArraySource<'a> {
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

pub(crate) fn fmt_t(t: f64) -> String {
    dsl_parser::num::sig(t, 9, false)
}

/// One level as the Python half hands it over: a data file (path, `(column, signal)`
/// renamings, sample interval) or arrays ([`LevelArg`]).
#[derive(FromPyObject)]
pub(crate) enum LevelIn<'py> {
    File(PathBuf, Vec<(String, String)>, Option<f64>),
    Arrays(LevelArg<'py>),
}

/// A bound level: a data file read in chunks, or NumPy's buffers.
pub(crate) type Source<'a> = Box<dyn LevelSource + 'a>;

/// Bind every level: files are opened as the command line opens them (header matched to
/// the measured signals, sample interval fixed), arrays are checked by [`bind_arrays`].
pub(crate) fn bind<'a>(
    py: Python<'_>,
    ir: &ModelIr,
    levels: &'a [LevelIn<'_>],
) -> PyResult<Vec<Source<'a>>> {
    Ok(bind_held(py, ir, levels)?.0)
}

/// [`bind`], with the memory (bytes) the levels' measured columns take when read whole:
/// estimated from a file's size, counted for arrays (diagnosis copies them).
pub(crate) fn bind_held<'a>(
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
pub(crate) fn file_options(
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
pub(crate) fn split_choice(
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
pub(crate) type SplitLevels = (Split, Vec<Record>, Vec<String>);

/// With one level, cut it into levels as the command line cuts one file
/// ([`SplitChoice::split`]); with several, `None` (an error when a split option was
/// given). A file is read whole, refused above the memory limit unless `allow_large`; an
/// array level is taken with all its columns (a `t` column sets the start time).
pub(crate) fn split_levels(
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
pub(crate) fn segment_sources<'a>(
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
pub(crate) fn refs<'a>(sources: &'a [Source<'_>]) -> Vec<&'a dyn LevelSource> {
    sources
        .iter()
        .map(|s| s.as_ref() as &dyn LevelSource)
        .collect()
}

/// Check one level of arrays against the model and bind it as an [`ArraySource`]:
/// contiguous arrays, a uniform time column (or a sample interval given), and the runtime's
/// checks of a level in memory ([`check_columns`]: every measured signal present, columns
/// of one length, finite values, enough samples, a positive sample interval).
pub(crate) fn bind_arrays<'a>(
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
        // The checks of every level held in memory: the runtime's, as for a record.
        let col_of = check_columns(ir, label, names, &slices, ts).map_err(|e| {
            let (column, sample) = match &e {
                RtDataError::MissingColumn { signal, .. } => (Some(signal.clone()), None),
                RtDataError::RaggedRecord { column, .. } => (Some(column.clone()), None),
                RtDataError::SampleNonFinite { column, sample, .. } => {
                    (Some(column.clone()), Some(*sample as usize))
                }
                _ => (None, None),
            };
            runtime_error_at(py, &e, Some(level), column, sample)
        })?;
        let cols = col_of.iter().map(|k| k.map(|k| slices[k])).collect();
        Ok(ArraySource {
            origin: label.clone(),
            ts,
            cols,
            n,
        })
    }
}
