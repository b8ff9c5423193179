"""dynid: detect, identify and diagnose nonlinear force elements in mechanical models from
random-excitation data (covariance method), from Python.

The package runs the same Rust runtime as the ``dynid`` command line::

    import dynid
    model = dynid.Model.from_file("models/sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=400, seed=1)      # one DataFrame per level
    result = model.identify(data)
    result.parameters                                  # value, stderr per parameter
    run = model.compare(data, parameters=result)       # measured vs model, free run
    run.plot()                                         # needs matplotlib

Data are a list with one level each: a ``pandas.DataFrame``, a dict of 1-D arrays
(shapes ``(N,)``, ``(1, N)`` or ``(N, 1)``), or the path of a data file as the command
line reads it (CSV or other delimited text, MATLAB ``.mat``, HDF5, Parquet). A level has a column per measured signal (``m1.x``, ``m1.v``, ``m1.a`` of
an accelerometer, ``u``) and a uniform time column ``t`` (or give ``sample=TS``);
``map={"disp": "m1.x"}`` renames columns. Float64 columns are read without a copy.
Without pandas, ``simulate`` returns dicts of NumPy arrays and ``.parameters`` is a dict
of arrays. Every ``to_dict()`` is the object the command's ``--json`` writes.
"""

import errno as _errno
import html as _html
import json as _json
import os as _os
import typing as _t

import numpy as _np

from . import _dynid
from .errors import CompileError, DataError, DynidError, OptionError, ParameterError

try:  # pandas is optional
    import pandas as _pd
except ImportError:  # pragma: no cover - exercised by the CI run without pandas
    _pd = None

__version__ = _dynid.__version__
__all__ = [
    "Model",
    "Identification",
    "Refinement",
    "Comparison",
    "Detection",
    "Diagnosis",
    "Segments",
    "detect",
    "diagnose",
    "segments",
    "MomentStats",
    "moment_design",
    "moments",
    "merge",
    "Fleet",
    "fleet",
    "CompileError",
    "DataError",
    "DynidError",
    "OptionError",
    "ParameterError",
    "has_pandas",
]

#: The RK4 sub-steps per sample interval of driven simulations (as the command line).
_SUBSTEPS = 20


def __dir__() -> _t.List[str]:
    return sorted(__all__ + ["__version__", "errors"])


def has_pandas() -> bool:
    """Whether pandas is installed.

    Returns
    -------
    bool
        True when results are DataFrames, False when they are dicts of NumPy arrays.
    """
    return _pd is not None


def _table(columns: _t.Dict[str, _t.Any], index=None, index_name="name"):
    """A DataFrame when pandas is there, else a dict of NumPy arrays (the index first)."""
    if _pd is not None:
        df = _pd.DataFrame(columns, index=list(index) if index is not None else None)
        if index is not None:
            df.index.name = index_name
        return df
    out: _t.Dict[str, _t.Any] = {}
    if index is not None:
        out[index_name] = _np.asarray(list(index), dtype=object)
    for k, v in columns.items():
        out[k] = _np.asarray(v)
    return out


def _html_table(rows, header) -> str:
    head = "".join(f"<th>{_html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{_html.escape(c)}</td>" for c in r) + "</tr>" for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _g(x, digits: int = 4) -> str:
    return "–" if x is None else f"{x:.{digits}g}"


def _pyplot():
    """matplotlib.pyplot, or an ImportError that says how to get it."""
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        raise ImportError(
            "plotting needs matplotlib, which dynid does not install: "
            "`pip install matplotlib` (the results themselves need only NumPy)"
        ) from None
    return plt


def _error(cls, message: str, help: str, code: str, **attrs):
    err = cls(f"{message}\n  help: {help}\n  [{code}]")
    err.code, err.help = code, help
    for k, v in attrs.items():
        setattr(err, k, v)
    return err


# ---------------------------------------------------------------------------------------
# Data: DataFrames, dicts of arrays or CSV files → the level tuples of the native module.


def _is_path(x) -> bool:
    return isinstance(x, (str, _os.PathLike))


def _columns_of(level, i: int):
    """(names, getter) of one level: a DataFrame or a mapping of name → array."""
    if _pd is not None and isinstance(level, _pd.DataFrame):
        names = [str(c) for c in level.columns]
        if level.index.name == "t" and "t" not in names:
            return names + ["t"], lambda c: (level.index if c == "t" else level[c])
        return names, lambda c: level[c]
    if isinstance(level, _t.Mapping):
        return [str(c) for c in level.keys()], lambda c: level[c]
    raise TypeError(
        f"level {i + 1}: expected a pandas.DataFrame, a dict of arrays or the path of a CSV "
        f"file (one level each), got {type(level).__name__}"
    )


def _as_column(values, level: int, name: str) -> _np.ndarray:
    """A contiguous 1-D float64 array; no copy for a contiguous float64 input. MATLAB-shaped
    vectors, ``(1, N)`` or ``(N, 1)``, are taken as ``(N,)``."""
    if _pd is not None and isinstance(values, (_pd.Series, _pd.Index)):
        values = values.to_numpy()
    try:
        a = _np.asarray(values, dtype=_np.float64)
    except (TypeError, ValueError) as e:
        raise _error(
            DataError,
            f"level {level}, column `{name}`: not numeric ({e})",
            "give numbers (float64) in every column the model measures",
            "dynid::data::not_a_number",
            level=level,
            column=name,
        ) from None
    if a.ndim == 2 and 1 in a.shape:
        a = a.reshape(-1)
    if a.ndim != 1:
        raise _error(
            DataError,
            f"level {level}, column `{name}`: expected a vector, got an array of shape {a.shape}",
            "one column per signal, one value per sample: shape (N,), (1, N) or (N, 1)",
            "dynid::data::shape",
            level=level,
            column=name,
        )
    return _np.ascontiguousarray(a)


def _as_list(data, what: str = "data"):
    """The levels as a list, and whether one level was given alone."""
    if (_pd is not None and isinstance(data, _pd.DataFrame)) or isinstance(data, _t.Mapping) or _is_path(data):
        return [data], True
    if not isinstance(data, (list, tuple)):
        raise TypeError(
            f"{what}: expected a list with one DataFrame, dict of arrays or CSV path per level, "
            f"got {type(data).__name__}"
        )
    if not data:
        raise _error(
            DataError,
            f"{what}: no levels given",
            "give one DataFrame, dict of arrays or CSV path per level",
            "dynid::data::no_levels",
        )
    return list(data), False


def _check_map(map) -> _t.List[_t.Tuple[str, str]]:
    if map is None:
        return []
    if not isinstance(map, _t.Mapping):
        raise TypeError(f"map: expected a dict of column → signal, got {type(map).__name__}")
    return [(str(c), str(s)) for c, s in map.items()]


def _levels(compiled, data, sample, map=None, what: str = "data", every_column: bool = False):
    """The level tuples for the native module: ``(path, map, sample)`` for a file,
    ``(label, names, columns, t, sample)`` for arrays: the measured signals' columns, and
    with ``every_column`` also every other numeric one (a record to be cut into levels is
    judged and cut by any of its columns)."""
    data, _ = _as_list(data, what)
    pairs = _check_map(map)
    rename = dict(pairs)
    wanted = compiled.measured()
    out = []
    for i, level in enumerate(data):
        if _is_path(level):
            path = _os.fspath(level)
            if not _os.path.exists(path):
                raise FileNotFoundError(_errno.ENOENT, f"level {i + 1}: no data file", path)
            out.append((path, pairs, None if sample is None else float(sample)))
            continue
        names, get = _columns_of(level, i)
        signal_of = {n: rename.get(n, n) for n in names}
        column_of = {s: n for n, s in signal_of.items()}
        missing = [n for n in wanted if n not in column_of]
        if missing:
            name = missing[0]
            raise _error(
                DataError,
                f"level {i + 1}: no column for the measured signal `{name}` (columns: {', '.join(names)})",
                f"name a column `{name}`, rename one to it (map={{'COLUMN': '{name}'}}), or "
                f"declare `{name}` unmeasured in the model",
                "dynid::data::missing_column",
                level=i + 1,
                column=name,
            )
        cols = [_as_column(get(column_of[n]), i + 1, n) for n in wanted]
        signals = list(wanted)
        if every_column:
            for n in names:
                if n == "t" or signal_of[n] in signals:
                    continue
                try:
                    cols.append(_as_column(get(n), i + 1, n))
                except DataError:
                    continue  # a text column: nothing to judge or cut by
                signals.append(signal_of[n])
        t = _as_column(get("t"), i + 1, "t") if "t" in names and sample is None else None
        out.append((f"level {i + 1}", signals, cols, t, None if sample is None else float(sample)))
    return out


