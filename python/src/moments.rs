//! Moment statistics from Python: a design made from a sample, statistics measured from
//! levels with it, merged and solved — the library's `MomentDesign` / `MomentStats`
//! (docs/distributed.md). The statistics pickle through their `.dynm` bytes, so a
//! distributed engine can ship them between processes; the design crosses as its JSON.

use crate::errors::{guarded, option_error, runtime_error};
use crate::levels::{bind, refs, LevelIn};
use crate::model::{json, CompiledModel};
use dynid::runtime::ident::print::format_equations;
use dynid::runtime::ident::{MomentDesign, MomentStats};
use dynid::runtime::IdentifyOptions;
use dynid::schema::IdentifyDoc;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

/// Merged or measured moment statistics (immutable): what identification accumulates per
/// level, with the design they were made with.
#[pyclass(module = "dynid._dynid", frozen, name = "MomentStats")]
pub(crate) struct PyMomentStats {
    stats: MomentStats,
}

#[pymethods]
impl PyMomentStats {
    /// The number of levels (records) held.
    fn __len__(&self) -> usize {
        self.stats.len()
    }

    /// Where each level came from, in order.
    fn origins(&self) -> Vec<String> {
        self.stats.origins()
    }

    /// The design the statistics were made with, as JSON (that of `--design-only`).
    fn design(&self) -> PyResult<String> {
        json(self.stats.design())
    }

    /// The `.dynm` bytes (the file `dynid moments --out` writes).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.stats.to_bytes())
    }

    /// Pickled as its `.dynm` bytes, rebuilt by `_moments_from_bytes`.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyBytes>,))> {
        let rebuild = py.import("dynid._dynid")?.getattr("_moments_from_bytes")?;
        Ok((rebuild, (self.to_bytes(py),)))
    }

    /// These statistics followed by `other`'s; refused for another design or model.
    fn merge(&self, py: Python<'_>, other: &PyMomentStats) -> PyResult<PyMomentStats> {
        guarded(py, || {
            let stats = self
                .stats
                .clone()
                .merge(other.stats.clone())
                .map_err(|e| runtime_error(py, &e))?;
            Ok(PyMomentStats { stats })
        })
    }

    /// Solve into the identification of the levels pooled: `(json, equations)` as
    /// `CompiledModel.identify` returns them (without the corner check, which needs data).
    fn identify(&self, py: Python<'_>, model: &CompiledModel) -> PyResult<(String, String)> {
        guarded(py, || {
            let ir = &model.ir;
            let id = py
                .detach(|| self.stats.identify(ir))
                .map_err(|e| runtime_error(py, &e))?;
            Ok((json(&IdentifyDoc::new(&id))?, format_equations(ir, &id)))
        })
    }
}

/// Rebuild statistics from their `.dynm` bytes (pickle's constructor).
#[pyfunction]
pub(crate) fn _moments_from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<PyMomentStats> {
    guarded(py, || {
        let stats = MomentStats::from_bytes(data, "pickled moment statistics")
            .map_err(|e| runtime_error(py, &e))?;
        Ok(PyMomentStats { stats })
    })
}

/// The design made from a sample of the data (JSON): corners, time blocks per record and
/// noise corrections, as `dynid moments --design-only`.
#[pyfunction]
#[pyo3(signature = (model, levels, corners=None, noise_correction=true, balance=false, column_chains=false, keep_rests=false, allow_large=false, filtered_equation=false, weighted_rows=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn moment_design(
    py: Python<'_>,
    model: &CompiledModel,
    levels: Vec<LevelIn<'_>>,
    corners: Option<Vec<f64>>,
    noise_correction: bool,
    balance: bool,
    column_chains: bool,
    keep_rests: bool,
    allow_large: bool,
    filtered_equation: bool,
    weighted_rows: bool,
) -> PyResult<String> {
    guarded(py, || {
        let ir = &model.ir;
        let sources = bind(py, ir, &levels)?;
        let opts = EstimatorKeywords {
            corners,
            noise_correction,
            balance,
            column_chains,
            keep_rests,
            allow_large,
            filtered_equation,
            weighted_rows,
            input_delay: false,
            instrument_rows: true,
        }
        .options();
        let design = py
            .detach(|| MomentDesign::from_data(ir, &refs(&sources), &opts))
            .map_err(|e| runtime_error(py, &e))?;
        json(&design)
    })
}

/// The estimator keywords that `identify` and `moment_design` share (as the command
/// line's `EstimatorArgs`: a design must be the one `identify` would make with the same
/// keywords).
pub(crate) struct EstimatorKeywords {
    pub corners: Option<Vec<f64>>,
    pub noise_correction: bool,
    pub balance: bool,
    pub column_chains: bool,
    pub keep_rests: bool,
    pub allow_large: bool,
    pub filtered_equation: bool,
    pub weighted_rows: bool,
    /// `--input-delay` (`identify` only: moment statistics do not carry it).
    pub input_delay: bool,
    /// `instrument_rows` (`identify` only: moment statistics always hold the instrument
    /// rows, or the filtered equation's without the delay).
    pub instrument_rows: bool,
}

impl EstimatorKeywords {
    /// The library's options for these keywords.
    pub(crate) fn options(self) -> IdentifyOptions {
        IdentifyOptions {
            corners: self.corners,
            balance: self.balance,
            noise_correction: self.noise_correction,
            column_chains: self.column_chains,
            keep_rests: self.keep_rests,
            allow_large: self.allow_large,
            filtered: self.filtered_equation,
            efficient: self.weighted_rows,
            input_delay: self.input_delay,
            auto_rows: !self.instrument_rows,
            ..Default::default()
        }
    }
}

/// The statistics of `levels` measured with `design` (the JSON of [`moment_design`]).
#[pyfunction]
#[pyo3(signature = (model, levels, design, allow_large=false))]
pub(crate) fn measure_moments(
    py: Python<'_>,
    model: &CompiledModel,
    levels: Vec<LevelIn<'_>>,
    design: &str,
    allow_large: bool,
) -> PyResult<PyMomentStats> {
    guarded(py, || {
        let ir = &model.ir;
        let design: MomentDesign = serde_json::from_str(design).map_err(|e| {
            option_error(
                py,
                format!("not a moment design ({e})"),
                "give the JSON of dynid.moment_design(...) or of `dynid moments --design-only`, unchanged",
                "dynid::moments::design",
            )
        })?;
        let sources = bind(py, ir, &levels)?;
        let stats = py
            .detach(|| MomentStats::measure(ir, &refs(&sources), &design, allow_large))
            .map_err(|e| runtime_error(py, &e))?;
        Ok(PyMomentStats { stats })
    })
}
