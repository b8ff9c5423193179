"""Detection and diagnosis through the Python API, on simulated data whose hidden effect
is known (the data of `dynid demo`: Coulomb friction r = 0.3 between two masses that the
model under test leaves out)."""

import pytest

import dynid


@pytest.fixture(scope="module")
def friction_data():
    models = __import__("conftest").MODELS
    truth = dynid.Model.from_file(models / "two_mass_friction.dyn")
    return truth.simulate(duration=400, burn_in=50, seed=7)


@pytest.fixture(scope="module")
def diagnosis(friction_data):
    models = __import__("conftest").MODELS
    return dynid.diagnose(models / "two_mass_linear.dyn", friction_data)


def test_diagnosis_names_the_missing_friction(diagnosis):
    d = diagnosis
    found = d.found
    assert len(found) >= 1
    assert found[0]["effect"] == {"kind": "coulomb"}
    assert found[0]["location"]["a"] == "m1" and found[0]["location"]["b"] == "m2"
    # About 2.5x the spread over seeds 1..10 (largest |r/0.3 - 1| = 1.9e-3, largest
    # gap_after/gap_before = 0.004), measured by `python python/examples/spread.py 10`.
    assert abs(found[0]["value"] / 0.3 - 1) < 5e-3, found[0]
    assert d.to_dict()["gap_after"] < 0.01 * d.to_dict()["gap_before"]
    assert "Most likely missing effect: Coulomb friction" in d.summary
    html = d._repr_html_()
    assert html.startswith("<iframe srcdoc=") and "&lt;html" in html
    p = d.parameters
    names = list(p.index) if dynid.has_pandas() else list(p["parameter"])
    assert found[0]["param"] in names
    # The corrected model's values, not the friction-free model re-fitted (whose d2 the
    # missing friction inflates about twofold): d2 within 2 % of the truth 0.2.
    values = list(p["value"])
    d2 = values[names.index("d2")]
    assert abs(d2 / 0.2 - 1) < 0.02, p
    moved_d2 = [m["identified"] for m in d.to_dict()["moved"] if m["name"] == "d2"][0]
    assert moved_d2 > 1.2 * d2, (moved_d2, d2)
    assert "sign(v)" in d.fixed_source
    assert d.fixed_model.unknowns  # the corrected model compiles


def test_detection_flags_the_coupling(models, friction_data):
    det = dynid.detect(models / "two_mass_linear.dyn", friction_data)
    assert det.elements == {
        "k1/d1 (ground, m1)": "linear",
        "k2/d2 (m1, m2)": "nonlinear: Coulomb friction",
    }, det.table
    p = det.parameters
    n = len(p) if dynid.has_pandas() else len(p["value"])
    assert n == 3 * len(det.to_dict()["detection"]["params"])
    assert "<pre>" in det._repr_html_()


def test_diagnosis_plots_its_spectra_and_frf(diagnosis, tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    d = diagnosis
    fig = d.plot_spectra()
    measured = [a for a in fig.axes]
    assert len(measured) == len(d._spectra) >= 1
    for ax in fig.axes:
        labels = [l.get_label() for l in ax.get_lines()]
        # The measured PSD first (under the models), then each model's free run.
        assert labels[0] == "measured" and "corrected (level withheld)" in labels, labels
        assert ax.get_xlabel() == "frequency [Hz]" and ax.get_ylabel().endswith("²/Hz]")
    # One frequency range for every panel.
    assert len({ax.get_xlim() for ax in fig.axes}) == 1
    fig.savefig(tmp_path / "psd.png")
    plt.close(fig)
    fig = d.plot_frf()
    assert fig.axes[0].get_xlabel() == "frequency [Hz]"
    plt.close(fig)
