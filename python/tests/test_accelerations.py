"""A shaker test: accelerations and the force only (``measure m.a, u``)."""

import dynid

# (true value, relative tolerance): about 2.5x the largest relative error over seeds 1..4
# at 300 s per level with 5 % noise (k 0.40 %, d 3.8 %; `identify` weights each row by its
# own estimated error at this noise, and with `instrument_rows=True` k 0.60 %, d 2.5 %),
# measured on the same records from the command line (`model.simulate` runs the simulator
# with the settings of `dynid simulate models/sdof_linear_accel.dyn --duration 300 --noise
# 0.05 --seed S`, S = 1..4, then `dynid identify`).
TRUTH = {"k": (4.0, 0.01), "d": (0.4, 0.095)}
SEED = 1


def columns(level):
    return list(level.keys()) if isinstance(level, dict) else list(level.columns)


def test_accelerations_are_columns_and_identify_the_linear_terms(models):
    model = dynid.Model.from_file(models / "sdof_linear_accel.dyn")
    assert model.measured == ["u", "m.a"]
    data = model.simulate(duration=300, seed=SEED, noise=0.05)
    assert columns(data[0]) == ["t", "u", "m.a"]
    result = model.identify(data)
    for name, (true, tol) in TRUTH.items():
        assert abs(result[name] / true - 1) < tol, (name, result[name])
    # The rows `identify` chose for these noisy accelerations, and the keyword that keeps
    # the unit-norm rows.
    assert result.to_dict()["filter"]["auto_rows"] is True
    assert result.to_dict()["filter"]["weighted_rows"] is True
    unit = model.identify(data, instrument_rows=True).to_dict()["filter"]
    assert (unit["auto_rows"], unit["weighted_rows"]) == (False, False)


def test_nonlinear_term_of_an_acceleration_only_body_reads_the_integrated_displacement():
    # The cubic spring reads the displacement integrated from `m.a`. Seeds 1..4 at 300 s,
    # 5 % noise (`dynid simulate` of this model `--duration 300 --noise 0.05 --seed S`,
    # then `dynid identify`): k3 within 10.7 %, k within 13.8 % (no damper: k is poorly
    # conditioned); bounds about 2.3 times those.
    src = (
        "model m {\n body m = 1.0\n input u on m\n spring k (ground, m) ~ 4.0\n"
        " force nl (ground, m) = k3 ~ 1.0 * s^3\n measure m.a, u\n"
        " excite u: lowpass(corner = 10) levels [6, 15]\n}\n"
    )
    model = dynid.Model.from_source(src)
    result = model.identify(model.simulate(duration=300, seed=SEED, noise=0.05))
    assert abs(result["k3"] / 1.0 - 1) < 0.25, result["k3"]
    assert abs(result["k"] / 4.0 - 1) < 0.3, result["k"]


def test_detection_weights_the_rows_of_accelerations(models):
    # `dynid.detect` on records of accelerations weights each row by its own estimated
    # error and says so in `rows`; `instrument_rows=True` keeps unit norm; asking for both
    # is an option error. On this linear oscillator nothing drifts either way.
    model = dynid.Model.from_file(models / "sdof_linear_accel.dyn")
    data = model.simulate(duration=300, seed=SEED, noise=0.05)
    chosen = dynid.detect(model, data)
    assert chosen.to_dict()["detection"]["rows"] == "weighted_for_accelerations"
    unit = dynid.detect(model, data, instrument_rows=True)
    assert unit.to_dict()["detection"]["rows"] == "unit_norm"
    for det in (chosen, unit):
        assert all(v == "linear" for v in det.elements.values()), det.elements
    try:
        dynid.detect(model, data, weighted_rows=True, instrument_rows=True)
    except dynid.OptionError:
        pass
    else:
        raise AssertionError("weighted_rows with instrument_rows was accepted")
