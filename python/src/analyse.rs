//! Detection, splitting and diagnosis: the functions that compare a model with several
//! levels.

use crate::errors::{
    compile_error, guarded, identify_error, option_error, report_error, runtime_error,
};
use crate::levels::{bind, bind_held, refs, segment_sources, split_choice, split_levels, LevelIn};
use crate::model::{json, read_records, report_progress, sim_level, CompiledModel, SimLevel};
use dynid::dsl_parser;
use dynid::runtime::data::Split;
use dynid::runtime::detect::detect_from_data;
use dynid::runtime::detect::DetectOptions;
use dynid::runtime::diagnose as rt_diagnose;
use dynid::runtime::diagnose::DiagnoseOptions;
use dynid::runtime::record::Record;
use dynid::runtime::refine as rt_refine;
use dynid::runtime::sim;
use dynid::runtime::IdentifyOptions;
use dynid::schema;
use dynid::schema::detection_warnings;
use dynid::schema::DetectDoc;
use dynid::schema::DiagnosisJson;
use dynid::schema::RefineReport;
use dynid::schema::SCHEMA_VERSION;
use numpy::PyArray1;
use pyo3::prelude::*;

/// A detection: JSON, the table, warnings and `(element, verdict)` in words.
pub(crate) type DetectOut = (String, String, Vec<String>, Vec<(String, String)>);

/// Detect nonlinear elements of a linear model: `(json, table, warnings, verdicts)`, the
/// JSON that of `dynid detect --json`, the verdicts as `(element, verdict)` in words. One
/// level is cut into levels as the command line cuts one file (`segments`, `split_by`,
/// `cut`); the segment table is the first warning's companion in the JSON (`segments`).
#[pyfunction]
#[pyo3(signature = (model, levels, alpha=1e-3, frf_periods=None, segments=None, split_by=None, cut="auto", allow_large=false, weighted_rows=false, instrument_rows=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn detect(
    py: Python<'_>,
    model: &CompiledModel,
    levels: Vec<LevelIn<'_>>,
    alpha: f64,
    frf_periods: Option<usize>,
    segments: Option<usize>,
    split_by: Option<String>,
    cut: &str,
    allow_large: bool,
    weighted_rows: bool,
    instrument_rows: bool,
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
        let dopts = DetectOptions {
            alpha,
            ..Default::default()
        };
        if weighted_rows && instrument_rows {
            return Err(option_error(
                py,
                "weighted_rows and instrument_rows ask for opposite rows".to_string(),
                "one of them",
                "dynid::detect::option",
            ));
        }
        let iopts = IdentifyOptions {
            allow_large,
            efficient: weighted_rows,
            auto_rows: !instrument_rows,
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
        let too_alike = detection_warnings(&det, &fits, &dopts);
        let split = split.as_ref().map(|s| &s.0);
        let cycle_note = split.and_then(Split::cycles_note);
        let mut warnings: Vec<String> = too_alike.iter().map(|w| w.message.clone()).collect();
        warnings.extend(cycle_note);
        let value = DetectDoc::new(&det, &fits, &too_alike, split, &frfs);
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
pub(crate) fn split<'py>(
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
        let out = records.into_iter().map(|r| sim_level(py, r)).collect();
        Ok((json(&split)?, split.table(), out, labels))
    })
}

/// The power spectra of a diagnosis' report, per response signal of its largest level:
/// `(signal, unit, level (1-based), frequencies in Hz, measured PSD, [(model, PSD)])`,
/// each PSD one-sided in unit²/Hz.
pub(crate) type SpectrumOut<'py> = (
    String,
    String,
    usize,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Vec<(String, Bound<'py, PyArray1<f64>>)>,
);

pub(crate) fn spectra_out<'py>(
    py: Python<'py>,
    d: &rt_diagnose::Diagnosis,
) -> Vec<SpectrumOut<'py>> {
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
pub(crate) fn diagnose<'py>(
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
        let value = DiagnosisJson {
            schema_version: SCHEMA_VERSION,
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
pub(crate) fn refine_corrected(
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
