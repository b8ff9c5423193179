"""Work too large for memory is refused in Python as by the command line: the estimate is
made before a sample is read, the error names it with the override (`allow_large=True`,
the command's `--allow-large`), and the override lets the work past the estimate."""

import numpy as np
import pytest

import dynid

from test_workflow import MODELS


def chain_source(n: int) -> str:
    """A chain of `n` bodies with every position measured (as the runtime's test model
    `chain_source`): about terabytes of moments for n = 500."""
    s = f"model chain{n} {{\n"
    s += "".join(f"    body m{i} = 1.0\n" for i in range(1, n + 1))
    s += f"    input u on m{n}\n    measure " + "".join(f"m{i}.x, " for i in range(1, n + 1)) + "u\n"
    for i in range(1, n + 1):
        a = "ground" if i == 1 else f"m{i - 1}"
        s += f"    spring k{i} ({a}, m{i}) ~ 4.0\n    damper d{i} ({a}, m{i}) ~ 0.4\n"
    return s + "    excite u: lowpass(corner = 10) levels [6, 15, 40]\n}\n"


def chain_levels(tmp_path, n: int):
    """Three level files of three samples each (different values: no level is a copy)."""
    header = ",".join(["t"] + [f"m{i}.x" for i in range(1, n + 1)] + ["u"])
    files = []
    for level in range(1, 4):
        rows = [f"{0.01 * k}" + f",{0.1 * level * (k + 1)}" * (n + 1) for k in range(3)]
        p = tmp_path / f"level_{level}.csv"
        p.write_text(header + "\n" + "\n".join(rows) + "\n")
        files.append(str(p))
    return files


def test_identification_memory_is_refused_before_reading_unless_allow_large(tmp_path):
    model = dynid.Model.from_source(chain_source(500), name="chain500.dyn")
    files = chain_levels(tmp_path, 500)
    calls = {
        "identify": lambda **kw: model.identify(files, **kw),
        "detect": lambda **kw: dynid.detect(model, files, **kw),
        "diagnose": lambda **kw: dynid.diagnose(model, files, **kw),
    }
    for name, call in calls.items():
        with pytest.raises(dynid.DynidError) as e:
            call()
        assert e.value.code == "dynid::identify::too_large", (name, str(e.value))
        text = str(e.value)
        for part in ["TB of memory", "above the limit of about 8 GB", "1000 unknowns"]:
            assert part in text, (name, part, text)
        # The override lets it past the estimate (to the data, three samples too few).
        with pytest.raises(dynid.DataError) as e:
            call(allow_large=True)
        assert e.value.code == "dynid::data::too_few_samples", (name, str(e.value))


def sparse_csv(path, head: str, size: int):
    """A file of `size` bytes starting with `head`, sparse after it: only its size says
    how large the record would be."""
    path.write_text(head)
    with open(path, "r+b") as f:
        f.truncate(size)


def test_records_read_whole_are_refused_above_the_limit_unless_allow_large(tmp_path):
    # 3 MB of rows, then 40 GiB of (sparse) file: about 29 GB of three columns.
    t = 0.01 * np.arange(100_000)
    rows = np.column_stack([t, np.sin(t), np.cos(t), np.sin(3 * t)])
    head = "t,m.x,m.v,u\n" + "\n".join(f"{r[0]:.2f},{r[1]:.6f},{r[2]:.6f},{r[3]:.6f}" for r in rows) + "\n"
    big, big2 = tmp_path / "big.csv", tmp_path / "big2.csv"
    sparse_csv(big, head, 40 << 30)
    sparse_csv(big2, head.replace("0.00,", "0.00,1"), 40 << 30)
    sdof = MODELS / "sdof_linear.dyn"
    # One file cut into levels is read whole: refused from its size.
    for call in [lambda **kw: dynid.detect(sdof, str(big), **kw), lambda **kw: dynid.segments(sdof, str(big), **kw)]:
        with pytest.raises(dynid.DataError) as e:
            call()
        assert e.value.code == "dynid::data::too_large", str(e.value)
        assert "big.csv" in str(e.value) and "GB of memory" in str(e.value) and "allow_large=True" in e.value.help
    # Diagnosis reads its records whole: the records and the moments, estimated together.
    with pytest.raises(dynid.DynidError) as e:
        dynid.diagnose(sdof, [str(big), str(big2)])
    assert e.value.code == "dynid::identify::too_large", str(e.value)
    assert "diagnosis would take" in str(e.value) and "for the records read whole" in str(e.value)


def test_the_help_names_the_keyword_not_the_flag(tmp_path):
    model = dynid.Model.from_source(chain_source(500), name="chain500.dyn")
    with pytest.raises(dynid.DynidError) as e:
        model.identify(chain_levels(tmp_path, 500))
    assert "`allow_large=True`" in e.value.help and "--allow-large" not in e.value.help