def _frame(names, cols, ts: float, t0: float):
    n = len(cols[0]) if cols else 0
    d = {"t": t0 + ts * _np.arange(n, dtype=_np.float64)}
    d.update(zip(names, cols))
    return _pd.DataFrame(d, copy=False) if _pd is not None else d


def _values_of(parameters) -> _t.Optional[_t.List[_t.Tuple[str, float]]]:
    """``(name, value)`` pairs from a dict, an Identification or a Refinement."""
    if parameters is None:
        return None
    if isinstance(parameters, Refinement):
        return [(n, float(v)) for n, v in parameters.values.items()]
    if isinstance(parameters, Identification):
        if parameters.refined is not None and parameters.refined.applied:
            return [(n, float(v)) for n, v in parameters.refined.values.items()]
        return [(n, float(p["value"])) for n, p in parameters.to_dict()["parameters"].items()]
    if isinstance(parameters, _t.Mapping):
        out = []
        for n, v in parameters.items():
            try:
                out.append((str(n), float(v)))
            except (TypeError, ValueError):
                raise _error(
                    ParameterError,
                    f"parameter `{n}` = {v!r} is not a number",
                    "give a dict of parameter name → value",
                    "dynid::parameter",
                ) from None
        return out
    raise TypeError(
        "parameters: expected a dict of name → value, an Identification or a Refinement, "
        f"got {type(parameters).__name__}"
    )


def _input_records(compiled, inputs, sample, map):
    """``(names, columns, ts, t0)`` per level of measured inputs (arrays or CSV files)."""
    levels, single = _as_list(inputs, "inputs")
    pairs = _check_map(map)
    rename = dict(pairs)
    out = []
    for i, level in enumerate(levels):
        if _is_path(level):
            path = _os.fspath(level)
            if not _os.path.exists(path):
                raise FileNotFoundError(_errno.ENOENT, f"inputs, level {i + 1}: no data file", path)
            if _pd is None:
                raise ImportError("reading a CSV file of inputs in Python needs pandas: `pip install pandas`")
            level = _pd.read_csv(path)
        names, get = _columns_of(level, i)
        cols, used = [], []
        for n in names:
            if n == "t":
                continue
            try:
                cols.append(_as_column(get(n), i + 1, n))
            except DataError:
                continue  # a text column the model does not read
            used.append(rename.get(n, n))
        if "t" in names and sample is None:
            t = _as_column(get("t"), i + 1, "t")
            if len(t) < 2:
                raise _error(DataError, f"inputs, level {i + 1}: fewer than 2 samples", "give a longer record", "dynid::data::too_few_samples", level=i + 1)
            ts, t0 = float(t[1] - t[0]), float(t[0])
        elif sample is not None:
            ts, t0 = float(sample), 0.0
        else:
            raise _error(
                DataError,
                f"inputs, level {i + 1}: no sample interval: no `t` column",
                "add a `t` column or give the interval with `sample=TS` (seconds)",
                "dynid::data::no_sample_interval",
                level=i + 1,
            )
        out.append((used, cols, ts, t0))
    return out, single


def _progress(progress):
    """The callback handed to the runtime: ``progress`` itself when it is callable, tqdm
    bars (one per stage) for ``True``, None for None or False."""
    if progress is None or progress is False:
        return None
    if callable(progress):
        return progress
    if progress is not True:
        raise TypeError(f"progress: expected a callable(stage, done, total) or True, got {type(progress).__name__}")
    try:
        from tqdm.auto import tqdm
    except ImportError:
        raise ImportError(
            "progress=True draws tqdm bars, which dynid does not install: `pip install tqdm`, "
            "or pass a callable(stage, done, total)"
        ) from None
    bars: _t.Dict[str, _t.Any] = {}

    def update(stage: str, done: int, total: int) -> None:
        bar = bars.get(stage)
        if bar is None:
            for other in bars.values():
                other.close()
            bar = bars[stage] = tqdm(total=total, desc=stage)
        bar.total = total
        bar.n = done
        bar.refresh()

    return update


# ---------------------------------------------------------------------------------------
# Results.


class Refinement:
    """An output-error refinement: the covariance estimate refined by minimising the
    free-run (simulation) error of all levels, as ``dynid identify --refine``.

    Attributes
    ----------
    parameters : DataFrame or dict of arrays
        Per parameter: ``start`` (the covariance estimate), ``value`` (refined), ``stderr``
        (from the final Jacobian, white residuals assumed: a lower bound).
    values : dict
        The refined values by name (the start values where the fit was not applied).
    applied : bool
        Whether the refined values were kept (``note`` says why not).
    free_run : DataFrame or dict of arrays
        Free-run RMS error per signal and record set (``estimation``, ``test``), of the
        start and the refined values, absolute and relative to the signal's std.
    """

    def __init__(self, result: _t.Dict[str, _t.Any]):
        self._d = result

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The refinement as ``dynid identify --refine --json`` writes it (``refined``).

        Returns
        -------
        dict
            ``refinement`` (the fit), ``estimation`` and ``test`` (free-run errors of the
            start and the refined values).
        """
        return self._d

    @property
    def applied(self) -> bool:
        return bool(self._d["refinement"]["applied"])

    @property
    def note(self) -> _t.Optional[str]:
        return self._d["refinement"].get("note")

    @property
    def values(self) -> _t.Dict[str, float]:
        return {p["name"]: p["value"] for p in self._d["refinement"]["params"]}

    @property
    def parameters(self):
        ps = self._d["refinement"]["params"]
        return _table(
            {
                "start": [p["start"] for p in ps],
                "value": [p["value"] for p in ps],
                "stderr": [p["stderr"] for p in ps],
            },
            index=[p["name"] for p in ps],
            index_name="parameter",
        )

    @property
    def free_run(self):
        rows = {"set": [], "start_rms": [], "refined_rms": [], "start_relative": [], "refined_relative": []}
        names = []
        for what in ("estimation", "test"):
            cov, ref = self._d[what]
            for c, f in zip(cov, ref):
                names.append(c["signal"])
                rows["set"].append(what)
                rows["start_rms"].append(c["rms"])
                rows["refined_rms"].append(f["rms"])
                rows["start_relative"].append(c["relative"])
                rows["refined_relative"].append(f["relative"])
        return _table(rows, index=names, index_name="signal")

    def __repr__(self) -> str:
        r = self._d["refinement"]
        lines = [
            f"output-error refinement: {r['iterations']} iterations "
            f"({'converged' if r['converged'] else 'iteration limit'}), "
            f"cost {r['cost_start']:.3e} -> {r['cost_end']:.3e}"
            + ("" if r["applied"] else f" (not applied: {r.get('note')})"),
            f"{'parameter':<12} {'covariance':>14} {'refined':>14} {'std. error':>12}",
        ]
        for p in r["params"]:
            lines.append(f"{p['name']:<12} {_g(p['start'], 6):>14} {_g(p['value'], 6):>14} {_g(p['stderr']):>12}")
        return "\n".join(lines)


class Identification:
    """The identified parameters (all levels pooled into one least-squares problem), as
    ``dynid identify``.

    Attributes
    ----------
    parameters : DataFrame or dict of arrays
        Value, standard error and significance per parameter.
    condition : float
        Condition number of the scaled least-squares problem.
    unidentifiable : dict
        The parameters the data cannot determine, with the reason.
    warnings, fit_warnings : list
        Warnings; residuals the model cannot explain, with their likely cause.
    equations : str
        The identified equations of motion.
    refined : Refinement or None
        The output-error refinement (``identify(..., refine=True)``).

    Examples
    --------
    >>> result = model.identify(data)              # doctest: +SKIP
    >>> result["k3"], result.parameters            # doctest: +SKIP
    >>> model.compare(data, parameters=result).plot()  # doctest: +SKIP
    """

    def __init__(self, result: _t.Dict[str, _t.Any], equations: str, model=None, data=None):
        self._d = result
        self.equations = equations
        self._model = model
        self._data = data

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The result as ``dynid identify --json`` writes it (one schema for both).

        Returns
        -------
        dict
            ``schema_version``, ``parameters`` ({name: {value, stderr, significant}}),
            ``condition``, ``rows``, ``residual``, ``levels``, ``unidentifiable``,
            ``warnings``, ``fit_warnings``, ``filter``, ``estimated``, ``shapes``, and
            ``refined`` after a refinement (every key: docs/json.md).
        """
        return self._d

    @property
    def parameters(self):
        """Value, standard error and significance per parameter, in the model's order of
        unknowns (the JSON map ``to_dict()["parameters"]`` is keyed by name)."""
        ps = self._d["parameters"]
        order = list(getattr(self._model, "unknowns", None) or [])
        names = [n for n in order if n in ps] + [n for n in ps if n not in order]
        return _table(
            {
                "value": [ps[n]["value"] for n in names],
                "stderr": [ps[n]["stderr"] for n in names],
                "significant": [ps[n]["significant"] for n in names],
            },
            index=names,
            index_name="parameter",
        )

    @property
    def values(self) -> _t.Dict[str, float]:
        """The identified values by name."""
        return {n: p["value"] for n, p in self._d["parameters"].items()}

    def __getitem__(self, name: str) -> float:
        return self._d["parameters"][name]["value"]

    @property
    def condition(self) -> float:
        return self._d["condition"]

    @property
    def unidentifiable(self) -> _t.Dict[str, str]:
        return {u["name"]: u["reason"] for u in self._d["unidentifiable"]}

    @property
    def warnings(self) -> _t.List[_t.Any]:
        return self._d["warnings"]

    @property
    def fit_warnings(self) -> _t.List[_t.Any]:
        """Residuals the model cannot explain, each with ``check``, ``cause``
        (``sensor_offset``, ``constant_force``, ``wrong_mass``, ``missing_body``, ...) and ``message``."""
        return self._d.get("fit_warnings", [])

    @property
    def refined(self) -> _t.Optional[Refinement]:
        r = self._d.get("refined")
        return None if r is None else Refinement(r)

    def plot(self, data=None, level: int = 1, ax=None, **kw):
        """Measured vs model: the identified model driven by the measured inputs of one
        level, from its measured initial state, over the measured responses.

        Parameters
        ----------
        data : list, optional
            The levels to compare with (default: the levels it was identified from).
        level : int, default 1
            The level to draw (1-based).
        ax : matplotlib Axes or sequence of Axes, optional
            Where to draw (one per measured position or velocity).
        **kw
            Passed to :meth:`Model.compare` (``sample``, ``map``, ``from_rest``).

        Returns
        -------
        matplotlib.figure.Figure
            The figure (one panel per measured response signal).

        Raises
        ------
        ImportError
            Without matplotlib.
        """
        if self._model is None:
            raise ValueError("this result knows no model: use Model.compare(data, parameters=result).plot()")
        data = self._data if data is None else data
        if data is None:
            raise ValueError("give the levels to compare with: result.plot(data)")
        return self._model.compare(data, parameters=self, **kw).plot(level=level, ax=ax)

    def _rows(self) -> _t.List[_t.List[str]]:
        rows = []
        for name, p in self._d["parameters"].items():
            rel = f"{100 * p['stderr'] / abs(p['value']):.2f} %" if p["value"] else "–"
            rows.append([name, _g(p["value"], 6), _g(p["stderr"], 4), rel, "" if p["significant"] else "n.s."])
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
        if self.refined is not None:
            lines.extend(["", repr(self.refined)])
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        eq = f"<pre>{_html.escape(self.equations.rstrip())}</pre>"
        t = _html_table(self._rows(), ["parameter", "value", "std. error", "rel.", ""])
        extra = "".join(
            f"<p>{_html.escape(u['name'])}: not identifiable: {_html.escape(u['reason'])}</p>"
            for u in self._d["unidentifiable"]
        )
        return f"{eq}{t}{extra}<p>condition {self.condition:.3e}, {self._d['rows']} rows</p>"


