"""The spread over seeds behind the tolerances of python/tests (prints only):

    python python/examples/spread.py [SEEDS]

For seeds 1..SEEDS (default 10): the largest relative error of each parameter identified
from `sdof_cubic_coulomb` at 400 s per level (test_identify.py), and of the friction the
diagnosis of `two_mass_linear` finds in `two_mass_friction` data with its gap ratio
(test_diagnose.py).
"""

import pathlib
import sys

import dynid

MODELS = pathlib.Path(__file__).resolve().parents[2] / "models"
seeds = range(1, int(sys.argv[1]) + 1 if len(sys.argv) > 1 else 11)

model = dynid.Model.from_file(MODELS / "sdof_cubic_coulomb.dyn")
truth = {"k": 4.0, "d": 0.4, "k3": 2.0, "r": 0.3}
worst = {n: 0.0 for n in truth}
for seed in seeds:
    result = model.identify(model.simulate(duration=400, seed=seed))
    for n, t in truth.items():
        worst[n] = max(worst[n], abs(result[n] / t - 1))
print("identify sdof_cubic_coulomb, 400 s, seeds", list(seeds))
for n, w in worst.items():
    print(f"  {n:<3} largest relative error {w:.2e}")

friction = dynid.Model.from_file(MODELS / "two_mass_friction.dyn")
r_worst, ratio_worst = 0.0, 0.0
for seed in seeds:
    d = dynid.diagnose(MODELS / "two_mass_linear.dyn", friction.simulate(duration=400, burn_in=50, seed=seed))
    f = d.found[0]
    r_worst = max(r_worst, abs(f["value"] / 0.3 - 1))
    dd = d.to_dict()
    ratio_worst = max(ratio_worst, dd["gap_after"] / dd["gap_before"])
    print(f"  seed {seed}: {f['param']} = {f['value']:.5f}, gap {dd['gap_before']:.2f} % -> {dd['gap_after']:.3f} %")
print(f"diagnose two_mass_linear on two_mass_friction data, 400 s: largest |r/0.3 - 1| {r_worst:.2e}, largest gap_after/gap_before {ratio_worst:.3f}")
