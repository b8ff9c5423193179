"""Identification from simulated data with known parameters, through the Python API."""

import numpy as np
import pytest

import dynid

# (true value, relative tolerance): about 2.5x the largest relative error over seeds 1..10
# at 400 s per level (k 5.1e-4, d 1.5e-3, k3 4.0e-4, r 1.9e-3), measured by
# `python python/examples/spread.py 10`.
TRUTH = {"k": (4.0, 1.5e-3), "d": (0.4, 4e-3), "k3": (2.0, 1e-3), "r": (0.3, 5e-3)}


def columns(level):
    """A level as a dict of arrays, whatever simulate returned."""
    if isinstance(level, dict):
        return level
    return {c: level[c].to_numpy() for c in level.columns}


def test_recovery_with_fixed_seed(models):
    model = dynid.Model.from_file(models / "sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=400, seed=1)
    assert len(data) == 3
    if dynid.has_pandas():
        assert list(data[0].columns) == ["t", "m.x", "m.v", "u"]
    result = model.identify(data)
    for name, (true, tol) in TRUTH.items():
        assert abs(result[name] / true - 1) < tol, (name, result[name])
    d = result.to_dict()
    assert d["condition"] >= 1 and not d["unidentifiable"]
    p = result.parameters
    if dynid.has_pandas():
        assert list(p.columns[:2]) == ["value", "stderr"]
        assert p.loc["k3", "stderr"] > 0
    else:
        assert list(p["parameter"]) == ["k", "d", "k3", "r"]
        assert (p["stderr"] > 0).all()
    assert "<table>" in result._repr_html_()
    assert result.equations.startswith("m: ")


def test_dicts_of_arrays_give_the_same_result_as_dataframes(models):
    model = dynid.Model.from_file(models / "sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=200, seed=3)
    dicts = [columns(level) for level in data]
    a = model.identify(data).to_dict()["parameters"]
    b = model.identify(dicts).to_dict()["parameters"]
    assert a == b
    # Without a time column the sample interval is given.
    no_t = [{k: v for k, v in c.items() if k != "t"} for c in dicts]
    assert model.identify(no_t, sample=0.01).to_dict()["parameters"] == a


def test_from_source_and_model_properties():
    model = dynid.Model.from_source(
        """
        model sdof {
            body m = 1.0
            input u on m
            spring k (ground, m) ~ 4.0
            damper d (ground, m) ~ 0.4
        }"""
    )
    assert model.name == "sdof"
    assert model.unknowns == ["k", "d"]
    assert model.measured == ["m.x", "m.v", "u"]
    assert model.equations == "m: 1 m.x'' + k m.x + d m.x' = u\n"
    assert model.to_dict()["name"] == "sdof"


def test_a_sensor_offset_is_warned_about_and_named(models):
    # The same guard as `dynid identify`: a zero offset on the position sensor leaves a
    # residual the linear model cannot explain, named with its likely cause.
    model = dynid.Model.from_file(models / "sdof_linear.dyn")
    clean = model.identify(model.simulate(duration=200, seed=1))
    assert clean.fit_warnings == []
    shifted = []
    for level in model.simulate(duration=200, seed=1):
        level["m.x"] = level["m.x"] + 1.0
        shifted.append(level)
    result = model.identify(shifted)
    (w,) = result.fit_warnings
    assert (w["check"], w["cause"], w["subject"]) == ("large_residual", "sensor_offset", "m")
    assert result.to_dict()["fit_warnings"] == result.fit_warnings


def test_identify_keywords_are_the_commands_flags(models):
    # Planned moves with dwells (a third of every cycle at rest): by default the rests
    # are left out of the moments; `keep_rests` keeps them and the mass goes off. Seed 1,
    # 25 s at 1 kHz, the instrument rows: m −0.002 % by default, +2.9 % with the rests kept
    # (the servo bench over 12 seeds: RMS 0.094 % and 23 %).
    model = dynid.Model.from_file(models / "servo_axis_planned.dyn")
    data = model.simulate(duration=25, seed=1, sample=0.001)
    default = model.identify(data, instrument_rows=True)
    rests = [level["rests"] for level in default.to_dict()["levels"]]
    assert all(r["intervals"] > 0 and r["samples"] > 0 for r in rests), rests
    assert abs(default["m"] / 50 - 1) < 3e-3, default["m"]
    kept = model.identify(data, keep_rests=True)
    assert all(level.get("rests") is None for level in kept.to_dict()["levels"])
    assert abs(kept["m"] / 50 - 1) > 1e-2, kept["m"]
    chains = model.identify(data, column_chains=True, allow_large=True)
    assert chains["d"] != default["d"]
    assert abs(chains["m"] / 50 - 1) < 3e-3, chains["m"]


def test_weighted_rows_keyword(models):
    # `weighted_rows` is `--weighted-rows`: a second solve with the rows whitened, which
    # moves the estimates (within their errors on this friendly record) and is written
    # into a design made with it.
    model = dynid.Model.from_file(models / "two_mass_linear_accel.dyn")
    data = model.simulate(duration=300, seed=2, noise=0.05)
    default = model.identify(data, corner_check=False)
    weighted = model.identify(data, weighted_rows=True, corner_check=False)
    assert weighted["k1"] != default["k1"]
    assert abs(weighted["k1"] / 4 - 1) < 0.02, weighted["k1"]
    design = dynid.moment_design(model, data, weighted_rows=True)
    assert '"efficient":true' in design.replace(" ", "")


def test_filtered_equation_keyword(models):
    # `filtered_equation` is `--filtered-equation`: one corner, said in the report, and the
    # planned moves' mass within the same 0.3 % as the defaults (docs/method.md §2).
    model = dynid.Model.from_file(models / "servo_axis_planned.dyn")
    data = model.simulate(duration=25, seed=1, sample=0.001)
    result = model.identify(data, filtered_equation=True, corner_check=False)
    filt = result.to_dict()["filter"]
    assert len(filt["corners"]) == 1, filt["corners"]
    assert filt["corners_from"]["filtered"] is True
    assert abs(result["m"] / 50 - 1) < 3e-3, result["m"]
    design = dynid.moment_design(model, data, filtered_equation=True)
    assert '"filtered":true' in design.replace(" ", "")


def test_input_delay_keyword(models):
    # `input_delay` is `--input-delay`: one more parameter, the force's delay in seconds.
    # `simulate` holds the controller's force over each sample, half a sample (0.5 ms)
    # behind the straight line between samples; the CLI's test on 13 s finds 0.501 ms
    # (tests/servo_workflow.rs).
    model = dynid.Model.from_file(models / "servo_axis_planned.dyn")
    data = model.simulate(duration=25, seed=1, sample=0.001)
    result = model.identify(data, filtered_equation=True, input_delay=True, corner_check=False)
    assert 3e-4 < result["u.delay"] < 6e-4, result["u.delay"]
    assert "u(t − " in result.equations, result.equations


def test_instrument_rows_keyword(models):
    # On a servo axis's kind of record (Coulomb friction, a measured force, velocities
    # estimated from an encoder's positions) `identify` chooses the rows of the filtered
    # equation with the force's delay and says so in `filter.auto_rows`: the same estimates
    # as asking for them. `instrument_rows` is `--instrument-rows`: the instrument rows,
    # no delay (docs/method.md §2, "The rows `identify` chooses").
    model = dynid.Model.from_file(models / "servo_axis_planned.dyn")
    data = model.simulate(duration=25, seed=1, sample=0.001)
    chosen = model.identify(data, corner_check=False)
    assert chosen.to_dict()["filter"]["auto_rows"] is True
    asked = model.identify(data, filtered_equation=True, input_delay=True, corner_check=False)
    assert asked.to_dict()["filter"]["auto_rows"] is False
    assert chosen["m"] == asked["m"] and chosen["u.delay"] == asked["u.delay"]
    kept = model.identify(data, instrument_rows=True, corner_check=False)
    assert kept.to_dict()["filter"]["auto_rows"] is False
    assert "u.delay" not in kept.to_dict()["parameters"]
    assert abs(kept["m"] / 50 - 1) < 3e-3, kept["m"]