class Comparison:
    """Measured vs model: the model driven by each level's measured inputs from its
    measured initial state (a free run), next to the measured responses.

    Attributes
    ----------
    measured : list
        The levels as given (one DataFrame or dict of arrays each).
    simulated : list
        The free runs (``t`` and the model's measured signals), one per level.
    errors : DataFrame or dict of arrays
        Free-run RMS error per level and response signal, absolute and relative to the
        measured signal's standard deviation.
    """

    def __init__(self, measured, simulated, responses: _t.List[str], units: _t.Dict[str, str]):
        self.measured = measured
        self.simulated = simulated
        self._responses = responses
        self._units = units

    @property
    def errors(self):
        levels, signals, rms, rel = [], [], [], []
        for i, (m, s) in enumerate(zip(self.measured, self.simulated)):
            for sig in self._responses:
                a = _np.asarray(m[sig], dtype=float).reshape(-1)
                b = _np.asarray(s[sig], dtype=float)
                e = float(_np.sqrt(_np.mean((a - b) ** 2)))
                levels.append(i + 1)
                signals.append(sig)
                rms.append(e)
                sd = float(_np.std(a))
                rel.append(e / sd if sd > 0 else _np.nan)
        return _table({"level": levels, "signal": signals, "rms": rms, "relative": rel})

    def plot(self, level: int = 1, ax=None, signals: _t.Optional[_t.Sequence[str]] = None):
        """Draw the measured responses of one level with the model's free run on them.

        Parameters
        ----------
        level : int, default 1
            The level to draw (1-based).
        ax : matplotlib Axes or sequence of Axes, optional
            One per drawn signal; by default a new figure with one panel per signal.
        signals : sequence of str, optional
            The signals to draw (default: the measured positions and velocities).

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ImportError
            Without matplotlib.

        Examples
        --------
        >>> fig = model.compare(data, parameters=result).plot()   # doctest: +SKIP
        >>> fig.savefig("measured_vs_model.png")                  # doctest: +SKIP
        """
        plt = _pyplot()
        if not 1 <= level <= len(self.measured):
            raise ValueError(f"level {level}: there are {len(self.measured)} levels (1-based)")
        sigs = list(signals) if signals is not None else list(self._responses)
        m, s = self.measured[level - 1], self.simulated[level - 1]
        if ax is None:
            fig, axes = plt.subplots(len(sigs), 1, sharex=True, figsize=(9, 2.6 * len(sigs) + 0.6), squeeze=False)
            axes = list(axes[:, 0])
        else:
            axes = list(ax) if isinstance(ax, (list, tuple, _np.ndarray)) else [ax]
            fig = axes[0].figure
        t = _np.asarray(s["t"], dtype=float)
        for a, sig in zip(axes, sigs):
            meas = _np.asarray(m[sig], dtype=float).reshape(-1)
            a.plot(t, meas, color="#222222", lw=1.6, label="measured")
            a.plot(t, _np.asarray(s[sig], dtype=float), color="#d62728", lw=1.0, ls="--", label="model (free run)")
            unit = self._units.get(sig, "")
            a.set_ylabel(f"{sig} [{unit}]" if unit else sig)
            a.grid(alpha=0.3)
        axes[0].legend(loc="upper right", fontsize=9, framealpha=0.9)
        axes[-1].set_xlabel("time [s]")
        axes[0].set_title(f"Measured vs model, level {level}")
        fig.tight_layout()
        return fig

    def __repr__(self) -> str:
        e = self.errors
        rows = zip(e["level"], e["signal"], e["rms"], e["relative"])
        lines = [f"{'level':>5} {'signal':<10} {'free-run RMS':>14} {'rel.':>8}"]
        lines += [f"{lv:>5} {sg:<10} {r:>14.4g} {100 * q:>7.2f}%" for lv, sg, r, q in rows]
        return "\n".join(lines)


def _verdict_text(v) -> str:
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


