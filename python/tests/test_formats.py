"""MATLAB .mat (v5, written by scipy.io.savemat) and HDF5 (.h5, written by h5py) files
identify in Python with the same result as the CSV files of the same samples (the
readers are the command line's). CI installs scipy and h5py and sets
DYNID_EXPECT_NOTEBOOK=1, which makes a missing one a failure instead of a skip."""

import importlib
import os

import numpy as np
import pytest

import dynid

from test_workflow import MODELS, columns


def need(module):
    if os.environ.get("DYNID_EXPECT_NOTEBOOK") == "1":
        return importlib.import_module(module)
    return pytest.importorskip(module)


@pytest.fixture(scope="module")
def levels():
    model = dynid.Model.from_file(MODELS / "sdof_cubic_coulomb.dyn")
    return model, [columns(level) for level in model.simulate(duration=200, seed=6)]


def write_csv(path, level):
    names = list(level)
    np.savetxt(path, np.column_stack([level[n] for n in names]), delimiter=",", header=",".join(names), comments="", fmt="%.17g")


def same(a, b):
    """Two identifications agree to the last digits (the samples are bit-identical; only
    the order of floating-point sums may differ between readers)."""
    assert a.values.keys() == b.values.keys()
    for name in a.values:
        assert a.values[name] == pytest.approx(b.values[name], rel=1e-12), name
    pa, pb = a.to_dict()["parameters"], b.to_dict()["parameters"]
    for name in pa:
        assert pa[name]["stderr"] == pytest.approx(pb[name]["stderr"], rel=1e-9), name


def test_mat_and_hdf5_files_identify_as_their_csv(levels, tmp_path):
    sio = need("scipy.io")
    h5py = need("h5py")
    model, data = levels
    csv, mat, mat_vectors, h5 = [], [], [], []
    for i, level in enumerate(data, 1):
        names = list(level)
        table = np.column_stack([level[n] for n in names])
        write_csv(tmp_path / f"level_{i}.csv", level)
        csv.append(str(tmp_path / f"level_{i}.csv"))
        # MAT v5: one N×k matrix and a cell array `names` naming its columns.
        sio.savemat(tmp_path / f"level_{i}.mat", {"data": table, "names": np.array(names, dtype=object)})
        mat.append(str(tmp_path / f"level_{i}.mat"))
        # MAT v5, compressed: one column vector per signal (a dot is no MATLAB name: mapped).
        vectors = {n.replace(".", "_"): level[n][:, None] for n in names}
        sio.savemat(tmp_path / f"vectors_{i}.mat", vectors, do_compression=True)
        mat_vectors.append(str(tmp_path / f"vectors_{i}.mat"))
        # HDF5: one N×k dataset and a dataset of names.
        with h5py.File(tmp_path / f"level_{i}.h5", "w") as f:
            f["data"] = table
            f["names"] = names
        h5.append(str(tmp_path / f"level_{i}.h5"))
    expected = model.identify(csv)
    same(model.identify(mat), expected)
    same(model.identify(mat_vectors, map={"m_x": "m.x", "m_v": "m.v"}), expected)
    same(model.identify(h5), expected)
    # Mixed formats in one call, as levels.
    same(model.identify([mat[0], h5[1], csv[2]]), expected)
