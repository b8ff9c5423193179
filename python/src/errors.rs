//! Runtime errors as the exceptions of `dynid.errors`: the class from the error's code,
//! the message with its help line and code, and the level, column and sample where known.

use dynid::dsl_parser::CompileErrors;
use dynid::runtime::IdentifyError;
use miette::Diagnostic;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::BoundObject;

/// An exception of `dynid.errors` with `message` and the given attributes.
pub(crate) fn raise(
    py: Python<'_>,
    class: &str,
    message: String,
    attrs: Vec<(&str, Py<PyAny>)>,
) -> PyErr {
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
pub(crate) fn guarded<T>(py: Python<'_>, call: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
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

pub(crate) fn obj<'py, T: IntoPyObject<'py>>(py: Python<'py>, v: T) -> Py<PyAny> {
    match v.into_pyobject(py) {
        Ok(b) => b.into_any().unbind(),
        Err(_) => py.None(),
    }
}

/// The level number in a label `level N`, if it is one.
pub(crate) fn level_of(origin: &str) -> Option<usize> {
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
pub(crate) fn runtime_error(py: Python<'_>, e: &dyn Diagnostic) -> PyErr {
    runtime_error_at(py, e, None, None, None)
}

pub(crate) fn runtime_error_at(
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
pub(crate) fn error_class(code: &str) -> &'static str {
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
pub(crate) fn raise_located(
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
pub(crate) fn pythonic(help: &str) -> String {
    // `--map COLUMN=SIGNAL` is `map={"COLUMN": "SIGNAL"}`.
    let mut help = help.to_string();
    if let Some(at) = help.find("`--map COLUMN=") {
        let from = at + "`--map COLUMN=".len();
        if let Some(len) = help[from..].find('`') {
            let signal = help[from..from + len].to_string();
            help.replace_range(
                at..=from + len,
                &format!("`map={{\"COLUMN\": \"{signal}\"}}`"),
            );
        }
    }
    help.replace("`--allow-large`", "`allow_large=True`")
        .replace("`--filter-corners`", "`filter_corners=[...]`")
        .replace("`--segments N`", "`segments=N`")
        .replace("`--segments ", "`segments=")
        .replace("`--split-by SIGNAL`", "`split_by=\"SIGNAL\"`")
        .replace("`--cut amplitude`", "`cut=\"amplitude\"`")
}

/// An identification error; an outlier names its column and sample.
pub(crate) fn identify_error(py: Python<'_>, e: &IdentifyError) -> PyErr {
    match e {
        // Samples count from 1 in Python's errors, as in the messages.
        IdentifyError::Outlier { sample, column, .. } => {
            runtime_error_at(py, e, None, Some(column.clone()), Some(sample + 1))
        }
        _ => runtime_error(py, e),
    }
}

/// A data problem found here, before the runtime sees the level.
pub(crate) fn data_error(
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
pub(crate) fn line_column(src: &str, at: usize) -> (usize, usize) {
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
pub(crate) fn compile_error(py: Python<'_>, e: &CompileErrors, src: &str) -> PyErr {
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

/// An option the call refuses, as `OptionError` (a `ValueError`).
pub(crate) fn option_error(py: Python<'_>, message: String, help: &str, code: &str) -> PyErr {
    raise_located(py, "OptionError", message, help, code, None, None, None)
}

/// A `miette::Report` as a Python exception (its code picks the class).
pub(crate) fn report_error(py: Python<'_>, e: &dyn Diagnostic) -> PyErr {
    runtime_error(py, e)
}