def _plot_frf(frfs, what: str, ax=None):
    """The measured FRF (H1) of every level, solid, and the linear model fitted at that
    level, dashed in the same colour: magnitude over frequency in Hz, one panel per
    response."""
    plt = _pyplot()
    if not frfs:
        raise _error(
            DynidError,
            f"this {what} has no frequency response: the model measures no input, or no position or velocity",
            "measure the input that drives the model (a column per `input`) and a response",
            "dynid::frf::none",
        )
    outputs = frfs[0]["outputs"]
    if ax is None:
        fig, axes = plt.subplots(1, len(outputs), figsize=(5.2 * len(outputs), 4.0), squeeze=False)
        axes = list(axes.ravel())
    else:
        axes = list(ax) if isinstance(ax, (list, tuple, _np.ndarray)) else [ax]
        fig = axes[0].figure
    colors = plt.rcParams["axes.prop_cycle"].by_key().get("color", ["C0", "C1", "C2"])
    for j, (a, out) in enumerate(zip(axes, outputs)):
        for k, level in enumerate(frfs):
            c = colors[k % len(colors)]
            f = _np.asarray(level["measured"]["freq_hz"], dtype=float)
            h = _np.asarray(level["measured"]["h"][j], dtype=float).reshape(-1, 2)
            a.loglog(f, _np.hypot(h[:, 0], h[:, 1]), color=c, lw=1.6, label=f"{level['label']} measured")
            model = [(_np.nan, _np.nan) if v is None else v for v in level["model"][j]] if level["model"] else []
            if model:
                m = _np.asarray(model, dtype=float)
                a.loglog(f, _np.hypot(m[:, 0], m[:, 1]), color=c, lw=1.2, ls="--", label=f"{level['label']} model")
        unit = frfs[0]["units"][j]
        a.set_xlabel("frequency [Hz]")
        a.set_ylabel(f"|{out} / {frfs[0]['input']}| [{unit}]")
        a.set_title(f"{out} over {frfs[0]['input']}", fontsize=10)
        a.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8, loc="best")
    fig.tight_layout()
    return fig


_FRF_DOC = """Frequency response of every level: the measured H1 estimate (solid) and the
        linear model fitted at that level (dashed, same colour), magnitude over frequency
        in Hz, one panel per measured response (the report's FRF figure).

        Parameters
        ----------
        ax : matplotlib Axes or sequence of Axes, optional
            One per response; by default a new figure.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ImportError
            Without matplotlib.
        DynidError
            The model measures no input or no response (no FRF).

        Examples
        --------
        >>> result.plot_frf().savefig("frf.png")    # doctest: +SKIP
        """


