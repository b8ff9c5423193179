"""Moment statistics from Python: measured per record, merged in any grouping, pickled, and
solved to the identification of the same records in one process (docs/distributed.md); the
fleet's view (docs/fleet.md); and the Dask example on its synthetic fleet."""

import importlib.util
import json
import os
import pathlib
import pickle
import subprocess
import sys

import pytest

import dynid

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"


def same(a, b, rel=1e-10):
    """Every estimate and standard error of two identification documents equal to `rel`."""
    assert a["parameters"].keys() == b["parameters"].keys()
    for name, p in a["parameters"].items():
        q = b["parameters"][name]
        for key in ("value", "stderr"):
            assert abs(p[key] - q[key]) <= rel * abs(q[key]), (name, key, p[key], q[key])


def test_pieces_merged_and_pickled_equal_the_records_identified_together(models):
    model = dynid.Model.from_file(models / "sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=200, seed=3, noise=0.01)
    whole = model.identify(data, corner_check=False).to_dict()
    design = dynid.moment_design(model, data)
    pieces = [dynid.moments(model, [level], design) for level in data]
    assert [len(p) for p in pieces] == [1, 1, 1]
    # Pickled as a distributed engine ships them, then merged in two groupings.
    pieces = [pickle.loads(pickle.dumps(p)) for p in pieces]
    in_order = dynid.merge(pieces)
    grouped = dynid.merge([pieces[0], dynid.merge(pieces[1:])])
    assert len(in_order) == 3
    for stats in (in_order, grouped):
        same(model.identify_moments(stats).to_dict(), whole)
    # The model pickles too (as its source).
    again = pickle.loads(pickle.dumps(model))
    same(again.identify_moments(in_order).to_dict(), whole)


def test_statistics_of_another_design_or_damaged_bytes_are_refused(models):
    model = dynid.Model.from_file(models / "sdof_cubic_coulomb.dyn")
    data = model.simulate(duration=200, seed=4)
    a = dynid.moments(model, [data[0]], dynid.moment_design(model, data))
    b = dynid.moments(model, [data[1]], dynid.moment_design(model, data, filter_corners=[2, 4, 8]))
    with pytest.raises(dynid.DynidError) as e:
        dynid.merge([a, b])
    assert e.value.code == "dynid::moments::other_design"
    with pytest.raises(dynid.DynidError) as e:
        dynid._dynid._moments_from_bytes(a.to_bytes()[:100])
    assert e.value.code == "dynid::moments::truncated"
    with pytest.raises(dynid.OptionError) as e:
        dynid.moments(model, [data[0]], "{}")
    assert e.value.code == "dynid::moments::design"


def dask_ready():
    need = ("dask", "distributed", "pyarrow", "pandas")
    missing = [m for m in need if importlib.util.find_spec(m) is None]
    if missing and os.environ.get("DYNID_EXPECT_DASK") == "1":
        pytest.fail(f"DYNID_EXPECT_DASK=1 but {', '.join(missing)} cannot be imported")
    if missing:
        pytest.skip(f"the Dask example needs {', '.join(missing)}")


def test_the_dask_example_finds_the_five_faulty_machines_of_its_fleet(tmp_path):
    dask_ready()
    script = EXAMPLES / "fleet_dask.py"
    run = subprocess.run(
        [sys.executable, str(script), "--out", str(tmp_path), "--workers", "2"],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    spec = importlib.util.spec_from_file_location("fleet_dask", script)
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    view = json.loads((tmp_path / "fleet.json").read_text())
    flagged = sorted(m["name"] for m in view["machines"] if m["status"] == "flagged")
    assert flagged == sorted(ex.machine_name(i) for i in ex.FAULTS), run.stdout
    for m in view["machines"]:
        if m["status"] == "flagged":
            assert m["moved"][0]["name"] == ex.FAULTS[int(m["name"][1:])][0], m
        else:
            assert m["status"] == "consistent", m
    # The design was made from the first machine's records, as identifying them in one
    # process makes it: that machine, identified from its pieces on the cluster, equals its
    # records identified together, to 1e-10.
    docs = json.loads((tmp_path / "identifications.json").read_text())
    first = ex.machine_name(0)
    paths = ex.partitions(tmp_path / "data")[first]
    model = dynid.Model.from_source(ex.SOURCE, "axis")
    same(docs[first], model.identify(paths, corner_check=False).to_dict())
