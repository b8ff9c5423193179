"""dynid from Python, notebook style: run it cell by cell (`# %%` cells open in Jupyter,
VS Code or Spyder), or as a script from the repository root:

    python python/examples/notebook.py

It simulates a two-mass system with Coulomb friction between the masses, identifies the
parameters of the model that knows the friction, asks detection which element of the
linear model hides a nonlinearity, and diagnoses the friction-free model against the data.
"""

# %%
import pathlib
import time

import numpy as np

import dynid

MODELS = pathlib.Path(__file__).resolve().parents[2] / "models"

# %% The "real" system: simulated with known parameters (Coulomb friction r = 0.3).
truth = dynid.Model.from_file(MODELS / "two_mass_friction.dyn")
print(truth)
data = truth.simulate(duration=400, burn_in=50, seed=7)  # one DataFrame per level
print(f"{len(data)} levels of {len(data[0]['t'])} samples; columns {list(data[0].keys())}")

# %% Identification of the model that knows the friction: all levels pooled.
t0 = time.perf_counter()
result = truth.identify(data)
print(f"identified in {time.perf_counter() - t0:.2f} s")
print(result)  # in a notebook, `result` alone shows an HTML table
print(result.parameters)

# %% Detection on the linear model: which element hides a nonlinearity?
detection = dynid.detect(MODELS / "two_mass_linear.dyn", data)
print(detection)
print(detection.elements)

# %% Diagnosis of the friction-free model: where the gap is, what closes it.
diagnosis = dynid.diagnose(MODELS / "two_mass_linear.dyn", data)
print(diagnosis.summary)  # in a notebook, `diagnosis` alone shows the HTML report inline
print(diagnosis.parameters)
diagnosis.save_report("two_mass_diagnosis.html")
print("report written to two_mass_diagnosis.html")

# %% The corrected model, with the identified friction as its nominal value.
print(diagnosis.fixed_source)

# %% Bad data are refused naming the level, column and sample.
bad = [{k: np.array(v, dtype=float) for k, v in level.items()} for level in data]
bad[1]["m2.x"][9] = float("nan")
try:
    truth.identify(bad)
except dynid.DataError as e:
    print(f"DataError: level {e.level}, column {e.column}, sample {e.sample}\n{e}")