class Detection:
    """Which elements of a linear model hide a nonlinearity, from per-level linear fits, as
    ``dynid detect``.

    Attributes
    ----------
    elements : dict
        The verdict per element in words.
    parameters : DataFrame or dict of arrays
        Each linear parameter's estimate at every level (value, stderr): a drift with the
        level betrays a nonlinearity.
    table : str
        The table ``dynid detect`` prints.
    warnings : list of str
        Levels too alike to resolve an effect, and similar.
    """

    def __init__(self, result, table: str, warnings, verdicts):
        self._d = result
        self.table = table
        self.warnings = warnings
        self._verdicts = dict(verdicts)

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The result as ``dynid detect --json`` writes it (one schema for both).

        Returns
        -------
        dict
            ``schema_version``, ``detection``, ``intensities``, ``sigma_v_source``,
            ``batch_blocks`` (also as ``jackknife_blocks`` until schema version 3),
            ``segments``, ``warnings``, ``cycles_note``, ``frf``
            (every key: docs/json.md).
        """
        return self._d

    @property
    def elements(self) -> _t.Dict[str, str]:
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

    def plot(self, ax=None):
        """Parameter drift: each linear parameter identified at every level, over the
        element's intensity (σ of its relative displacement for a stiffness, of its relative
        velocity for a damping), with ±1 standard error bars, relative to its weighted mean.

        Parameters
        ----------
        ax : matplotlib Axes or sequence of Axes, optional
            One per parameter; by default a new figure with one panel per parameter.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ImportError
            Without matplotlib.
        """
        plt = _pyplot()
        params = self._d["detection"]["params"]
        if ax is None:
            cols = min(3, len(params))
            rows = -(-len(params) // cols)
            fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
            axes = list(axes.ravel())
        else:
            axes = list(ax) if isinstance(ax, (list, tuple, _np.ndarray)) else [ax]
            fig = axes[0].figure
        unit = {"σ_s": "m", "σ_v": "m/s"}
        for a, p in zip(axes, params):
            c = p["curve"]
            mean = p["mean"] if p["mean"] else 1.0
            x = _np.asarray(p["sigma"], dtype=float)
            y = _np.asarray(c["values"], dtype=float) / mean
            e = _np.asarray(c["stderrs"], dtype=float) / abs(mean)
            color = "#d62728" if p["drifting"] else "#1f77b4"
            a.errorbar(x, y, yerr=e, fmt="o-", color=color, capsize=3, lw=1.4)
            a.axhline(1.0, color="#888888", lw=0.8, ls=":")
            name = p["sigma_name"]
            a.set_xlabel(f"{name} [{unit[name]}]" if name in unit else name)
            a.set_ylabel(f"{c['param']} / weighted mean")
            a.set_title(f"{c['param']} ({c['element']}){': drifts' if p['drifting'] else ''}", fontsize=10)
            a.grid(alpha=0.3)
        for a in axes[len(params):]:
            a.set_visible(False)
        fig.tight_layout()
        return fig

    def plot_frf(self, ax=None):
        return _plot_frf(self._d.get("frf") or [], "detection", ax)

    plot_frf.__doc__ = _FRF_DOC

    def __repr__(self) -> str:
        return self.table.rstrip() + "".join(f"\nwarning: {w}" for w in self.warnings)

    def _repr_html_(self) -> str:
        return f"<pre>{_html.escape(repr(self))}</pre>"


class Diagnosis:
    """Where a model and the data disagree, the most likely unmodelled effect and how far
    the gap shrinks once it is added (scored on a withheld level), as ``dynid diagnose``.

    Attributes
    ----------
    summary : str
        The text ``dynid diagnose`` prints.
    report_html : str
        Its HTML report (``_repr_html_`` shows it inline in a notebook).
    parameters : DataFrame or dict of arrays
        The corrected model's parameters (the model as given plus every found effect)
        identified on all levels: value, stderr, nominal, kind.
    fixed_source : str
        The corrected model as ``.dyn`` source; ``fixed_model`` compiles it.
    refined : Refinement or None
        The corrected model refined by output error (``diagnose(…, refine=True)``).
    segments : dict or None
        How one record was cut into levels (``segments=``).
    """

    def __init__(self, result, summary: str, report_html: str, source: _t.Optional[str] = None, spectra=()):
        self._d = result
        self.summary = summary
        self.report_html = report_html
        self._source = source
        self._spectra = list(spectra)

    def plot_frf(self, ax=None):
        return _plot_frf(self._d.get("frf") or [], "diagnosis", ax)

    plot_frf.__doc__ = _FRF_DOC

    def plot_spectra(self, ax=None):
        """Power spectral density of each measured response on the largest level: the
        measured signal (thick, grey, drawn first so that no model hides it) and the free
        runs of the model as given (nominal), re-identified and corrected, each with that
        level withheld (the report's PSD figure); one frequency range for all panels.

        Parameters
        ----------
        ax : matplotlib Axes or sequence of Axes, optional
            One per response; by default a new figure.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ImportError
            Without matplotlib.

        Examples
        --------
        >>> d.plot_spectra().savefig("psd.png")    # doctest: +SKIP
        """
        plt = _pyplot()
        spectra = self._spectra
        if not spectra:
            raise _error(
                DynidError,
                "this diagnosis has no spectra: no free run of the largest level succeeded",
                "see the summary for the levels whose free run diverged",
                "dynid::diagnose::no_spectra",
            )
        if ax is None:
            fig, axes = plt.subplots(1, len(spectra), figsize=(5.2 * len(spectra), 4.0), squeeze=False)
            axes = list(axes.ravel())
        else:
            axes = list(ax) if isinstance(ax, (list, tuple, _np.ndarray)) else [ax]
            fig = axes[0].figure
        fmax = max(float(_np.asarray(s[3])[-1]) for s in spectra)
        styles = {"nominal": ("#1f77b4", ":"), "re-identified (level withheld)": ("#ff7f0e", "--")}
        for a, (signal, unit, level, f, measured, models) in zip(axes, spectra):
            f = _np.asarray(f)
            keep = f > 0
            a.semilogy(f[keep], _np.asarray(measured)[keep], color="#555555", lw=3.0, alpha=0.6, label="measured")
            for name, psd in models:
                color, ls = styles.get(name, ("#d62728", "-"))
                a.semilogy(f[keep], _np.asarray(psd)[keep], color=color, ls=ls, lw=1.3, label=name)
            a.set_xlim(0.0, fmax)
            a.set_xlabel("frequency [Hz]")
            a.set_ylabel(f"PSD of {signal} [{unit}²/Hz]" if unit else f"PSD of {signal}")
            a.set_title(f"{signal}, level {level}", fontsize=10)
            a.grid(alpha=0.3, which="both")
        axes[0].legend(fontsize=8, loc="best")
        fig.tight_layout()
        return fig

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The result as ``dynid diagnose --json`` writes it (one schema for both).

        Returns
        -------
        dict
            ``schema_version`` and the diagnosis' fields with ``free_run_start`` and
            ``frf`` (every key: docs/json.md).
        """
        return self._d

    @property
    def verdict(self) -> str:
        return _verdict_text(self._d["verdict"])

    @property
    def found(self) -> _t.List[_t.Dict[str, _t.Any]]:
        return self._d["found"]

    @property
    def fixed_source(self) -> str:
        """The corrected model as ``.dyn`` source; after ``refine=True`` with the refined
        values when the refinement was applied (as ``--write-model`` writes it)."""
        return self._source if self._source is not None else self._d["fixed_source"]

    @property
    def refined(self) -> _t.Optional[Refinement]:
        """The output-error refinement of the corrected model on all levels
        (``refine=True``, ``dynid diagnose --refine``), else None."""
        r = self._d.get("refined")
        return None if r is None else Refinement(r)

    @property
    def segments(self) -> _t.Optional[_t.Dict[str, _t.Any]]:
        """How one record was cut into levels (JSON ``segments``), else None."""
        return self._d.get("segments")

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

    def plot(self, ax=None):
        """Parameter drift: the model's parameters identified at every level, relative to
        their value at the first level that has one, with ±1 standard error bars.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Where to draw; by default a new figure.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ImportError
            Without matplotlib.
        """
        plt = _pyplot()
        if ax is None:
            fig, ax = plt.subplots(figsize=(8, 4))
        else:
            fig = ax.figure
        n = len(self._d["levels"])
        x = _np.arange(1, n + 1)
        for p in self._d["drift"]:
            vals = [_np.nan if v is None else v for v in p["per_level"]]
            errs = [_np.nan if v is None else v for v in p["stderr"]]
            ref = next((v for v in vals if _np.isfinite(v) and v != 0), None)
            if ref is None:
                continue
            ax.errorbar(x, _np.asarray(vals) / ref, yerr=_np.abs(_np.asarray(errs) / ref), fmt="o-", capsize=3, label=p["name"])
        ax.axhline(1.0, color="#888888", lw=0.8, ls=":")
        ax.set_xticks(x)
        ax.set_xlabel("level")
        ax.set_ylabel("identified value / value at the first level")
        ax.set_title("Parameter drift over the levels")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=9, ncol=2, loc="best")
        fig.tight_layout()
        return fig

    def save_report(self, path) -> None:
        """Write the HTML report (it opens offline).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write.
        """
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
    """A compiled model (``.dyn`` source or a compiled ``.json`` model).

    Examples
    --------
    >>> model = dynid.Model.from_file("models/sdof_cubic_coulomb.dyn")   # doctest: +SKIP
    >>> model.unknowns                                                    # doctest: +SKIP
    ['k', 'd', 'k3', 'r']
    """

    def __init__(self, compiled: "_dynid.CompiledModel"):
        self._m = compiled

    def __reduce__(self):
        # Pickled as its source (a distributed engine ships models to its workers).
        return (Model.from_source, (self._m.source(), self._m.name))

    @classmethod
    def from_file(cls, path) -> "Model":
        """Compile a ``.dyn`` file, or load ``dynid compile --emit json`` output.

        Parameters
        ----------
        path : str or os.PathLike
            The model file (``.dyn``, or ``.json`` for a compiled model).

        Returns
        -------
        Model

        Raises
        ------
        FileNotFoundError
            When there is no such file.
        CompileError
            With the rendered diagnostic, line and column (a ``ValueError``).
        """
        p = _os.fspath(path)
        if not _os.path.exists(p):
            raise FileNotFoundError(_errno.ENOENT, "no model file", p)
        if _os.path.isdir(p):
            raise IsADirectoryError(_errno.EISDIR, "a directory, not a model file", p)
        return cls(_dynid.compile_file(p))

    @classmethod
    def from_source(cls, source: str, name: str = "<source>") -> "Model":
        """Compile ``.dyn`` source text.

        Parameters
        ----------
        source : str
            The model text.
        name : str, default "<source>"
            The file name shown in diagnostics.

        Returns
        -------
        Model

        Raises
        ------
        CompileError
            With the rendered diagnostic, line and column (a ``ValueError``).
        """
        return cls(_dynid.compile_source(source, name))

    @property
    def name(self) -> str:
        return self._m.name

    @property
    def equations(self) -> str:
        return self._m.equations()

    @property
    def unknowns(self) -> _t.List[str]:
        """The unknown parameters, in declaration order."""
        return self._m.unknowns()

    @property
    def measured(self) -> _t.List[str]:
        """The measured signals: the columns every level needs."""
        return self._m.measured()

    @property
    def source(self) -> str:
        """The model as ``.dyn`` source."""
        return self._m.source()

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The compiled model (the JSON of ``dynid compile --emit json``)."""
        return _json.loads(self._m.to_json())

    def with_parameters(self, parameters) -> "Model":
        """The model with the unknown parameters' nominal values set.

        Parameters
        ----------
        parameters : dict, Identification or Refinement
            Values by name (an Identification gives its refined values where a refinement
            was applied, else the covariance estimate).

        Returns
        -------
        Model

        Raises
        ------
        ParameterError
            A name that is not an unknown parameter, or a value that is not finite.
        """
        return Model(self._m.with_values(_values_of(parameters)))

    def __repr__(self) -> str:
        return f"<dynid.Model {self.name}: unknowns {', '.join(self.unknowns) or 'none'}>\n{self.equations.rstrip()}"

    def simulate(
        self,
        levels: _t.Optional[_t.Sequence[float]] = None,
        duration: float = 2000.0,
        seed: int = 1,
        sample: _t.Optional[float] = None,
        noise: float = 0.0,
        burn_in: float = 100.0,
        inputs=None,
        parameters=None,
        from_rest: bool = False,
        substeps: int = _SUBSTEPS,
        map=None,
    ):
        """Simulate the model: at its excitation levels (random excitation, as
        ``dynid simulate``), or driven by measured inputs (as ``dynid simulate --input``).

        Parameters
        ----------
        levels : sequence of float, optional
            White-noise intensities of the excitation, one per level (default: the model's
            ``excite`` levels). Not with ``inputs``.
        duration, burn_in : float
            Seconds recorded per level, and simulated before the record starts.
        seed : int
            Seed of the excitation.
        sample : float, optional
            Sample interval in seconds (default 0.01; with ``inputs``: the interval of
            levels without a ``t`` column).
        noise : float
            Measurement noise as a fraction of each signal's standard deviation.
        inputs : DataFrame, dict of arrays, CSV path, or a list of them, optional
            Measured inputs, one record per level: a column per model input (and
            reference), and ``t`` (or ``sample``). Other columns are ignored.
        parameters : dict, Identification or Refinement, optional
            Values of the unknown parameters (default: their nominal values).
        from_rest : bool, default False
            With ``inputs``: start at rest at the origin instead of at the measured initial
            state of the record (positions from the first sample, velocities from their
            column or the first three positions).
        substeps : int, default 20
            With ``inputs``: RK4 sub-steps per sample interval.
        map : dict, optional
            With ``inputs``: column → signal renamings.

        Returns
        -------
        list of DataFrame (or of dicts of arrays without pandas)
            One per level: ``t`` and the model's measured signals. With ``inputs`` given as
            one level (not a list), that one level. What a random simulation simulated
            (``truth.json`` of ``dynid simulate``) is kept in ``last_truth``.

        Raises
        ------
        ParameterError
            An unknown parameter without a value, or a bad ``parameters`` entry.
        DataError
            Inputs without a column the model needs, or with non-finite values.

        Examples
        --------
        >>> data = model.simulate(duration=400, seed=1)                     # doctest: +SKIP
        >>> result = model.identify(data)                                    # doctest: +SKIP
        >>> free_run = model.simulate(inputs=data[0], parameters=result)     # doctest: +SKIP
        """
        m = self._m if parameters is None else self._m.with_values(_values_of(parameters))
        if inputs is not None:
            if levels is not None:
                raise _error(
                    OptionError,
                    "levels and inputs are both given",
                    "a driven simulation takes its levels from the measured inputs: drop `levels`",
                    "dynid::sim::config",
                )
            records, single = _input_records(m, inputs, sample, map)
            runs = m.simulate_inputs(records, None, bool(from_rest), int(substeps))
            out = [_frame(names, cols, ts, t0) for names, cols, ts, t0 in runs]
            return out[0] if single else out
        lv = None if levels is None else [float(x) for x in levels]
        records, truth = m.simulate(lv, float(duration), int(seed), 0.01 if sample is None else float(sample), float(noise), float(burn_in))
        self.last_truth = _json.loads(truth)
        return [_frame(names, cols, ts, t0) for names, cols, ts, t0 in records]

    def compare(self, data, parameters=None, sample=None, map=None, from_rest: bool = False, substeps: int = _SUBSTEPS) -> Comparison:
        """Measured vs model: the model driven by every level's measured inputs from its
        measured initial state (a free run), next to the measured responses.

        Parameters
        ----------
        data : list of DataFrame, dict of arrays or CSV path
            The measured levels (inputs and responses).
        parameters : dict, Identification or Refinement, optional
            Values of the unknown parameters (default: their nominal values).
        sample : float, optional
            Sample interval where a level has no ``t`` column.
        map : dict, optional
            Column → signal renamings.
        from_rest, substeps
            As in :meth:`simulate`.

        Returns
        -------
        Comparison
            ``errors`` (free-run RMS per level and signal) and ``plot()`` (the overlay).

        Examples
        --------
        >>> run = model.compare(data, parameters=model.identify(data))   # doctest: +SKIP
        >>> run.errors                                                    # doctest: +SKIP
        >>> run.plot(level=2)                                             # doctest: +SKIP
        """
        levels, _ = _as_list(data)
        measured = []
        for i, level in enumerate(levels):
            if _is_path(level):
                if _pd is None:
                    raise ImportError("reading CSV files in Python needs pandas: `pip install pandas`")
                path = _os.fspath(level)
                if not _os.path.exists(path):
                    raise FileNotFoundError(_errno.ENOENT, f"level {i + 1}: no data file", path)
                level = _pd.read_csv(path)
            if map:
                names, get = _columns_of(level, i)
                level = {dict(map).get(n, n): _as_column(get(n), i + 1, n) for n in names}
            measured.append(level)
        # The measured signals are checked as identify checks them.
        _levels(self._m, measured, sample, None)
        simulated = self.simulate(inputs=measured, parameters=parameters, sample=sample, from_rest=from_rest, substeps=substeps)
        pairs = self._m.responses()
        responses = [n for n, _ in pairs]
        units = dict(pairs)
        return Comparison(measured, simulated, responses, units)

    def identify(
        self,
        data,
        sample: _t.Optional[float] = None,
        filter_corners: _t.Optional[_t.Sequence[float]] = None,
        noise_correction: bool = True,
        balance: bool = False,
        column_chains: bool = False,
        keep_rests: bool = False,
        allow_large: bool = False,
        map=None,
        refine: bool = False,
        test=None,
        weights: _t.Optional[_t.Mapping[str, float]] = None,
        shooting: _t.Optional[float] = None,
        substeps: int = _SUBSTEPS,
        allow_long: bool = False,
        progress=None,
        corner_check: bool = True,
        filtered_equation: bool = False,
        weighted_rows: bool = False,
        input_delay: bool = False,
        instrument_rows: bool = False,
    ) -> Identification:
        """Identify the unknown parameters, all levels pooled, as ``dynid identify``.

        Parameters
        ----------
        data : list of DataFrame, dict of arrays or CSV path
            One level each (a single DataFrame or dict is one level).
        sample : float, optional
            Sample interval in seconds where a level has no ``t`` column.
        filter_corners : sequence of float, optional
            Identification filter corners in rad/s (default: designed from the data).
        noise_correction, balance, column_chains, keep_rests, allow_large : bool
            The command's flags (``--no-noise-correction`` is ``noise_correction=False``).
        map : dict, optional
            Column → signal renamings (``--map disp=m1.x`` is ``map={"disp": "m1.x"}``).
        refine : bool, default False
            Refine the covariance estimate by minimising the free-run simulation error
            (``--refine``); the result's ``refined`` holds it.
        test : list, optional
            With ``refine``: levels on which to report the free-run errors of both
            estimates, not used for fitting (``--test``).
        weights : dict, optional
            With ``refine``: weight per compared signal (``--weight m1.x=2``).
        shooting : float, optional
            With ``refine``: longest sub-record in seconds (``--shooting``).
        substeps : int, default 20
            With ``refine``: RK4 sub-steps per sample interval.
        allow_long : bool, default False
            With ``refine``: run above the step limit (``--allow-long``).
        progress : callable or True, optional
            With ``refine``: called as ``progress(stage, done, total)`` after every
            iteration (stage ``"refinement"``, done and the most iterations allowed),
            from the thread doing the work; ``True`` draws a tqdm bar (tqdm optional).
        corner_check : bool, default True
            Repeat the identification with the highest filter corner moved a factor 4 down
            and up, and list the estimates that move (``filter.corner_moves`` of
            ``to_dict()``; two further identifications); ``False`` is
            ``--no-corner-check``.
        filtered_equation : bool, default False
            Rows of the filtered equation at one corner (``--filtered-equation``; docs/method.md
            §2): smaller errors of masses, friction and offsets on records whose input is
            smooth between samples.
        weighted_rows : bool, default False
            Solve a second time with each level's rows weighted by their estimated
            covariance, shrunk halfway to its diagonal (``--weighted-rows``): on a many-body
            structure measured by noisy accelerometers it removes the shrinkage of the
            unit-norm rows, but its standard errors come out smaller than the spread they
            stand for (docs/method.md §2). Without it such records get each row weighted by
            its own estimated error (see ``instrument_rows``).
        input_delay : bool, default False
            Estimate a delay of each measured input against its record (``--input-delay``):
            one more parameter per input, ``"u.delay"`` in seconds, for a force that acts
            later than it is recorded or changes between samples in a way a straight line
            does not follow (docs/method.md §2, "The input between samples").
        instrument_rows : bool, default False
            Keep the instrument rows, each at unit norm, where ``identify`` would choose
            others (``--instrument-rows``). It chooses, and says so in ``filter.auto_rows``
            of ``to_dict()``, when no other row, corner or noise keyword is given: on a servo
            axis's kind of record (friction with a sign of a velocity, a measured force,
            velocities estimated from measured positions with no noise worth a correction)
            the filtered equation with the input's delay; on records of measured
            accelerations, each row weighted by its own estimated error, the weights
            re-estimated until the estimate settles, or read once where re-estimating them
            would drive a mass to zero (``filter.weighted_rows``, ``filter.weight_steps``,
            ``filter.weights_settled``, ``filter.weights_collapsed``; docs/method.md §2,
            "Rows for accelerations", and §5, "Iterated weighting").

        Returns
        -------
        Identification
            Its ``to_dict()`` is the object ``dynid identify --json`` writes.

        Raises
        ------
        FileNotFoundError
            A CSV path that does not exist.
        DataError
            Bad data (a ``ValueError``) naming the level, column and sample.
        OptionError
            A setting out of range (a ``ValueError``).

        Examples
        --------
        >>> result = model.identify(data)                       # doctest: +SKIP
        >>> result = model.identify(["level_1.csv", "level_2.csv"], map={"disp": "m1.x"})  # doctest: +SKIP
        >>> model.identify(data, refine=True).refined           # doctest: +SKIP
        """
        levels = _levels(self._m, data, sample, map)
        corners = None if filter_corners is None else [float(c) for c in filter_corners]
        if not refine and (test is not None or weights or shooting is not None):
            raise _error(
                OptionError,
                "test, weights and shooting are settings of the refinement",
                "give refine=True, or drop them",
                "dynid::refine::option",
            )
        rarg = None
        if refine:
            tests = [] if test is None else _levels(self._m, test, sample, map, "test")
            w = [(str(k), float(v)) for k, v in (weights or {}).items()]
            rarg = (w, None if shooting is None else float(shooting), int(substeps), tests, bool(allow_long))
        js, eq = self._m.identify(
            levels,
            corners,
            bool(noise_correction),
            bool(balance),
            bool(column_chains),
            bool(keep_rests),
            bool(allow_large),
            rarg,
            _progress(progress),
            bool(corner_check),
            bool(filtered_equation),
            bool(weighted_rows),
            bool(input_delay),
            bool(instrument_rows),
        )
        return Identification(_json.loads(js), eq, model=self, data=data)

    def identify_moments(self, stats) -> Identification:
        """Identify from moment statistics (:func:`moments`, :func:`merge`), as
        ``dynid identify --from``: the same estimates and standard errors as identifying
        their records together. Without data there is no corner check, closed-loop hint or
        refinement.

        Examples
        --------
        >>> result = model.identify_moments(dynid.merge(parts))   # doctest: +SKIP
        """
        js, eq = stats.identify(self._m)
        return Identification(_json.loads(js), eq, model=self)

    def refine(self, data, **kw) -> Refinement:
        """Identify, then refine the estimate by output-error minimisation: the free-run
        error of all levels (Levenberg-Marquardt), as ``dynid identify --refine``.

        Parameters
        ----------
        data : list of DataFrame, dict of arrays or CSV path
            One level each.
        **kw
            The keywords of :meth:`identify` (``test``, ``weights``, ``shooting``, ...).

        Returns
        -------
        Refinement
            Its ``to_dict()`` is the ``refined`` object of ``dynid identify --refine --json``.

        Examples
        --------
        >>> r = model.refine(data)            # doctest: +SKIP
        >>> r.parameters, r.free_run          # doctest: +SKIP
        """
        kw["refine"] = True
        result = self.identify(data, **kw)
        return result.refined


def _model(m) -> Model:
    return m if isinstance(m, Model) else Model.from_file(m)


_SPLIT_DOC = """    segments : int, optional
        With ONE level: cut it into this many contiguous levels (at least 2), as
        ``--segments N`` [default: one per cycle of a repeated trajectory, else 3 by
        amplitude]. A single level is always cut; several levels are never cut (a split
        setting with several is an ``OptionError``).
    split_by : str, optional
        With one level: judge the amplitude by this signal (``--split-by``) [default: the
        first measured position of the model].
    cut : {"auto", "cycles", "amplitude"}, default "auto"
        With one level: where to cut (``--cut``): at the cycles of a repeated trajectory
        when it repeats with one amplitude, else by amplitude; ``"cycles"`` insists,
        ``"amplitude"`` never cuts at cycles.
    allow_large : bool, default False
        Run even when the memory estimated before reading the data is above the safety
        limit (8 GB), as ``--allow-large``; without it such work is refused
        (``DynidError`` or ``DataError`` with code ``dynid::identify::too_large`` or
        ``dynid::data::too_large``) before a sample is read."""


def _split_kw(segments, split_by, cut):
    if segments is not None:
        if isinstance(segments, bool) or not isinstance(segments, (int, _np.integer)):
            raise TypeError(f"segments: expected a whole number, got {type(segments).__name__}")
        if segments < 2:
            raise _error(
                OptionError,
                f"segments = {segments}: must be at least 2 (a split gives at least two levels)",
                "give segments=N with N of at least 2 (3–8 levels make the drift test sharpest)",
                "dynid::split::segments",
            )
        segments = int(segments)
    return segments, None if split_by is None else str(split_by), str(cut)


class Segments:
    """One record cut into levels, as ``dynid detect`` and ``dynid diagnose`` cut a single
    data file (:func:`segments`).

    Attributes
    ----------
    levels : list of DataFrame or dict of arrays
        One level per segment (by amplitude: quietest first; at cycles: in time order),
        each with every column of the record and its own ``t``.
    labels : list of str
        ``record [t0–t1 s]`` per segment.
    table : str
        The segment table the command line prints to stderr.
    """

    def __init__(self, result, table: str, levels, labels):
        self._d = result
        self.table = table
        self.levels = levels
        self.labels = list(labels)

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The split as the ``segments`` object of ``dynid detect --json`` and
        ``dynid diagnose --json``.

        Returns
        -------
        dict
            ``signal``, ``omega`` (rad/s), ``min_len``, ``window``, ``segments`` (``start``,
            ``len``, ``t_start``, ``t_end``, ``sigma`` each) and ``cycles`` when cut at
            cycles.
        """
        return self._d

    def __len__(self) -> int:
        return len(self.levels)

    def __repr__(self) -> str:
        return self.table.rstrip()


