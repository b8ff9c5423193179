"""One record cut into levels in Python (`segments=`, `split_by=`, `cut=`, `dynid.segments`)
exactly as `dynid detect` / `dynid diagnose` cut one data file: the same levels and the
same errors, since both call the runtime's one split (`SplitChoice`)."""

import json
import subprocess

import numpy as np
import pytest

import dynid

from test_workflow import MODELS, columns, dynid_binary

LINEAR = MODELS / "sdof_linear.dyn"


@pytest.fixture(scope="module")
def one_record(tmp_path_factory):
    """The three levels of sdof_cubic_coulomb (intensities 6, 15, 40) joined end to end
    into one record with one time axis, as a dict of arrays and as a CSV file written to
    full precision (so that both give bit-identical samples)."""
    truth = dynid.Model.from_file(MODELS / "sdof_cubic_coulomb.dyn")
    levels = [columns(level) for level in truth.simulate(duration=120, seed=5)]
    names = list(levels[0])
    record = {n: np.concatenate([lv[n] for lv in levels]) for n in names}
    ts = float(levels[0]["t"][1] - levels[0]["t"][0])
    record["t"] = ts * np.arange(len(record["t"]), dtype=np.float64)
    path = tmp_path_factory.mktemp("one") / "one.csv"
    np.savetxt(path, np.column_stack([record[n] for n in names]), delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return record, str(path)


def cli(exe, args, tmp_path, ok=True):
    out = tmp_path / "out.json"
    p = subprocess.run([exe, *args, "--json", str(out)], capture_output=True, text=True)
    if ok:
        assert p.returncode == 0, p.stderr
        return json.loads(out.read_text())
    assert p.returncode != 0
    return p.stderr


@pytest.mark.parametrize("segments", [None, 4])
def test_python_cuts_one_record_into_the_levels_of_the_command_line(one_record, tmp_path, segments):
    exe = dynid_binary()
    record, path = one_record
    flags = [] if segments is None else ["--segments", str(segments)]
    expected = cli(exe, ["detect", str(LINEAR), path, *flags], tmp_path)
    assert len(expected["segments"]["segments"]) == (3 if segments is None else segments)
    # The file: the whole detection is the command's JSON (the levels' origins included).
    det = dynid.detect(LINEAR, path, segments=segments)
    assert det.to_dict() == expected
    # The split alone, of the file and of the same record as arrays: the same segments.
    assert dynid.segments(LINEAR, record, segments=segments).to_dict() == expected["segments"]
    split = dynid.segments(LINEAR, path, segments=segments)
    assert split.to_dict() == expected["segments"]
    assert len(split) == len(expected["segments"]["segments"])
    assert split.labels[0].startswith(path + " [")
    for level, seg in zip(split.levels, expected["segments"]["segments"]):
        t = np.asarray(level["t"])
        assert len(t) == seg["len"]
        assert t[0] == pytest.approx(seg["t_start"], abs=1e-9) and t[-1] == pytest.approx(seg["t_end"], abs=1e-9)
        # Every column of the record, not only the measured ones.
        assert set(columns(level)) == set(record)
    # The split levels identify as levels given one by one.
    assert dynid.detect(LINEAR, split.levels).elements == det.elements


def test_split_by_and_cut_are_the_command_line_options(one_record, tmp_path):
    exe = dynid_binary()
    record, path = one_record
    expected = cli(exe, ["detect", str(LINEAR), path, "--split-by", "m.v", "--cut", "amplitude", "--segments", "3"], tmp_path)
    got = dynid.segments(LINEAR, record, split_by="m.v", cut="amplitude", segments=3).to_dict()
    assert got == expected["segments"] and got["signal"] == "m.v"


def test_split_errors_are_the_command_line_errors(one_record, tmp_path):
    exe = dynid_binary()
    record, path = one_record
    cases = [
        # (python call, CLI flags, exception, code)
        (lambda: dynid.detect(LINEAR, [path, path], segments=3), [path, "--segments", "3"], dynid.OptionError, "dynid::split::several_files"),
        (lambda: dynid.detect(LINEAR, path, segments=40), ["--segments", "40"], dynid.DataError, "dynid::split::too_short"),
        (lambda: dynid.segments(LINEAR, path, split_by="nope"), ["--split-by", "nope"], dynid.DataError, "dynid::split::unknown_signal"),
        (lambda: dynid.diagnose(LINEAR, path, cut="cycles"), ["--cut", "cycles"], dynid.DataError, "dynid::split::no_cycles"),
    ]
    for call, flags, exc, code in cases:
        with pytest.raises(exc) as e:
            call()
        assert e.value.code == code, str(e.value)
        command = "diagnose" if "cycles" in flags else "detect"
        stderr = cli(exe, [command, str(LINEAR), path, *flags], tmp_path, ok=False)
        assert code in stderr, stderr
        # The message's first line, as the command prints it.
        first = str(e.value).splitlines()[0]
        printed = " ".join(stderr.replace("│", " ").split())
        assert " ".join(first.split()) in printed, (first, stderr)
    with pytest.raises(dynid.OptionError) as e:
        dynid.detect(LINEAR, path, segments=1)
    assert e.value.code == "dynid::split::segments"
    with pytest.raises(dynid.OptionError) as e:
        dynid.segments(LINEAR, path, cut="middle")
    assert e.value.code == "dynid::split::cut"
    with pytest.raises(dynid.OptionError):
        dynid.segments(LINEAR, [path, path])


def test_diagnose_cuts_and_refines_as_the_command_line(one_record, tmp_path):
    # `dynid diagnose --segments 3 --refine`: the same segments, diagnosis and refinement
    # of the corrected model (one library call each), and the refined values in the model
    # that `--write-model` writes.
    exe = dynid_binary()
    _, path = one_record
    model_out = tmp_path / "fixed.dyn"
    expected = cli(exe, ["diagnose", str(LINEAR), path, "--segments", "3", "--refine", "--quiet", "--write-model", str(model_out)], tmp_path)
    seen = []
    d = dynid.diagnose(LINEAR, path, segments=3, refine=True, progress=lambda *a: seen.append(a))
    got = d.to_dict()
    # Progress of both long steps, as the command's bars: the candidate search to its end,
    # then the refinement's iterations.
    search = [(k, n) for s, k, n in seen if s == "searching unmodelled effects"]
    # (the total grows when the backlash gaps are refined in a second round)
    assert search and all(0 < k <= n for k, n in search), seen
    assert max(k for k, _ in search) == max(n for _, n in search), seen
    refinement = [(k, n) for s, k, n in seen if s == "refinement"]
    assert refinement and all(0 <= k <= n for k, n in refinement), seen
    assert [s for s, _, _ in seen].index("refinement") >= len(search)
    expected.pop("closed_loop_hint", None)  # a note of the command line only
    assert got == expected
    assert d.segments == expected["segments"] and d.refined.to_dict() == expected["refined"]
    assert d.fixed_source == model_out.read_text()
