//! `dynid._dynid`: the native half of the Python package `dynid`.
//!
//! A thin layer over the same crates as the `dynid` command line: models are compiled by
//! `dsl-parser`, and simulation, identification, detection and diagnosis are the runtime's
//! functions. The Python half (`dynid/__init__.py`) turns DataFrames and dicts into the
//! level tuples taken here and wraps the JSON results in small classes.
//!
//! Data cross over without a copy where NumPy's layout allows: each column arrives as a
//! contiguous `float64` array and is streamed by [`levels::ArraySource`] straight from NumPy's
//! buffer (diagnosis alone copies the records, as the command line does, because its free
//! runs hold whole trajectories). The interpreter lock is released while the runtime works.
//!
//! Errors become the exceptions of `dynid.errors`: `CompileError` (with the rendered
//! diagnostic, line and column), `DataError` (a `ValueError` naming the level, column and
//! sample) and `DynidError` for everything else, each with the runtime's code and help.
//! The JSON results are the runtime's documents (`dynid_runtime::schema`, docs/json.md),
//! the same that the command line's `--json` writes.
//!
//! Modules: [`model`] (`CompiledModel`: compilation, simulation, identification),
//! [`moments`] (moment statistics: design, measure, merge, solve, pickle), [`fleet`] (the
//! fleet's view of machines identified one by one),
//! [`analyse`] (detection, splitting, diagnosis), [`levels`] (the levels handed over,
//! bound to a model and checked), [`errors`] (runtime errors as Python exceptions).

mod analyse;
mod errors;
mod fleet;
mod levels;
mod model;
mod moments;

use analyse::{detect, diagnose, split};
use errors::guarded;
use fleet::fleet_view;
use model::{compile_file, compile_source, CompiledModel};
use moments::{_moments_from_bytes, measure_moments, moment_design, PyMomentStats};
use pyo3::prelude::*;

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
    m.add_class::<PyMomentStats>()?;
    m.add_function(wrap_pyfunction!(moment_design, m)?)?;
    m.add_function(wrap_pyfunction!(measure_moments, m)?)?;
    m.add_function(wrap_pyfunction!(_moments_from_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(compile_source, m)?)?;
    m.add_function(wrap_pyfunction!(compile_file, m)?)?;
    m.add_function(wrap_pyfunction!(fleet_view, m)?)?;
    m.add_function(wrap_pyfunction!(detect, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(split, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_inside_the_boundary, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