def segments(model, data, sample: _t.Optional[float] = None, map=None, segments: _t.Optional[int] = None, split_by: _t.Optional[str] = None, cut: str = "auto", allow_large: bool = False) -> Segments:
    """Cut one record whose amplitude varies (a run-up, a sweep of drive levels, repeated
    cycles of one trajectory) into levels, exactly as ``dynid detect`` and
    ``dynid diagnose`` cut a single data file.

    Parameters
    ----------
    model : Model, str or os.PathLike
        The model (or its file): its measured signals are checked and its first measured
        position is the default signal judged.
    data : DataFrame, dict of arrays or path of a data file
        ONE record.
    sample : float, optional
        Sample interval in seconds where the record has no ``t`` column.
    map : dict, optional
        Column → signal renamings.
    SPLIT_PARAMETERS

    Returns
    -------
    Segments
        The levels, their labels and the table.

    Raises
    ------
    OptionError
        More than one record, or ``segments`` below 2.
    DataError
        A record too short for the segments, a signal that does not oscillate or is not a
        column (code ``dynid::split::...``, as the command line).

    Examples
    --------
    >>> split = dynid.segments("models/sdof_linear.dyn", "run_up.csv", segments=4)  # doctest: +SKIP
    >>> det = dynid.detect("models/sdof_linear.dyn", split.levels)                    # doctest: +SKIP
    """
    m = _model(model)
    levels, _ = _as_list(data)
    if len(levels) != 1:
        raise _error(
            OptionError,
            f"segments() cuts one record, but {len(levels)} were given",
            "give one record; with several, each record is one level",
            "dynid::split::several_files",
        )
    level = _levels(m._m, levels, sample, map, every_column=True)[0]
    seg, by, cut = _split_kw(segments, split_by, cut)
    js, table, recs, labels = _dynid.split(m._m, level, seg, by, cut, bool(allow_large))
    return Segments(_json.loads(js), table, [_frame(*r) for r in recs], labels)


