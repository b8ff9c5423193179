import pathlib

import pytest

MODELS = pathlib.Path(__file__).resolve().parents[2] / "models"


@pytest.fixture
def models():
    """The example models of the repository (`models/`)."""
    return MODELS
