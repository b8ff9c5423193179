"""dynid: detect, identify and diagnose nonlinear force elements in mechanical models from
random-excitation data (covariance method), from Python.

The package runs the same Rust runtime as the ``dynid`` command line::

    import dynid
    model = dynid.Model.from_file("models/sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=400, seed=1)      # one DataFrame per level
    result = model.identify(data)
    result.parameters                                  # value, stderr per parameter

Data are a list with one level each: a ``pandas.DataFrame`` or a dict of 1-D arrays, with
a column per measured signal (``m1.x``, ``m1.v``, ``m1.a`` of an accelerometer, ``u``)
and a uniform time column ``t`` (or give ``sample=TS``). Float64 columns are read without a copy. Without pandas,
``simulate`` returns dicts of NumPy arrays and ``.parameters`` is a dict of arrays.
"""

from __future__ import annotations

import html as _html
import json as _json
import os as _os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as _np

from . import _dynid
from .errors import CompileError, DataError, DynidError

try:  # pandas is optional
    import pandas as _pd
except ImportError:  # pragma: no cover - exercised by the CI run without pandas
    _pd = None

__version__ = _dynid.__version__
__all__ = [
    "Model",
    "Identification",
    "Detection",
    "Diagnosis",
    "detect",
    "diagnose",
    "CompileError",
    "DataError",
    "DynidError",
    "has_pandas",
]


def has_pandas() -> bool:
    """Whether pandas is installed (results are DataFrames then, else dicts of arrays)."""
    return _pd is not None


def _table(columns: Dict[str, Any], index: Optional[Sequence[str]] = None, index_name="name"):
    """A DataFrame when pandas is there, else a dict of NumPy arrays (the index first)."""
    if _pd is not None:
        df = _pd.DataFrame(columns, index=list(index) if index is not None else None)
        if index is not None:
            df.index.name = index_name
        return df
    out: Dict[str, Any] = {}
    if index is not None:
        out[index_name] = _np.asarray(list(index), dtype=object)
    for k, v in columns.items():
        out[k] = _np.asarray(v)
    return out


def _html_table(rows: List[List[str]], header: List[str]) -> str:
    head = "".join(f"<th>{_html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{_html.escape(c)}</td>" for c in r) + "</tr>" for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _g(x: Optional[float], digits: int = 4) -> str:
    return "–" if x is None else f"{x:.{digits}g}"


# ---------------------------------------------------------------------------------------
# Data: DataFrames or dicts of arrays → the level tuples of the native module.


def _columns_of(level: Any, i: int):
    """(names, getter) of one level: a DataFrame or a mapping of name → 1-D array."""
    if _pd is not None and isinstance(level, _pd.DataFrame):
        names = [str(c) for c in level.columns]
        if level.index.name == "t" and "t" not in names:
            return names + ["t"], lambda c: (level.index if c == "t" else level[c])
        return names, lambda c: level[c]
    if isinstance(level, Mapping):
        return [str(c) for c in level.keys()], lambda c: level[c]
    raise TypeError(
        f"level {i + 1}: expected a pandas.DataFrame or a dict of arrays (one level each), "
        f"got {type(level).__name__}"
    )


def _as_column(values: Any, level: int, name: str) -> _np.ndarray:
    """A contiguous float64 array; no copy for a contiguous float64 input."""
    if _pd is not None and isinstance(values, (_pd.Series, _pd.Index)):
        values = values.to_numpy()
    try:
        a = _np.ascontiguousarray(values, dtype=_np.float64)
    except (TypeError, ValueError) as e:
        err = DataError(
            f"level {level}, column `{name}`: not numeric ({e})\n"
            "  help: give numbers (float64) in every column the model measures\n"
            "  [dynid::data::not_a_number]"
        )
        err.code, err.level, err.column = "dynid::data::not_a_number", level, name
        raise err from None
    if a.ndim != 1:
        err = DataError(
            f"level {level}, column `{name}`: expected a 1-D array, got shape {a.shape}\n"
            "  help: one column per signal, one value per sample\n"
            "  [dynid::data::shape]"
        )
        err.code, err.level, err.column = "dynid::data::shape", level, name
        raise err
    return a