def detect(linear_model, data, sample: _t.Optional[float] = None, alpha: float = 1e-3, map=None, frf_periods: _t.Optional[int] = None, segments: _t.Optional[int] = None, split_by: _t.Optional[str] = None, cut: str = "auto", allow_large: bool = False, weighted_rows: bool = False, instrument_rows: bool = False) -> Detection:
    """Which elements of a linear model hide a nonlinearity, and which kind, as
    ``dynid detect``: the linear model is identified at every level, and a parameter that
    drifts with the level names the effect.

    Parameters
    ----------
    linear_model : Model, str or os.PathLike
        The linear model (or its file).
    data : list of DataFrame, dict of arrays or data file path
        One level each: at least two, better three to eight spanning a factor of three or
        more in amplitude (two levels show a drift but cannot tell its shape); or ONE
        record whose amplitude varies, cut into levels (``segments``).
    sample : float, optional
        Sample interval in seconds where a level has no ``t`` column.
    alpha : float, default 1e-3
        Significance of the constancy test of each parameter curve.
    map : dict, optional
        Column → signal renamings.
    frf_periods : int, optional
        Each record holds this many periods of a periodic excitation (``--frf-periods``).
    SPLIT_PARAMETERS
    weighted_rows : bool, default False
        Fit each level with each row weighted by its own estimated error
        (``--weighted-rows``). Chosen without it where the record measures accelerations
        (the detection's ``rows`` says ``weighted_for_accelerations``): per-level values
        free of the shrinkage that noise on accelerations gives unit-norm rows
        (docs/detection.md, "Noisy accelerations").
    instrument_rows : bool, default False
        Keep each row at unit norm where detection would weight them
        (``--instrument-rows``).

    Returns
    -------
    Detection
        Its ``to_dict()`` is the object ``dynid detect --json`` writes (``segments`` when
        one record was cut).

    Raises
    ------
    OptionError
        ``alpha`` not between 0 and 1, a split setting with several levels,
        ``weighted_rows`` with ``instrument_rows``.

    Examples
    --------
    >>> det = dynid.detect("models/two_mass_linear.dyn", data)   # doctest: +SKIP
    >>> det.elements                                              # doctest: +SKIP
    >>> det.plot()                                                # doctest: +SKIP
    >>> dynid.detect("models/sdof_linear.dyn", "run_up.csv", segments=4)  # doctest: +SKIP
    """
    m = _model(linear_model)
    seg, by, cut = _split_kw(segments, split_by, cut)
    data, single = _as_list(data)
    levels = _levels(m._m, data, sample, map, every_column=len(data) == 1)
    js, table, warnings, verdicts = _dynid.detect(m._m, levels, float(alpha), frf_periods, seg, by, cut, bool(allow_large), bool(weighted_rows), bool(instrument_rows))
    return Detection(_json.loads(js), table, warnings, verdicts)


