"""Coverage and null calibration of the paired intervals (scripts/coverage_study.py, development seeds):
drive-level random effects plus AR(0.8) within drives. The full table (2000 replications per cell, report
seeds) is in the script's docstring; these runs are small enough for the suite and still fail if coverage
collapses (the naive t of one drive's windows, which takes them as independent, fails the same check)."""

from __future__ import annotations

import pytest

from conftest import load_script

coverage_study = load_script("coverage_study")


@pytest.mark.slow
@pytest.mark.parametrize("drives,windows,lo,reps", [(1, 25, 0.88, 400), (5, 25, 0.91, 300), (12, 25, 0.91, 300),
                                                    (30, 25, 0.91, 300)])
def test_coverage_of_the_95_percent_interval(drives, windows, lo, reps):
    """D = 1: the interval holds the drive's own mean (it describes that drive only); D ≥ 5: the mean of the
    population of drives. Thresholds ~3 binomial SE below the targets (90 % at D = 1, 93 % at D ≥ 5)."""
    c = coverage_study.coverage(drives, reps, n=windows, seed0=0)
    assert lo <= c["coverage"] <= 0.995, c


@pytest.mark.slow
def test_the_coverage_check_fails_the_naive_one_drive_interval():
    # the same check, with the windows taken as independent: it must not pass (it covers about half the time)
    c = coverage_study.coverage(1, 400, n=25, seed0=0, one_drive="naive")
    assert c["coverage"] < 0.7, c


def test_null_is_called_significant_about_five_percent_of_the_time():
    # two methods with the same expected drift, independent noise: 200 replications of 5 drives × 25 windows
    z = coverage_study.null_rate(200, drives=5, n=25, seed0=500_000)
    assert 0.02 <= z["significant"] <= 0.09, z
