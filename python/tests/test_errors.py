"""Bad models and bad data are refused with exceptions that say where and what to do."""

import numpy as np
import pytest

import dynid


def levels(models, duration=100):
    model = dynid.Model.from_file(models / "sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=duration, seed=2)
    return model, [
        level if isinstance(level, dict) else {c: level[c].to_numpy().copy() for c in level.columns}
        for level in data
    ]


def test_non_finite_sample_names_level_column_and_sample(models):
    model, data = levels(models)
    data[1]["m.x"][16] = np.nan
    with pytest.raises(ValueError) as e:
        model.identify(data)
    err = e.value
    assert isinstance(err, dynid.DataError)
    assert (err.level, err.column, err.sample) == (2, "m.x", 17)
    # The runtime's check of a level in memory (as for a record cut from a file).
    assert "level 2: sample 17, column `m.x`: NaN is not a finite number" in str(err)
    assert err.code == "dynid::data::non_finite"
    assert "help:" in str(err)


def test_missing_column_and_ragged_columns(models):
    model, data = levels(models)
    del data[2]["m.v"]
    with pytest.raises(dynid.DataError) as e:
        model.identify(data)
    assert (e.value.level, e.value.column) == (3, "m.v")
    assert "no column for the measured signal `m.v`" in str(e.value)

    model, data = levels(models)
    data[0]["u"] = data[0]["u"][:-5]
    with pytest.raises(dynid.DataError, match="level 1: column `u` has .* samples"):
        model.identify(data)


def test_non_uniform_time_and_outlier(models):
    model, data = levels(models)
    data[0]["t"][50] += 0.004
    with pytest.raises(dynid.DataError) as e:
        model.identify(data)
    assert (e.value.level, e.value.column, e.value.sample) == (1, "t", 51)

    model, data = levels(models)
    data[2]["u"][99] = 1e12
    with pytest.raises(dynid.DataError) as e:
        model.identify(data)
    assert e.value.code == "dynid::data::outlier"
    assert (e.value.level, e.value.column, e.value.sample) == (3, "u", 100)


def test_not_numeric_column(models):
    model, data = levels(models)
    data[0]["u"] = np.array(["a"] * len(data[0]["u"]))
    with pytest.raises(dynid.DataError, match="level 1, column `u`: not numeric"):
        model.identify(data)


def test_compile_error_carries_the_rendered_diagnostic_line_and_column():
    source = "model rig {\n    body m1 = 1.0\n    input u on m1\n    damper d2 (m1, m3) ~ 0.2\n}\n"
    with pytest.raises(dynid.CompileError) as e:
        dynid.Model.from_source(source, name="rig.dyn")
    err = e.value
    assert (err.line, err.column) == (4, 20)
    assert err.code == "dyn::undefined_name"
    assert "unknown body `m3`" in str(err) and "rig.dyn" in str(err)
    assert "did you mean `m1`?" in err.rendered
    assert len(err.errors) == 1


def test_missing_model_file(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        dynid.Model.from_file(tmp_path / "nope.dyn")
    assert e.value.filename == str(tmp_path / "nope.dyn") and "no model file" in str(e.value)


def test_a_panic_in_the_runtime_is_a_dynid_error_not_a_panic_exception():
    # pyo3 turns an uncaught panic into pyo3_runtime.PanicException, which
    # `except Exception` does not catch; every call into the runtime catches it first.
    with pytest.raises(dynid.DynidError) as e:
        dynid._dynid._panic_inside_the_boundary()
    assert e.value.code == "dynid::internal"
    assert "internal error" in str(e.value)
    assert "index out of bounds" in str(e.value)


def test_detection_on_two_levels_says_they_are_too_few(models):
    # Before: a two-parameter template fitted to two levels indexed past its matrix and
    # Python saw pyo3_runtime.PanicException.
    truth = dynid.Model.from_file(models / "sdof_cubic_coulomb.dyn")
    data = truth.simulate(duration=500, seed=3)[:2]
    det = dynid.detect(models / "sdof_linear.dyn", data)
    assert "too few to rank any template" in " ".join(det.elements.values())
