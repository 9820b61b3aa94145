"""scripts/nees_check.py: the NEES of position, velocity and both, and ``oracle_law`` (the batch filter told the
law) scored at the same epochs as the online engine's methods."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_script

nees_check = load_script("nees_check")


def test_nees_of_position_velocity_and_both():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(9, 9))
    P = a @ a.T + 9 * np.eye(9)  # correlated position and velocity, with the attitude block the filter keeps
    e = rng.normal(size=6)
    n3, nv, n6 = nees_check.nees_values(e, P)
    assert n3 == pytest.approx(e[:3] @ np.linalg.inv(P[:3, :3]) @ e[:3], rel=1e-12)
    assert nv == pytest.approx(e[3:] @ np.linalg.inv(P[3:6, 3:6]) @ e[3:], rel=1e-12)
    assert n6 == pytest.approx(e @ np.linalg.inv(P[:6, :6]) @ e, rel=1e-12)
    Pb = P.copy()
    Pb[:3, 3:6] = Pb[3:6, :3] = 0.0  # uncorrelated: the 6-dof NEES is the sum of the two
    assert sum(nees_check.nees_values(e, Pb)[:2]) == pytest.approx(nees_check.nees_values(e, Pb)[2], rel=1e-12)


def test_oracle_law_is_scored_as_the_oracle_when_the_law_adds_nothing():
    """Under the law ``none`` ``oracle_law`` and ``oracle`` are one filter (tests/experiments/test_oracle_law.py):
    the batch path of the script must then give the online engine's NEES at the same epochs."""
    job = (1004, None, "noise:1.5,3,1", "none", 60.0, 180.0, 1)
    law = nees_check.nees_run((job[0], "oracle_law", *job[2:]))
    online = nees_check.nees_run((job[0], "oracle", *job[2:]))
    assert len(law["nees3"]) == len(online["nees3"]) == 120  # 1 Hz epochs from 60 s after the start to the end
    for key in ("nees3", "neesv", "nees6"):
        np.testing.assert_allclose(law[key], online[key], rtol=1e-4, err_msg=key)
    assert 0.5 < np.mean(law["nees3"]) < 10.0  # a filter with the true models: near its 3 dof, not degenerate