def _levels(compiled, data: Any, sample: Optional[float]):
    """The level tuples for the native module: (label, names, columns, t, sample)."""
    if (_pd is not None and isinstance(data, _pd.DataFrame)) or isinstance(data, Mapping):
        data = [data]
    if not isinstance(data, (list, tuple)):
        raise TypeError(
            "data: expected a list with one DataFrame or dict of arrays per level, "
            f"got {type(data).__name__}"
        )
    if not data:
        raise ValueError("data: no levels given (one DataFrame or dict of arrays per level)")
    wanted = compiled.measured()
    out = []
    for i, level in enumerate(data):
        names, get = _columns_of(level, i)
        present = [n for n in wanted if n in names]
        missing = [n for n in wanted if n not in names]
        if missing:
            name = missing[0]
            err = DataError(
                f"level {i + 1}: no column for the measured signal `{name}` "
                f"(columns: {', '.join(names)})\n"
                f"  help: name a column `{name}`, rename one to it, or declare `{name}` "
                "unmeasured in the model\n"
                "  [dynid::data::missing_column]"
            )
            err.code, err.level, err.column = "dynid::data::missing_column", i + 1, name
            raise err
        cols = [_as_column(get(n), i + 1, n) for n in present]
        t = _as_column(get("t"), i + 1, "t") if "t" in names and sample is None else None
        out.append((f"level {i + 1}", present, cols, t, sample))
    return out


# ---------------------------------------------------------------------------------------
# Results.


class Identification:
    """The identified parameters (all levels pooled into one least-squares problem).

    ``parameters``: value, stderr and significance per parameter; ``condition``; the
    parameters the data cannot determine (``unidentifiable``); ``warnings``;
    ``fit_warnings`` (residuals the model cannot explain, with their likely cause);
    ``equations``, the identified equations; ``to_dict()``, everything (the fields of
    ``dynid identify --json``).
    """

    def __init__(self, result: Dict[str, Any], equations: str):
        self._d = result
        self.equations = equations

    def to_dict(self) -> Dict[str, Any]:
        return self._d

    @property
    def parameters(self):
        ps = self._d["params"]
        return _table(
            {
                "value": [p["value"] for p in ps],
                "stderr": [p["stderr"] for p in ps],
                "significant": [p["significant"] for p in ps],
            },
            index=[p["name"] for p in ps],
            index_name="parameter",
        )

    def __getitem__(self, name: str) -> float:
        for p in self._d["params"]:
            if p["name"] == name:
                return p["value"]
        raise KeyError(name)

    @property
    def condition(self) -> float:
        return self._d["condition"]

    @property
    def unidentifiable(self) -> Dict[str, str]:
        return {u["name"]: u["reason"] for u in self._d["unidentifiable"]}

    @property
    def warnings(self) -> List[Any]:
        return self._d["warnings"]

    @property
    def fit_warnings(self) -> List[Any]:
        """Residuals the model cannot explain, each with ``check``, ``cause``
        (``sensor_offset``, ``constant_force``, ``wrong_mass``, ``missing_body``, ...) and ``message``."""
        return self._d.get("fit_warnings", [])

    def _rows(self) -> List[List[str]]:
        rows = []
        for p in self._d["params"]:
            rel = f"{100 * p['stderr'] / abs(p['value']):.2f} %" if p["value"] else "–"
            rows.append(
                [p["name"], _g(p["value"], 6), _g(p["stderr"], 4), rel, "" if p["significant"] else "n.s."]
            )
        return rows

    def __repr__(self) -> str:
        lines = [self.equations.rstrip(), ""]
        lines.append(f"{'parameter':<12} {'value':>14} {'std. error':>12} {'rel.':>9}")
        for r in self._rows():
            lines.append(f"{r[0]:<12} {r[1]:>14} {r[2]:>12} {r[3]:>9} {r[4]}".rstrip())
        for u in self._d["unidentifiable"]:
            lines.append(f"{u['name']:<12} not identifiable: {u['reason']}")
        lines.append(f"condition {self.condition:.3e}, {self._d['rows']} rows")
        lines.extend(f"warning: {w['message']}" for w in self.fit_warnings)
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        eq = f"<pre>{_html.escape(self.equations.rstrip())}</pre>"
        t = _html_table(self._rows(), ["parameter", "value", "std. error", "rel.", ""])
        extra = "".join(
            f"<p>{_html.escape(u['name'])}: not identifiable: {_html.escape(u['reason'])}</p>"
            for u in self._d["unidentifiable"]
        )
        return f"{eq}{t}{extra}<p>condition {self.condition:.3e}, {self._d['rows']} rows</p>"


def _verdict_text(v: Any) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, dict) and v:
        k, inner = next(iter(v.items()))
        if isinstance(inner, dict):
            name = inner.get("template") or inner.get("effect") or inner.get("name")
            if name:
                return f"{k}: {name}"
        return str(k)
    return str(v)


