"""The cost of the Python layer around identification (prints only):

    dynid simulate models/sdof_cubic_coulomb.dyn --out DIR       # 3 levels x 2000 s
    python python/examples/overhead.py models/sdof_cubic_coulomb.dyn DIR/level_*.csv

Reads the CSV files once with pandas (or NumPy), then times, best of 5: the whole
`model.identify(data)` call, the native call alone on prepared levels, and the data
preparation (`float64` columns handed over in place). Compare with
`time dynid identify MODEL DIR/level_*.csv`, which also parses the CSV files.
"""

import sys
import time

import numpy as np

import dynid
from dynid import _levels

model = dynid.Model.from_file(sys.argv[1])
t0 = time.perf_counter()
if dynid.has_pandas():
    import pandas as pd

    data = [pd.read_csv(p) for p in sys.argv[2:]]
else:
    data = []
    for p in sys.argv[2:]:
        a = np.genfromtxt(p, delimiter=",", names=True)
        data.append({n: np.ascontiguousarray(a[n]) for n in a.dtype.names})
read = time.perf_counter() - t0


def best(f, n=5):
    times = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


levels = _levels(model._m, data, None)
whole = best(lambda: model.identify(data))
native = best(lambda: model._m.identify(levels, None, True, False))
prep = best(lambda: _levels(model._m, data, None), 20)
n = sum(len(level["t"]) for level in data)
print(f"{len(data)} levels, {n} samples; CSV read by {'pandas' if dynid.has_pandas() else 'numpy'} in {read:.3f} s")
print(f"model.identify(data):      {whole * 1e3:8.1f} ms (best of 5)")
print(f"native identify alone:     {native * 1e3:8.1f} ms")
print(f"data preparation (_levels): {prep * 1e3:7.2f} ms")
print(f"Python layer:              {(whole - native) * 1e3:8.1f} ms ({100 * (whole - native) / whole:.1f} % of the call)")
