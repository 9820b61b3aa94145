"""Coverage and null calibration of the paired intervals (scripts/coverage_study.py, development seeds):
drive-level random effects plus AR(0.8) within drives."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location(
    "coverage_study", Path(__file__).resolve().parents[2] / "scripts" / "coverage_study.py")
coverage_study = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(coverage_study)


@pytest.mark.slow
@pytest.mark.parametrize("drives,windows,lo", [(1, 100, 0.90), (5, 25, 0.93), (12, 25, 0.93), (30, 25, 0.93)])
def test_coverage_of_the_95_percent_interval(drives, windows, lo):
    """D = 1: the interval holds the drive's own mean (it describes that drive only); D ≥ 5: the mean of the
    population of drives. 600 replications (binomial SE ≈ 0.9 %)."""
    c = coverage_study.coverage(drives, 600, n=windows, seed0=0)
    assert lo <= c["coverage"] <= 0.99, c


def test_null_is_called_significant_about_five_percent_of_the_time():
    # two methods with the same expected drift, independent noise: 200 replications of 5 drives × 25 windows
    z = coverage_study.null_rate(200, drives=5, n=25, seed0=500_000)
    assert 0.02 <= z["significant"] <= 0.09, z