class Detection:
    """Which elements of a linear model hide a nonlinearity, from per-level linear fits.

    ``elements``: the verdict per element; ``parameters``: each linear parameter's
    estimate at every level (value, stderr; a drift with the level betrays a
    nonlinearity); ``table``: the table ``dynid detect`` prints; ``to_dict()``: the fields
    of ``dynid detect --json``.
    """

    def __init__(self, result: Dict[str, Any], table: str, warnings: List[str], verdicts):
        self._d = result
        self.table = table
        self.warnings = warnings
        self._verdicts = dict(verdicts)

    def to_dict(self) -> Dict[str, Any]:
        return self._d

    @property
    def elements(self) -> Dict[str, str]:
        """The verdict per element in words (``linear``, ``nonlinear: Coulomb friction``,
        ``ambiguous between …``, ``drifts, unexplained …``)."""
        return dict(self._verdicts)

    @property
    def parameters(self):
        names, levels, values, stderrs, drifting = [], [], [], [], []
        for p in self._d["detection"]["params"]:
            c = p["curve"]
            for k, (v, s) in enumerate(zip(c["values"], c["stderrs"])):
                names.append(c["param"])
                levels.append(k + 1)
                values.append(v)
                stderrs.append(s)
                drifting.append(p["drifting"])
        cols = {"level": levels, "value": values, "stderr": stderrs, "drifting": drifting}
        return _table(cols, index=names, index_name="parameter")

    def __repr__(self) -> str:
        return self.table.rstrip() + "".join(f"\nwarning: {w}" for w in self.warnings)

    def _repr_html_(self) -> str:
        return f"<pre>{_html.escape(repr(self))}</pre>"