def diagnose(model, data, sample: _t.Optional[float] = None, map=None, frf_periods: _t.Optional[int] = None, segments: _t.Optional[int] = None, split_by: _t.Optional[str] = None, cut: str = "auto", allow_large: bool = False, refine: bool = False, progress=None) -> Diagnosis:
    """Where the model and the data disagree, the most likely unmodelled effect and how far
    the gap shrinks on a withheld level, as ``dynid diagnose``.

    Parameters
    ----------
    model : Model, str or os.PathLike
        The simulation model with nominal values (or its file).
    data : list of DataFrame, dict of arrays or data file path
        One level each, at least two; or ONE record cut into levels (``segments``).
    sample : float, optional
        Sample interval in seconds where a level has no ``t`` column.
    map : dict, optional
        Column → signal renamings.
    frf_periods : int, optional
        Each record holds this many periods of a periodic excitation (``--frf-periods``).
    SPLIT_PARAMETERS
    refine : bool, default False
        Refine the corrected model's values by output-error minimisation on all levels
        (``--refine``): ``refined`` holds the refinement and ``fixed_source`` the refined
        values, as ``--write-model`` writes them.
    progress : callable or True, optional
        Called as ``progress(stage, done, total)`` as the work goes on: stage
        ``"searching unmodelled effects"`` (candidates tried of all), then with ``refine``
        ``"refinement"`` (iterations of the most allowed), possibly from worker threads;
        ``True`` draws tqdm bars (tqdm optional), as the command's progress bars.

    Returns
    -------
    Diagnosis
        Its ``to_dict()`` is the object ``dynid diagnose --json`` writes.

    Examples
    --------
    >>> d = dynid.diagnose("models/two_mass_linear.dyn", data)   # doctest: +SKIP
    >>> print(d.summary); d.fixed_model                           # doctest: +SKIP
    >>> dynid.diagnose("models/sdof_linear.dyn", "run_up.csv", segments=3, refine=True)  # doctest: +SKIP
    """
    m = _model(model)
    seg, by, cut = _split_kw(segments, split_by, cut)
    data, single = _as_list(data)
    levels = _levels(m._m, data, sample, map, every_column=len(data) == 1)
    js, summary, report, source, spectra = _dynid.diagnose(m._m, levels, frf_periods, seg, by, cut, bool(allow_large), bool(refine), _progress(progress))
    return Diagnosis(_json.loads(js), summary, report, source if refine else None, spectra)


for _f in (segments, detect, diagnose):
    _f.__doc__ = _f.__doc__.replace("    SPLIT_PARAMETERS", _SPLIT_DOC)
del _f


#: Moment statistics (``dynid.moments``): what identification accumulates per record, with
#: the design they were made with. ``len(stats)`` records; ``stats.merge(other)``;
#: ``stats.origins()``; ``stats.design()`` (JSON); ``stats.to_bytes()`` (a ``.dynm`` file).
#: Picklable (as its ``.dynm`` bytes).
MomentStats = _dynid.MomentStats


def moment_design(model, data, sample: _t.Optional[float] = None, filter_corners: _t.Optional[_t.Sequence[float]] = None, noise_correction: bool = True, balance: bool = False, column_chains: bool = False, keep_rests: bool = False, allow_large: bool = False, map=None, filtered_equation: bool = False, weighted_rows: bool = False) -> str:
    """The design moment statistics are made with, decided from a sample of the data before
    any piece is measured, as ``dynid moments --design-only`` (docs/distributed.md).

    Parameters
    ----------
    model : Model, str or os.PathLike
        The model (or its file).
    data : list of DataFrame, dict of arrays or data file path
        A sample of the data set, one record each: its first pass decides the corners
        (unless given), the time blocks per record (from the shortest) and the noise
        corrections.
    sample, filter_corners, noise_correction, balance, column_chains, keep_rests, allow_large, map, filtered_equation, weighted_rows
        As :meth:`Model.identify`.

    Returns
    -------
    str
        The design as JSON (give it to :func:`moments` for every piece).

    Examples
    --------
    >>> design = dynid.moment_design(model, ["day_001.parquet"])   # doctest: +SKIP
    """
    m = _model(model)
    data, _ = _as_list(data)
    levels = _levels(m._m, data, sample, map)
    corners = None if filter_corners is None else [float(c) for c in filter_corners]
    return _dynid.moment_design(m._m, levels, corners, bool(noise_correction), bool(balance), bool(column_chains), bool(keep_rests), bool(allow_large), bool(filtered_equation), bool(weighted_rows))


def moments(model, data, design: str, sample: _t.Optional[float] = None, map=None, allow_large: bool = False) -> "MomentStats":
    """The moment statistics of some records, measured with ``design``, as
    ``dynid moments --design``: each record is one level of the pooled problem.

    Parameters
    ----------
    model : Model, str or os.PathLike
        The model the design was made for.
    data : list of DataFrame, dict of arrays or data file path
        The records of this piece (a partition of the data set).
    design : str
        The JSON of :func:`moment_design`.

    Returns
    -------
    MomentStats
        Picklable; merge with :func:`merge`, solve with :meth:`Model.identify_moments`.

    Raises
    ------
    OptionError
        ``design`` is not a design.
    DynidError
        A record too short for the design, or a design of another model
        (``dynid::moments::*``).

    Examples
    --------
    >>> part = dynid.moments(model, ["m017/day_001.parquet"], design)   # doctest: +SKIP
    """
    m = _model(model)
    data, _ = _as_list(data)
    levels = _levels(m._m, data, sample, map)
    return _dynid.measure_moments(m._m, levels, str(design), bool(allow_large))


def merge(parts) -> "MomentStats":
    """Merge moment statistics of one design, in order (associative: any grouping gives
    the same statistics).

    Raises
    ------
    DynidError
        Statistics of another design or model (``dynid::moments::other_design``), or none.
    """
    parts = list(parts)
    if not parts:
        raise _error(OptionError, "nothing to merge", "give at least one MomentStats", "dynid::moments::empty")
    out = parts[0]
    for p in parts[1:]:
        out = out.merge(p)
    return out


class Fleet:
    """The fleet's view, as ``dynid fleet``: the fleet's model (a robust centre and the
    between-machine spread), and the machines inconsistent with it by a χ² test of each
    machine's estimate against the fleet's (Bonferroni over the machines), with the
    parameters that moved (docs/fleet.md).

    Attributes
    ----------
    flagged : list of str
        The machines inconsistent with their fleet.

    ``str(fleet)`` is the report ``dynid fleet`` prints; ``to_dict()`` the object
    ``dynid fleet --json`` writes.
    """

    def __init__(self, doc: _t.Dict[str, _t.Any], text: str):
        self._d = doc
        self._text = text

    def to_dict(self) -> _t.Dict[str, _t.Any]:
        """The view as ``dynid fleet --json`` writes it (docs/json.md)."""
        return self._d

    @property
    def flagged(self) -> _t.List[str]:
        return [m["name"] for m in self._d["machines"] if m.get("status") == "flagged"]

    def __str__(self) -> str:
        return self._text

    def __repr__(self) -> str:
        return f"<dynid.Fleet: {len(self._d['machines'])} machines, flagged {self.flagged}>"


def fleet(machines: _t.Mapping[str, _t.Any], alpha: float = 0.01) -> Fleet:
    """Test machines of one model, each identified on its own, against their fleet, as
    ``dynid fleet``.

    Parameters
    ----------
    machines : dict
        Machine name → its :class:`Identification` (or the dict of its ``to_dict()``, or
        the JSON text ``dynid identify --json`` wrote).
    alpha : float, default 0.01
        Family-wise level: the chance that any machine consistent with its fleet is
        flagged.

    Returns
    -------
    Fleet

    Examples
    --------
    >>> view = dynid.fleet({name: model.identify(data[name]) for name in data})  # doctest: +SKIP
    >>> view.flagged                                                             # doctest: +SKIP
    """
    docs = []
    for name, m in machines.items():
        if isinstance(m, Identification):
            m = m.to_dict()
        docs.append((str(name), m if isinstance(m, str) else _json.dumps(m)))
    js, text = _dynid.fleet(docs, float(alpha))
    return Fleet(_json.loads(js), text)
