//! `CompiledModel`: a compiled model and its methods (simulation, identification), and
//! the compilation of models from text or files.

use crate::errors::{
    compile_error, guarded, identify_error, obj, option_error, raise, raise_located, report_error,
    runtime_error,
};
use crate::levels::{bind, refs, LevelIn, Source};
use dynid::dsl_parser;
use dynid::dsl_parser::ir::ModelIr;
use dynid::dsl_parser::ir::SignalKind;
use dynid::runtime::diagnose as rt_diagnose;
use dynid::runtime::ident::check_corners;
use dynid::runtime::ident::print::format_equations;
use dynid::runtime::identify;
use dynid::runtime::record::Record;
use dynid::runtime::refine as rt_refine;
use dynid::runtime::refine::RefineOptions;
use dynid::runtime::sim;
use dynid::runtime::sim::SimConfig;
use dynid::runtime::sim::Start;
use dynid::runtime::sim::DEFAULT_SUBSTEPS;
use dynid::schema::IdentifyDoc;
use dynid::schema::RefineReport;
use numpy::PyArray1;
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use std::path::Path;

/// A compiled model (the IR), immutable.
#[pyclass(module = "dynid._dynid", frozen)]
pub(crate) struct CompiledModel {
    pub(crate) ir: ModelIr,
}

/// One simulated level: signal names, columns, sample interval, start time.
pub(crate) type SimLevel<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>, f64, f64);

/// A record as Python receives it: names, one NumPy array per column (moved, no copy), the
/// sample interval and the start time.
pub(crate) fn sim_level(py: Python<'_>, r: Record) -> SimLevel<'_> {
    let cols = r
        .columns
        .into_iter()
        .map(|c| PyArray1::from_vec(py, c))
        .collect();
    (r.names, cols, r.ts, r.t0)
}

pub(crate) fn json<T: serde::Serialize>(v: &T) -> PyResult<String> {
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
            let records = out.records.into_iter().map(|r| sim_level(py, r)).collect();
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
            Ok(runs.into_iter().map(|r| sim_level(py, r)).collect())
        })
    }

    /// Identify the unknown parameters from all levels pooled: `(json, equations)`, the
    /// JSON that of `dynid identify --json` (with `refined` after a refinement), the corner
    /// check included unless `corner_check` is false (`--no-corner-check`).
    #[pyo3(signature = (levels, corners=None, noise_correction=true, balance=false, column_chains=false, keep_rests=false, allow_large=false, refine=None, progress=None, corner_check=true, filtered_equation=false, weighted_rows=false, input_delay=false, instrument_rows=false))]
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
        corner_check: bool,
        filtered_equation: bool,
        weighted_rows: bool,
        input_delay: bool,
        instrument_rows: bool,
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
            let opts = crate::moments::EstimatorKeywords {
                corners,
                noise_correction,
                balance,
                column_chains,
                keep_rests,
                allow_large,
                filtered_equation,
                weighted_rows,
                input_delay,
                instrument_rows,
            }
            .options();
            let id = py
                .detach(|| {
                    let levels = refs(&sources);
                    let mut id = identify(ir, &levels, &opts)?;
                    if corner_check {
                        check_corners(ir, &levels, &opts.as_identified(&id), &mut id);
                    }
                    Ok::<_, dynid::runtime::IdentifyError>(id)
                })
                .map_err(|e| identify_error(py, &e))?;
            let mut report = None;
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
                report = Some(
                    py.detach(|| {
                        RefineReport::compute(ir, &start, &est, &test, &ropts, &|p| {
                            report_progress(cb, "refinement", p.iteration, p.max_iter)
                        })
                    })
                    .map_err(|e| report_error(py, &e))?,
                );
            }
            let doc = IdentifyDoc::new(&id).with_refined(report.as_ref());
            Ok((json(&doc)?, format_equations(ir, &id)))
        })
    }
}

/// A progress callback from Python, `callback(stage, done, total)`, callable from any
/// thread of the runtime while the interpreter is released (it attaches for the call).
/// An exception it raises is reported as unraisable and the work goes on.
pub(crate) fn report_progress(
    callback: Option<&Py<PyAny>>,
    stage: &str,
    done: usize,
    total: usize,
) {
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
pub(crate) type RefineArg<'py> = (
    Vec<(String, f64)>,
    Option<f64>,
    usize,
    Vec<LevelIn<'py>>,
    bool,
);

/// A record of measured inputs: names, columns, sample interval, start time.
pub(crate) type InputRecord<'py> = (Vec<String>, Vec<PyReadonlyArray1<'py, f64>>, f64, f64);

/// Every level read whole (the refinement simulates whole records).
pub(crate) fn read_records(
    py: Python<'_>,
    ir: &ModelIr,
    sources: &[Source<'_>],
) -> PyResult<Vec<Record>> {
    sources
        .iter()
        .map(|s| rt_diagnose::read_record(s.as_ref(), ir).map_err(|e| runtime_error(py, &e)))
        .collect()
}

/// `ir` with the unknown parameters `values` set as their nominal values.
pub(crate) fn with_values(
    py: Python<'_>,
    ir: &ModelIr,
    values: &[(String, f64)],
) -> PyResult<ModelIr> {
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

pub(crate) fn read_source(path: &Path) -> String {
    dsl_parser::read_source(path)
        .ok()
        .flatten()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

/// The text of a compiled model, read once and at most 64 MiB of it (a bigger file is not a
/// model, and would be read whole into memory).
pub(crate) fn read_json_text(path: &Path) -> std::io::Result<String> {
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
pub(crate) fn compile_source(py: Python<'_>, source: &str, name: &str) -> PyResult<CompiledModel> {
    guarded(py, || {
        dsl_parser::compile_str(name, source)
            .map(|ir| CompiledModel { ir })
            .map_err(|e| compile_error(py, &e, source))
    })
}

/// Compile a `.dyn` file, or load a `.json` compiled model (`dynid compile --emit json`).
#[pyfunction]
pub(crate) fn compile_file(py: Python<'_>, path: std::path::PathBuf) -> PyResult<CompiledModel> {
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