class Diagnosis:
    """Where a model and the data disagree, the most likely unmodelled effect and how far
    the gap shrinks once it is added (scored on a withheld level).

    ``summary``: the text ``dynid diagnose`` prints; ``report_html``: its HTML report
    (``_repr_html_`` shows it inline in a notebook); ``parameters``: the corrected
    model's parameters identified on all levels (value, stderr, nominal, kind); ``fixed_source``: the corrected model as
    ``.dyn`` source; ``to_dict()``: the fields of ``dynid diagnose --json``.
    """

    def __init__(self, result: Dict[str, Any], summary: str, report_html: str):
        self._d = result
        self.summary = summary
        self.report_html = report_html

    def to_dict(self) -> Dict[str, Any]:
        return self._d

    @property
    def verdict(self) -> str:
        return _verdict_text(self._d["verdict"])

    @property
    def found(self) -> List[Dict[str, Any]]:
        return self._d["found"]

    @property
    def fixed_source(self) -> str:
        return self._d["fixed_source"]

    @property
    def fixed_model(self) -> "Model":
        return Model.from_source(self.fixed_source, name=f"{self._d['model']}_fixed.dyn")

    @property
    def parameters(self):
        """The corrected model's parameters (the model as given plus every found effect),
        identified on all levels: value, standard error, nominal value of the model as
        given, and kind (``model`` or ``found effect``) — the values ``fixed_source``
        holds. The model as given re-fitted without the effects (biased where an effect is
        missing) is ``to_dict()["moved"]``."""
        names, values, stderrs, nominals, kinds = [], [], [], [], []
        for p in self._d["parameters"]:
            names.append(p["name"])
            values.append(p["value"])
            stderrs.append(p["stderr"])
            nominals.append(_np.nan if p["nominal"] is None else p["nominal"])
            kinds.append(p["kind"])
        cols = {"value": values, "stderr": stderrs, "nominal": nominals, "kind": kinds}
        return _table(cols, index=names, index_name="parameter")

    def save_report(self, path: Union[str, "_os.PathLike[str]"]) -> None:
        """Write the HTML report (it opens offline)."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.report_html)

    def __repr__(self) -> str:
        return self.summary.rstrip()

    def _repr_html_(self) -> str:
        # The report is a whole HTML document: an iframe keeps its styles to itself.
        doc = _html.escape(self.report_html, quote=True)
        return (
            f'<iframe srcdoc="{doc}" style="width:100%;height:720px;border:0" '
            'sandbox="allow-scripts"></iframe>'
        )


# ---------------------------------------------------------------------------------------
# The model and the functions.


class Model:
    """A compiled model (``.dyn`` source or a compiled ``.json`` model)."""

    def __init__(self, compiled: "_dynid.CompiledModel"):
        self._m = compiled

    @classmethod
    def from_file(cls, path: Union[str, "_os.PathLike[str]"]) -> "Model":
        """Compile a ``.dyn`` file (or load ``dynid compile --emit json`` output).

        Raises CompileError with the rendered diagnostic, line and column."""
        return cls(_dynid.compile_file(_os.fspath(path)))

    @classmethod
    def from_source(cls, source: str, name: str = "<source>") -> "Model":
        """Compile ``.dyn`` source text; ``name`` is shown in diagnostics."""
        return cls(_dynid.compile_source(source, name))

    @property
    def name(self) -> str:
        return self._m.name

    @property
    def equations(self) -> str:
        return self._m.equations()

    @property
    def unknowns(self) -> List[str]:
        """The unknown parameters, in declaration order."""
        return self._m.unknowns()

    @property
    def measured(self) -> List[str]:
        """The measured signals: the columns every level needs."""
        return self._m.measured()

    @property
    def source(self) -> str:
        """The model as ``.dyn`` source."""
        return self._m.source()

    def to_dict(self) -> Dict[str, Any]:
        """The compiled model (the JSON of ``dynid compile --emit json``)."""
        return _json.loads(self._m.to_json())

    def __repr__(self) -> str:
        return f"<dynid.Model {self.name}: unknowns {', '.join(self.unknowns) or 'none'}>\n{self.equations.rstrip()}"

    def simulate(
        self,
        levels: Optional[Sequence[float]] = None,
        duration: float = 2000.0,
        seed: int = 1,
        sample: float = 0.01,
        noise: float = 0.0,
        burn_in: float = 100.0,
    ) -> List[Any]:
        """Simulate the model at its excitation levels (or ``levels``, white-noise
        intensities), unknown parameters at their nominal values, as ``dynid simulate``.

        Returns one level each: a DataFrame with ``t`` and the measured signals (a dict
        of NumPy arrays without pandas). ``noise`` is measurement noise as a fraction of
        each signal's standard deviation. What was simulated (parameter values, levels,
        settings: the ``truth.json`` of ``dynid simulate``) is kept in ``last_truth``."""
        lv = None if levels is None else [float(x) for x in levels]
        records, truth = self._m.simulate(lv, float(duration), int(seed), float(sample), float(noise), float(burn_in))
        self.last_truth = _json.loads(truth)
        out = []
        for names, cols, ts, t0 in records:
            n = len(cols[0]) if cols else 0
            d = {"t": t0 + ts * _np.arange(n, dtype=_np.float64)}
            d.update(zip(names, cols))
            out.append(_pd.DataFrame(d, copy=False) if _pd is not None else d)
        return out

    def identify(
        self,
        data: Any,
        sample: Optional[float] = None,
        filter_corners: Optional[Sequence[float]] = None,
        noise_correction: bool = True,
        balance: bool = False,
        column_chains: bool = False,
        keep_rests: bool = False,
        allow_large: bool = False,
    ) -> Identification:
        """Identify the unknown parameters from one level per item of ``data``, all levels
        pooled, as ``dynid identify``. Bad data raise DataError (a ValueError) naming the
        level, column and sample. The keywords are the command's flags: ``column_chains``
        (``--column-chains``), ``keep_rests`` (``--keep-rests``: keep the rests of bodies
        with a Coulomb term in the moments), ``allow_large`` (``--allow-large``: run work
        whose memory estimate is above the limit)."""
        levels = _levels(self._m, data, sample)
        corners = None if filter_corners is None else [float(c) for c in filter_corners]
        js, eq = self._m.identify(
            levels,
            corners,
            bool(noise_correction),
            bool(balance),
            bool(column_chains),
            bool(keep_rests),
            bool(allow_large),
        )
        return Identification(_json.loads(js), eq)


def _model(m: Union[Model, str, "_os.PathLike[str]"]) -> Model:
    return m if isinstance(m, Model) else Model.from_file(m)


def detect(
    linear_model: Union[Model, str, "_os.PathLike[str]"],
    data: Any,
    sample: Optional[float] = None,
    alpha: float = 1e-3,
) -> Detection:
    """Which elements of a linear model hide a nonlinearity, and which kind, from one
    level per item of ``data`` (at least three), as ``dynid detect``."""
    m = _model(linear_model)
    js, table, warnings, verdicts = _dynid.detect(m._m, _levels(m._m, data, sample), float(alpha))
    return Detection(_json.loads(js), table, warnings, verdicts)


def diagnose(
    model: Union[Model, str, "_os.PathLike[str]"],
    data: Any,
    sample: Optional[float] = None,
) -> Diagnosis:
    """Where the model and the data disagree, the most likely unmodelled effect and how far
    the gap shrinks on a withheld level, from one level per item of ``data`` (at least
    two), as ``dynid diagnose``."""
    m = _model(model)
    js, summary, report = _dynid.diagnose(m._m, _levels(m._m, data, sample))
    return Diagnosis(_json.loads(js), summary, report)
