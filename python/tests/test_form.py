"""The result form each run of the suite claims to test."""

import os

import pytest

import dynid


def test_pandas_is_what_the_run_expects():
    """`DYNID_EXPECT_PANDAS=1` (or `0`), set by `.ci/run` for its two runs, makes the run
    fail unless results are DataFrames (or dicts of NumPy arrays): each run tests the form
    it claims to test."""
    want = os.environ.get("DYNID_EXPECT_PANDAS")
    if want is None:
        pytest.skip("DYNID_EXPECT_PANDAS not set")
    assert dynid.has_pandas() == (want == "1"), f"DYNID_EXPECT_PANDAS={want}"
